#!/usr/bin/env bash
# cli_buoyancy.sh - buoyancy from the first step, in both models (fluid.settle). A sphere is
# held still in the middle of a tank of water at rest (5 mm spacing, the tank 8 spacings wider
# and 10 taller than the sphere); the fluid settles around it for 0.3 s before t = 0
# (fluid.settle). The fluid's force on it over the first rows (2 ms) must be Archimedes' rho V
# g within 5 %, rho the fluid's own density (its mass over the volume it fills: the Clavet
# fluid at k = 1000 compresses by about 5 % under its weight, and a body displaces the fluid
# that is there, not the nominal density). Without the settling the same sphere feels -0.28
# rho V g in its first step (the lattice starts without pressure: fluid and body fall
# together). The force's parts (fluid_force_parts: pressure, viscosity, contacts, stick, added
# mass) must sum to it.
# - Clavet's relaxation, radius 3, 6 and 10 spacings, with both walls (effects.pressure.wall:
#   the mirror and the ghost, src/pressure.c).
# - Carreau-Yasuda (Newtonian, nu = 3.8e-4 m^2/s), radius 1.5, 2, 3, 6 and 10 spacings, with
#   wall_pressure: hydrostatic (src/cy_walls.c) and eta 1e-5: at the default 1e-2 the force
#   swings from step to step by a standard deviation of 6-30% of rho V g, and at 1e-4 by a
#   period-two swing of up to 13% at 1.5 spacings (tests/README.md, "Buoyancy by radius").
#   Jacobi at 1.5 and 2 spacings; from 3 spacings on the conjugate gradients from zero
#   (warm_start 0): there Jacobi stops at its 100-iteration cap every step (its density error
#   2.5e-5 to 1e-4) where the conjugate gradients reach eta in 49-76 iterations, in 11.5 / 21
#   / 61 s against 19.4 / 30 / 86-113 s at 3 / 6 / 10 spacings (one core).
# Args: STF_BINARY PROJECT_DIR
. "$(dirname "$0")/lib_cli.sh" cli_buoyancy "$@"
stf=$STF
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive
for spec in "cl mirror 3 6 10" "cl ghost 3 6 10" "cy hydrostatic 1.5 2 3 6 10"; do
read -r model wall radii <<<"$spec"
for RS in $radii; do
    if [ $model = cl ]; then # the relaxation's wall is an effects.pressure key
        /usr/bin/python3 "$PROJ/tests/held_sphere.py" scene cl "$RS" 0.004 > ball_$RS.yaml
        walls=(--set effects.pressure.wall=$wall)
    else
        solver=; case $RS in 1.5|2) ;; *) solver="pressure_solver=cg warm_start=0" ;; esac
        /usr/bin/python3 "$PROJ/tests/held_sphere.py" scene cy "$RS" 0.004 eta=1e-5 wall_pressure=$wall $solver > ball_$RS.yaml
        walls=()
    fi
    "$stf" run ball_$RS.yaml -o ball_$RS.h5 --quiet "${walls[@]}" 2>err_$RS.txt ||
        fail "$model, R = $RS spacings, $wall wall: the run failed: $(cat err_$RS.txt)"
    /usr/bin/python3 - "$RS" "$model $wall" <<'PY' || fail "$model, R = $RS spacings, $wall wall: the first step's buoyancy is not Archimedes' within 5 %"
import sys, h5py, numpy as np
RS, wall = sys.argv[1], sys.argv[2]; s = 0.005; R = float(RS) * s
W = round((2 * R + 8 * s) / s) * s; V = 4 / 3 * np.pi * R ** 3
f = h5py.File("ball_%s.h5" % RS, "r")
z = f["Step#0/z"][:]                     # the settled fluid at t = 0
layer = int(round((W / s) ** 2))         # particles in one layer
level = np.sort(z)[-layer:].mean() + s / 2
rho = len(z) * f.attrs["particle_mass"] / (W * W * level - V) if "particle_mass" in f.attrs else \
      len(z) * 970 * s ** 3 / (W * W * level - V)
F = f["bodies/ball/fluid_force"][1:3, 2]  # the first rows after t = 0 (2 ms apart)
want = rho * 9.81 * V
err = F / want - 1
print("cli_buoyancy: R = %s spacings, %s wall: fluid density %.1f kg/m^3, force %s N, rho V g %.4f N, "
      "errors %s" % (RS, wall, rho, np.round(F, 4), want, np.round(err, 4)))
# the force by part (pressure, viscosity, contacts, stick, added mass) sums to it, and the
# parts this scene has no effect for (no stick; a held body takes no added mass) are zero
P = f["bodies/ball/fluid_force_parts"][:].reshape(-1, 5, 3)
Fall = f["bodies/ball/fluid_force"][:]
gap = abs(P.sum(axis=1) - Fall).max()
if gap > 1e-9 * abs(Fall).max() or abs(P[:, 3:]).max() != 0:
    print("cli_buoyancy: R = %s spacings: the parts do not add up to the force (%.3g N) or "
          "stick / added mass are not zero" % (RS, gap))
    sys.exit(1)
print("cli_buoyancy: R = %s spacings: of the force, the pressure carries %.3f, the contacts %.3f"
      % (RS, P[1:3, 0, 2].mean() / F.mean(), P[1:3, 2, 2].mean() / F.mean()))
sys.exit(0 if np.all(abs(err) < 0.05) else 1)
PY
done
done
if [ $fails -ne 0 ]; then
    echo "cli_buoyancy: $fails failure(s)" >&2
    exit 1
fi
echo "cli_buoyancy: ok"
