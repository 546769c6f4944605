#!/usr/bin/env bash
# Checkpoint and resume: a run stopped by kill -9 or SIGTERM and continued with
# `stf run --resume` ends bit-identical to the same run never stopped: every dataset and
# attribute of the two files (frames, body series, statistics, metrics) compared byte for
# byte, except wall_seconds. The reference runs take no checkpoint (--checkpoint off), so
# the comparison also shows that taking checkpoints does not change a run.
#   - springs + window history + a ball (ODE contacts), a checkpoint every 10 frames: killed
#     twice (the second time while resumed, after a checkpoint of the resumed run, every 7
#     frames), resumed each time; frames written after the checkpoint are dropped and redone;
#   - SIGTERM (exit 130, a checkpoint at the last frame), resumed as `stf run SCENE -o OUT
#     --resume` with another thread count;
#   - sum-of-exponentials history, and the Carreau-Yasuda model with its warm start;
#   - refused, file untouched: another scene or --set, --set or --duration with --resume,
#     a file without a checkpoint (exit 2); a finished run says so and exits 0.
# The processes are frozen (SIGSTOP) once their file has grown past a size, then signalled,
# so the stop lands mid-run whatever the machine's load: no step here waits for a wall-clock
# time (the periodic checkpoints are taken every N frames, --checkpoint-frames, not every S
# seconds of wall time, and the waits for a file to grow last as long as the run does).
# Args: STF_BINARY PROJECT_DIR
. "$(dirname "$0")/lib_cli.sh" cli_resume "$@"
stf=$STF; src=$PROJ
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive
scene=$src/tests/scenes/small_drop.yaml

cat >same.py <<'PY'
# same.py A B: every dataset and attribute of A and B equal byte for byte (but wall_seconds)
import sys, h5py, numpy as np
def items(path):
    out = {}
    with h5py.File(path, "r") as f:
        def attrs(name, obj):
            for k, v in obj.attrs.items():
                if k != "wall_seconds":
                    out["%s@%s" % (name, k)] = np.asarray(v)
        attrs("/", f)
        def visit(name, obj):
            attrs(name, obj)
            if isinstance(obj, h5py.Dataset):
                out[name] = np.asarray(obj[()])
        f.visititems(visit)
    return out
a, b = items(sys.argv[1]), items(sys.argv[2])
bad = sorted(set(a) ^ set(b))
for k in set(a) & set(b):
    x, y = a[k], b[k]
    if x.dtype != y.dtype or x.shape != y.shape or (x.tobytes() != y.tobytes() if x.dtype != object else x.tolist() != y.tolist()):
        bad.append(k)
frames = sum(1 for k in a if k.startswith("Step#") and k.endswith("/x"))
if bad or frames < 10:
    print("%s vs %s: %d frames, %d items differ: %s" % (sys.argv[1], sys.argv[2], frames, len(bad), sorted(bad)[:8]))
    sys.exit(1)
PY
same() { /usr/bin/python3 same.py "$1" "$2" || fail "$3: $2 differs from $1"; }

# freeze_at FILE BYTES PID: waits until FILE has grown past BYTES, then freezes PID: 0; 1 if
# PID ended first. No time limit: however slowly the machine runs it, the run either grows
# its file or ends (and ctest's timeout catches a hang).
freeze_at() {
    while kill -0 "$3" 2>/dev/null; do
        if [ "$(stat -c %s "$1" 2>/dev/null || echo 0)" -gt "$2" ]; then
            kill -STOP "$3"
            return 0
        fi
        sleep 0.05
    done
    return 1
}

# stop_run HOW FILE BYTES ARGS...: runs stf ARGS in the background, stops it once FILE has
# BYTES: HOW = KILL (kill -9) or TERM (SIGTERM, then let it finish the frame). Sets rc.
stop_run() {
    local how=$1 file=$2 bytes=$3
    shift 3
    "$stf" "$@" --quiet 2>>stop.err &
    local pid=$!
    freeze_at "$file" "$bytes" $pid || fail "$file: the run ended before it was stopped"
    kill -"$how" $pid
    kill -CONT $pid 2>/dev/null
    wait $pid
    rc=$?
}

# resume FILE: stf run --resume FILE; checks the exit status and the message
resume() {
    "$stf" run --resume "$1" 2>resume.err
    local r=$?
    [ $r -eq 0 ] || fail "resume $1: exit $r, want 0 ($(cat resume.err))"
    grep -q "resuming $1 at t = " resume.err || fail "resume $1: no 'resuming' message: $(cat resume.err)"
}

