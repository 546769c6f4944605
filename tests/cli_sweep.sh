# cli_sweep.sh - `stf sweep` end to end on a tiny scene (tests/scenes/small_drop.yaml, 320
# particles, 0.1 s): a 2 x 3 grid gives the same summary (every metric bit-identical) run
# serially, with 2 local jobs and under `mpirun -n 2 --oversubscribe` (skipped, with a message,
# when MPI is not installed or stf was built without it); every row equals `stf report` of its
# own file (to the report's 9 digits) and, bit for bit, a plain `stf run` with the same --set's; a heavier ball ends lower (the varied
# values reach the runs); the scene's expectations are held per run; a list file gives the same
# rows as the grid; an interrupted sweep (a killed run, a SIGINT'd run, a missing file) resumes
# and reruns only those, a signal stops a sweep (exit 130); a different sweep into the same DIR and bad input exit 2 and change
# nothing; the plot is a PNG.
#
# usage: bash cli_sweep.sh STF_BINARY PROJECT_DIR   (run in the build's tests directory)
. "$(dirname "$0")/lib_cli.sh" cli_sweep "$@"

SCENE="$PROJ/tests/scenes/small_drop.yaml"
PY=/usr/bin/python3
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive

# The scene with an expect block: the first holds for every run, the second only for the
# lighter balls (the fluid's top speed grows with the ball's mass: see the rows).
cp "$SCENE" drop.yaml
printf 'expect:\n  first_contact_time: "< 0.05"\n  fluid.max_speed: "< 1.8"\n' >> drop.yaml
SCENE=$PWD/drop.yaml
# The grid: no history vs history, three ball masses.
GRID=(--vary effects.history.k_hist=0,10000 --vary bodies.0.mass=0.02:0.08:3 --duration 0.1 --threads 1)

# same_metrics A.csv B.csv: equal but for the wall_seconds column.
same_metrics() {
    "$PY" - "$1" "$2" <<'EOF'
import csv, sys
def rows(p):
    r = list(csv.DictReader(open(p)))
    for x in r: x.pop("wall_seconds")
    return r
a, b = rows(sys.argv[1]), rows(sys.argv[2])
if a != b:
    for x, y in zip(a, b):
        if x != y: print("differ:", {k: (x[k], y.get(k)) for k in x if x[k] != y.get(k)})
    sys.exit(1)
EOF
}

"$STF" sweep "$SCENE" "${GRID[@]}" --quiet --jobs 1 -o serial 2>serial.err
rc=$?
[ $rc -eq 1 ] || { fail "serial sweep exited $rc (expected 1: some runs fail an expectation)"; cat serial.err >&2; }
"$STF" sweep "$SCENE" "${GRID[@]}" --quiet --jobs 2 -o parallel 2>parallel.err || [ $? -eq 1 ] ||
    { fail "parallel sweep failed"; cat parallel.err >&2; }
same_metrics serial/summary.csv parallel/summary.csv || fail "2 local jobs give another summary than 1"

# the summary: one row a run, values as asked, metrics equal to each file's own report
"$PY" - serial "$STF" "$SCENE" <<'EOF' || fail "summary.csv content"
import csv, json, math, subprocess, sys
d, stf, scene = sys.argv[1:4]
rows = list(csv.DictReader(open(d + "/summary.csv")))
ok = True
def bad(msg):
    global ok
    ok = False
    print("cli_sweep:", msg, file=sys.stderr)
if len(rows) != 6: bad(f"{len(rows)} rows, expected 6")
want = [(k, m) for k in ("0", "10000") for m in ("0.02", "0.05", "0.08")]
if [(r["effects.history.k_hist"], r["bodies.0.mass"]) for r in rows] != want:
    bad("the rows are not the grid in order (last key fastest)")
for i, r in enumerate(rows):
    if r["status"] != "ok": bad(f"run {i} status {r['status']}")
    if not float(r["wall_seconds"]) > 0: bad(f"run {i} wall time {r['wall_seconds']}")
    rep = json.loads(subprocess.run([stf, "report", f"{d}/run_{i:04d}.h5", "--json"],
                                    capture_output=True, text=True, check=True).stdout)
    b = rep["bodies"]["ball"]
    def same(col, v):
        s = r[col]
        if v is None:
            if s != "": bad(f"run {i} {col}: {s!r} but the report says null")
        elif s == "" or not math.isclose(float(s), float(v), rel_tol=1e-8, abs_tol=1e-12):  # JSON: 9 digits
            bad(f"run {i} {col}: {s!r} but the report says {v!r}")
    for k in ("first_contact_time", "bounces", "max_rebound_height", "roll_distance", "sink_time", "float_duration"):
        same("ball." + k, b[k])
    same("ball.final_z", b["final_position"][2])
    for k in ("particles", "escaped", "max_speed", "com_rebound_height", "finger_height"):
        same("fluid." + k, rep["fluid"][k])
    same("time_end", rep["time_end"])
    # the expectations, held here from the metrics
    fails = (not float(r["ball.first_contact_time"]) < 0.05) + (not float(r["fluid.max_speed"]) < 1.8)
    if r["expectations_failed"] != str(fails) or r["pass"] != ("pass" if fails == 0 else "fail"):
        bad(f"run {i}: pass {r['pass']} with {r['expectations_failed']} failed, expected {fails}")
