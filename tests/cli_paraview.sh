# cli_paraview.sh - the output opened by the reader users have, ParaView (pvbatch under
# xvfb-run; Debian: paraview python3-paraview xvfb, which .ci/run installs). Skipped (77)
# without them.
#   - a short bowling ball run: its XDMF sidecar opened with ParaView's XDMF readers, every
#     frame's particle count the HDF5 file's, the ball a triangle surface at the position
#     /bodies gives (h5py), and a picture of a frame that shows the particles and the ball
#     (tests/paraview_check.py);
#   - the same run frozen while it goes, between two frames: ParaView opens the sidecar it
#     has written so far and reads every frame in it, fewer than the run's; the run then
#     ends with exit 0.
#
# usage: bash cli_paraview.sh STF_BINARY PROJECT_DIR   (run in the build's tests directory)
command -v pvbatch >/dev/null && command -v xvfb-run >/dev/null &&
    /usr/bin/python3 -c "import paraview" 2>/dev/null ||
    { echo "cli_paraview: no pvbatch, xvfb-run or ParaView's Python modules (Debian: paraview python3-paraview xvfb): skipped"; exit 77; }
. "$(dirname "$0")/lib_cli.sh" cli_paraview "$@"
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive
PY=/usr/bin/python3
SCENE=$PROJ/scenes/bowling_ball.yaml
COARSE=(--set fluid.spacing=0.05 --threads 1 --quiet)

# expected FILE.h5 OUT.json: frame times, particle counts and the spheres' centres at the
# frames (their /bodies position series interpolated to the frame times), from h5py
expected() {
    "$PY" - "$1" "$2" <<'EOF'
import json, sys
import h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
steps = sorted((k for k in f if k.startswith("Step#")), key=lambda k: int(k[5:]))
times = [float(f[k].attrs["TimeValue"]) for k in steps]
bodies = {}
for name in f["bodies"]:
    kind, *size = str(f.attrs["body.%s.shape" % name]).split()
    if kind != "sphere":
        continue
    t, p = f["bodies"][name]["time"][:], f["bodies"][name]["position"][:]
    bodies[name] = {"radius": float(size[0]),
                    "centre": [[float(np.interp(tk, t, p[:, c])) for c in range(3)] for tk in times]}
json.dump({"times": times, "particles": [int(f[k]["x"].shape[0]) for k in steps],
           "bodies": bodies}, open(sys.argv[2], "w"))
EOF
}

# pv SCRIPT ARGS...: pvbatch under a virtual X server; its output in pv.log. The machine
# may run other X servers (xvfb-run -a can pick a display another one takes at the same
# time): a random display, and up to 3 tries while pvbatch cannot reach its X server.
pv() {
    local try rc
    for try in 1 2 3; do
        xvfb-run -n $((200 + RANDOM % 700)) -s "-screen 0 1024x768x24" pvbatch "$@" >pv.log 2>&1
        rc=$?
        grep -q -E "bad X server connection|Xvfb failed to start|cannot open display" pv.log || break
        echo "cli_paraview: no X server for pvbatch (try $try)" >&2
    done
    return $rc
}

# ---- a finished run -----------------------------------------------------------------------
if "$STF" run "$SCENE" -o ball.h5 --duration 0.3 "${COARSE[@]}" 2>run.err; then
    expected ball.h5 ball.json || fail "h5py could not read ball.h5"
    "$PY" -c 'import json,sys; e=json.load(open(sys.argv[1])); sys.exit(not(len(e["times"]) >= 10 and "ball" in e["bodies"]))' ball.json ||
        fail "ball.h5: fewer than 10 frames or no ball"
    pv "$PROJ/tests/paraview_check.py" "$WORK/ball.json" "$WORK/ball.xmf" "$WORK/ball.png" ||
        { fail "ParaView on ball.xmf:"; grep -v "Skipping unrecognized array" pv.log >&2; }
    grep "paraview_check:" pv.log
    [ -s ball.png ] || fail "ball.png not written"
else
    fail "stf run bowling_ball.yaml exited non-zero: $(cat run.err)"
fi

# ---- a running simulation -----------------------------------------------------------------
# frozen between two frames (no process holds a lock on the file: the writer has released it)
"$STF" run "$SCENE" -o live.h5 --duration 3 "${COARSE[@]}" 2>live.err &
pid=$!
between_frames() {
    while kill -0 $pid 2>/dev/null; do
        if [ -s live.xmf ] && [ "$(grep -c '<Time ' live.xmf)" -ge 4 ]; then
            kill -STOP $pid
            flock -n -x live.h5 true && return 0
            kill -CONT $pid
        fi
        sleep 0.02
    done
    return 1
}
if between_frames; then
    cp live.xmf snap.xmf # the frames written so far
    cat >live_check.py <<'EOF'
import sys
from paraview.simple import XDMFReader
from paraview import servermanager as sm
from vtkmodules.vtkCommonDataModel import vtkCompositeDataSet
r = XDMFReader(FileNames=[sys.argv[1]])
ts = list(r.TimestepValues)
bad = 0
for t in ts:
    r.UpdatePipeline(time=t)
    it = sm.Fetch(r).NewIterator()
    it.InitTraversal()
    sizes = {}
    while not it.IsDoneWithTraversal():
        md = it.GetCurrentMetaData()
        sizes[md.Get(vtkCompositeDataSet.NAME())] = it.GetCurrentDataObject().GetNumberOfPoints()
        it.GoToNextItem()
    bad += not (sizes.get("particles", 0) > 0 and sizes.get("ball", 0) > 0)
print("live_check: %d frames, %d without particles or ball" % (len(ts), bad))
sys.exit(1 if bad or not ts else 0)
EOF
    pv live_check.py "$WORK/live.xmf" || { fail "ParaView on a running simulation's live.xmf:"; cat pv.log >&2; }
    grep "live_check:" pv.log
    shown=$(grep -c '<Time ' snap.xmf)
    kill -CONT $pid
    wait $pid
    rc=$?
    [ $rc -eq 0 ] || fail "the run ParaView read exited $rc: $(cat live.err)"
    total=$("$PY" -c 'import h5py,sys; print(sum(1 for k in h5py.File(sys.argv[1],"r") if k.startswith("Step#")))' live.h5)
    # each frame has two <Time> (particles, ball)
    [ $((shown / 2)) -lt "$total" ] || fail "ParaView saw $((shown / 2)) frames, the finished run has $total"
else
    fail "live.h5: the run ended before ParaView could look at it"
    wait $pid
fi

if [ $fails -ne 0 ]; then
    echo "cli_paraview: $fails failure(s)" >&2
    exit 1
fi
echo "cli_paraview: ok"
exit 0
