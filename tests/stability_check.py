#!/usr/bin/python3
"""stability_check.py OUT.h5 [--energy-margin F] [--work J] [--density-max R] [--min-time S]
                          [--energy-from S]

Reads an stf output file and asserts, over every frame of the run:
  - no NaN or Inf in any particle or body state;
  - no particle outside the container (inner box, one spacing of tolerance; the top is open);
  - no body through a wall or the floor (its centre at least its half height minus one
    spacing from every wall and the floor);
  - total mechanical energy (particles and bodies: kinetic, rotational for spheres, and
    potential from the container floor) never above E0 + work + margin, with
    margin = F * E0 (F from --energy-margin, default 0.05) and work the stated upper bound
    of the energy put in (--work, J: vibration, prescribed motion; default 0); with
    --energy-from S, E0 is the largest energy up to time S and the check covers t > S;
  - density error bounded: the largest kernel density of any particle (sum of (1-r/h)^2,
    the pressure effect's density) divided by the rest density stays below --density-max
    (default 2.0) in every frame checked (every frame for <= 60 frames, else 60 spread out).
Prints the measured figures; exits 0 when all hold, 1 otherwise (with the reasons).
"""
import math
import sys

import h5py
import numpy as np
import yaml


def fail(msgs, text):
    msgs.append(text)


def parse_args(argv):
    opts = {"energy_margin": 0.05, "work": 0.0, "density_max": 2.0, "min_time": 0.0,
            "energy_from": 0.0}
    path = None
    i = 0
    while i < len(argv):
        a = argv[i]
        if a.startswith("--"):
            opts[a[2:].replace("-", "_")] = float(argv[i + 1])
            i += 2
        else:
            path = a
            i += 1
    return path, opts


def param(params, key):
    for line in params.splitlines():
        if line.startswith(key + ":"):
            return float(line.split(":")[1].split("#")[0])
    raise KeyError(key)


def body_masses(scene):
    out = {}
    for b in scene.get("bodies", []) or []:
        if b.get("motion", "dynamic") != "dynamic":
            continue
        r = b.get("radius", 0.0)
        if "mass" in b:
            m = float(b["mass"])
        elif b["shape"] == "sphere":
            m = float(b["density"]) * 4.0 / 3.0 * math.pi * r**3
        elif b["shape"] == "box":
            sx, sy, sz = b["size"]
            m = float(b["density"]) * sx * sy * sz
        else:
            raise SystemExit("stability_check: give mass for shape " + b["shape"])
        inertia = 0.4 * m * r * r if b["shape"] == "sphere" else None
        out[b["name"]] = (m, inertia)
    return out


def max_density_ratio(x, h, rest):
    """Largest sum_j (1 - r/h)^2 over particles, over the rest density (brute force)."""
    n = x.shape[0]
    best = 0.0
    for s in range(0, n, 512):
        d = x[s:s + 512, None, :] - x[None, :, :]
        r = np.sqrt((d * d).sum(axis=2))
        w = np.clip(1.0 - r / h, 0.0, None) ** 2
        rho = w.sum(axis=1) - 1.0  # minus the particle itself (r = 0)
        best = max(best, float(rho.max()))
    return best / rest


