# exp_lib.sh - shared by the cli_exp_*.sh tests (the paper's experiments at a reduced
# resolution): run a scene variant and read one of its metrics back from `stf report --json`.
# Source it after setting stf (the binary) and src (the project directory).
set -u
tmp=$(mktemp -d "${PWD:-/tmp}/exp.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}

# run TAG SCENE [--set/--unset ...]: runs the scene into $tmp/TAG.h5; exits the test on failure.
run() {
    local tag=$1 scene=$2; shift 2
    "$stf" run "$src/scenes/$scene.yaml" -o "$tmp/$tag.h5" --quiet "$@" >"$tmp/$tag.log" 2>&1 \
        || { echo "$tag: stf run failed:" >&2; cat "$tmp/$tag.log" >&2; exit 1; }
}

# run_d_series SCENE [--set ...]: the paper's series, into none (no history, no boundary
# stick) and d50, d150, d250: the paper's d = 50, 150, 250 steps of its 33 ms step, given as
# the history memory in seconds (1.65, 4.95, 8.25 s; d in steps of our 1 ms step would be
# windows 33 times shorter than the paper's).
run_d_series() {
    local scene=$1; shift
    run none "$scene" "$@" --unset effects.history --unset effects.boundary_stick
    run d50 "$scene" "$@" --set effects.history.memory=1.65
    run d150 "$scene" "$@" --set effects.history.memory=4.95
    run d250 "$scene" "$@" --set effects.history.memory=8.25
}

# metric TAG KEY: prints the metric (a dotted path into the report JSON: fluid.solid_duration,
# bodies.ball.final_position.2); null prints nan.
metric() {
    "$stf" report "$tmp/$1.h5" --json | python3 -c '
import json, sys
v = json.load(sys.stdin)
for k in sys.argv[1].split("."):
    v = v[int(k)] if isinstance(v, list) else v[k]
print("nan" if v is None else v)' "$2"
}

# holds "EXPR" WHAT: evaluates a Python comparison of numbers; prints it and counts failures.
fails=0
holds() {
    if python3 -c "import sys; from math import nan; sys.exit(0 if ($1) else 1)"; then
        echo "ok:   $2  ($1)"
    else
        echo "FAIL: $2  ($1)" >&2
        fails=$((fails + 1))
    fi
}
