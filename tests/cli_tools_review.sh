# cli_tools_review.sh - the file tools (report, plot, render, sweep, history) on users' files:
# `stf report`'s metrics agree with the same quantities computed from the output file by
# h5py, and bad input exits 2 with a message and leaves every existing file as it was.
#
# usage: bash cli_tools_review.sh STF_BINARY PROJECT_DIR   (run in the build's tests directory)
. "$(dirname "$0")/lib_cli.sh" cli_tools_review "$@"
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive
PY=/usr/bin/python3 # with h5py
SCENE=$PROJ/tests/scenes/small_drop.yaml

# expect_bad NAME CMD...: CMD exits 2 and prints a message on stderr.
expect_bad() {
    local name=$1
    shift
    "$@" >"$name.out" 2>"$name.err"
    local rc=$?
    [ $rc -eq 2 ] || fail "$name: exited $rc, expected 2 ($*)"
    [ -s "$name.err" ] || fail "$name: no message on stderr ($*)"
}

# A ball thrown up from the resting fluid's surface (1 m/s, 2 cm radius): it touches at
# t = 0, rises v^2 / 2g = 5.1 cm and comes down again.
"$STF" run "$SCENE" -o b.h5 --quiet --threads 1 --set 'fluid.blocks.0.velocity=[0, 0, 0]' \
    --set 'bodies.0.velocity=[0.2, 0, 1]' --set 'bodies.0.position=[0, 0, 0.1]' >run.err 2>&1 ||
    { fail "stf run exited $?"; cat run.err >&2; exit 1; }

# 1. report: metrics against an independent reading of the file (definitions: metrics.h)
"$STF" report b.h5 --json >report.json || fail "stf report --json exited $?"
"$PY" - b.h5 report.json <<'EOF' || fail "stf report disagrees with h5py"
import json, sys
import h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
m = json.load(open(sys.argv[2]))
radius, spacing = 0.02, float(f.attrs["spacing"])
steps = sorted((k for k in f if k.startswith("Step#")), key=lambda k: int(k[5:]))
z0 = f[steps[0]]["z"][()]
surface = z0.max() + spacing / 2  # the highest particle centre + spacing/2 at t = 0
b = f["bodies/ball"]
t, pos = b["time"][()], b["position"][()]
z = pos[:, 2]
touch = np.nonzero(z - radius <= surface + spacing)[0]
assert len(touch), "the ball never touches"
c = touch[0]
sunk = np.nonzero(z + radius < surface)[0]
end = sunk[0] if len(sunk) else len(z)
# rise from the lowest point after contact to the highest point after that, before sinking
lo = np.minimum.accumulate(z[c:end])
rebound = (z[c:end] - lo).max()
speed = max(np.sqrt(sum(f[s][k][()].astype(float) ** 2 for k in ("vx", "vy", "vz"))).max() for s in steps)
want = {"time_end": float(f[steps[-1]].attrs["TimeValue"]), "surface_height": surface,
        "first_contact_time": t[c], "max_rebound_height": rebound,
        "final_x": pos[-1, 0], "final_y": pos[-1, 1], "final_z": pos[-1, 2], "max_speed": speed,
        "particles": len(f[steps[-1]]["x"])}
ball = m["bodies"]["ball"]
got = {"time_end": m["time_end"], "surface_height": m["surface_height"],
       "first_contact_time": ball["first_contact_time"],
       "max_rebound_height": ball["max_rebound_height"],
       "final_x": ball["final_position"][0], "final_y": ball["final_position"][1],
       "final_z": ball["final_position"][2], "max_speed": m["fluid"]["max_speed"],
       "particles": m["fluid"]["particles"]}
bad = [f"{k}: report {got[k]!r}, h5py {want[k]!r}" for k in want
       if got[k] is None or abs(got[k] - want[k]) > 1e-6 * max(1.0, abs(want[k]))]
# the physics: a rise of v^2 / 2g (1 m/s up) within 10%, one bounce
g = 9.81
if not abs(rebound - 1.0 / (2 * g)) < 0.1 / (2 * g): bad.append(f"rebound {rebound} m, not ~{1/(2*g):.4f} m")
if ball["bounces"] != 1: bad.append(f"bounces {ball['bounces']}, expected 1")
if bad: sys.exit("\n".join(bad))
EOF

