#!/usr/bin/env bash
# The paper's bowling sequence (Fig. 1, 13) in the strict metrics of src/io/metrics.h, at a
# reduced resolution: scenes/bowling_ball.yaml at 2.5 cm spacing (5.4K particles; the
# material scales itself to the spacing, fluid.reference_spacing), over STF_BOWLING_SECONDS
# (default 4 s: impact, bounce, roll and rest).
#  - with history: the jammed fluid carries the ball (penetration <= R/2), it bounces at least
#    once on the surface, rolls at least 2 R on the surface turning (omega R / v >= 0.7), and
#    rests on the surface (slower than 5 cm/s, depth <= R) for at least 1 s;
#  - without history (bowling_ball_no_history.yaml): the ball is at least R deep within 0.3 s
#    of contact (read from its own body series), never bounces and never rests on the surface;
#  - the two differ as the paper says: with history the ball goes in less than half as deep.
#  - tests/density_frames.py reads the run's density frame by frame as the metric does.
# Args: STF_BINARY PROJECT_DIR
set -u
stf=$1; src=$2
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT; cd "$tmp"
secs=${STF_BOWLING_SECONDS:-4}
rc=0
fail() { echo "cli_bowling: $*" >&2; rc=1; }
"$stf" run "$src/scenes/bowling_ball.yaml" -o hist.h5 --set fluid.spacing=0.025 \
  --duration "$secs" --quiet || fail "bowling_ball: stf run failed"
"$stf" run "$src/scenes/bowling_ball_no_history.yaml" -o none.h5 --set fluid.spacing=0.025 \
  --duration 1.5 --quiet || fail "bowling_ball_no_history: stf run failed"
"$stf" report hist.h5 --json >hist.json && "$stf" report none.h5 --json >none.json \
  || fail "stf report failed"
/usr/bin/python3 - hist.json none.json none.h5 <<'PY' || rc=1
import json, sys
import h5py
import numpy as np
h = json.load(open(sys.argv[1]))["bodies"]["ball"]
n = json.load(open(sys.argv[2]))
S, nb = n["surface_height"], n["bodies"]["ball"]
R = h["radius"]
bad = []
def want(ok, what):
    print(("ok:   " if ok else "FAIL: ") + what)
    if not ok:
        bad.append(what)
want(h["penetration_depth"] <= 0.5 * R, "with history: penetration %.4f m <= R/2 = %.4f m" % (h["penetration_depth"], 0.5 * R))
want(h["bounces"] >= 1, "with history: %d bounce(s) on the surface" % h["bounces"])
want(h["roll_distance"] >= 2 * R, "with history: rolls %.3f m >= 2 R on the surface" % h["roll_distance"])
want(h["rolling_ratio"] is not None and h["rolling_ratio"] >= 0.7,
     "with history: rolling, omega R / v = %s >= 0.7" % h["rolling_ratio"])
want(h["rest_on_surface"] >= 1.0, "with history: rests %.2f s on the surface >= 1 s" % h["rest_on_surface"])
f = h5py.File(sys.argv[3], "r")
t, p = f["bodies/ball/time"][:], f["bodies/ball/position"][:]
tc = nb["first_contact_time"]
early = (t >= tc) & (t <= tc + 0.3)
depth = S - (p[early, 2] - R)
want(depth.max() >= R, "without history: %.3f m deep within 0.3 s of contact >= R" % depth.max())
want(nb["bounces"] == 0, "without history: no bounce (%d)" % nb["bounces"])
want(nb["rest_on_surface"] == 0, "without history: no rest on the surface (%g s)" % nb["rest_on_surface"])
want(h["penetration_depth"] < 0.5 * nb["penetration_depth"],
     "history halves the penetration at least: %.3f against %.3f m" % (h["penetration_depth"], nb["penetration_depth"]))
sys.exit(1 if bad else 0)
PY
# tests/density_frames.py (the metric's estimator frame by frame, on 400 particles of the
# bulk) agrees with the run's fluid.density_error_max, which reads every bulk particle: the
# largest |mean - 1| over the frames after the first, within 0.2 percentage points (the
# sample's standard error is about 0.1).
/usr/bin/python3 "$src/tests/density_frames.py" hist.h5 >frames.txt || fail "density_frames.py failed"
/usr/bin/python3 - hist.json frames.txt <<'PY' || rc=1
import json, sys
m = json.load(open(sys.argv[1]))["fluid"]["density_error_max"]
rows = [l.split() for l in open(sys.argv[2]).read().splitlines()[1:]]
worst = max(abs(float(e)) for t, e in rows[1:])
ok = abs(worst - m) <= 0.002
print(("ok:   " if ok else "FAIL: ") + "density_frames.py's largest frame %.4f against density_error_max %.4f (%d frames)" % (worst, m, len(rows)))
sys.exit(0 if ok else 1)
PY
exit $rc
