#!/usr/bin/env bash
# cli_settling.sh - drag: a steel sphere (7800 kg/m^3, radius a = 7.5 mm) settling along the
# axis of a square tank (side 6 cm, a / (W/2) = 0.25) of silicone oil (970 kg/m^3,
# Carreau-Yasuda with n = 1: Newtonian, nu = 1e-2 m^2/s, Re about 0.06), at a / s = 2
# spacings for 0.3 s (tests/settling_scene.py; 8,136 particles, about 20 s of one core).
# Holds (tests/settling_check.py --test):
# - the sphere sinks at every row after its first 10 ms (a sphere let go at rest in Stokes
#   flow settles without turning back; a sphere that swings up and down fails);
# - its speed over the second half lies between 0 and the unbounded Stokes speed (walls
#   only slow it: minimum dissipation);
# - the fluid's force stays below 10 [(rho_f V + M) g + rho_f A v^2 / 2], the bound of
#   cli_body_sweep.
# - its speed over the second half within 15 % of Stokes' law with the wall factor of
#   W. L. Haberman and R. M. Sayre (1958) for the tube of the tank's cross-section (measured
#   -5.0 %; tests/README.md has the resolution study, "Drag of a settling sphere": +16.2 %,
#   -5.0 %, -3.5 % at 1.5, 2, 3 spacings of radius; the drag still grows as the step
#   shrinks).
# Args: STF_BINARY PROJECT_DIR
. "$(dirname "$0")/lib_cli.sh" cli_settling "$@"
stf=$STF; src=$PROJ
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive
/usr/bin/python3 "$src/tests/settling_scene.py" 2 > settle.yaml
"$stf" run settle.yaml -o settle.h5 --quiet 2>err.txt || fail "the run failed: exit $? ($(cat err.txt))"
[ $fails -eq 0 ] && { /usr/bin/python3 "$src/tests/settling_check.py" settle.h5 2 --test || fail "see above"; }
if [ $fails -ne 0 ]; then
    echo "cli_settling: $fails failure(s)" >&2
    exit 1
fi
echo "cli_settling: ok"
