#!/usr/bin/env bash
# Makes the pictures of scenes/README.md's measured experiments from the shipped scenes and prints
# each run's metrics. Run from the project root after building:
#   bash scenes/pictures/experiments.sh [build/tools/stf]
# Runs are written to out/experiments/ (full resolution except the full-history bowling runs,
# which are at 3 cm spacing for 1 s: the full history costs O(steps) per particle per step).
set -eu
stf=${1:-build/tools/stf}
out=out/experiments; pic=scenes/pictures
mkdir -p "$out"
run() { local tag=$1; shift; "$stf" run "$@" -o "$out/$tag.h5" --quiet; "$stf" report "$out/$tag.h5" --json >"$out/$tag.json"; }

# Fig. 9-10: the fluid ball dropped on the floor, without history and with the paper's d = 50,
# 150, 250 (its 33 ms steps: 1.65, 4.95, 8.25 s of memory)
run drop_no_history scenes/fluid_drop_no_history.yaml
run drop_d50 scenes/fluid_drop.yaml --set effects.history.memory=1.65
run drop_d150 scenes/fluid_drop.yaml --set effects.history.memory=4.95
run drop_d250 scenes/fluid_drop.yaml --set effects.history.memory=8.25
for t in drop_no_history drop_d50 drop_d150 drop_d250; do
    "$stf" render "$out/$t.h5" --color khist --max 30000 --frames 17,22,33,199 --width 320 --height 200 \
        --camera 0.3,-0.36,0.22 --look 0,0,0.03 --montage "$pic/fluid_$t.png"
done

# Fig. 11: sliding off a 30 degree ramp
run slide_no_history scenes/fluid_slide_no_history.yaml
run slide_d50 scenes/fluid_slide.yaml --set effects.history.memory=1.65
run slide_d150 scenes/fluid_slide.yaml --set effects.history.memory=4.95
run slide_d250 scenes/fluid_slide.yaml --set effects.history.memory=8.25
for t in slide_no_history slide_d150; do
    "$stf" render "$out/$t.h5" --color khist --max 30000 --frames 8,20,40,150 --width 320 --height 200 \
        --camera 0.1,-0.95,0.55 --look 0.05,0,0.1 --montage "$pic/fluid_$t.png"
done

# Fig. 12: a layer let down gently
run gentle_no_history scenes/gentle_settle_no_history.yaml
run gentle scenes/gentle_settle.yaml

# Fig. 5-6: the vibrated layer
run vibration scenes/vibration.yaml
run vibration_no_history scenes/vibration_no_history.yaml
for t in vibration vibration_no_history; do
    "$stf" render "$out/$t.h5" --color khist --max 4000000 --frames 15,45,89 --width 300 --height 220 \
        --camera 0.4,-0.5,0.45 --look 0,0,0.06 --montage "$pic/$t.png"
    "$stf" render "$out/$t.h5" --color khist --max 4000000 --frames 60,89 --width 400 --height 220 \
        --camera 0,-0.75,0.13 --look 0,0,0.09 --montage "$pic/${t}_side.png"
done

# Fig. 8: the bowling ball with full history and q = 0.2 against q = 0.5, d = 150
run bowling_q02_full scenes/bowling_ball.yaml --set fluid.spacing=0.03 --duration 1.0 \
    --set effects.history.q=0.2 --set effects.history.mode=full
run bowling_q05_d150 scenes/bowling_ball.yaml --set fluid.spacing=0.03 --duration 1.0 \
    --set effects.history.q=0.5 --set effects.history.d=150
for t in bowling_q02_full bowling_q05_d150; do "$stf" plot "$out/$t.h5" -o "$pic/${t}_plot.png"; done

# Fig. 2-4: the single-particle history analysis
"$stf" history -o "$out/history" >/dev/null
for f in fig2_weights fig3_impact fig4_constant; do cp "$out/history/$f.png" "$pic/history_$f.png"; done

for j in "$out"/*.json; do echo "== $(basename "$j" .json)"; cat "$j"; done
