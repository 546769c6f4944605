#!/usr/bin/env bash
# cy_table3.sh - the second paper's Table 3 for this code: time per simulated second of the
# Carreau-Yasuda model with implicit and with explicit viscosity, each at the largest stable
# time step from a list.
#
#   tools/cy_table3.sh [STF_BINARY] [SCENE] [DURATION_S] [THREADS]
#   defaults: build/tools/stf scenes/cy_collapse_thickening.yaml 0.3 1
#   CY_TABLE3_SET="fluid.spacing=0.025" adds --set overrides (space-separated) to every run.
#
# A time step is stable when `stf run` ends normally (exit 0, not the blow-up exit 3) and no
# particle is faster than 3 m/s (free fall from the column's top gives 2.4 m/s). Each
# solver's list is tried from the largest step down; the first stable one is reported with
# its wall time (the run's wall_seconds attribute) divided by the simulated time.
set -u
STF=${1:-build/tools/stf}
SCENE=${2:-scenes/cy_collapse_thickening.yaml}
DUR=${3:-0.3}
THREADS=${4:-1}
OUT=$(mktemp -d "${TMPDIR:-/tmp}/cy_table3.XXXXXX") || exit 1
trap 'rm -rf "$OUT"' EXIT

extra=()
for kv in ${CY_TABLE3_SET:-}; do extra+=(--set "$kv"); done
implicit_dts="0.004 0.003 0.002 0.0015 0.001 0.0006 0.0003"
explicit_dts="0.0003 0.0002 0.00015 0.0001 0.00007 0.00005 0.00003 0.00002"

# run SOLVER DT: prints "exit max_speed wall_seconds steps mean_cg mean_pressure_iterations"
run() {
    local f="$OUT/$1_$2.h5"
    "$STF" run "$SCENE" --set dt="$2" --set effects.carreau_yasuda.viscosity_solver="$1" \
        --duration "$DUR" --threads "$THREADS" --quiet -o "$f" "${extra[@]}" 2>"$OUT/err"
    local rc=$?
    /usr/bin/python3 - "$f" "$rc" <<'EOF'
import sys, json, h5py
f, rc = h5py.File(sys.argv[1], "r"), sys.argv[2]
m = json.loads(f["metrics"].attrs["json"]) if "metrics" in f else {"fluid": {"max_speed": float("nan")}}
a = f.attrs
print(rc, m["fluid"]["max_speed"], a.get("wall_seconds", float("nan")), a.get("substeps", 0),
      a.get("viscosity_iterations_mean", float("nan")), a.get("pressure_iterations_mean", float("nan")))
EOF
}

echo "scene $SCENE, $DUR s simulated, $THREADS thread(s); $(uptime)"
printf '| viscosity | largest stable dt (s) | unstable at (s) | steps | CG iterations / step | pressure iterations / step | wall s per simulated s |\n'
printf '| --- | --- | --- | --- | --- | --- | --- |\n'
for solver in implicit explicit; do
    dts=$implicit_dts
    [ $solver = explicit ] && dts=$explicit_dts
    unstable="-"
    for dt in $dts; do
        read -r rc vmax wall steps cg pit < <(run $solver "$dt")
        if [ "$rc" = 0 ] && /usr/bin/python3 -c "import sys; sys.exit(0 if float('$vmax') < 3 else 1)"; then
            per=$(/usr/bin/python3 -c "print('%.1f' % ($wall / $DUR))")
            printf '| %s | %s | %s | %s | %.1f | %.2f | %s |\n' $solver "$dt" "$unstable" "$steps" "$cg" "$pit" "$per"
            break
        fi
        echo "  ($solver dt = $dt: exit $rc, max speed $vmax m/s: unstable)" >&2
        unstable=$dt
    done
done