def main():
    path, o = parse_args(sys.argv[1:])
    f = h5py.File(path, "r")
    A = f.attrs
    msgs = []
    scene = yaml.safe_load(A["scene"])
    s, m = float(A["spacing"]), float(A["particle_mass"])
    params = A["parameters"]
    h, rest = param(params, "h"), param(params, "rest_density")
    g = abs(float((scene.get("effects", {}).get("gravity") or {}).get("g", [0, 0, -9.81])[2])) \
        if "gravity" in (scene.get("effects") or {}) else 0.0
    x0, x1, y0, y1, z0 = (float(A[k]) for k in
                          ("container_x0", "container_x1", "container_y0", "container_y1",
                           "container_z0"))
    steps = sorted(int(k[5:]) for k in f if k.startswith("Step#"))
    if len(steps) < 2:
        fail(msgs, "fewer than 2 frames")
    masses = body_masses(scene)
    bodies = {}
    for name in (f["bodies"] if "bodies" in f else []):
        b = f["bodies"][name]
        bodies[name] = {k: b[k][:] for k in b}
        for k, v in bodies[name].items():
            if not np.all(np.isfinite(v)):
                fail(msgs, "body %s: non-finite %s" % (name, k))
        hh = float(A["body.%s.half_height" % name])
        p = bodies[name]["position"]
        lo = min(p[:, 0].min() - x0, x1 - p[:, 0].max(), p[:, 1].min() - y0, y1 - p[:, 1].max(),
                 p[:, 2].min() - z0)
        if lo < hh - s:
            fail(msgs, "body %s: through a wall or the floor (centre %.4g m from a wall, "
                 "half height %.4g m)" % (name, lo, hh))
        print("body %s: closest centre-wall distance %.4g m (half height %.4g m)" % (name, lo, hh))
    t_end = float(f["Step#%d" % steps[-1]].attrs["TimeValue"])
    if t_end < o["min_time"] - 1e-9:
        fail(msgs, "run ended at t = %g s, before %g s" % (t_end, o["min_time"]))
    check_at = set(steps if len(steps) <= 60 else
                   [steps[int(round(i * (len(steps) - 1) / 59))] for i in range(60)])
    E, worst_out, dens = [], 0.0, []
    for st in steps:
        gr = f["Step#%d" % st]
        t = float(gr.attrs["TimeValue"])
        x = np.stack([gr[k][:] for k in ("x", "y", "z")], axis=1).astype(np.float64)
        v = np.stack([gr[k][:] for k in ("vx", "vy", "vz")], axis=1).astype(np.float64)
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(v))):
            fail(msgs, "frame %d (t = %g s): NaN or Inf" % (st, t))
            continue
        out = max((x0 - s - x[:, 0]).max(), (x[:, 0] - x1 - s).max(),
                  (y0 - s - x[:, 1]).max(), (x[:, 1] - y1 - s).max(), (z0 - s - x[:, 2]).max())
        worst_out = max(worst_out, out)
        e = 0.5 * m * (v * v).sum() + m * g * (x[:, 2] - z0).sum()
        for name, (mb, inertia) in masses.items():
            b = bodies[name]
            k = int(np.argmin(np.abs(b["time"] - t)))
            vb, wb, pb = b["velocity"][k], b["angular_velocity"][k], b["position"][k]
            e += 0.5 * mb * float(vb @ vb) + mb * g * (pb[2] - z0)
            if inertia is not None:
                e += 0.5 * inertia * float(wb @ wb)
        E.append((t, e))
        if st in check_at:
            dens.append((t, max_density_ratio(x, h, rest)))
    if worst_out > 0:
        fail(msgs, "particles outside the container (by %.4g m beyond one spacing)" % worst_out)
    if E:
        # E0: the first frame's energy, or the largest up to --energy-from (a start that
        # stores energy E does not count, e.g. coincident particles, releases it first)
        e0 = max(e for t, e in E if t <= o["energy_from"] + 1e-12)
        t_max, e_max = max(((t, e) for t, e in E if t > o["energy_from"] + 1e-12),
                           key=lambda te: te[1], default=E[0])
        bound = e0 + o["work"] + o["energy_margin"] * abs(e0)
        print("energy: E0 = %.6g J, max %.6g J at t = %.4g s (%.3g of E0), bound %.6g J "
              "(work %.4g J + margin %.3g E0)" % (e0, e_max, t_max, e_max / e0 if e0 else 0,
                                                   bound, o["work"], o["energy_margin"]))
        if e_max > bound:
            fail(msgs, "energy %.6g J at t = %.4g s above E0 + work + margin = %.6g J"
                 % (e_max, t_max, bound))
    if dens:
        t_d, d_max = max(dens, key=lambda td: td[1])
        print("density: max kernel density / rest = %.3f at t = %.4g s (bound %.3g), %d frames"
              % (d_max, t_d, o["density_max"], len(dens)))
        if d_max > o["density_max"]:
            fail(msgs, "density %.3f x rest at t = %.4g s above %.3g" % (d_max, t_d,
                                                                          o["density_max"]))
    print("frames %d, t_end %.4g s, worst particle excursion beyond walls+spacing %.3g m"
          % (len(steps), t_end, worst_out))
    if "substeps" in A and "steps" in A:
        print("steps %d, substeps %d (dt %g..%g s), spring-saturated substeps %d"
              % (A["steps"], A["substeps"], A["dt_min"], A["dt_max"],
                 A.get("spring_saturated_substeps", 0)))
    for msg in msgs:
        print("stability_check: FAIL: %s: %s" % (path, msg), file=sys.stderr)
    return 1 if msgs else 0


if __name__ == "__main__":
    sys.exit(main())
