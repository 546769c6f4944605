#!/usr/bin/env bash
# The settings checked for the paper's vibration fingers (scenes/README.md, "Vibration"):
# each pair is the shipped scene with / without history at 2 cm spacing (3 s), with the
# changes given; prints fluid.finger_height (of the fluid body) and fluid.escaped of both,
# and the surface analysis of scenes/sweeps/surface_relief.py when h5py is present.
# About 10 s of CPU a pair at 2 cm.
# usage: bash scenes/sweeps/vibration_checks.sh [STF] [DIR]
set -eu
here=$(cd "$(dirname "$0")" && pwd)
. "$here/vibration_lib.sh"
STF=${1:-$here/../../build/tools/stf}
DIR=${2:-vibration_checks}
mkdir -p "$DIR"
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
metric() { "$STF" report "$1" --json | /usr/bin/python3 -c \
    'import json, sys; f = json.load(sys.stdin)["fluid"]; print(f["finger_height"], f["escaped"])'; }
# pair TAG SCENE_WITH SCENE_WITHOUT [--set ...]: the history settings are dropped for "without"
pair() {
    local tag=$1 sh=$2 sn=$3; shift 3
    local none=() a
    for a in "$@"; do case $a in effects.history.*|effects.boundary_stick.*) unset 'none[-1]';; *) none+=("$a");; esac; done
    "$STF" run "$sh" -o "$DIR/${tag}_h.h5" --quiet --set fluid.spacing=0.02 "$@"
    "$STF" run "$sn" -o "$DIR/${tag}_n.h5" --quiet --set fluid.spacing=0.02 "${none[@]}"
    echo "$tag: finger_height (m), escaped: with history $(metric "$DIR/${tag}_h.h5"); without $(metric "$DIR/${tag}_n.h5")"
    /usr/bin/python3 -c 'import h5py' 2>/dev/null && \
        /usr/bin/python3 "$here/surface_relief.py" "$DIR/${tag}_h.h5" "$DIR/${tag}_n.h5"
    return 0
}
H=$here/../vibration.yaml; N=$here/../vibration_no_history.yaml
V=container.vibration
pair shipped "$H" "$N"
for o in 3000 10000 30000; do pair onset$o "$H" "$N" --set effects.history.k_onset=$o; done
pair onset30000_khx5 "$H" "$N" --set effects.history.k_onset=30000 --set effects.history.k_hist=1000000
pair d500 "$H" "$N" --set effects.history.d=500
pair d500_onset10000 "$H" "$N" --set effects.history.d=500 --set effects.history.k_onset=10000
pair f15 "$H" "$N" --set $V.frequency=15 --set $V.amplitude=0.003 --set effects.history.k_onset=3000
pair f10 "$H" "$N" --set $V.frequency=10 --set $V.amplitude=0.005 --set effects.history.k_onset=3000
pair f25 "$H" "$N" --set $V.frequency=25 --set $V.amplitude=0.004
thin=(--set container.size=[0.2,0.2,0.2] --set fluid.blocks.0.min=[-0.1,-0.1,0]
      --set fluid.blocks.0.max=[0.1,0.1,0.03] --set $V.frequency=40 --set $V.amplitude=0.0015)
pair thin "$H" "$N" "${thin[@]}" --set fluid.spacing=0.01
pair thin_onset3000 "$H" "$N" "${thin[@]}" --set fluid.spacing=0.01 --set effects.history.k_onset=3000

# The paper's "equally distributed vibration sources": nine 6 x 6 cm kinematic pistons in the
# floor under a 6 cm layer, 10 Hz, 1.5 cm, each with its own random frequency changes.
pistons() { # pistons HISTORY(0|1)
    layer vibration_sources 0.15 0.06 "$1" 50 3000
    printf 'container: {size: [0.3, 0.3, 0.3], wall: 0.02, friction: 0.2}\nbodies:\n'
    local n=0 x y
    for x in -0.1 0 0.1; do for y in -0.1 0 0.1; do n=$((n + 1)); cat <<YAML
  - {name: p$n, shape: box, size: [0.06, 0.06, 0.04], position: [$x, $y, -0.005], motion: kinematic,
     stick: $([ "$1" = 1 ] && echo true || echo false),
     vibration: {axis: [0, 0, 1], amplitude: 0.015, frequency: 10, jitter: 0.3, jitter_period: 0.25, seed: $n}}
YAML
    done; done
}
pistons 1 >"$DIR/sources.yaml"; pistons 0 >"$DIR/sources_no_history.yaml"
pair sources "$DIR/sources.yaml" "$DIR/sources_no_history.yaml"
pair sources_onset0 "$DIR/sources.yaml" "$DIR/sources_no_history.yaml" --set effects.history.k_onset=0
pair sources_d500 "$DIR/sources.yaml" "$DIR/sources_no_history.yaml" --set effects.history.d=500

# A thin layer at 1 cm (20 x 20 x 4 cm, 1,600 particles, d = 150) shaken at 10, 20, 30 Hz with
# 2, 5, 10 mm (0.8-36 g), k_hist 5e4 and 2e5, onset 0 and 3000, against the same without
# history: `stf sweep` of each, and the ratio of the finger heights (about 4 s of CPU a run).
thin() { # thin HISTORY(0|1)
    layer thin_layer 0.1 0.04 "$1" 150 0
    cat <<YAML
container:
  size: [0.2, 0.2, 0.25]
  wall: 0.02
  friction: 0.2
  motion: kinematic
  vibration: {axis: [0, 0, 1], amplitude: 0.003, frequency: 20, jitter: 0.3, jitter_period: 0.25, seed: 7}
YAML
}
thin 1 >"$DIR/thin.yaml"; thin 0 >"$DIR/thin_no_history.yaml"
F=container.vibration.frequency=10,20,30; A=container.vibration.amplitude=0.002,0.005,0.01
"$STF" sweep "$DIR/thin_no_history.yaml" --vary $F --vary $A -o "$DIR/thin_none" --jobs 2 --threads 1 >/dev/null
"$STF" sweep "$DIR/thin.yaml" --vary $F --vary $A --vary effects.history.k_hist=50000,200000 \
    --vary effects.history.k_onset=0,3000 -o "$DIR/thin_hist" --jobs 2 --threads 1 >/dev/null
/usr/bin/python3 - "$DIR/thin_none/summary.csv" "$DIR/thin_hist/summary.csv" <<'PY'
import csv, sys
key = lambda r: (r["container.vibration.frequency"], r["container.vibration.amplitude"])
none = {key(r): float(r["fluid.finger_height"]) for r in csv.DictReader(open(sys.argv[1]))}
ratios = [float(r["fluid.finger_height"]) / none[key(r)] for r in csv.DictReader(open(sys.argv[2]))]
print("thin layer: finger height with / without history, %d runs: %.2f .. %.2f" % (len(ratios), min(ratios), max(ratios)))
PY
