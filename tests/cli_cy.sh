# cli_cy.sh - the Carreau-Yasuda scenes through the command-line tool, at test resolution:
#   - bad Carreau-Yasuda input exits 2 naming FILE:LINE:COL and the key, output untouched;
#   - the block into a pool: the Newtonian block splashes and the non-Newtonian one does not
#     (their expect blocks hold fluid.splash_height above 0.3 m and below 0.1 m, and the
#     Newtonian one is more than 3x the other);
#   - the shear-thickening collapse at dt = 3e-4 s: implicit viscosity runs, explicit stops
#     with exit 3, a message naming the step and 'carreau_yasuda viscosity (explicit)', and
#     a readable file up to the last good frame;
#   - every frame carries the solver statistics (pressure iterations >= 2, density error < eta).
#
# usage: bash cli_cy.sh STF_BINARY PROJECT_DIR   (run in the build's tests directory)
. "$(dirname "$0")/lib_cli.sh" cli_cy "$@"

SC="$PROJ/scenes"
export OMP_NUM_THREADS=1

# ---- bad input: exit 2, FILE:LINE:COL: KEY, nothing written
printf 'precious %s\n' "$$" >out.h5
cp out.h5 out.h5.ref
bad() { # NAME PATTERN FILE
    "$STF" run "$3" -o out.h5 >"$1.out" 2>"$1.err"
    local rc=$?
    [ $rc -eq 2 ] || fail "$1: exit $rc, want 2"
    grep -q -E "$2" "$1.err" || fail "$1: stderr '$(cat "$1.err")' does not match '$2'"
    cmp -s out.h5 out.h5.ref || fail "$1: out.h5 was overwritten"
    [ ! -e out.xmf ] || fail "$1: out.xmf created"
}
# bad_edit NAME SCENE SED_EXPR LINE_REGEX REST: the scene edited by SED_EXPR into NAME.yaml
# must be refused at the line matching LINE_REGEX, the message matching REST after it.
bad_edit() {
    sed "$3" "$SC/$2.yaml" >"$1.yaml"
    local line
    line=$(grep -n -m1 -e "$4" "$1.yaml" | cut -d: -f1)
    bad "$1" "^$1.yaml:$line:$5" "$1.yaml"
}
bad_edit neg_n cy_falling_column 's/n: 1, eta: 0.01}/n: -1, eta: 0.01}/' 'carreau_yasuda: {' \
    "[0-9]+: effects.carreau_yasuda.n: must be > 0"
bad_edit bad_solver cy_collapse_thickening 's/viscosity_solver: implicit/viscosity_solver: sideways/' 'viscosity_solver: sideways' \
    "[0-9]+: effects.carreau_yasuda.viscosity_solver: expected one of: implicit, explicit"
bad_edit bad_form cy_collapse_thickening 's/viscosity_solver: implicit}/viscosity_solver: implicit, viscosity_form: sideways}/' 'viscosity_form: sideways' \
    "[0-9]+: effects.carreau_yasuda.viscosity_form: expected one of: morris, central"
bad_edit bad_cfl dam_break_3d 's/cfl: 0.5,/cfl: 1.5,/' 'cfl: 1.5' "[0-9]+: effects.carreau_yasuda.cfl: "
bad_edit bad_dtmax dam_break_3d 's/dt_max: 0.005,/dt_max: -1,/' 'dt_max: -1' "[0-9]+: effects.carreau_yasuda.dt_max: "
bad_edit mixed cy_falling_column 's/  gravity: {g: \[0, 0, -9.81\]}/  gravity: {g: [0, 0, -9.81]}\n  pressure: {k: 1000}/' '  pressure:' \
    "3: effects.pressure: not part of fluid.model carreau_yasuda"
bad_edit nomodel cy_falling_column 's/  model: carreau_yasuda/  model: clavet_stf/' 'carreau_yasuda: {' \
    "3: effects.carreau_yasuda: needs fluid.model: carreau_yasuda"

# ---- the pool: splash ordering at 0.2 m spacing (3943 particles; the scenes: 0.1 m, 32,751)
# and 4 ms steps (CFL number below 0.1 at the splash's 7 m/s)
for s in cy_block_into_pool cy_block_into_pool_nonnewtonian; do
    "$STF" check "$SC/$s.yaml" --set fluid.spacing=0.2 --set dt=0.004 -o "$s.h5" --quiet >"$s.check" 2>&1 ||
        fail "$s: expectations failed: $(cat "$s.check")"
