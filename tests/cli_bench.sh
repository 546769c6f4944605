#!/usr/bin/env bash
# cli_bench.sh - `stf bench` end to end on the bowling ball at a coarse spacing (about 1.1K
# particles, a few steps, without the scene's 1 s of settling: 15 s instead of 280 s on one
# core), so it checks behaviour, never speed (speed targets are in the benchmark's own
# output, not in tests):
#  - effects (--repeat 2: the fastest of two runs a row): every effect of the scene turned
#    off in turn; an effect that is off costs no stage time and no storage (the command
#    itself fails otherwise), and the rows are there;
#  - accuracy --knobs history: writes the CSV (one row per setting) and a PNG; the reference
#    (full history) has zero error; the sum-of-exponentials history with 16 terms is closer to
#    the full history than a 10-step window is;
#  - accuracy --knobs solver on the Carreau-Yasuda dam break: four settings of the solvers'
#    tolerances (x0.1 the reference, with zero error), every error finite and under 5 mm
#    (the tolerances move the fluid, not the flow); a knob that does not apply to the scene
#    (solver on the bowling ball) and an unknown knob are exit 2, no directory made;
#  - grid: two rows (the scene's particles and about 10x as many), candidates per particle
#    more than neighbours, and the neighbours per particle within 20% of each other;
#  - scaling with a fixed dt: two rows, one substep per step, the per-substep ratio equal to
#    the per-step one;
#  - scaling --grow domain: the same spacing on both rows and 9-11.5x the particles (the pool
#    widened sqrt(10)x in x and y); --grow with anything else is exit 2;
#  - table1 times whole history time blocks: with a fixed dt (one sample a step) and
#    --steps 3, the window rows time one block (16 steps for d = 50 and 150, 32 for d = 500)
#    and the rows without a window (d = 0, soe) 3 steps;
#  - table1 refuses a missing scene with exit 2, and an unknown benchmark is exit 2;
#  - history.terms is refused (exit 2, key named) without mode soe and outside [1, 64].
# usage: bash cli_bench.sh STF_BINARY PROJECT_DIR
. "$(dirname "$0")/lib_cli.sh" cli_bench "$@"
SCENE="$PROJ/scenes/bowling_ball.yaml"
export OMP_NUM_THREADS=1

"$STF" bench effects "$SCENE" --set fluid.spacing=0.04 --set fluid.settle=0 --steps 3 --threads 1 --repeat 2 >effects.out 2>effects.err \
    || { fail "bench effects exited $?"; cat effects.err >&2; }
grep -q "^# stf bench effects .*fastest of 2 run(s) a row" effects.out \
    || fail "bench effects: --repeat 2 not in the header"
for row in "all (scene)" "no gravity" "no viscosity" "no pressure" "no springs+history" "no history" \
           "no boundary_stick"; do
    grep -q "^$row " effects.out || fail "bench effects: no row '$row'"
done
# the history column (6th stage) of the 'no history' row is exactly 0
awk '/^no history /{ for (i = 1; i <= NF; i++) if ($i == "|") { print $(i + 5); exit } }' effects.out \
    | grep -qx "0.000" || fail "bench effects: history stage time not 0 with history off"

"$STF" bench accuracy "$SCENE" --set fluid.spacing=0.04 --set fluid.settle=0 --duration 0.08 --knobs history --threads 1 \
    -o acc >acc.out 2>acc.err || { fail "bench accuracy exited $?"; cat acc.err >&2; }
[ -s acc/accuracy.csv ] || fail "no accuracy.csv"
[ "$(wc -l <acc/accuracy.csv)" -eq 9 ] || fail "accuracy.csv: want a header and 8 rows, got $(wc -l <acc/accuracy.csv) lines"
head -c 8 acc/accuracy.png | od -An -tx1 | tr -d ' \n' | grep -q '^89504e470d0a1a0a$' || fail "accuracy.png is not a PNG"
/usr/bin/python3 - acc/accuracy.csv <<'PY' || fail "accuracy.csv errors"
import csv, sys
rows = {r["setting"]: r for r in csv.DictReader(open(sys.argv[1]))}
err = lambda s: float(rows[s]["err_body_path_m"])
assert err("full") == 0.0, rows["full"]
assert err("soe K=16") < err("window d=10"), (err("soe K=16"), err("window d=10"))
assert all(float(r["cpu_s"]) > 0 for r in rows.values())
PY
grep -q "^cheapest history" acc.out || fail "bench accuracy names no cheapest setting"

"$STF" bench accuracy "$PROJ/scenes/cy_dam_break.yaml" --knobs solver --full --duration 0.08 --threads 1 \
    -o accs >accs.out 2>accs.err || { fail "bench accuracy --knobs solver exited $?"; cat accs.err >&2; }
/usr/bin/python3 - accs/accuracy.csv <<'PY' || fail "accuracy.csv (solver) wrong"
import csv, math, sys
rows = list(csv.DictReader(open(sys.argv[1])))
assert [r["setting"] for r in rows] == ["tolerances x0.1", "tolerances x0.3", "tolerances x1",
                                        "tolerances x3"], rows
