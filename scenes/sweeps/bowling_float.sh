#!/usr/bin/env bash
# The bowling ball (scenes/bowling_ball.yaml) across the history parameters, at a reduced
# resolution (spacing 3 cm: 2,420 particles; 2 s simulated, dt = 1 ms). Two sweeps:
#  DIR/grid:  k_hist in {0, 2.5, 5, 10} in the paper's units of k_min (0, 50000, 100000,
#             200000 in SI at the scene's 2 cm reference spacing, see src/README.md, "Units") x
#             d in {50, 150, 250} steps: 12 runs. Plots: float duration (grid.png) and the
#             ball's final height (grid_final_z.png) against k_hist, one line per d.
#  DIR/onset: k_hist from 0 to 2.5 k_min in steps of 0.5 (0..50000 SI), d = 50: 6 runs, where
#             the ball stops sinking. Plot: float duration (onset.png).
# Each writes its summary.csv (the shipped ones: bowling_float_grid.csv, bowling_float_onset.csv).
#
# usage: bash scenes/sweeps/bowling_float.sh [STF] [DIR] [more stf sweep options, e.g. --jobs 2]
set -eu
here=$(cd "$(dirname "$0")" && pwd)
STF=${1:-$here/../../build/tools/stf}
DIR=${2:-bowling_float}
shift $(( $# < 2 ? $# : 2 ))
common=("$here/../bowling_ball.yaml" --set fluid.spacing=0.03 --duration 5)
mkdir -p "$DIR"
st=0
"$STF" sweep "${common[@]}" -o "$DIR/grid" \
    --vary effects.history.k_hist=0,75000,150000,300000 --vary effects.history.d=50,150,250 \
    --plot ball.float_duration --png "$DIR/grid.png" "$@" || st=$?
# the same sweep again: every run is done, so this only draws another metric
"$STF" sweep "${common[@]}" -o "$DIR/grid" \
    --vary effects.history.k_hist=0,75000,150000,300000 --vary effects.history.d=50,150,250 \
    --plot ball.final_z --png "$DIR/grid_final_z.png" "$@" || st=$?
"$STF" sweep "${common[@]}" -o "$DIR/onset" \
    --vary effects.history.k_hist=0:75000:6 --set effects.history.d=50 \
    --plot ball.float_duration --png "$DIR/onset.png" "$@" || st=$?
exit $st