done
/usr/bin/python3 - cy_block_into_pool.h5 cy_block_into_pool_nonnewtonian.h5 <<'EOF' || fail "splash ordering"
import sys, h5py, json
n, v = (json.loads(h5py.File(p, "r")["metrics"].attrs["json"])["fluid"] for p in sys.argv[1:])
assert n["splash_height"] > 3 * v["splash_height"], (n["splash_height"], v["splash_height"])
print("cli_cy: splash_height %.3f m (Newtonian) vs %.3f m (shear thinning)" % (n["splash_height"], v["splash_height"]))
EOF

# ---- dt = 3e-4 s: implicit runs, explicit blows up (exit 3, named, last good frame kept);
# at the scene's resolution (the explicit limit falls with the spacing squared), 0.06 s
"$STF" run "$SC/cy_collapse_thickening.yaml" --duration 0.06 --set frame_rate=200 -o imp.h5 --quiet 2>imp.err ||
    fail "implicit at dt = 3e-4 s failed: $(cat imp.err)"
"$STF" run "$SC/cy_collapse_thickening.yaml" --duration 0.06 --set frame_rate=200 \
    --set effects.carreau_yasuda.viscosity_solver=explicit -o exp.h5 --quiet 2>exp.err
rc=$?
[ $rc -eq 3 ] || fail "explicit at dt = 3e-4 s: exit $rc, want 3"
grep -q -E "step [0-9]+ .*particle [0-9]+.*blew up.*carreau_yasuda viscosity \(explicit\)" exp.err ||
    fail "explicit failure message: $(cat exp.err)"

# ---- the files: solver statistics per frame, readable after the failure
/usr/bin/python3 - imp.h5 exp.h5 <<'EOF' || fail "HDF5 solver statistics"
import sys, h5py
imp, exp = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
frames = [k for k in imp.keys() if k.startswith("Step#")]
assert len(frames) >= 9, frames
for k in frames:
    a = imp[k].attrs
    if k == "Step#0":
        continue
    assert a["pressure_iterations_max"] >= 2, (k, dict(a))
    assert a["density_error_max"] < 0.01, (k, dict(a))
    assert a["viscosity_iterations_max"] >= 1, (k, dict(a))
assert imp.attrs["pressure_iterations_mean"] >= 2
ef = [k for k in exp.keys() if k.startswith("Step#")]
assert len(ef) >= 1 and "TimeValue" in exp[ef[-1]].attrs, ef
print("cli_cy: %d frames with solver statistics; explicit run kept %d frames" % (len(frames), len(ef)))
EOF

# ---- the statistics cover every substep (the CFL split), not the last of each step: the
# run's root attributes against `stf bench dam`, which sums every substep's own (a falling
# column at 0.15 m, 490 particles; one projection iteration at most, so the errors vary)
SST=(--set fluid.spacing=0.15 --set dt=0.02 --set dt_control=fixed --set effects.carreau_yasuda.cfl=0.15
    --set effects.carreau_yasuda.min_pressure_iterations=1 --set effects.carreau_yasuda.max_pressure_iterations=1
    --set effects.carreau_yasuda.eta=0.0001 --set frame_rate=50)
"$STF" run "$SC/cy_falling_column.yaml" --duration 1 "${SST[@]}" -o sst.h5 --quiet 2>sst.err ||
    fail "statistics run: $(cat sst.err)"
"$STF" bench dam "$SC/cy_falling_column.yaml" --duration 1 --threads 1 "${SST[@]}" >sst.bench 2>&1 ||
    fail "statistics bench: $(cat sst.bench)"
/usr/bin/python3 - sst.h5 sst.bench <<'EOF2' || fail "solver statistics over the substeps"
import sys, h5py
a = h5py.File(sys.argv[1], "r").attrs
row = [l.split() for l in open(sys.argv[2]) if l.strip() and not l.startswith("#")][-1]
substeps_per_s, err_max = float(row[4]), float(row[8]) / 100
assert round(a["substeps"]) == round(substeps_per_s), (a["substeps"], substeps_per_s)
assert a["substeps"] > 2 * a["steps"], "the CFL never split a step"
assert abs(a["density_error_max"] - err_max) <= 1e-5, \
    "density_error_max %g, the substeps' largest %g" % (a["density_error_max"], err_max)
print("cli_cy: density_error_max %.4g over %d substeps (bench: %.4g)" % (a["density_error_max"], a["substeps"], err_max))
EOF2

[ $fails -eq 0 ] && echo "cli_cy: ok"
exit $((fails > 0))
