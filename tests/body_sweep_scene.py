# body_sweep_scene.py MODEL RS RATIO PLACE SHAPE [DURATION [NU]] [key=value ...] -> a scene on stdout (the sweep
# of tests/cli_body_sweep.sh): MODEL cl (Clavet) | cy (Carreau-Yasuda, Newtonian, NU m^2/s,
# default 3.8e-4); a
# sphere of radius RS spacings (or a cube of side 2 RS spacings) of RATIO times the fluid's
# density, placed inside the fluid (its centre at mid-depth), half in (its centre on the
# surface) or above it (2 spacings clear), in water (970 kg/m^3) at 5 mm spacing that fills a
# tank 8 spacings wider than the body and 10 spacings plus its diameter deep, settled for
# 0.3 s (fluid.settle). key=value adds to the carreau_yasuda block (wall_pressure=hydrostatic ...).
# tank_scene() is the tank, the fluid and its settling that tests/held_sphere.py shares.
import sys
s = 0.005

def tank(RS):
    """The body's radius R and the tank's width W and fluid depth H (m) for RS spacings."""
    R = RS * s
    return R, round((2 * R + 8 * s) / s) * s, round((2 * R + 10 * s) / s) * s

def tank_scene(name, model, RS, duration, frame_rate, height, body, cy=(), nu="3.8e-4"):
    """The scene: water at 5 mm spacing filling the tank, settled for 0.3 s; model cl or cy
    (cy: the keys of cy added to the Newtonian carreau_yasuda block); the container height(R,
    H) tall and the body's lines body(R, W, H) after '  - name: ball'."""
    R, W, H = tank(RS)
    if model == 'cy':
        fl = "  model: carreau_yasuda"
        eff = "  carreau_yasuda: {" + ", ".join(["mu0: " + nu, "mu_inf: " + nu, "n: 1"] + list(cy)) + "}"
    else:
        fl = "  model: clavet_stf"
        eff = "  viscosity: {sigma: 2.0}\n  pressure: {k: 1000, k_near: 200}"
    return f"""name: {name}
duration: {duration}
dt: 0.001
frame_rate: {frame_rate}
fluid:
{fl}
  spacing: {s}
  density: 970
  settle: 0.3
  blocks:
    - min: [{-W/2}, {-W/2}, 0.0]
      max: [{W/2}, {W/2}, {H}]
effects:
  gravity: {{g: [0, 0, -9.81]}}
{eff}
container:
  size: [{W}, {W}, {height(R, H)}]
  wall: 0.01
  friction: 0.0
  stick: false
bodies:
  - name: ball
{body(R, W, H)}"""

if __name__ == "__main__":
    model, RS, ratio, place, shape = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), sys.argv[4], sys.argv[5]
    def body(R, W, H):
        zc = {'inside': H/2, 'half': H, 'above': H+R+2*s}[place]
        geo = f"shape: sphere\n    radius: {R}" if shape == 'sphere' else f"shape: box\n    size: [{2*R}, {2*R}, {2*R}]"
        return f"    {geo}\n    density: {970*ratio}\n    position: [0, 0, {zc}]\n"
    pos = [a for a in sys.argv[6:] if "=" not in a]
    kv = [a.replace("=", ": ") for a in sys.argv[6:] if "=" in a]
    print(tank_scene("sw", model, RS, pos[0] if pos else 0.6, 50,
                     lambda R, H: H+2*R+0.05, body, kv, nu=pos[1] if len(pos) > 1 else "3.8e-4"))
