#!/usr/bin/env bash
# Paper Fig. 8: full history (every past step) with q = 0.2 gives a longer-lasting
# solidification than q = 0.5 with d = 150. The bowling ball scene at 3 cm spacing (2420
# particles), the first second: with q = 0.2 and full history the pool holds the ball higher
# (its centre ends at least a sixth of the spacing higher) and it bounces higher; a ball that
# sinks (top under the surface) with q = 0.2 must not do so before the q = 0.5 ball.
# Args: STF_BINARY PROJECT_DIR
stf=$1; src=$2
. "$src/tests/exp_lib.sh"
S="--set fluid.spacing=0.03 --duration 1.0"
run full02 bowling_ball $S --set effects.history.q=0.2 --set effects.history.mode=full
run d150q05 bowling_ball $S --set effects.history.q=0.5 --set effects.history.d=150
zf=$(metric full02 bodies.ball.final_position.2); zd=$(metric d150q05 bodies.ball.final_position.2)
rf=$(metric full02 bodies.ball.max_rebound_height); rd=$(metric d150q05 bodies.ball.max_rebound_height)
sf=$(metric full02 bodies.ball.sink_time); sd=$(metric d150q05 bodies.ball.sink_time)
echo "q=0.2 full: final centre height $zf m, rebound $rf m, sink time $sf s"
echo "q=0.5 d=150: final centre height $zd m, rebound $rd m, sink time $sd s"
holds "$zf >= $zd + 0.005" "q=0.2 full history holds the ball higher"
holds "$rf > $rd" "and it bounces higher"
holds "($sf != $sf) or ($sd == $sd and $sf >= $sd)" "it does not sink earlier"
exit $((fails > 0))
