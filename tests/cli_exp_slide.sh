#!/usr/bin/env bash
# Paper Fig. 11: a fluid ball thrown onto a 30 degree ramp (scenes/fluid_slide.yaml, the
# cornstarch material), without history and with the paper's d = 50, 150, 250 (its steps of
# 33 ms: 1.65, 4.95, 8.25 s of memory). Claims:
#  - at 1.5 cm spacing (251 particles) for 14 s: the time it keeps its solid state
#    (fluid.solid_duration) grows with d: none < 50 < 150 < 250, each step by >= 2 frames
#    (measured 0.05, 6.27, 9.42, 10.36 s: the ball rolls off the ramp as a solid, comes to rest
#    on the floor and softens seconds later, once the windows have dropped the impacts; 14 s
#    holds the softening of all three);
#  - at 1 cm (895 particles, the scene's own spacing and memory): with history it jumps after
#    the first contact with the ramp (the centre of mass's rise in the first 0.3 s, twice as
#    high as and 1.5 mm higher than without; measured 10.1 mm and 0) and slides as a solid (it
#    keeps its shape >= 0.4 s of the 2 s run); without history it smears out (< 0.2 s). The
#    paper gives the jump to its longest memory; its windows, 1.65 s and longer, are longer
#    than the jump, so Eq. 3 sums the same samples for every d and the jump is the same.
# Args: STF_BINARY PROJECT_DIR
stf=$1; src=$2
. "$src/tests/exp_lib.sh"
run_d_series fluid_slide --set fluid.spacing=0.015 --set duration=14.0
for t in none d50 d150 d250; do
    eval "sd_$t=$(metric $t fluid.solid_duration)"
    echo "$t: solid_duration $(eval echo \$sd_$t) s"
done
holds "$sd_none + 0.02 <= $sd_d50 and $sd_d50 + 0.02 <= $sd_d150 and $sd_d150 + 0.02 <= $sd_d250" \
    "solid duration none < 50 < 150 < 250"
run jump fluid_slide --duration 0.3
run jump_none fluid_slide_no_history --duration 0.3
run hist fluid_slide
run none1 fluid_slide_no_history
jh=$(metric jump fluid.com_rebound_height) jn=$(metric jump_none fluid.com_rebound_height)
sh=$(metric hist fluid.solid_duration) sn=$(metric none1 fluid.solid_duration)
echo "1 cm: jump after the first contact: history $jh m, none $jn m; solid_duration $sh s, $sn s"
holds "$jh >= 2 * $jn and $jh >= $jn + 0.0015" "1 cm: with history it jumps off the ramp, without it does not"
holds "$sh >= 0.4 and $sn < 0.2" "1 cm: with history it slides as a solid, without it smears out"
exit $((fails > 0))