# ---- springs + window history + a ball: kill -9, resume, kill -9 again, resume -------------
D=3
"$stf" run "$scene" -o ref.h5 --duration $D --quiet --checkpoint off || fail "reference run"
size=$(stat -c %s ref.h5)
# after_checkpoint PID CKPT_MIN: PID (frozen, writing kill.h5) is let run in short spells
# until the file holds a checkpoint taken after CKPT_MIN frames and a frame after it (the
# frozen writer's file is consistent on disk: read without the lock; a read that lands
# inside a flush fails and is tried again); 1 if PID ended first
after_checkpoint() {
    while kill -0 "$1" 2>/dev/null; do
        HDF5_USE_FILE_LOCKING=FALSE /usr/bin/python3 -c '
import h5py, sys
f = h5py.File("kill.h5", "r")
c = f["checkpoint.new" if "checkpoint.new" in f else "checkpoint"]["run.frames"][0]
sys.exit(0 if int(sys.argv[1]) < c < sum(1 for k in f if k.startswith("Step#")) else 1)' "$2" \
            2>/dev/null && return 0
        kill -CONT "$1" 2>/dev/null; sleep 0.02; kill -STOP "$1" 2>/dev/null
    done
    return 1
}
# a checkpoint every 10 frames; the kill lands once frames follow the last one
"$stf" run "$scene" -o kill.h5 --duration $D --checkpoint-frames 10 --quiet &
pid=$!
freeze_at kill.h5 $((size / 3)) $pid || fail "kill.h5: the run ended before it was stopped"
after_checkpoint $pid 0 || fail "kill.h5: the run ended before a frame followed a checkpoint"
kill -KILL $pid
kill -CONT $pid 2>/dev/null
wait $pid 2>/dev/null
ckpt1=$(/usr/bin/python3 -c '
import h5py
f = h5py.File("kill.h5", "r")
frames = sum(1 for k in f if k.startswith("Step#"))
c = f["checkpoint"]
assert 10 <= c["run.frames"][0] < frames and c["run.frames"][0] % 10 == 0, (c["run.frames"][0], frames)
assert c["sim.steps"][0] > 0 and "fluid.x" in c and "history.ring" in c and "springs.rest" in c
print(c["run.frames"][0])') || fail "kill.h5: no checkpoint, or no frame after it to drop"
echo "kill.h5: checkpoint after frame ${ckpt1:-?}"
# killed again while resumed, once the resumed run has taken a checkpoint of its own
"$stf" run --resume kill.h5 --quiet --checkpoint-frames 7 &
pid=$!
freeze_at kill.h5 $((2 * size / 3)) $pid || fail "the resumed run ended before it was stopped"
after_checkpoint $pid "${ckpt1:-0}" || fail "the resumed run ended before it took a checkpoint"
kill -KILL $pid
kill -CONT $pid 2>/dev/null
wait $pid 2>/dev/null
/usr/bin/python3 - "${ckpt1:-0}" <<'PY' || fail "kill.h5: no checkpoint of the resumed run"
import h5py, sys
f = h5py.File("kill.h5", "r")
c = f["checkpoint"]["run.frames"][0]
assert c > int(sys.argv[1]) and c % 7 == 0, (c, sys.argv[1])
PY
resume kill.h5
same ref.h5 kill.h5 "kill -9 twice"
"$stf" report kill.h5 >/dev/null || fail "stf report of the resumed file"

# ---- SIGTERM: exit 130 with a checkpoint; resumed as SCENE -o OUT --resume, 2 threads -----
stop_run TERM term.h5 $((size / 2)) run "$scene" -o term.h5 --duration $D --checkpoint-frames 100000
[ $rc -eq 130 ] || fail "SIGTERM: exit $rc, want 130"
cp term.h5 stopped.h5 # for the refusals below
"$stf" run "$scene" -o term.h5 --resume --threads 2 --quiet 2>resume.err ||
    fail "resume SCENE -o term.h5 --resume: $(cat resume.err)"
same ref.h5 term.h5 "SIGTERM"
diff <(sed s/ref.h5/OUT/g ref.xmf) <(sed s/term.h5/OUT/g term.xmf) >/dev/null ||
    fail "SIGTERM: the XDMF sidecar of the resumed run differs"

# ---- refusals: exit 2 and the file unchanged; a finished run: exit 0, unchanged -----------
sum0=$(md5sum <stopped.h5)
refuse() { # NAME WANT PATTERN ARGS...
    local name=$1 want=$2 pat=$3
    shift 3
    "$stf" run "$@" >refuse.out 2>refuse.err
    local r=$?
    [ $r -eq "$want" ] || fail "$name: exit $r, want $want ($(cat refuse.err))"
    grep -q "$pat" refuse.err || fail "$name: message lacks '$pat': $(cat refuse.err)"
}
refuse "another scene" 2 "written by another scene" "$scene" --set effects.viscosity.sigma=3 -o stopped.h5 --resume
refuse "--set with OUT.h5" 2 "is an output file" --resume stopped.h5 --set dt=0.002
refuse "--duration" 2 "cannot be combined" --resume stopped.h5 --duration 5
refuse "not an output" 2 "cannot resume" --resume "$scene" -o missing.h5
[ "$(md5sum <stopped.h5)" = "$sum0" ] || fail "a refused resume changed the file"
"$stf" run "$scene" -o nockpt.h5 --duration $D --quiet --checkpoint off &
pid=$!
freeze_at nockpt.h5 $((size / 3)) $pid || fail "nockpt.h5: the run ended before it was stopped"
kill -TERM $pid
kill -CONT $pid
wait $pid
sum1=$(md5sum <nockpt.h5)
refuse "no checkpoint" 2 "has no checkpoint" --resume nockpt.h5
[ "$(md5sum <nockpt.h5)" = "$sum1" ] || fail "resume without a checkpoint changed the file"
sum2=$(md5sum <ref.h5)
refuse "finished" 0 "already ended" --resume ref.h5
[ "$(md5sum <ref.h5)" = "$sum2" ] || fail "resume of a finished run changed the file"

# ---- sum-of-exponentials history --------------------------------------------------------
soe=(--set effects.history.mode=soe --set effects.history.terms=8)
"$stf" run "$scene" -o soe_ref.h5 --duration 2 --quiet --checkpoint off "${soe[@]}" || fail "soe reference"
stop_run TERM soe.h5 $(($(stat -c %s soe_ref.h5) / 2)) run "$scene" -o soe.h5 --duration 2 "${soe[@]}" \
    --checkpoint-frames 100000
[ $rc -eq 130 ] || fail "soe: exit $rc, want 130"
resume soe.h5
same soe_ref.h5 soe.h5 "soe history"

# ---- Carreau-Yasuda with warm start -----------------------------------------------------
cy=$src/scenes/cy_block_into_pool.yaml
cyset=(--set fluid.spacing=0.2 --set dt=0.004 --set effects.carreau_yasuda.warm_start=0.5 --set frame_rate=50)
"$stf" run "$cy" -o cy_ref.h5 --duration 0.8 --quiet --checkpoint off "${cyset[@]}" || fail "cy reference"
stop_run KILL cy.h5 $(($(stat -c %s cy_ref.h5) / 2)) run "$cy" -o cy.h5 --duration 0.8 --checkpoint 0 "${cyset[@]}"
resume cy.h5
same cy_ref.h5 cy.h5 "carreau_yasuda"

# springs.passive: the last step's history derivative is in the checkpoint
pv=(--set effects.springs.passive=true)
"$stf" run "$scene" -o pv_ref.h5 --duration 1 --quiet --checkpoint off "${pv[@]}" || fail "passive reference"
stop_run KILL pv.h5 $(($(stat -c %s pv_ref.h5) / 2)) run "$scene" -o pv.h5 --duration 1 --checkpoint 0 "${pv[@]}"
resume pv.h5
same pv_ref.h5 pv.h5 "springs.passive"

# the Clavet fluid with the projection as its pressure (its warm-start pressures are in the
# checkpoint and follow the particles' reordering)
pj=(--set fluid.settle=0 --unset effects.pressure.k --unset effects.pressure.k_near --unset effects.pressure.rest
    --set effects.pressure.mode=projection --set effects.pressure.solver=cg
    --set effects.pressure.warm_start=1 --set effects.pressure.eta=0.001)
"$stf" run "$src/tests/scenes/still_box.yaml" -o pj_ref.h5 --duration 0.6 --quiet --checkpoint off \
  "${pj[@]}" || fail "projection reference"
stop_run KILL pj.h5 $(($(stat -c %s pj_ref.h5) / 2)) run "$src/tests/scenes/still_box.yaml" -o pj.h5 \
  --duration 0.6 --checkpoint 0 "${pj[@]}"
resume pj.h5
same pj_ref.h5 pj.h5 "pressure projection"
# its solver's statistics per frame and per run, as the Carreau-Yasuda model's
/usr/bin/python3 - <<'PY' || fail "pressure projection: the solver's statistics are missing or out of range"
import h5py
f = h5py.File("pj_ref.h5", "r")
frames = [k for k in f if k.startswith("Step#") and k != "Step#0"]
it = [f[k].attrs["pressure_iterations_mean"] for k in frames]
assert len(it) > 10 and min(it) >= 2, it[:5]          # min_iterations is 2
assert 0 <= f.attrs["density_error_max"] <= 0.001 * 1.0001, f.attrs["density_error_max"]
PY

[ $fails -eq 0 ] && echo "cli_resume: all passed"
exit $((fails > 0))
