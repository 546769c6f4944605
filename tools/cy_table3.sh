#!/usr/bin/env bash
# cy_table3.sh - the second paper's Table 3 for this code: time per simulated second of the
# Carreau-Yasuda model with implicit and with explicit viscosity, each at the largest stable
# time step from a list.
#
#   tools/cy_table3.sh [STF_BINARY] [SCENE] [DURATION_S] [THREADS]
#   defaults: build/tools/stf scenes/cy_collapse_thickening.yaml 0.3 1
#   CY_TABLE3_SET="fluid.spacing=0.025" adds --set overrides (space-separated) to every run.
#
# A time step is good when `stf run` ends normally (exit 0, not the blow-up exit 3), no
# particle is faster than 3 m/s (free fall from the column's top gives 2.5 m/s), and the
# front of the collapsing column (largest particle x at the end) is within one particle
# spacing of the implicit solver's at dt = 3e-4 s: large implicit steps stay stable but
# damp the flow (backward Euler with the viscosity frozen over the step). Each solver's list
# is tried from the largest step down; the first good one is reported with its wall time
# (the run's wall_seconds attribute) divided by the simulated time.
set -u
STF=${1:-build/tools/stf}
SCENE=${2:-scenes/cy_collapse_thickening.yaml}
DUR=${3:-0.3}
THREADS=${4:-1}
OUT=$(mktemp -d "${TMPDIR:-/tmp}/cy_table3.XXXXXX") || exit 1
trap 'rm -rf "$OUT"' EXIT

extra=()
for kv in ${CY_TABLE3_SET:-}; do extra+=(--set "$kv"); done
implicit_dts="0.016 0.012 0.008 0.006 0.004 0.003 0.002 0.001 0.0006 0.0003"
explicit_dts="0.0003 0.0002 0.00015 0.0001 0.00007 0.00005 0.00003 0.00002"

# run SOLVER DT: prints "exit max_speed wall_seconds steps mean_cg mean_pressure_iterations
# front", front the largest particle x of the last frame (m): how far the column spread
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
steps = sorted((k for k in f.keys() if k.startswith("Step#")), key=lambda k: int(k[5:]))
front = float(f[steps[-1]]["x"][:].max()) if steps else float("nan")
print(rc, m["fluid"]["max_speed"], a.get("wall_seconds", float("nan")), a.get("substeps", 0),
      a.get("viscosity_iterations_mean", float("nan")), a.get("pressure_iterations_mean", float("nan")),
      front, a.get("spacing", float("nan")))
EOF
}

# A reference for the front: the implicit solver at a small step.
read -r _ _ _ _ _ _ ref_front spacing < <(run implicit 0.0003)
echo "scene $SCENE, $DUR s simulated, $THREADS thread(s); $(uptime)"
printf '| viscosity | largest good dt (s) | rejected at (s) | steps | CG iterations / step | pressure iterations / step | front x at the end (m) | wall s per simulated s |\n'
printf '| --- | --- | --- | --- | --- | --- | --- | --- |\n'
for solver in implicit explicit; do
    dts=$implicit_dts
    [ $solver = explicit ] && dts=$explicit_dts
    unstable="-"
    for dt in $dts; do
        read -r rc vmax wall steps cg pit front _ < <(run $solver "$dt")
        if [ "$rc" = 0 ] && /usr/bin/python3 -c "import sys; sys.exit(0 if float('$vmax') < 3 and abs($front - $ref_front) <= $spacing else 1)"; then
            per=$(/usr/bin/python3 -c "print('%.1f' % ($wall / $DUR))")
            printf '| %s | %s | %s | %s | %.1f | %.2f | %.3f | %s |\n' $solver "$dt" "$unstable" "$steps" "$cg" "$pit" "$front" "$per"
            break
        fi
        echo "  ($solver dt = $dt: exit $rc, max speed $vmax m/s, front $front m: rejected)" >&2
        unstable=$dt
    done
done
echo "reference: implicit at dt = 0.0003 s puts the front at x = $ref_front m; a step is good when the run ends normally, no particle exceeds 3 m/s and the front is within one spacing ($spacing m) of the reference"
