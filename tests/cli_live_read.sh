# cli_live_read.sh - reading a running simulation's file (h5py), which the writer closes
# between frames (stf_h5_release):
#   - opened mid-run, the file shows the frames written so far: at least one, fewer than the
#     run ends with; the run then ends with exit 0 and a complete file;
#   - a reader that keeps the file open does not stop the run: while it holds the file for
#     2 s, its own frames stay readable and another reader sees the run go on; the run ends
#     with exit 0 and every frame;
#   - a reader holding the file across the end of a run that compacts it (a checkpoint at
#     every frame, removed at the end: stf_h5_compact) keeps reading its frames, and the
#     compacted file is complete;
#   - the XDMF sidecar is there while the run goes and names only frames in the file.
# A reader's opening fails while the writer writes ("unable to lock file"): it tries again;
# while another reader holds the file the writer writes past its lock, and a second reader's
# opening may find a frame half-written: it opens again (other).
#
# usage: bash cli_live_read.sh STF_BINARY PROJECT_DIR   (run in the build's tests directory)
. "$(dirname "$0")/lib_cli.sh" cli_live_read "$@"
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive
PY=/usr/bin/python3
SCENE=$PROJ/tests/scenes/small_drop.yaml # 50 frames per second

cat >lib.py <<'EOF'
import errno, sys, time
import h5py, numpy as np

def open_retry(path, **kw):
    """h5py.File(path, 'r'), tried again while the writer holds its lock (or the file is
    not there yet); returns (file, failed openings)."""
    tries = 0
    while True:
        try:
            return h5py.File(path, "r", **kw), tries
        except (OSError, BlockingIOError) as e:
            tries += 1
            if tries > 2000:
                raise
            time.sleep(0.01)

def frames(f):
    return sorted(int(k[5:]) for k in f if k.startswith("Step#"))

def count_frames(path):
    """the frames a fresh opening of path sees"""
    f, _ = open_retry(path)
    with f:
        return len(frames(f))

def check_complete(path, want):
    """the finished file: frames 0..want-1 with finite data, exit_status 0, /metrics"""
    with h5py.File(path, "r") as f:
        s = frames(f)
        assert s == list(range(want)), "frames %s..%s (%d), want %d" % (s[:1], s[-1:], len(s), want)
        for k in s:
            g = f["Step#%d" % k]
            for d in ("x", "y", "z", "vx", "vy", "vz"):
                assert np.all(np.isfinite(g[d][:])), (k, d)
        assert int(f.attrs["exit_status"]) == 0, f.attrs["exit_status"]
        assert "json" in f["metrics"].attrs
        assert "checkpoint" not in f
        b = f["bodies/ball"]
        assert b["time"].shape[0] == b["position"].shape[0] > want, b["time"].shape
        assert all("Step#%d" % k in f["body_meshes/ball"] for k in s)
EOF

# finished NAME RC WANT: the run NAME ended with exit 0 and its file is complete
finished() {
    [ "$2" -eq 0 ] || fail "$1: the run exited $2: $(cat "$1.err")"
    PYTHONPATH=. "$PY" -c 'import sys, lib; lib.check_complete(sys.argv[1], int(sys.argv[2]))' "$1.h5" "$3" ||
        fail "$1.h5: not complete"
    h5dump -H "$1.h5" >/dev/null 2>&1 || fail "$1.h5: h5dump -H fails"
    "$STF" report "$1.h5" >/dev/null 2>&1 || fail "$1.h5: stf report fails"
    [ -e "$1.h5.compact" ] && fail "$1.h5.compact left behind"
}

