#!/usr/bin/env bash
# Paper Fig. 5-6, what this model reproduces of it: a layer shaken by its container's floor
# (scenes/vibration.yaml, 8 Hz with random frequency changes, 3 g) at 2 cm spacing (1125
# particles). With history the shaken layer stiffens and stays in its container; the same
# fluid without history sloshes over the walls (at least 1% of its particles). The paper's
# fingers (fluid.finger_height with history >= 2x without) do NOT appear in this model: the
# measured finger heights (of the fluid body, spray excluded) are printed, not held; the
# history layer's is the lower one (README, "Experiments", lists every setting tried).
# Args: STF_BINARY PROJECT_DIR
stf=$1; src=$2
. "$src/tests/exp_lib.sh"
S="--set fluid.spacing=0.02"
run hist vibration $S
run none vibration_no_history $S
eh=$(metric hist fluid.escaped); en=$(metric none fluid.escaped); n=$(metric none fluid.particles)
fh=$(metric hist fluid.finger_height); fn=$(metric none fluid.finger_height)
echo "escaped: history $eh, none $en of $n; finger_height: history $fh m, none $fn m"
holds "$eh == 0" "with history the shaken layer stays in the container"
holds "$en >= 0.01 * $n" "without history it spills"
exit $((fails > 0))
