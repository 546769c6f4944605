#!/usr/bin/env bash
# Paper Fig. 9-10: a fluid ball dropped on the floor (scenes/fluid_drop.yaml) at 1.5 cm
# spacing (251 particles), without history and with d = 50, 150, 250 steps. Claims: without
# history it does not bounce, with history its centre of mass rebounds (at least twice as
# high, and by more than a tenth of the spacing), and the time it keeps its shape
# (fluid.solid_duration) grows with d: none < 50 < 150 < 250, each step by >= 2 frames.
# Args: STF_BINARY PROJECT_DIR
stf=$1; src=$2
. "$src/tests/exp_lib.sh"
S="--set fluid.spacing=0.015"
run_d_series fluid_drop $S
for t in none d50 d150 d250; do
    eval "reb_$t=$(metric $t fluid.com_rebound_height) sd_$t=$(metric $t fluid.solid_duration)"
    echo "$t: com_rebound_height $(eval echo \$reb_$t) m, solid_duration $(eval echo \$sd_$t) s"
done
for d in 50 150 250; do
    r=$(eval echo \$reb_d$d)
    holds "$r >= 2 * $reb_none and $r > 0.0015" "d=$d rebounds, none does not"
done
holds "$sd_none + 0.02 <= $sd_d50 and $sd_d50 + 0.02 <= $sd_d150 and $sd_d150 + 0.02 <= $sd_d250" \
    "solid duration none < 50 < 150 < 250"
exit $((fails > 0))
