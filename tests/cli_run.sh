# cli_run.sh - `stf run` end to end: a small scene with every effect runs, the HDF5 file has
# the documented layout (frames Step#N with float32 x,y,z,vx,vy,vz and an increasing
# TimeValue; root attributes; /metrics with a JSON attribute), the XDMF companion exists,
# h5dump reads the file, `stf report --json` prints valid JSON, and --set / --unset runs work;
# `stf CMD --help` (and -h) prints that command's usage to stdout, exit 0, for every command;
# a run that checkpointed at every frame ends as small as one that did not (same contents).
#
# usage: bash cli_run.sh STF_BINARY PROJECT_DIR   (run in the build's tests directory)
. "$(dirname "$0")/lib_cli.sh" cli_run "$@"

SCENE="$PROJ/tests/scenes/small_drop.yaml"
PY=/usr/bin/python3

# run NAME ARGS...: runs stf, expects exit 0.
run() {
    local name=$1
    shift
    "$STF" run "$SCENE" -o "$name.h5" --quiet --threads 1 "$@" >"$name.out" 2>"$name.err"
    local rc=$?
    if [ $rc -ne 0 ]; then
        fail "stf run $* exited $rc; stderr:"
        cat "$name.err" >&2
        return 1
    fi
    [ -s "$name.h5" ] || { fail "$name.h5 not written"; return 1; }
    return 0
}

# check_h5 FILE: the layout of an output file (python + h5py).
check_h5() {
    "$PY" - "$1" <<'EOF'
import json, math, sys
import h5py

path = sys.argv[1]
errors = []
def err(msg):
    errors.append(msg)

with h5py.File(path, "r") as f:
    steps = sorted((k for k in f.keys() if k.startswith("Step#")), key=lambda k: int(k[5:]))
    if len(steps) < 2:
        err("fewer than 2 frames: %r" % list(f.keys()))
    if steps and steps[0] != "Step#0":
        err("first frame is %s, not Step#0" % steps[0])
    idx = [int(k[5:]) for k in steps]
    if idx != list(range(len(idx))):
        err("frame numbers not consecutive from 0: %r" % idx)
    times = []
    nparticles = None
    for k in steps:
        g = f[k]
        for d in ("x", "y", "z", "vx", "vy", "vz"):
            if d not in g:
                err("%s/%s missing" % (k, d))
                continue
            ds = g[d]
            if ds.dtype != "float32":
                err("%s/%s is %s, not float32" % (k, d, ds.dtype))
            if ds.ndim != 1:
                err("%s/%s has %d dimensions" % (k, d, ds.ndim))
            if nparticles is None:
                nparticles = ds.shape[0]
            elif ds.shape[0] != nparticles:
                err("%s/%s has %d values, frame 0 had %d" % (k, d, ds.shape[0], nparticles))
            if not all(math.isfinite(float(v)) for v in ds[()]):
                err("%s/%s has non-finite values" % (k, d))
        if "TimeValue" not in g.attrs:
            err("%s has no TimeValue" % k)
        else:
            times.append(float(g.attrs["TimeValue"]))
    if times and times[0] != 0.0:
        err("Step#0 TimeValue is %g, not 0" % times[0])
    if any(b <= a for a, b in zip(times, times[1:])):
        err("TimeValue not increasing: %r" % times)
    for a in ("scene", "version", "particles", "substeps", "wall_seconds", "dt_min", "dt_max"):
        if a not in f.attrs:
            err("root attribute %s missing" % a)
    if "particles" in f.attrs and nparticles is not None and int(f.attrs["particles"]) != nparticles:
        err("particles attribute %s != frame size %d" % (f.attrs["particles"], nparticles))
    if "substeps" in f.attrs and "dt_min" in f.attrs and "dt_max" in f.attrs and times:
        # the substeps cover the simulated time: substeps * dt with one length (dt_min ==
        # dt_max), between substeps * dt_min and substeps * dt_max when the control split
        # some steps (an impact's compression, ode_glue/stf_ode.c)
        ns, lo, hi = int(f.attrs["substeps"]), float(f.attrs["dt_min"]), float(f.attrs["dt_max"])
        tol = 1e-9 + 1e-6 * times[-1]
        if not (ns * lo - tol <= times[-1] <= ns * hi + tol):
            err("%d substeps of %g..%g s cover %g..%g s but the last frame is at %g s"
                % (ns, lo, hi, ns * lo, ns * hi, times[-1]))
        if lo == hi and abs(ns * lo - times[-1]) > tol:
            err("substeps * dt = %g s but the last frame is at %g s" % (ns * lo, times[-1]))
    if "dt_min" in f.attrs and "dt_max" in f.attrs and float(f.attrs["dt_min"]) > float(f.attrs["dt_max"]):
        err("dt_min > dt_max")
    if "scene" in f.attrs:
        s = f.attrs["scene"]
        s = s.decode() if isinstance(s, bytes) else str(s)
        if "duration" not in s:
            err("scene attribute does not hold the scene text: %r" % s[:80])
    if "metrics" not in f:
        err("/metrics group missing")
    elif "json" not in f["metrics"].attrs:
        err("/metrics has no json attribute")
    else:
        s = f["metrics"].attrs["json"]
        s = s.decode() if isinstance(s, bytes) else str(s)
        try:
            m = json.loads(s)
        except ValueError as e:
            err("/metrics json does not parse: %s" % e)
            m = {}
        for key in ("time_end", "surface_height", "bodies", "fluid"):
            if key not in m:
                err("/metrics json lacks %s" % key)
        if "time_end" in m and times and abs(float(m["time_end"]) - times[-1]) > 1e-6:
            err("metrics time_end %s != last frame time %g" % (m["time_end"], times[-1]))
        fl = m.get("fluid", {})
        if isinstance(fl, dict) and fl.get("escaped", 0) != 0:
            err("%s particles escaped the container" % fl.get("escaped"))

if errors:
    for e in errors:
        print("  " + path + ": " + e, file=sys.stderr)
    sys.exit(1)
EOF
}

