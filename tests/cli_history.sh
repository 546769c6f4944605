# cli_history.sh - `stf history` end to end: the figures of paper section 3.2 are written
# (CSV + PNG) with the expected columns; with constant velocity and full history the
# stiffness is the closed form k_hist v t^(1-q) / Gamma(2-q); longer windows give larger or
# equal peaks; the stiffness decays after the motion stops; a profile file is read; bad
# input exits 2 (with FILE:LINE for a bad profile).
#
# usage: bash cli_history.sh STF_BINARY PROJECT_DIR   (run in the build's tests directory)
. "$(dirname "$0")/lib_cli.sh" cli_history "$@"

PY=/usr/bin/python3
: "$PROJ"

# ---------------------------------------------------------------- default run
"$STF" history -o out --k-hist 2.5 >stdout.txt 2>stderr.txt
rc=$?
[ "$rc" -eq 0 ] || fail "stf history exited $rc: $(cat stderr.txt)"
for f in fig2_weights fig3_impact fig4_constant; do
    for e in csv png; do
        [ -s "out/$f.$e" ] || fail "out/$f.$e missing or empty"
        grep -q "out/$f.$e" stdout.txt || fail "no line for out/$f.$e on stdout"
    done
done
[ "$(wc -l <stdout.txt)" -eq 6 ] || fail "expected 6 lines on stdout, got $(wc -l <stdout.txt)"

"$PY" - out 2.5 <<'PYEOF' || fail "checks of the CSV files (above)"
import csv, math, sys
d, khist = sys.argv[1], float(sys.argv[2])
bad = []

def table(path):
    rows = [r for r in csv.reader(l for l in open(path) if not l.startswith("#"))]
    return rows[0], [[float(x) for x in r] for r in rows[1:]]

# figure 2: weights
head, rows = table(f"{d}/fig2_weights.csv")
if head != ["lag", "q0.2", "q0.5", "q0.8"]:
    bad.append(f"fig2 columns {head}")
if rows and any(abs(r - 1) > 1e-12 for r in rows[0][1:]):
    bad.append(f"fig2: weight at lag 0 is not 1: {rows[0]}")
if len(rows) != 51:
    bad.append(f"fig2: {len(rows)} rows, expected lags 0..50")

windows = ["d50", "d150", "d500", "full"]
expect = ["step", "t", "v"] + [f"q{q}_{w}" for q in ("0.2", "0.5", "0.8") for w in windows]
for name in ("fig3_impact", "fig4_constant"):
    head, rows = table(f"{d}/{name}.csv")
    if head != expect:
        bad.append(f"{name} columns {head}, expected {expect}")
        continue
    col = {h: i for i, h in enumerate(head)}
    t = [r[col["t"]] for r in rows]
    v = [r[col["v"]] for r in rows]
    if len(rows) < 200:
        bad.append(f"{name}: only {len(rows)} rows")
    # last moving sample
    stop = max(i for i, x in enumerate(v) if x != 0)
    for q in ("0.2", "0.5", "0.8"):
        k = {w: [r[col[f"q{q}_{w}"]] for r in rows] for w in windows}
        peaks = [max(k[w]) for w in windows]
        # windows over 16 steps sum in float32 blocks: within 1.0e-6 of the sum of |terms|
        # (src/history.c), so equal peaks (before a window fills) may differ by that much
        for a, b, wa, wb in zip(peaks, peaks[1:], windows, windows[1:]):
            if not b >= a * (1 - 2e-6):
                bad.append(f"{name} q={q}: peak {wb} {b:.6g} < peak {wa} {a:.6g}")
        for w in windows:
            after = k[w][stop:]
            rises = [i for i in range(1, len(after)) if after[i] > after[i - 1] * (1 + 2e-6) + 1e-15]
            if rises:
                bad.append(f"{name} q={q} {w}: stiffness rises after the motion stops (step {stop + rises[0]})")
            if not after[-1] < 0.8 * after[0]:
                bad.append(f"{name} q={q} {w}: no decay after the stop ({after[0]:.6g} -> {after[-1]:.6g})")
        if name == "fig4_constant":
            # constant velocity from the first sample: closed form while the velocity is constant
            start = next(i for i, x in enumerate(v) if x != 0)
            vc = v[start]
            end = start
            while end + 1 < len(v) and v[end + 1] == vc:
                end += 1
            if end - start < 100:
                bad.append(f"fig4: constant velocity for only {end - start} steps")
            qq = float(q)
            worst = 0.0
            for i in range(start + 1, end + 1):
                tt = t[i] - t[start]
                ref = khist * vc * tt ** (1 - qq) / math.gamma(2 - qq)
                worst = max(worst, abs(k["full"][i] - ref) / ref)
            print(f"fig4 q={q}: full history vs k_hist v t^(1-q)/Gamma(2-q) over steps "
                  f"{start + 1}..{end}: max relative difference {worst:.3g}")
            if not worst < 1e-6:
                bad.append(f"fig4 q={q}: full history differs from the closed form by {worst:.3g} relative")
            print(f"fig4 q={q}: peaks " + ", ".join(f"{w} {p:.6g}" for w, p in zip(windows, peaks)))