# physics: with the same throw, a heavier ball ends lower, with and without history
for k in ("0", "10000"):
    z = [float(r["ball.final_z"]) for r in rows if r["effects.history.k_hist"] == k]
    if not (z[0] > z[1] > z[2]): bad(f"k_hist {k}: final heights {z} do not fall with mass")
if len({r["pass"] for r in rows}) != 2: bad("expected some runs to pass and some to fail")
sys.exit(0 if ok else 1)
EOF

# a row equals a plain stf run with the same --set's (the sweep adds nothing)
"$STF" run "$SCENE" -o plain.h5 --set effects.history.k_hist=10000 --set bodies.0.mass=0.05 \
    --duration 0.1 --threads 1 --quiet || fail "plain stf run"
"$STF" report plain.h5 --json > plain.json && "$STF" report serial/run_0004.h5 --json > row4.json &&
    cmp -s plain.json row4.json || fail "run 4 of the sweep differs from a plain stf run"

# the list form: two of the grid's runs, each twice (--repeat 2)
printf '# k_hist and mass\neffects.history.k_hist=10000 bodies.0.mass=0.08\n\neffects.history.k_hist=0   bodies.0.mass=0.02 # light\n' > runs.list
"$STF" sweep "$SCENE" --list runs.list --repeat 2 --duration 0.1 --threads 1 --quiet -o listed 2>listed.err || [ $? -eq 1 ] ||
    { fail "list sweep failed"; cat listed.err >&2; }
"$PY" - <<'EOF' || fail "the list form's rows differ from the grid's"
import csv
g = list(csv.DictReader(open("serial/summary.csv")))
l = list(csv.DictReader(open("listed/summary.csv")))
for x in g + l: x.pop("wall_seconds"), x.pop("run"), x.pop("repeat")
assert len(l) == 4 and l[0] == l[1] == g[5] and l[2] == l[3] == g[0], (l, g[5], g[0])
EOF

# resume: run 1 killed (no exit_status), run 3 interrupted (exit_status 130), run 5 missing
cp -r serial resumed
rm -f resumed/run_0001.h5 resumed/run_0003.h5 # (the copies would pass for grown files)
"$STF" run "$SCENE" -o resumed/run_0001.h5 --duration 20 --threads 1 --quiet &
pid=$!
grown resumed/run_0001.h5 $pid 100000 || fail "run 1 ended before it was killed"
kill -KILL $pid 2>/dev/null
wait $pid 2>/dev/null
"$STF" run "$SCENE" -o resumed/run_0003.h5 --duration 20 --threads 1 --quiet 2>int.err &
pid=$!
grown resumed/run_0003.h5 $pid 100000 || fail "run 3 ended before it was interrupted"
kill -INT $pid
wait $pid
[ $? -eq 130 ] || fail "an interrupted stf run did not exit 130"
rm -f resumed/run_0005.h5 resumed/summary.csv
touch -d '2000-01-01' resumed/run_0000.h5
"$STF" sweep "$SCENE" "${GRID[@]}" --jobs 1 -o resumed 2>resumed.err
grep -q "6 runs, 3 to do (3 already done)" resumed.err || { fail "resume did not find 3 runs to do"; cat resumed.err >&2; }
[ "$(stat -c %Y resumed/run_0000.h5)" = "$(date -d 2000-01-01 +%s)" ] || fail "resume rewrote a finished run"
same_metrics serial/summary.csv resumed/summary.csv || fail "the resumed sweep's summary differs"

# a signal to the sweep stops it: the running run saves what it has, exit 130, rows say so
"$STF" sweep "$SCENE" --vary bodies.0.mass=0.02,0.05 --duration 5 --jobs 1 --threads 1 --quiet -o stopped 2>stopped.err &
pid=$!
grown stopped/run_0000.h5 $pid 100000 || fail "the sweep ended before it was stopped"
kill -TERM $pid
wait $pid
rc=$?
[ $rc -eq 130 ] || { fail "a stopped sweep exited $rc, not 130"; cat stopped.err >&2; }
grep -q '^0,0.02,0,interrupted,' stopped/summary.csv && grep -q '^1,0.05,0,missing,' stopped/summary.csv ||
    { fail "a stopped sweep's summary does not say interrupted/missing"; cat stopped/summary.csv >&2; }

