#!/usr/bin/env bash
# Paper Fig. 9-10: a fluid ball dropped on the floor (scenes/fluid_drop.yaml, the cornstarch
# material) without history and with the paper's d = 50, 150, 250 (its steps of 33 ms: 1.65,
# 4.95, 8.25 s of memory). Claims:
#  - Fig. 9, at 1.5 cm spacing (251 particles) for 14 s: without history it does not bounce,
#    with history its centre of mass rebounds (at least twice as high, and by more than a
#    tenth of the spacing), and the time it keeps its shape (fluid.solid_duration) grows with
#    d: none < 50 < 150 < 250, each step by >= 2 frames. The windows are longer than the
#    bounce, so the three rebounds are the same (Eq. 3 sums the same samples until 1.65 s
#    after the start); they differ when the fluid softens, seconds later (measured 0, 4.77,
#    6.20, 6.72 s): the run must outlast the longest memory's softening, hence 14 s;
#  - Fig. 10, at 1 cm (895 particles, the scene's own spacing and memory, 2 s): the ball with
#    history bounces (twice as high as, and 1.5 mm higher than, the one without) and keeps its
#    shape at least 0.4 s, the one without keeps it less than 0.2 s.
# Args: STF_BINARY PROJECT_DIR
stf=$1; src=$2
. "$src/tests/exp_lib.sh"
run_d_series fluid_drop --set fluid.spacing=0.015 --set duration=14.0
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
run hist fluid_drop
run none1 fluid_drop_no_history
rh=$(metric hist fluid.com_rebound_height) sh=$(metric hist fluid.solid_duration)
rn=$(metric none1 fluid.com_rebound_height) sn=$(metric none1 fluid.solid_duration)
echo "1 cm: history: com_rebound_height $rh m, solid_duration $sh s; none: $rn m, $sn s"
holds "$rh >= 2 * $rn and $rh >= $rn + 0.0015" "1 cm: the ball with history bounces, the one without does not"
holds "$sh >= 0.4 and $sn < 0.2" "1 cm: with history it keeps its shape, without it spreads"
exit $((fails > 0))
