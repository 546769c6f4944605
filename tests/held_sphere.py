# held_sphere.py - the held sphere of cli_buoyancy in either model, for the buoyancy study of
# tests/README.md ("Buoyancy by radius").
#   held_sphere.py scene MODEL RS [DURATION] [key=value ...] > s.yaml
#       MODEL cl (Clavet, cli_buoyancy's water: k 1000, sigma 2) | cy (Carreau-Yasuda,
#       Newtonian nu = 3.8e-4 m^2/s, the body sweep's); a kinematic sphere of radius RS spacings
#       (5 mm) at mid-depth of a tank 8 spacings wider and 10 taller than it, the fluid settled
#       around it for 0.3 s (cli_buoyancy's scene with cl); DURATION default 0.2 s. key=value adds to the
#       carreau_yasuda block (cy: eta=1e-4 pressure_solver=cg wall_pressure=mirror ...).
#   held_sphere.py read OUT.h5 RS
#       the fluid's force on the sphere over rho_f V g (rho_f the fluid's own density: its
#       mass over the volume it fills, as cli_buoyancy): the first rows, the mean and the
#       standard deviation over the run's rows after t = 0, and the standard deviation of the
#       fluid's mean vertical velocity over the frames (the column's breathing).
import sys
from body_sweep_scene import s, tank, tank_scene
if sys.argv[1] == "scene":
    model, RS = sys.argv[2], float(sys.argv[3])
    dur = sys.argv[4] if len(sys.argv) > 4 and "=" not in sys.argv[4] else "0.2"
    kv = [a.replace("=", ": ") for a in sys.argv[4:] if "=" in a]
    print(tank_scene(f"held_sphere_{model}_{RS:g}", model, RS, dur, 1000, lambda R, H: H + 0.1,
                     lambda R, W, H: f"    shape: sphere\n    radius: {R}\n    motion: kinematic\n"
                                     f"    position: [0, 0, {H / 2}]", kv))
else:
    import h5py, numpy as np
    f = h5py.File(sys.argv[2], "r")
    RS = float(sys.argv[3]); R, W, H = tank(RS); V = 4 / 3 * np.pi * R ** 3
    z = f["Step#0/z"][:]
    level = np.sort(z)[-int(round((W / s) ** 2)):].mean() + s / 2
    rho = len(z) * f.attrs.get("particle_mass", 970 * s ** 3) / (W * W * level - V)
    F = f["bodies/ball/fluid_force"][1:, 2] / (rho * 9.81 * V)
    frames = sorted((k for k in f if k.startswith("Step#")), key=lambda k: int(k[5:]))
    vz = np.array([f[k]["vz"][:].mean() for k in frames[1:]])
    print("RS %g: rho_f %.1f kg/m^3; F / (rho_f V g): rows 1-5 %s, mean %.3f, sd %.3f; "
          "column's mean vz sd %.2f mm/s" % (RS, rho, np.round(F[:5], 2), F.mean(), F.std(),
                                              1e3 * vz.std()))