# the stopped sweep started again: the interrupted run continues from its checkpoint
# (stf run --resume) and ends as a plain run of the same --set's, bit for bit
"$STF" sweep "$SCENE" --vary bodies.0.mass=0.02,0.05 --duration 5 --jobs 1 --threads 1 -o stopped 2>restarted.err ||
    [ $? -eq 1 ] || { fail "the restarted sweep failed"; cat restarted.err >&2; }
grep -q "run 0 continues .*run_0000.h5 from its checkpoint" restarted.err ||
    { fail "the restarted sweep did not resume run 0"; cat restarted.err >&2; }
"$STF" run "$SCENE" -o plain5.h5 --set bodies.0.mass=0.02 --duration 5 --threads 1 --quiet \
    --checkpoint off || fail "plain 5 s run"
"$PY" - <<'EOF' || fail "the resumed run differs from a plain run"
import h5py, numpy as np
a, b = h5py.File("stopped/run_0000.h5", "r"), h5py.File("plain5.h5", "r")
ka = sorted(k for k in a if k.startswith("Step#"))
assert ka == sorted(k for k in b if k.startswith("Step#")), "frames differ"
for k in ka:
    for d in ("x", "y", "z", "vx", "vy", "vz"):
        assert np.array_equal(a[k][d][:], b[k][d][:]), (k, d)
for n in a["bodies"]:
    assert np.array_equal(a["bodies"][n]["position"][:], b["bodies"][n]["position"][:]), n
EOF

# a different sweep into the same DIR: exit 2, nothing changed
cp serial/summary.csv before.csv
"$STF" sweep "$SCENE" --vary bodies.0.mass=0.03 --duration 0.1 --quiet -o serial 2>other.err
[ $? -eq 2 ] && grep -q "different sweep" other.err || fail "a different sweep into a used DIR was not refused"
cmp -s before.csv serial/summary.csv || fail "a refused sweep changed summary.csv"

# bad input: a bad key or value exits 2 naming it, and makes no DIR
"$STF" sweep "$SCENE" --vary effects.history.q=0.5,7 --quiet -o badq 2>badq.err
[ $? -eq 2 ] && grep -q "effects.history.q" badq.err && [ ! -e badq ] || { fail "a bad value was not exit 2 (or DIR made)"; cat badq.err >&2; }
"$STF" sweep "$SCENE" --vary bodies.0.mass=1:2:0 --quiet -o badn 2>/dev/null
[ $? -eq 2 ] && [ ! -e badn ] || fail "COUNT 0 was accepted"
"$STF" sweep "$SCENE" --quiet -o none 2>/dev/null
[ $? -eq 2 ] || fail "a sweep without --vary or --list was accepted"

# the plot
[ "$(head -c 8 serial/summary.png | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ] || fail "summary.png is not a PNG"

# MPI: 2 ranks, the same summary
if ! command -v mpirun > /dev/null; then
    echo "cli_sweep: SKIP the MPI part: mpirun not installed (apt-get install openmpi-bin libopenmpi-dev, then rebuild)"
else
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
fi
if command -v mpirun > /dev/null && ! mpirun -n 2 --oversubscribe true > mpi_true.out 2>&1; then
    echo "cli_sweep: SKIP the MPI part: 'mpirun -n 2 --oversubscribe true' fails on this machine:"
    head -5 mpi_true.out
elif command -v mpirun > /dev/null; then
    mpirun -n 2 --oversubscribe "$STF" sweep "$SCENE" "${GRID[@]}" --jobs 1 -o mpi > mpi.out 2>mpi.err
    rc=$?
    if grep -q "built without MPI" mpi.err; then
        echo "cli_sweep: SKIP the MPI part: this stf was built without MPI (install libopenmpi-dev, rerun cmake)"
    else
        [ $rc -eq 1 ] || { fail "mpirun -n 2 stf sweep exited $rc"; cat mpi.err >&2; }
        grep -q "(rank 0)" mpi.err && grep -q "(rank 1)" mpi.err || { fail "the runs were not spread over both ranks"; cat mpi.err >&2; }
        same_metrics serial/summary.csv mpi/summary.csv || fail "mpirun -n 2 gives another summary than 1 job"
    fi
fi

if [ $fails -ne 0 ]; then
    echo "cli_sweep: $fails failure(s)" >&2
    exit 1
fi
echo "cli_sweep: ok"
