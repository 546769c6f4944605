#!/usr/bin/env bash
# Paper Fig. 11: a fluid ball thrown onto a 30 degree ramp (scenes/fluid_slide.yaml) at 1.5 cm
# spacing, without history and with d = 50, 150, 250 steps. Claim: the time it slides as a
# solid before it smears out (fluid.solid_duration) grows with d: none < 50 < 150 < 250, each
# step by >= 2 frames. Args: STF_BINARY PROJECT_DIR
stf=$1; src=$2
. "$src/tests/exp_lib.sh"
S="--set fluid.spacing=0.015"
run_d_series fluid_slide $S
for t in none d50 d150 d250; do
    eval "sd_$t=$(metric $t fluid.solid_duration)"
    echo "$t: solid_duration $(eval echo \$sd_$t) s"
done
holds "$sd_none + 0.02 <= $sd_d50 and $sd_d50 + 0.02 <= $sd_d150 and $sd_d150 + 0.02 <= $sd_d250" \
    "solid duration none < 50 < 150 < 250"
exit $((fails > 0))