# 2. a picture never replaces a file that is not a picture: plot -o or render --montage onto
#    the run itself (or a scene) refused, nothing changed; a PNG is replaced as before
cp b.h5 keep.h5
cp "$SCENE" scene.yaml
expect_bad plot_onto_run "$STF" plot b.h5 -o b.h5
cmp -s b.h5 keep.h5 || { fail "stf plot -o b.h5 overwrote the run b.h5"; cp keep.h5 b.h5; }
expect_bad montage_onto_run "$STF" render b.h5 --montage b.h5 --width 64 --height 48
cmp -s b.h5 keep.h5 || { fail "stf render --montage b.h5 overwrote the run b.h5"; cp keep.h5 b.h5; }
expect_bad plot_onto_scene "$STF" plot b.h5 -o scene.yaml
cmp -s scene.yaml "$SCENE" || fail "stf plot -o scene.yaml overwrote the scene"
"$STF" plot b.h5 -o p.png >/dev/null && "$STF" plot b.h5 -o p.png --width 400 >/dev/null ||
    fail "stf plot could not replace its own p.png"

# 3. sweep -o into an existing directory that holds no sweep (no plan.txt): refused, as it
#    would take a finished run_0000.h5 there for its own first run and replace summary.csv
mkdir other && cp keep.h5 other/run_0000.h5 && echo "my notes" >other/summary.csv
ls -l --time-style=+%s%N other >other.before
expect_bad sweep_other_dir "$STF" sweep "$SCENE" --vary bodies.0.mass=0.5,0.06 --duration 0.01 \
    --jobs 1 --threads 1 --quiet -o other
ls -l --time-style=+%s%N other | cmp -s - other.before && cmp -s other/run_0000.h5 keep.h5 &&
    grep -qx "my notes" other/summary.csv || fail "stf sweep -o other changed the directory"
mkdir empty
"$STF" sweep "$SCENE" --vary bodies.0.mass=0.05 --duration 0.01 --jobs 1 --threads 1 --quiet \
    -o empty >empty.out 2>empty.err || fail "stf sweep -o into an empty directory exited $?"

# 4. render into a directory of earlier frames: a damaged frame (its x data zeroed on disk,
#    so it no longer inflates) fails the render with exit 2, and the earlier frames stay
cp keep.h5 damaged.h5
"$PY" - damaged.h5 <<'EOF' || fail "cannot damage a copy of b.h5"
import sys, h5py
with h5py.File(sys.argv[1], "r") as f:
    steps = sorted((k for k in f if k.startswith("Step#")), key=lambda k: int(k[5:]))
    chunk = f[steps[6]]["x"].id.get_chunk_info(0)
with open(sys.argv[1], "r+b") as raw:
    raw.seek(chunk.byte_offset)
    raw.write(bytes(chunk.size))
EOF
"$STF" render b.h5 --every 1 -o frames --width 64 --height 48 >r1.out 2>r1.err ||
    fail "stf render b.h5 exited $?"
