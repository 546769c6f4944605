# settling_check.py OUT.h5 RS [LAMBDA] [key=value ...] [--test]: the settling sphere of
# tests/settling_scene.py (the same RS, LAMBDA and nu=, density= as the scene) against
# Stokes' law with the wall correction of its square tank. Prints one line. With --test it
# also holds tests/cli_settling.sh's assertions, the speed within 15% among them (exit 1 if
# one fails).
#
# Reference: U = U_Stokes / K, U_Stokes = 2/9 (rho_s - rho_f) g a^2 / mu (Re about 0.06 here:
# Oseen's inertial correction, 3/16 Re, is 1 %, left out). K is the wall factor of a sphere
# on the axis of a long circular tube of radius R (W. L. Haberman, R. M. Sayre, 1958):
#   K(l) = (1 - 0.75857 l^5) / (1 - 2.1050 l + 2.0865 l^3 - 1.7068 l^5 + 0.72603 l^6),
# l = a / R. The tank is square (side W): its factor lies between the tube inscribed in it
# (R = W/2, the larger drag) and the tube around it (R = W/sqrt 2): at equal velocity Stokes
# drag grows as the fluid's domain shrinks (Helmholtz's minimum dissipation), so
# U(R = W/2) <= U(square) <= U(R = W/sqrt 2). The point estimate takes the tube of the
# same cross-section (R = W/sqrt pi). The sphere's speed is its mean over the run's second
# half (the diffusion time across the tank, (W/2)^2 / nu, is 0.09 s).
import sys, h5py, numpy as np
args = [x for x in sys.argv[1:] if x != "--test"]
test = "--test" in sys.argv
path, RS = args[0], float(args[1])
lam = float(args[2]) if len(args) > 2 and "=" not in args[2] else 0.25
kv = dict(x.split("=", 1) for x in args[2:] if "=" in x)
a, g, rho_f = 0.0075, 9.81, 970.0
rho_s, nu = float(kv.get("density", 7800)), float(kv.get("nu", 1e-2))
s = a / RS; W = round(2 * a / lam / s) * s
def K(l): return (1 - 0.75857 * l ** 5) / (1 - 2.1050 * l + 2.0865 * l ** 3 - 1.7068 * l ** 5 + 0.72603 * l ** 6)
mu = rho_f * nu
U0 = 2 / 9 * (rho_s - rho_f) * g * a * a / mu
U = U0 / K(a / (W / np.sqrt(np.pi)))
Ulo, Uhi = U0 / K(a / (W / 2)), U0 / K(a / (W / np.sqrt(2)))
f = h5py.File(path, "r")
b = f["bodies/ball"]
t, z, v, F = b["time"][:], b["position"][:, 2], b["velocity"][:], b["fluid_force"][:]
late = t > t[-1] / 2
Us = -(z[late][-1] - z[late][0]) / (t[late][-1] - t[late][0])
Re = 2 * a * Us / nu
err = Us / U - 1
print("settling: a/s %g, tank %.4f m (a/(W/2) %.3f), U %.5f m/s (rows %.5f .. %.5f), "
      "reference %.5f m/s (bracket %.5f .. %.5f, unbounded Stokes %.5f), Re %.3f, error %+.1f%%"
      % (RS, W, a / (W / 2), Us, -v[late, 2].max(), -v[late, 2].min(), U, Ulo, Uhi, U0, Re, 100 * err))
if not test:
    sys.exit(0)
ok = True
V = 4 / 3 * np.pi * a ** 3; M = rho_s * V
speed = np.sqrt((v ** 2).sum(1)).max()
bound = 10 * ((rho_f * V + M) * g + 0.5 * rho_f * np.pi * a * a * speed ** 2)
Fmax = np.sqrt((F ** 2).sum(1)).max()
if not Fmax < bound:
    ok = False; print("settling: FAIL: fluid force %.3g N beyond %.3g N" % (Fmax, bound))
after = t > 0.01   # a sphere let go at rest settles without turning back (Stokes: monotone)
if not np.all(v[after, 2] < 0):
    ok = False; print("settling: FAIL: the sphere rose (largest v_z %.4f m/s)" % v[after, 2].max())
if not abs(err) <= 0.15:
    ok = False; print("settling: FAIL: U %.5f m/s is %+.1f%% off the reference %.5f (tolerance 15%%)" % (Us, 100 * err, U))
if not (0 < Us < U0):
    ok = False; print("settling: FAIL: U outside (0, unbounded Stokes %.5f)" % U0)
sys.exit(0 if ok else 1)
