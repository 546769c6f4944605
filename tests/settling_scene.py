# settling_scene.py RS [LAMBDA] [DURATION] [key=value ...] -> a scene on stdout (the settling
# sphere of tests/cli_settling.sh): a steel sphere (7800 kg/m^3) of radius a = 7.5 mm settling
# along the axis of a square tank of silicone oil (970 kg/m^3, Carreau-Yasuda with n = 1:
# Newtonian, nu = 1e-2 m^2/s: a falling-ball viscometer, Re about 0.06), resolved with
# a / s = RS spacings. The tank's half-width is a / LAMBDA (default 0.25), its fluid
# depth=D tank widths deep (default 2); the sphere starts one tank width below the surface,
# held while the fluid settles around it for 0.3 s (fluid.settle). The projection runs to
# eta = 1e-3 (the default 1e-2 lets the fluid column breathe at 1-2 cm/s, as fast as the
# sphere falls). The tank and the sphere have no Coulomb friction: a Newtonian fluid's wall
# stress is its viscosity's (the walls' no-slip, src/cy_walls.c); the collision stage's
# friction on top of it, the default 0.2, is a drag per contact that grows as the step
# shrinks (2 spacings: -15.5% at dt 2 ms, -18.8% at 1 ms, against -5.0% and -8.9% without).
# Optional key=value: nu, dt, eta, density, settle, depth, frame_rate, friction; z (m, the
# sphere's centre height instead of one tank width under the surface); pressure_solver,
# warm_start, wall_pressure, pressure_gradient (added to the carreau_yasuda block).
import sys
RS = float(sys.argv[1])
lam = float(sys.argv[2]) if len(sys.argv) > 2 else 0.25
dur = sys.argv[3] if len(sys.argv) > 3 else "0.3"
kv = dict(a.split("=", 1) for a in sys.argv[4:])
a = 0.0075; s = a / RS
n = round(2 * a / lam / s)            # particles across the tank
W = n * s; H = float(kv.get('depth', 2)) * n * s; zc = float(kv.get('z', H - n * s))
extra = "".join(f", {k}: {kv[k]}" for k in ("pressure_solver", "warm_start", "wall_pressure", "pressure_gradient") if k in kv)
nu = kv.get("nu", "1e-2")
print(f"""name: settling_{RS:g}
duration: {dur}
dt: {kv.get('dt', '0.002')}
frame_rate: {kv.get('frame_rate', '50')}
fluid:
  model: carreau_yasuda
  spacing: {s!r}
  density: 970
  settle: {kv.get('settle', '0.3')}
  blocks:
    - min: [{-W / 2!r}, {-W / 2!r}, 0.0]
      max: [{W / 2!r}, {W / 2!r}, {H!r}]
effects:
  gravity: {{g: [0, 0, -9.81]}}
  carreau_yasuda: {{mu0: {nu}, mu_inf: {nu}, n: 1, eta: {kv.get('eta', '0.001')}, max_pressure_iterations: 1000{extra}}}
container:
  size: [{W!r}, {W!r}, {H + 4 * s!r}]
  wall: {4 * s!r}
  friction: 0.0
  stick: false
bodies:
  - name: ball
    shape: sphere
    radius: {a}
    density: {kv.get('density', '7800')}
    position: [0, 0, {zc!r}]
    friction: {kv.get('friction', '0.0')}
""")
