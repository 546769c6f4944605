# cli_cy_periodic.sh - periodic axes from a scene file (container.periodic), through the
# command-line tool: scenes/cy_film_flow.yaml, a layer flowing down an incline, periodic in x
# and y. tests/cy_film_profile.py reads each run back with h5py and asserts that the same
# particles stay inside the periodic box in every frame, that the wrapped positions drift as
# the velocities say (particles cross the seams), and that the steady velocity profile
# matches the solution of nu(gamma) gamma = G (H - z):
#   - Newtonian (the scene): within 5% of the surface velocity, shape within 3%;
#   - shear thickening (mu0 = 0.01 m^2/s, K = 10 s, n = 1.5): within 10%, shape within 5%.
# (Shear thinning is left out: the SPH shear rate's noise thins the fluid where the stress is
# low, tests/README.md "Carreau-Yasuda validation".)
#
# usage: bash cli_cy_periodic.sh STF_BINARY PROJECT_DIR   (run in the build's tests directory)
. "$(dirname "$0")/lib_cli.sh" cli_cy_periodic "$@"

SCENE="$PROJ/scenes/cy_film_flow.yaml"
CHECK="$PROJ/tests/cy_film_profile.py"
export OMP_NUM_THREADS=1

"$STF" check "$SCENE" -o newton.h5 --quiet >newton.check 2>&1 ||
    fail "newtonian film: $(cat newton.check)"
/usr/bin/python3 "$CHECK" newton.h5 0.05 0.03 || fail "newtonian film profile"

"$STF" run "$SCENE" -o thick.h5 --quiet \
    --set 'effects.carreau_yasuda={mu0: 0.01, mu_inf: 0, K: 10, alpha: 2, n: 1.5}' 2>thick.err ||
    fail "shear-thickening film: $(cat thick.err)"
/usr/bin/python3 "$CHECK" thick.h5 0.10 0.05 || fail "shear-thickening film profile"

[ $fails -eq 0 ] && echo "cli_cy_periodic: ok"
exit $((fails > 0))
