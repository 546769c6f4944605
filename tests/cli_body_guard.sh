#!/usr/bin/env bash
# cli_body_guard.sh - a body beyond its physical bounds stops the run; interrupts act between
# substeps.
# - A body beyond any physical bound stops the run: a 0.1 mg ball of 2 cm radius (density
#   0.003 kg/m^3) in the small drop scene. Physically it rises at most at about 2 g (its
#   added mass, half the displaced fluid's, limits the acceleration); the explicit coupling
#   has no added mass and throws it at ~100 m/s, beyond its bound of 10 times the scene's
#   largest physical speed (ode_glue/stf_sim.c, body_bounds). Exit 3, a message naming the
#   body, the step and the stage, the last good frame readable.
# - Interrupts act within a second: tests/scenes/long_steps.yaml has frames of ~10 s of
#   wall-clock time and steps of ~60 substeps; SIGTERM must end it (exit 130, the file
#   readable) well before a frame could finish. The margin is generous (3 s against the
#   grace of 0.5 s plus one substep of ~20 ms and the file's close) so that a loaded machine
#   does not make it fail; before the check between substeps it took a whole frame (~10 s).
#   The same holds while the fluid settles before t = 0 (fluid.settle): it stops within one
#   settling step, with no output file.
# Args: STF_BINARY PROJECT_DIR
. "$(dirname "$0")/lib_cli.sh" cli_body_guard "$@"
stf=$STF; src=$PROJ
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive

# --- the bodies' blow-up detector ----------------------------------------------------------
"$stf" run "$src/tests/scenes/small_drop.yaml" -o blow.h5 --set bodies.0.mass=1e-7 --quiet 2>blow.txt
rc=$?
[ $rc -eq 3 ] || fail "body blow-up: exit $rc, want 3 ($(cat blow.txt))"
grep -q "body 'ball' blew up after stage '" blow.txt && grep -q "step [0-9]" blow.txt &&
    grep -q "beyond its physical bound" blow.txt ||
    fail "body blow-up: the message does not name body, step and stage: $(cat blow.txt)"
/usr/bin/python3 - <<'PY' || fail "blow.h5: the last good frame is not readable"
import h5py, numpy as np
f = h5py.File("blow.h5", "r")
assert f.attrs["exit_status"] == 3
steps = sorted(int(k[5:]) for k in f if k.startswith("Step#"))
assert len(steps) >= 2, steps
for s in steps:
    assert np.all(np.isfinite(f["Step#%d/x" % s][:]))
v = f["bodies/ball/velocity"][:]
assert np.all(np.isfinite(v))
PY
# the same ball at a physical mass (50 g) runs through: the detector does not fire
"$stf" run "$src/tests/scenes/small_drop.yaml" -o ok.h5 --quiet 2>ok.txt ||
    fail "small_drop with its own ball: exit $? ($(cat ok.txt))"

# --- interrupt latency -----------------------------------------------------------------------
# term_latency WHAT: SIGTERM to $pid, waits for it; sets rc (its exit) and lat (s)
term_latency() {
    local t0 t1
    t0=$(date +%s.%N)
    kill -TERM $pid
    wait $pid
    rc=$?
    t1=$(date +%s.%N)
    lat=$(echo "$t1 - $t0" | bc)
    echo "cli_body_guard: $1: $lat s"
}
"$stf" run "$src/tests/scenes/long_steps.yaml" -o long.h5 --quiet --threads 1 2>long.txt &
pid=$!
grown long.h5 $pid 300000 || fail "long_steps: the run ended before its first frame"
sleep 1 # inside the first steps
term_latency "SIGTERM to exit"
[ $rc -eq 130 ] || fail "long_steps: exit $rc after SIGTERM, want 130 ($(cat long.txt))"
grep -q "interrupted at t = " long.txt || fail "long_steps: no 'interrupted' message: $(cat long.txt)"
[ "$(echo "$lat < 3" | bc)" -eq 1 ] || fail "long_steps: SIGTERM took $lat s to end the run (want < 3 s)"
/usr/bin/python3 - <<'PY' || fail "long.h5: not readable after SIGTERM"
import h5py, numpy as np
f = h5py.File("long.h5", "r")
assert f.attrs["exit_status"] == 130
assert np.all(np.isfinite(f["Step#0/x"][:]))
PY

# --- interrupt latency while the fluid settles (before t = 0, no file yet) ---------------------
# fluid.settle = 10 s of the same scene is 100 steps of ~45 substeps; SIGTERM once the run has
# used 1 s of CPU (its handler is set before the settling starts): exit 130 within the same
# margin, no output file.
"$stf" run "$src/tests/scenes/long_steps.yaml" -o settle.h5 --set fluid.settle=10 --quiet \
    --threads 1 2>settle.txt &
pid=$!
while kill -0 $pid 2>/dev/null && [ "$(awk '{print $14}' /proc/$pid/stat 2>/dev/null || echo 0)" -lt \
    "$(getconf CLK_TCK)" ]; do sleep 0.05; done
term_latency "SIGTERM to exit while settling"
[ $rc -eq 130 ] || fail "settling: exit $rc after SIGTERM, want 130 ($(cat settle.txt))"
grep -q "fluid.settle: interrupted while the fluid settled" settle.txt ||
    fail "settling: no message naming the settling: $(cat settle.txt)"
[ "$(echo "$lat < 3" | bc)" -eq 1 ] || fail "settling: SIGTERM took $lat s to end the run (want < 3 s)"
[ ! -e settle.h5 ] || fail "settling: an output file was written for a run that never started"

if [ $fails -ne 0 ]; then
    echo "cli_body_guard: $fails failure(s)" >&2
    exit 1
fi
echo "cli_body_guard: ok"
