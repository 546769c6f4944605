#!/usr/bin/env bash
# Paper Fig. 12: without a high-energy interaction the shear-thickening fluid behaves like the
# viscoelastic one. A layer let down gently from 1 cm (scenes/gentle_settle.yaml) at 2 cm
# spacing, with and without history: the settled centre-of-mass height agrees within 5%, and
# neither bounces (rises by a quarter spacing, the default bounce_min_rise). Args: STF_BINARY PROJECT_DIR
stf=$1; src=$2
. "$src/tests/exp_lib.sh"
S="--set fluid.spacing=0.02"
run hist gentle_settle $S
run none gentle_settle_no_history $S
h=$(metric hist fluid.final_com_height); n=$(metric none fluid.final_com_height)
rh=$(metric hist fluid.com_rebound_height); rn=$(metric none fluid.com_rebound_height)
echo "final centre-of-mass height: history $h m, none $n m; rebound $rh m, $rn m"
holds "abs($h - $n) <= 0.05 * $n" "settled height within 5% of the viscoelastic run"
holds "$rh < 0.005 and $rn < 0.005" "no bounce in either (rise < a quarter spacing)"
exit $((fails > 0))
