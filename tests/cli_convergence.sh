#!/usr/bin/env bash
# cli_convergence.sh - `stf bench convergence` end to end, real runs (a few seconds each):
#  - the fluid drop at a 1.5 cm spacing for 0.3 s (the impact at 0.18 s), no -o: exit 0 or 1
#    (the verdict, never 2 or 3); the memory-in-steps warning (given d = 150 by --set: the
#    scene's memory is in seconds); the
#    default directory convergence-fluid_drop holds run0..run3.h5 and convergence.csv, whose
#    columns are the four runs (dt, dt/2, dt/4, 1.5x_spacing) and whose rows are every fluid
#    metric of src/io/metrics.c's list (read from the source, not a copy), each with a verdict,
#    and the runs' dt, spacing, wall, cpu, steps, substeps and particles;
#  - the runs' settings: the user's --set fluid.spacing is the base (1.5 and 2.25 cm), the
#    dt/2 and dt/4 runs took 2x and 4x the steps of the dt run (the files' "steps" attribute
#    by h5dump, and the table's run.steps row), and the coarse run has 1.5^3 = 3.4x fewer
#    particles (within 30%);
#  - the bowling ball (a body) at a 4 cm spacing for 0.15 s with --jobs 2 and -o: a row for
#    every body metric of the list ("ball.NAME"), and the verdict column agrees with the exit
#    code (1 if and only if some row says no);
#  - --tolerance 1e9 passes every judged metric (exit 0) on the files of a rerun;
#  - bad input is exit 2 and makes no directory: an unknown option, --tolerance -1, --jobs 0,
#    a missing scene; --tolerance on another benchmark is refused; --help is exit 0 with the
#    usage on stdout.
# usage: bash cli_convergence.sh STF_BINARY PROJECT_DIR
. "$(dirname "$0")/lib_cli.sh" cli_convergence "$@"
export OMP_NUM_THREADS=1
DROP="$PROJ/scenes/fluid_drop.yaml"

"$STF" bench convergence "$DROP" --set fluid.spacing=0.015 --set effects.history.d=150 --duration 0.3 \
    --threads 1 >drop.out 2>drop.err
rc=$?
[ $rc -eq 0 ] || [ $rc -eq 1 ] || { fail "bench convergence exited $rc (want 0 or 1)"; cat drop.err >&2; }
grep -q "^memory given in steps (d = 150): dt/2 and dt/4 change the memory in seconds; give effects.history.memory" \
    drop.err || fail "no warning about the memory given in steps"
D=convergence-fluid_drop
for f in run0.h5 run1.h5 run2.h5 run3.h5 convergence.csv; do
    [ -s "$D/$f" ] || fail "no $D/$f"
done
# the h5 files' steps: 2x and 4x the dt run's
attr() { h5dump -a "/$2" "$1" | awk '/\(0\):/ { print $2 }'; }
s0=$(attr $D/run0.h5 steps) s1=$(attr $D/run1.h5 steps) s2=$(attr $D/run2.h5 steps)
[ -n "$s0" ] && [ "$s1" -eq $((2 * s0)) ] && [ "$s2" -eq $((4 * s0)) ] \
    || fail "steps of the dt, dt/2, dt/4 runs: $s0 $s1 $s2 (want N, 2N, 4N)"
/usr/bin/python3 - "$D/convergence.csv" "$PROJ/src/io/metrics.c" "$rc" "$s0" drop.out <<'PY' || fail "convergence.csv (fluid drop) wrong"
import csv, re, sys
path, src, rc, s0, out = sys.argv[1], open(sys.argv[2]).read(), int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
names = lambda which: re.findall(r'"(\w+)"', re.search(which + r"\[\] = \{(.*?)\};", src, re.S).group(1))
fluid = names("stf_fluid_metric_names")
assert fluid and "particles" in fluid, fluid
rows = list(csv.reader(open(path)))
head = rows[0]
assert head[:6] == ["metric", "unit", "dt", "dt/2", "dt/4", "1.5x_spacing"], head
assert head[6:] == ["range", "spread_percent", "ok"], head
by = {r[0]: dict(zip(head, r)) for r in rows[1:]}
for n in fluid:
    assert "fluid." + n in by, ("no row", n)
    assert by["fluid." + n]["ok"] in ("yes", "no", "-"), by["fluid." + n]
for n in ("dt", "spacing", "wall", "cpu", "steps", "substeps", "particles"):
    assert "run." + n in by, ("no row run.", n)
