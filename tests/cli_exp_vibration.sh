#!/usr/bin/env bash
# Paper Fig. 5-6, what this model reproduces of it: a layer shaken by its container's floor
# (scenes/vibration.yaml, 8 Hz with random frequency changes, 3 g) at 2 cm spacing (1125
# particles) of the cornstarch material. With history the shaken layer stiffens and stays in
# its container; the same fluid without history sloshes over the walls (at least 1% of its
# particles).
# The paper's fingers (fluid.finger_height with history >= 2x without) do NOT appear in this
# model, and this test holds why: the history terms only add spring stiffness, and the stiffer
# they are, the flatter the shaken layer (the finger height, of the fluid body, falls from no
# history through a tenth of the material's k_hist to the material's own; scenes/README.md,
# "Vibration").
# Args: STF_BINARY PROJECT_DIR
stf=$1; src=$2
. "$src/tests/exp_lib.sh"
S="--set fluid.spacing=0.02"
run hist vibration $S
run soft vibration $S --set effects.history.k_hist=4.0e6   # a tenth of the material's
run none vibration_no_history $S
eh=$(metric hist fluid.escaped); en=$(metric none fluid.escaped); n=$(metric none fluid.particles)
fh=$(metric hist fluid.finger_height); fs=$(metric soft fluid.finger_height)
fn=$(metric none fluid.finger_height)
echo "escaped: history $eh, none $en of $n"
echo "finger_height: the material $fh m, a tenth of its k_hist $fs m, no history $fn m"
holds "$eh == 0" "with history the shaken layer stays in the container"
holds "$en >= 0.01 * $n" "without history it spills"
holds "$fs < 0.8 * $fn" "a little history stiffness flattens the shaken surface"
holds "$fh < 0.8 * $fs" "more history stiffness flattens it further"
exit $((fails > 0))
