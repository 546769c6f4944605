#!/usr/bin/env bash
# cli_deep_drag.sh - a body moving slowly through a deep Newtonian fluid feels a drag that
# does not depend on its depth (Stokes' drag holds no ambient pressure). A sphere of radius
# 2.14 spacings (a = 7.5 mm, s = 3.5 mm) in a thin oil (Carreau-Yasuda, n = 1, nu = 3.8e-4
# m^2/s) fills a tank 4.2 cm wide and 12.6 cm deep (tests/settling_scene.py, 5,104 particles);
# it is moved down at 10 mm/s (motion: kinematic) for 0.3 s from 2.6 cm and from 6.6 cm under
# the surface, with `wall_pressure: hydrostatic`, Jacobi, warm start 0.5, eta 1e-4.
# Holds, on the vertical fluid force over 0.15-0.3 s in units of rho_f V g (means):
# - with `pressure_gradient: offset` the two depths differ by less than 0.05 (the 5% of the
#   buoyancy tolerance; measured 1.02-1.05 at both);
# - the symmetric form, deep, reads at least 0.15 more than the offset form, deep: its
#   particle packing resists being rearranged with a stress that grows with the pressure,
#   and the resistance grew with the distance moved, not the speed (measured 1.42-1.48 at
#   6.6 cm, 1.19-1.24 at 2.6 cm; tests/README.md, "Moving through a deep fluid").
# Args: STF_BINARY PROJECT_DIR
. "$(dirname "$0")/lib_cli.sh" cli_deep_drag "$@"
stf=$STF; src=$PROJ
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive
common="2.142857 0.35 0.3 nu=3.8e-4 depth=3 dt=0.001 wall_pressure=hydrostatic eta=1e-4 warm_start=0.5"
scene() { # NAME Z [key=value ...]: the scene with the sphere moved down at 10 mm/s
    local name=$1 z=$2; shift 2
    /usr/bin/python3 "$src/tests/settling_scene.py" $common z="$z" "$@" |
        sed 's/^    density: .*/    motion: kinematic\n    velocity: [0, 0, -0.01]/' > "$name.yaml"
    grep -q "motion: kinematic" "$name.yaml" || fail "$name: the scene has no kinematic sphere"
}
scene off_shallow 0.1 pressure_gradient=offset
scene off_deep 0.06 pressure_gradient=offset
scene sym_deep 0.06
run() { "$stf" run "$1.yaml" -o "$1.h5" --quiet 2>"$1.err" || { fail "$1: exit $? ($(cat "$1.err"))"; return 1; }; }
run off_shallow & p1=$!
run off_deep
wait $p1 || fail "off_shallow failed"
run sym_deep
[ $fails -eq 0 ] && { /usr/bin/python3 - <<'PY' || fail "see above"; }
import h5py, numpy as np
a, rho, g = 0.0075, 970.0, 9.81
B = rho * g * 4 / 3 * np.pi * a ** 3
def force(path):
    b = h5py.File(path, "r")["bodies/ball"]
    t, F = b["time"][:], b["fluid_force"][:, 2] / B
    return F[(t > 0.15) & (t <= 0.3)].mean()
s, d, y = force("off_shallow.h5"), force("off_deep.h5"), force("sym_deep.h5")
print("cli_deep_drag: 10 mm/s down, F / (rho V g): offset %.3f (2.6 cm) %.3f (6.6 cm); "
      "symmetric %.3f (6.6 cm)" % (s, d, y))
assert abs(d - s) < 0.05, "the offset form's drag depends on the depth"
assert y > d + 0.15, "the symmetric form's deep resistance is gone: update tests/README.md"
PY
if [ $fails -ne 0 ]; then
    echo "cli_deep_drag: $fails failure(s)" >&2
    exit 1
fi
echo "cli_deep_drag: ok"