runs = ["dt", "dt/2", "dt/4", "1.5x_spacing"]
num = lambda key: [float(by[key][c]) for c in runs]
assert num("run.dt") == [0.001, 0.0005, 0.00025, 0.001], num("run.dt")
assert num("run.spacing") == [0.015, 0.015, 0.015, 0.0225], num("run.spacing")
assert num("run.steps")[:3] == [s0, 2 * s0, 4 * s0], num("run.steps")
assert all(w > 0 for w in num("run.wall")) and all(s >= n for s, n in zip(num("run.substeps"), num("run.steps")))
p = num("run.particles")
assert p[0] == p[1] == p[2] and p == num("fluid.particles"), p
ratio = p[0] / p[3]
assert abs(ratio / 1.5 ** 3 - 1) < 0.3, ("coarse run's particles", p, ratio)
verdicts = [r["ok"] for k, r in by.items() if not k.startswith("run.")]
assert (rc == 1) == ("no" in verdicts), (rc, verdicts)
table = open(out).read()
assert re.search(r"^run\.wall +s ", table, re.M) and re.search(r"^fluid\.max_speed +m/s ", table, re.M), table
PY

# a body's metrics, two runs at a time
"$STF" bench convergence "$PROJ/scenes/bowling_ball.yaml" --set fluid.spacing=0.04 --duration 0.15 \
    --threads 1 --jobs 2 -o bowl >bowl.out 2>bowl.err
rc=$?
[ $rc -eq 0 ] || [ $rc -eq 1 ] || { fail "bench convergence (bowling) exited $rc"; cat bowl.err >&2; }
/usr/bin/python3 - bowl/convergence.csv "$PROJ/src/io/metrics.c" "$rc" <<'PY' || fail "convergence.csv (bowling) wrong"
import csv, re, sys
path, src, rc = sys.argv[1], open(sys.argv[2]).read(), int(sys.argv[3])
names = lambda which: re.findall(r'"(\w+)"', re.search(which + r"\[\] = \{(.*?)\};", src, re.S).group(1))
body = names("stf_body_metric_names")
assert "penetration_depth" in body and "rolling_ratio" in body, body
by = {r["metric"]: r for r in csv.DictReader(open(path))}
for n in body:
    assert "ball." + n in by, ("no row", n)
assert by["ball.radius"]["ok"] == "yes", by["ball.radius"]
verdicts = [r["ok"] for k, r in by.items() if not k.startswith("run.")]
assert (rc == 1) == ("no" in verdicts), (rc, verdicts)
PY

"$STF" bench convergence "$DROP" --set fluid.spacing=0.015 --duration 0.3 --threads 1 --tolerance 1e9 \
    -o loose >loose.out 2>loose.err
rc=$?
[ $rc -eq 0 ] || { fail "--tolerance 1e9: want exit 0, got $rc"; cat loose.out loose.err >&2; }

# bad input: exit 2, no directory
for bad in "--bogus" "--tolerance -1" "--tolerance x" "--jobs 0"; do
    "$STF" bench convergence "$DROP" $bad -o badrun >/dev/null 2>bad.err
    r=$?
    [ $r -eq 2 ] && [ ! -e badrun ] || fail "bench convergence $bad: want exit 2 and no directory, got $r"
done
grep -q -- "--jobs" bad.err || fail "--jobs 0: the message does not name --jobs"
"$STF" bench convergence "$WORK/missing.yaml" -o badrun >/dev/null 2>&1
r=$?
[ $r -eq 2 ] && [ ! -e badrun ] || fail "a missing scene: want exit 2 and no directory, got $r"
"$STF" bench convergence >/dev/null 2>&1
[ $? -eq 2 ] || fail "no scene: want exit 2"
"$STF" bench accuracy "$DROP" --tolerance 0.1 >/dev/null 2>tol.err
[ $? -eq 2 ] && grep -q "only to: convergence" tol.err || fail "accuracy --tolerance: want exit 2"
"$STF" bench convergence --help >help.out 2>help.err
[ $? -eq 0 ] && grep -q "^usage: stf bench convergence SCENE" help.out && [ ! -s help.err ] \
    || fail "bench convergence --help: want the usage on stdout, exit 0"
"$STF" bench --help | grep -q "convergence SCENE" || fail "stf bench --help does not name convergence"
exit $((fails > 0))
