#!/usr/bin/env bash
# The bowling ball's float duration (and every other metric) over the history stiffness and
# the history window: k_hist in {0, 2.5, 5, 10} in the paper's units of k_min (0, 50000,
# 100000, 200000 in SI at the scene's 2 cm reference spacing, see README "Units") and d in
# {50, 150, 250} steps; 12 runs at a reduced resolution (spacing 3 cm: 2,420 particles),
# 2 s simulated. Writes DIR/summary.csv and DIR/summary.png (README, "Sweeps").
#
# usage: bash scenes/sweeps/bowling_float.sh [STF] [DIR] [extra stf sweep options, e.g. --jobs 2]
set -eu
here=$(cd "$(dirname "$0")" && pwd)
STF=${1:-$here/../../build/tools/stf}
DIR=${2:-bowling_float}
shift $(( $# < 2 ? $# : 2 ))
exec "$STF" sweep "$here/../bowling_ball.yaml" -o "$DIR" \
    --set fluid.spacing=0.03 --duration 2 \
    --vary effects.history.k_hist=0,50000,100000,200000 \
    --vary effects.history.d=50,150,250 \
    --plot ball.float_duration "$@"
