#!/usr/bin/env bash
# Why this model gives no vibration fingers (scenes/README.md, "Vibration"): two series that
# show the history terms flattening a shaken surface, never raising it.
#  1. The shipped vibration scene at 2 cm (3 s, seeds 7 and 8) for k_hist from 4e5 to 1.2e8
#     (the material has 4e7)
#     and without history: fluid.finger_height and fluid.escaped of each.
#  2. One vibration source: a 4 x 4 cm kinematic piston in the floor under a 16 x 16 x 5 cm
#     layer (1 cm spacing, 1,232 particles), 5, 10 and 15 Hz with 3-6 mm and random frequency
#     changes, with and without history: the finger heights and their ratio.
# About 3 min of wall on 2 cores.
# usage: bash scenes/sweeps/vibration_why.sh [STF] [DIR]
set -eu
here=$(cd "$(dirname "$0")" && pwd)
. "$here/vibration_lib.sh"
STF=${1:-$here/../../build/tools/stf}
DIR=${2:-vibration_why}
mkdir -p "$DIR"
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
sweep() { "$STF" sweep "$@" --jobs 2 --threads 1 --quiet >/dev/null; }
table() { # table SUMMARY.csv KEY...: the given columns and the two metrics, one row a run
    /usr/bin/python3 - "$@" <<'PY'
import csv, sys
keys = sys.argv[2:]
for r in csv.DictReader(open(sys.argv[1])):
    print("  ".join("%s=%s" % (k.split(".")[-1], r[k]) for k in keys),
          " finger_height %.2f cm  escaped %s" % (100 * float(r["fluid.finger_height"]), r["fluid.escaped"]))
PY
}

# 1. the history stiffness constant on the shipped scene
# (the shipped scenes' expect: blocks are for their own settings, not these)
S=(--set fluid.spacing=0.02 --unset expect --vary container.vibration.seed=7,8)
sweep "$here/../vibration_no_history.yaml" "${S[@]}" -o "$DIR/none"
sweep "$here/../vibration.yaml" "${S[@]}" -o "$DIR/khist" \
    --vary effects.history.k_hist=4.0e5,1.3e6,4.0e6,1.3e7,4.0e7,1.2e8
echo "1. shipped scene at 2 cm, no history:"; table "$DIR/none/summary.csv" container.vibration.seed
echo "   with history:"; table "$DIR/khist/summary.csv" effects.history.k_hist container.vibration.seed

# 2. one vibration source
source_scene() { # source_scene HISTORY(0|1)
    layer vibration_source 0.08 0.05 "$1" 50 0
    cat <<YAML
container: {size: [0.16, 0.16, 0.3], wall: 0.02, friction: 0.2}
bodies:
  - {name: source, shape: box, size: [0.04, 0.04, 0.04], position: [0, 0, -0.005],
     motion: kinematic, stick: $([ "$1" = 1 ] && echo true || echo false),
     vibration: {axis: [0, 0, 1], amplitude: 0.004, frequency: 10, jitter: 0.3,
                 jitter_period: 0.25, seed: 3}}
YAML
}
source_scene 1 >"$DIR/source.yaml"; source_scene 0 >"$DIR/source_no_history.yaml"
V=(--vary bodies.0.vibration.frequency=5,10,15 --vary bodies.0.vibration.amplitude=0.003,0.004,0.005,0.006)
sweep "$DIR/source_no_history.yaml" "${V[@]}" -o "$DIR/source_none"
sweep "$DIR/source.yaml" "${V[@]}" -o "$DIR/source_hist"
echo "2. one source (1 cm spacing): finger height without / with history"
/usr/bin/python3 - "$DIR/source_none/summary.csv" "$DIR/source_hist/summary.csv" <<'PY'
import csv, sys
key = lambda r: (float(r["bodies.0.vibration.frequency"]), float(r["bodies.0.vibration.amplitude"]))
none, hist = ({key(r): float(r["fluid.finger_height"]) for r in csv.DictReader(open(p))} for p in sys.argv[1:])
for k in sorted(none):
    print("  %2.0f Hz %.0f mm: %.2f / %.2f cm (ratio %.2f)" % (k[0], 1000 * k[1], 100 * none[k], 100 * hist[k], hist[k] / none[k]))
PY