errs = [float(r["err_fluid_com_m"]) for r in rows]
assert errs[0] == 0.0 and all(math.isfinite(e) and e < 0.005 for e in errs), errs
PY
"$STF" bench accuracy "$SCENE" --knobs solver -o nosolver >/dev/null 2>ns.err
[ $? -eq 2 ] && grep -q "no knob of 'solver' applies" ns.err && [ ! -e nosolver ] \
    || fail "accuracy --knobs solver on the bowling ball: want exit 2, no directory"
"$STF" bench accuracy "$SCENE" --knobs dt,speed -o nosolver >/dev/null 2>nk.err
[ $? -eq 2 ] && grep -q "unknown 'speed'" nk.err && [ ! -e nosolver ] || fail "accuracy --knobs dt,speed: want exit 2"

"$STF" bench grid "$SCENE" --set fluid.spacing=0.04 --set fluid.settle=0 --steps 2 --threads 1 >grid.out 2>grid.err \
    || { fail "bench grid exited $?"; cat grid.err >&2; }
awk '!/^#/ && $1 ~ /^[0-9]/ { rows++; if (!($3 > $4 && $4 > 0)) bad = 1; nb[rows] = $4; n[rows] = $2 }
     END { if (rows != 2 || bad || n[2] < 7 * n[1] || nb[2] > 1.2 * nb[1] || nb[2] < nb[1] / 1.2) exit 1 }' grid.out \
    || { fail "bench grid: rows wrong"; cat grid.out >&2; }

"$STF" bench table1 "$SCENE" --set fluid.spacing=0.04 --set fluid.settle=0 --set dt_control=fixed --steps 3 --warmup 2 \
    --threads 1 >t1.out 2>t1.err || { fail "bench table1 exited $?"; cat t1.err >&2; }
grep -qx "# steps timed (to whole history time blocks): 3 16 16 32 3 3 16 16 32 3" t1.out \
    || { fail "bench table1: timed steps not whole history blocks"; cat t1.out >&2; }
"$STF" bench table1 "$WORK/missing.yaml" --steps 1 >/dev/null 2>t1.err
[ $? -eq 2 ] || fail "table1 with a missing scene: want exit 2"
"$STF" bench nope >/dev/null 2>&1
[ $? -eq 2 ] || fail "unknown benchmark: want exit 2"
# scaling: two rows; the substeps per step are at least 1, and the per-substep ratio is the
# per-step ratio divided by the ratio of substeps
"$STF" bench scaling "$SCENE" --set fluid.spacing=0.04 --set fluid.settle=0 --set dt_control=fixed --steps 3 --warmup 2 \
    --threads 1 --repeat 2 >scaling.out 2>scaling.err || { fail "bench scaling exited $?"; cat scaling.err >&2; }
awk '!/^#/ && $1 ~ /^[0-9]/ { rows++; if (!($7 == 1.00 && $8 == $6 && $2 > 0)) bad = 1 }
     END { if (rows != 2 || bad) exit 1 }' scaling.out \
    || { fail "bench scaling (fixed dt): rows wrong"; cat scaling.out >&2; }
"$STF" bench scaling "$SCENE" --grow domain --set fluid.spacing=0.04 --set fluid.settle=0 --set dt_control=fixed --steps 2 \
    --warmup 1 --threads 1 >wide.out 2>wide.err || { fail "bench scaling --grow domain exited $?"; cat wide.err >&2; }
awk '!/^#/ && $1 ~ /^[0-9]/ { rows++; sp[rows] = $1; n[rows] = $2 }
     END { if (rows != 2 || sp[1] != 0.04 || sp[2] != 0.04 || n[2] < 9 * n[1] || n[2] > 11.5 * n[1]) exit 1 }' wide.out \
    || { fail "bench scaling --grow domain: rows wrong"; cat wide.out >&2; }
"$STF" bench scaling "$SCENE" --grow sideways >/dev/null 2>grow.err
[ $? -eq 2 ] && grep -q -- "--grow" grow.err || fail "scaling --grow sideways: want exit 2 naming --grow"
"$STF" bench scaling "$SCENE" --repeat 0 >/dev/null 2>rep.err
[ $? -eq 2 ] && grep -q -- "--repeat" rep.err || fail "scaling --repeat 0: want exit 2 naming --repeat"
# the soe history's parameter: only with mode soe, and in [1, 64]
"$STF" run "$SCENE" -o bad.h5 --set effects.history.terms=8 --duration 0.001 2>bad1.err
[ $? -eq 2 ] && grep -q "effects.history.terms: only with mode: soe" bad1.err || fail "terms without soe"
"$STF" run "$SCENE" -o bad.h5 --set effects.history.mode=soe --set effects.history.terms=0 --duration 0.001 2>bad2.err
[ $? -eq 2 ] && grep -q "effects.history.terms" bad2.err || fail "terms = 0"
[ ! -e bad.h5 ] || fail "a bad scene created its output file"
exit $((fails > 0))