md5sum frames/* >frames.before
expect_bad render_damaged "$STF" render damaged.h5 -o frames --width 80 --height 60
md5sum -c --quiet frames.before >/dev/null 2>&1 && [ "$(ls frames | wc -l)" = "$(wc -l <frames.before)" ] ||
    fail "stf render of a damaged file changed the frames already in the directory"

# 5. sweep's chart options are checked before any run: a metric or key that does not exist,
#    or a --png in a missing directory, exits 2 without running (it ran every run, then
#    said "no plot" and exited 0)
for opt in "--plot nosuch" "--plot ball.nosuch" "--x nosuch" "--series nosuch" "--png nodir/s.png" \
    "--png scene.yaml"; do
    name=sweep_$(echo "$opt" | tr -c 'a-z' _)
    expect_bad "$name" "$STF" sweep "$SCENE" --vary bodies.0.mass=0.05 --duration 0.01 --jobs 1 \
        --threads 1 --quiet -o "$name" $opt
    [ -e "$name/run_0000.h5" ] && fail "stf sweep $opt ran before refusing it"
done
"$STF" sweep "$SCENE" --vary bodies.0.mass=0.05,0.06 --duration 0.01 --jobs 1 --threads 1 --quiet \
    -o plotted --plot ball.final_z --x bodies.0.mass >plotted.out 2>plotted.err &&
    [ -s plotted/summary.png ] || fail "stf sweep --plot ball.final_z did not plot"

# 6. history: every refusal says why, at the right place
longq=$(printf '0.5%.0s,' $(seq 80))0.5
expect_bad hist_long_q "$STF" history --q "$longq" --fig 2 -o hist
expect_bad hist_long_d "$STF" history --d "$(printf '5%.0s,' $(seq 150))5" --fig 3 -o hist
printf 't,v\n0,1\n0.1,x\n' >badv.csv
expect_bad hist_bad_value "$STF" history --profile badv.csv --fig 3 -o hist
grep -q "badv.csv:3:.*'x'" hist_bad_value.err || fail "history: the bad value 'x' not named: $(cat hist_bad_value.err)"
printf 'nan,1\n0.1,2\n0.2,3\n' >nanrow.csv
expect_bad hist_nan_row "$STF" history --profile nanrow.csv --fig 3 -o hist
grep -q "nanrow.csv:1:" hist_nan_row.err || fail "history: a first row 'nan,1' not refused at line 1"

# 7. a run file cut short is said to be one (it was "not an stf output file")
head -c 100000 keep.h5 >short.h5
for cmd in report plot render; do
    expect_bad "short_$cmd" "$STF" $cmd short.h5
    grep -q "short.h5: .*cut short" "short_$cmd.err" || fail "stf $cmd short.h5: $(cat short_$cmd.err)"
done

# 8. an unknown option last on the line is called unknown (it was "needs a value")
for cmd in "render b.h5 --quiet" "plot b.h5 --json" "history --fig 2 --quiet"; do
    name=last_$(echo "$cmd" | tr -c 'a-z' _)
    expect_bad "$name" "$STF" $cmd
    grep -q "unknown option '--[a-z]*'" "$name.err" || fail "stf $cmd: $(head -1 $name.err)"
done

# 9. bench: an option the chosen benchmark does not read is refused before it runs (table1 -o
#    DIR, effects --knobs, grid --grow, dam --steps were silently ignored)
SMALL=(--set fluid.spacing=0.04 --threads 1)
for case in "table1 -o res --steps 1 --warmup 0" "effects --knobs dt --steps 1 --warmup 0" \
    "grid --grow domain --steps 1" "dam --steps 5" "accuracy --repeat 2 --knobs dt --duration 0.01"; do
    set -- $case
    what=$1 opt=$2
    shift
    name=bench_$what
    expect_bad "$name" "$STF" bench "$what" "$SCENE" "${SMALL[@]}" "$@"
    grep -q -- "$opt" "$name.err" || fail "stf bench $what $opt: $(head -1 $name.err)"
done
[ -e res ] && fail "stf bench table1 -o res made res"

# 10. render options that would be ignored are refused; --every picks a montage's frames
expect_bad render_every_list "$STF" render b.h5 --frames 1,2 --every 2 -o ev --width 64 --height 48
expect_bad render_every_one "$STF" render b.h5 --frames 3 --every 2 -o ev --width 64 --height 48
expect_bad render_max_alone "$STF" render b.h5 --max 3 -o ev --width 64 --height 48
# a range that ends past the last frame is refused, not cut to the file (0: runs to the end)
expect_bad render_past_end "$STF" render b.h5 --frames 0:11 -o ev --width 64 --height 48
grep -q "frame 11 out of range" render_past_end.err || fail "render --frames 0:11: $(cat render_past_end.err)"
[ -e ev ] && fail "stf render made ev for a refused command"
"$STF" render b.h5 --montage every.png --every 5 --width 64 --height 48 >every.out 2>every.err ||
    fail "stf render --montage --every 5 exited $?"
grep -q "(3 frames)" every.out || fail "stf render --montage --every 5 of 11 frames: $(cat every.out)"

# 11. sweep --list: a value the scene refuses is reported at its line of the list file
printf '# runs\nbodies.0.mass=0.05\n\nbodies.0.mass=abc\n' >bad.list
expect_bad sweep_list_value "$STF" sweep "$SCENE" --list bad.list --quiet -o listed
grep -q "bad.list:4:.*bodies.0.mass" sweep_list_value.err || fail "sweep --list: $(cat sweep_list_value.err)"

# 12. a render into a directory of a longer earlier render leaves only its own frames: the
#     earlier frame_0003.png .. were left after the new frame_0000..0002 (a mixed sequence,
#     which ffmpeg's frame_%04d.png pattern would put into the movie)
"$STF" render b.h5 --frames 0:2 -o frames --width 64 --height 48 >r3.out 2>r3.err ||
    fail "stf render --frames 0:2 exited $?"
[ "$(ls frames/frame_*.png | wc -l)" = 3 ] || fail "frames/ holds $(ls frames | tr '\n' ' ')after a 3-frame render"

# 13. every option a tool takes is in its --help (plot's --width/--height and render's --max
#     were missing from `stf plot --help` / `stf --help`)
"$STF" plot --help | grep -q -- "--width W" || fail "stf plot --help lacks --width"
"$STF" --help | grep -q -- "--max V" || fail "stf --help lacks render's --max"

if [ $fails -ne 0 ]; then
    echo "cli_tools_review: $fails failure(s)" >&2
    exit 1
fi
echo "cli_tools_review: ok"