for b in bad:
    print("cli_history:", b, file=sys.stderr)
sys.exit(1 if bad else 0)
PYEOF

# ---------------------------------------------------------------- options
"$STF" history --fig 2 -o only2 --q 0.3,0.6 >/dev/null 2>err.txt || fail "--fig 2 --q 0.3,0.6 failed: $(cat err.txt)"
[ -s only2/fig2_weights.png ] && [ ! -e only2/fig3_impact.csv ] || fail "--fig 2 wrote the wrong files"
head -n 3 only2/fig2_weights.csv | grep -q '^lag,q0.3,q0.6$' || fail "--q 0.3,0.6: columns of fig2_weights.csv"

# a profile file (t,v): the same built-in constant profile gives the same numbers
printf '# a test profile\nt,v\n' >prof.csv
for i in $(seq 0 60); do
    if [ "$i" -le 30 ]; then v=1; else v=0; fi
    echo "$(awk -v i="$i" 'BEGIN { printf "%.10f", i / 30 }'),$v" >>prof.csv
done
"$STF" history --fig 4 --profile prof.csv -o prof --d 10 >/dev/null 2>err.txt || fail "--profile prof.csv failed: $(cat err.txt)"
"$STF" history --fig 4 --steps 60 -o builtin --d 10 >/dev/null 2>err.txt || fail "--steps 60 failed: $(cat err.txt)"
"$PY" - prof/fig4_constant.csv builtin/fig4_constant.csv <<'PYEOF' || fail "--profile differs from the same built-in profile"
import sys
def rows(p):
    return [[float(x) for x in l.split(",")] for l in open(p) if l[0].isdigit()]
a, b = rows(sys.argv[1]), rows(sys.argv[2])
assert len(a) == len(b) == 61, (len(a), len(b))
worst = max(abs(x - y) for ra, rb in zip(a, b) for x, y in zip(ra[2:], rb[2:]))
assert worst < 1e-9, worst
PYEOF

# ---------------------------------------------------------------- bad input -> 2
expect2() { # expect2 WHAT PATTERN ARGS...
    local what=$1 pat=$2
    shift 2
    "$STF" history -o bad "$@" >/dev/null 2>err.txt
    local r=$?
    [ "$r" -eq 2 ] || fail "$what: exit $r, expected 2"
    grep -q -- "$pat" err.txt || fail "$what: message lacks '$pat': $(cat err.txt)"
}
expect2 "--q 1.5" "1.5" --q 1.5
expect2 "--q 0" "--q" --q 0,0.5
expect2 "--d -3" "--d" --d 50,-3
expect2 "--dt 0" "--dt" --dt 0
expect2 "--fig 5" "--fig" --fig 5
expect2 "unknown option" "unknown option" --frobnicate 1
printf '# velocities\n0\n0.5\nabc\n1\n' >badval.csv
expect2 "non-number in profile" "badval.csv:4" --profile badval.csv
printf 't,v\n0,0\n0.1,1\n0.3,1\n' >badstep.csv
expect2 "uneven times in profile" "badstep.csv:4" --profile badstep.csv
printf '0,1\n0.1,1,7\n' >badcols.csv
expect2 "three columns in profile" "badcols.csv:2" --profile badcols.csv
expect2 "missing profile" "nonexistent.csv" --profile nonexistent.csv

if [ "$fails" -ne 0 ]; then
    echo "cli_history: $fails check(s) failed" >&2
    exit 1
fi
echo "cli_history: all checks passed"
