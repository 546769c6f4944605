#!/usr/bin/env bash
# cli_passive.sh - springs.passive: the history springs give back no more energy than they
# took. tests/scenes/thin_layer_impact.yaml throws a steel ball at 3, 5 and 8 m/s onto 6 cm
# of the cornstarch over the floor. Eq. 6 as written stiffens a spring while it is
# compressed, and the stiffer spring then gives back more than it stored: the ball leaves
# faster than it came (8.33 m/s out at 8.09 in; at 3 and 5 m/s 0.94 and 0.83 of the speed).
# With springs.passive a spring that stiffens keeps its energy (src/springs.c): at each speed
# the ball must leave at most at the speed it hit with (energy can only be lost), and 1 and
# 2 threads give the same bits. Its resume is held in cli_resume.
# Args: STF_BINARY PROJECT_DIR
. "$(dirname "$0")/lib_cli.sh" cli_passive "$@"
stf=$STF
export OMP_WAIT_POLICY=passive
scene=$PROJ/tests/scenes/thin_layer_impact.yaml
for V in 3 5 8; do
    "$stf" run "$scene" -o p$V.h5 --threads 1 --quiet --set "bodies.0.velocity=[0,0,-$V]" \
        --set effects.springs.passive=true 2>err.txt || fail "$V m/s: the run failed: $(cat err.txt)"
    /usr/bin/python3 - p$V.h5 $V <<'PY' || fail "$V m/s: the ball left faster than it came"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
v = f["bodies/ball/velocity"][:, 2]
i = int(np.argmin(v))                  # the impact: its fastest downward speed
vin, vout = -v[i], v[i:].max()
print("cli_passive: %s m/s: in %.3f m/s, out %.3f m/s (%.2f)" % (sys.argv[2], vin, vout, vout / vin))
sys.exit(0 if vout <= vin else 1)
PY
done
"$stf" run "$scene" -o p2t.h5 --threads 2 --quiet --set "bodies.0.velocity=[0,0,-8]" \
    --set effects.springs.passive=true 2>err.txt || fail "2 threads: the run failed: $(cat err.txt)"
/usr/bin/python3 - <<'PY' || fail "1 and 2 threads differ"
import h5py, numpy as np
a, b = h5py.File("p8.h5", "r"), h5py.File("p2t.h5", "r")
for k in ("bodies/ball/position", "bodies/ball/velocity"):
    assert np.array_equal(a[k][:], b[k][:]), k
last = "Step#%d" % (sum(1 for k in a if k.startswith("Step#")) - 1)
for c in "xyz":
    assert np.array_equal(a[last][c][:], b[last][c][:]), c
PY
if [ $fails -ne 0 ]; then
    echo "cli_passive: $fails failure(s)" >&2
    exit 1
fi
echo "cli_passive: ok"