# ---- opened mid-run ---------------------------------------------------------------------
"$STF" run "$SCENE" -o mid.h5 --duration 6 --quiet --threads 1 2>mid.err &
pid=$!
grown mid.h5 $pid 100000 || fail "mid.h5: the run ended before it wrote a frame"
PYTHONPATH=. "$PY" - mid.h5 301 <<'EOF' || fail "mid.h5: h5py mid-run"
import sys, lib
f, tries = lib.open_retry(sys.argv[1])
s = lib.frames(f)
last = f["Step#%d" % s[-1]]
assert last["x"].shape == last["vz"].shape and "TimeValue" in last.attrs
assert 1 <= len(s) < int(sys.argv[2]), "%d frames mid-run, the run has %s" % (len(s), sys.argv[2])
assert s == list(range(len(s))), s
print("mid-run: %d of %s frames (%d openings refused while the writer wrote)" % (len(s), sys.argv[2], tries))
EOF
# the sidecar while the run goes: frames that are in the file
PYTHONPATH=. "$PY" - mid.h5 mid.xmf <<'EOF' || fail "mid.xmf: the sidecar mid-run"
import re, sys, lib
xmf = open(sys.argv[2]).read()
assert xmf.rstrip().endswith("</Xdmf>"), "the sidecar is cut short"
named = set(int(n) for n in re.findall(r'mid\.h5:/Step#(\d+)/x<', xmf))
f, _ = lib.open_retry(sys.argv[1])
assert named and named <= set(lib.frames(f)), (sorted(named)[-3:], lib.frames(f)[-3:])
EOF
wait $pid
finished mid $? 301

# ---- a reader holding the file open ------------------------------------------------------
"$STF" run "$SCENE" -o hold.h5 --duration 10 --quiet --threads 1 2>hold.err &
pid=$!
grown hold.h5 $pid 100000 || fail "hold.h5: the run ended before it wrote a frame"
PYTHONPATH=. "$PY" - hold.h5 <<'EOF' || fail "hold.h5: a reader holding the file"
import subprocess, sys, time, lib
import numpy as np
path = sys.argv[1]
count = "import sys, lib; print(lib.count_frames(sys.argv[1]))"
def other():  # frames another process sees; it opens again if it found a frame
    # half-written (the writer writes past this reader without HDF5's lock, h5io.c open_file)
    for attempt in range(20):
        r = subprocess.run([sys.executable, "-c", count, path], capture_output=True, text=True)
        if r.returncode == 0:
            return int(r.stdout)
        time.sleep(0.05)
    raise RuntimeError("the other reader failed 20 times: %s" % r.stderr[-500:])
f, _ = lib.open_retry(path)
mine = lib.frames(f)
before = other()
t0 = time.time()
while time.time() - t0 < 2:  # hold the file, reading its frames
    for k in mine:
        assert np.all(np.isfinite(f["Step#%d/x" % k][:]))
    time.sleep(0.05)
after = other()
f.close()
assert after > before >= len(mine) >= 1, (len(mine), before, after)
print("held for 2 s: opened with %d frames; another reader saw %d, then %d" % (len(mine), before, after))
EOF
wait $pid
finished hold $? 501

# ---- holding across the end of a run whose file is compacted -------------------------------
"$STF" run "$SCENE" -o end.h5 --duration 3 --quiet --threads 1 --checkpoint 0 2>end.err &
pid=$!
grown end.h5 $pid 100000 || fail "end.h5: the run ended before it wrote a frame"
PYTHONPATH=. "$PY" - end.h5 $pid <<'EOF' || fail "end.h5: a reader holding the file past the run's end"
import os, sys, time, lib
import numpy as np
f, _ = lib.open_retry(sys.argv[1])
mine = lib.frames(f)
pid = int(sys.argv[2])
while os.path.exists("/proc/%d" % pid) and open("/proc/%d/stat" % pid).read().split()[2] != "Z":
    time.sleep(0.05)
for k in mine:
    assert np.all(np.isfinite(f["Step#%d/x" % k][:]))
print("held past the end: %d frames still read" % len(mine))
EOF
wait $pid
finished end $? 151

if [ $fails -ne 0 ]; then
    echo "cli_live_read: $fails failure(s)" >&2
    exit 1
fi
echo "cli_live_read: ok"
exit 0