# scene_text FILE: prints the effective scene text stored in the file.
scene_text() {
    "$PY" -c 'import h5py,sys; s=h5py.File(sys.argv[1],"r").attrs["scene"]; print(s.decode() if isinstance(s,bytes) else s)' "$1"
}

# 1. the plain run
if run base; then
    [ -s base.out ] && fail "--quiet run printed on stdout: $(head -c 200 base.out)"
    check_h5 base.h5 || fail "base.h5 layout"
    [ -s base.xmf ] || fail "base.xmf (XDMF companion) missing"
    if [ -s base.xmf ]; then
        grep -q "base.h5" base.xmf || fail "base.xmf does not refer to base.h5"
    fi
    h5dump -H base.h5 >h5dump.out 2>h5dump.err || fail "h5dump -H base.h5 failed: $(head -c 300 h5dump.err)"
    grep -q 'GROUP "Step#0"' h5dump.out || fail "h5dump -H shows no /Step#0 group"
    if "$STF" report base.h5 --json >report.json 2>report.err; then
        "$PY" -c 'import json,sys; m=json.load(open(sys.argv[1])); [m[k] for k in ("time_end","surface_height","bodies","fluid")]' report.json ||
            fail "stf report --json: not valid JSON with the metric keys: $(head -c 300 report.json)"
    else
        fail "stf report base.h5 --json exited non-zero: $(cat report.err)"
    fi
    "$STF" report base.h5 >report.txt 2>&1 || fail "stf report base.h5 (text) failed"
fi

# 2. --set changes the effective scene (and the physics: q enters the history stiffness)
if run setq --set effects.history.q=0.3; then
    check_h5 setq.h5 || fail "setq.h5 layout"
    scene_text setq.h5 | grep -E >/dev/null 'q: *0\.3' || fail "--set effects.history.q=0.3 not in the stored scene"
fi

# 2b. `stf check`: an expectation "==" on time_end holds for the scene's duration (the time
# is summed step by step; == is equal to 1e-9) and fails for a value a step away
T=$(grep -E '^duration:' "$SCENE" | awk '{print $2}')
DT=$(grep -E '^dt:' "$SCENE" | awk '{print $2}')
"$STF" check "$SCENE" -o chk.h5 --quiet --threads 1 --set "expect.time_end=$T" >chk.out 2>&1 ||
    fail "stf check with expect time_end == $T failed: $(tail -n 3 chk.out)"
TN=$("$PY" -c "print($T - $DT)")
"$STF" check "$SCENE" -o chk2.h5 --quiet --threads 1 --set "expect.time_end=$TN" >chk2.out 2>&1 &&
    fail "stf check with expect time_end == $TN (a step short) passed"

# 3. --unset switches an effect off
if run nohist --unset effects.history; then
    check_h5 nohist.h5 || fail "nohist.h5 layout"
    scene_text nohist.h5 | grep >/dev/null 'history' && fail "--unset effects.history: history still in the stored scene"
    "$PY" - base.h5 nohist.h5 <<'EOF' || fail "history on/off runs"
import sys, h5py
a, b = (h5py.File(p, "r") for p in sys.argv[1:3])
last = max(int(k[5:]) for k in a.keys() if k.startswith("Step#"))
# with history the springs stiffen: khist is non-zero somewhere; without it, zero everywhere
ka = a["Step#%d" % last]["khist"][()] if "khist" in a["Step#%d" % last] else None
kb = b["Step#%d" % last]["khist"][()] if "khist" in b["Step#%d" % last] else None
if ka is not None and not (ka > 0).any():
    sys.exit("history on: no particle has history stiffness")
if kb is not None and (kb != 0).any():
    sys.exit("history off: history stiffness is not zero")
if int(b.attrs.get("history_steps", 0)) != 0:
    sys.exit("history off: history_steps attribute %s" % b.attrs["history_steps"])
EOF
fi

# checkpoints leave no space behind: a run that wrote one at every frame ends with a file the
# size of the same run without checkpoints (compacted at the end, stf_h5_compact), and the
# same contents (h5diff: only the wall time differs)
if run ck_every --checkpoint 0 && run ck_off --checkpoint off; then
    se=$(stat -c %s ck_every.h5) so=$(stat -c %s ck_off.h5)
    [ "$se" -le $((so + so / 10)) ] || fail "checkpointed run's file $se bytes against $so without checkpoints"
    h5diff ck_off.h5 ck_every.h5 >ck.diff 2>&1
    grep -v "wall_seconds" ck.diff | grep -q "^attribute\|^dataset\|Not comparable" &&
        { fail "checkpointed and plain runs differ beyond the wall time:"; cat ck.diff >&2; }
    [ -e ck_every.h5.compact ] && fail "ck_every.h5.compact left behind"
fi

# every command's --help / -h: its own usage lines on stdout, exit 0
for c in run check report render plot history bench sweep; do
    for h in --help -h; do
        "$STF" $c $h >help.out 2>help.err
        r=$?
        [ $r -eq 0 ] && grep -q "stf $c" help.out || fail "stf $c $h: exit $r, or no 'stf $c' usage on stdout"
    done
done
"$STF" run --help | grep -q "stf bench" && fail "stf run --help: prints other commands' usage"
if [ $fails -ne 0 ]; then
    echo "cli_run: $fails failure(s)" >&2
    exit 1
fi
echo "cli_run: ok"
exit 0
