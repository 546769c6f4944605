"""cy_film_profile.py - checks a run of scenes/cy_film_flow.yaml (a periodic film flowing down
an incline) against the steady solution of nu(gamma) gamma = G (H - z) (tests/cli_cy_periodic.sh).

usage: cy_film_profile.py OUT.h5 TOLERANCE SHAPE_TOLERANCE

Reads the scene's parameters back from the file (the effective scene text), the particles of
the last quarter of the run, and asserts:
  - every frame holds the same particles (ids), all inside the periodic box;
  - positions wrap consistently: unwrapping each particle's displacement between frames (the
    nearest periodic image) gives a mean drift equal to the time integral of the velocity
    (2%), and particles do cross the seam;
  - the velocity profile, in 10 layers, is within TOLERANCE of the surface velocity of the
    solution, and its shape (each profile scaled to its own largest value) within
    SHAPE_TOLERANCE.
"""
import sys

import h5py
import numpy as np


def parameters(f):
    """The run's effective parameters (the root attribute 'parameters', 'key: value  # unit')."""
    out = {}
    for line in f.attrs["parameters"].splitlines():
        key, _, value = line.partition(":")
        out[key.strip()] = value.split("#")[0].strip()
    return out


def viscosity(cy, g):
    """Eq. 3 of the second paper (as src/cy_viscosity.c: stf_cy_viscosity)."""
    t = (cy["K"] * g) ** cy["alpha"]
    return cy["mu_inf"] + (cy["mu0"] - cy["mu_inf"]) * (1 + t) ** ((cy["n"] - 1) / cy["alpha"])


def shear_rate(cy, tau):
    """The shear rate g with nu(g) g = tau (nu(g) g grows with g for every n > 0)."""
    lo, hi = 0.0, 1.0
    while viscosity(cy, hi) * hi < tau:
        hi *= 2
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if viscosity(cy, mid) * mid < tau:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def main():
    path, tol, shape_tol = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
    f = h5py.File(path, "r")
    p = parameters(f)
    cy = {k: float(p[k]) for k in ("mu0", "mu_inf", "K", "alpha", "n")}
    G = float(p["gravity"].strip("[]").split(",")[0])
    s = float(p["spacing"])
    lo = [float(f.attrs["container_%s0" % a]) for a in "xy"]
    size = [float(f.attrs["container_%s1" % a]) - lo[i] for i, a in enumerate("xy")]
    per = [float(v) for v in p["periodic"].strip("[]").split(",")]
    assert np.allclose(per[:2], size) and per[2] == 0, "periods %s, box %s" % (per, size)
    frames = sorted((k for k in f if k.startswith("Step#")), key=lambda k: int(k[5:]))
    ids0 = np.sort(f[frames[0]]["id"][:])
    n = len(ids0)
    H = n * s ** 3 / (size[0] * size[1])  # the layer's depth at the rest density

    # same particles, inside the box, consistent wrapping
    start = 3 * len(frames) // 4
    prev, drift, vsum, crossed = None, np.zeros(n), np.zeros(n), 0
    for k in frames:
        g = f[k]
        order = np.argsort(g["id"][:])
        assert np.array_equal(g["id"][:][order], ids0), k + ": the particles changed"
        x = np.stack([g["x"][:][order], g["y"][:][order]], axis=1)
        for a in range(2):
            assert x[:, a].min() >= lo[a] - 1e-6 and x[:, a].max() < lo[a] + size[a] + 1e-6, \
                "%s: a particle left the periodic box along %s" % (k, "xy"[a])
        if prev is not None:
            d = x[:, 0] - prev[:, 0]
            crossed += int(np.sum(np.abs(d) > size[0] / 2))  # jumped by a period: a seam
            d -= size[0] * np.round(d / size[0])  # nearest image
            drift += d
            dt = g.attrs["TimeValue"] - f[frames[frames.index(k) - 1]].attrs["TimeValue"]
            vsum += 0.5 * (g["vx"][:][order] + f[frames[frames.index(k) - 1]]["vx"][:][
                np.argsort(f[frames[frames.index(k) - 1]]["id"][:])]) * dt
        prev = x
    rel = abs(drift.mean() - vsum.mean()) / abs(vsum.mean())
    print("periodic: %d particles in every frame, inside the box; mean drift %.5f m vs the "
          "integral of the velocity %.5f m (%.2f%%); %d seam crossings; largest drift %.3f m "
          "(period %.3f m)" % (n, drift.mean(), vsum.mean(), 100 * rel, crossed, drift.max(), size[0]))
    assert rel < 0.02, "drift and velocity disagree by %.1f%%" % (100 * rel)
    assert crossed > 0, "no particle crossed the seam"

    # the profile, averaged over the last quarter of the frames
    z = np.concatenate([f[k]["z"][:] for k in frames[start:]])
    u = np.concatenate([f[k]["vx"][:] for k in frames[start:]])
    m = 2000
    zz = np.linspace(0, H, m + 1)
    gam = np.array([shear_rate(cy, G * (H - zi)) for zi in zz])
    ref = np.concatenate([[0], np.cumsum(0.5 * (gam[1:] + gam[:-1]) * (H / m))])
    usurf = ref[-1]
    layers = int(round(H / s))
    got, want = [], []
    print("   z (m)    u (m/s)   solution (m/s)   (n = %g, G = %g m/s^2, H = %.4f m)" % (cy["n"], G, H))
    for b in range(layers):
        sel = (z >= b * s) & (z < (b + 1) * s)
        if not sel.any():
            continue
        zc, uc = z[sel].mean(), u[sel].mean()
        got.append(uc)
        want.append(np.interp(zc, zz, ref))
        print("  %6.4f   %8.5f   %8.5f" % (zc, uc, want[-1]))
    got, want = np.array(got), np.array(want)
    worst = np.max(np.abs(got - want)) / usurf
    shape = np.max(np.abs(got / got.max() - want / want.max()))
    print("worst |u - u_ref| / u_ref(surface) = %.3f (tolerance %.2f); shape %.3f (tolerance %.2f)"
          % (worst, tol, shape, shape_tol))
    assert worst < tol and shape < shape_tol, "the profile is off"


if __name__ == "__main__":
    main()
