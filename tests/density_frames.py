# density_frames.py - the pool's bulk density frame by frame, the estimator of the run metrics'
# fluid.density_error_max (src/io/metrics.h): particles at least Rc = 3 spacings inside the
# container, under the median surface column and clear of every body, each sampling the
# smooth number density sum_j (1 - r^2/Rc^2)^2 over its integral times spacing^3. Prints
# each frame's mean - 1 over a fixed random sample of the bulk (400 particles: within about
# 0.05% of the metric's mean over all of them), to see when the metric's largest frame comes.
#   /usr/bin/python3 tests/density_frames.py OUT.h5 [EVERY]    (every EVERY-th frame, default 1)
import sys
import h5py
import numpy as np

f = h5py.File(sys.argv[1], "r")
every = int(sys.argv[2]) if len(sys.argv) > 2 else 1
s = float(f.attrs["spacing"]); rc = 3 * s
lo = np.array([float(f.attrs["container_%s0" % a]) for a in "xyz"])
hi = np.array([float(f.attrs["container_%s1" % a]) for a in "xyz"])
bodies = []
for name in f.get("bodies", {}):
    b = f["bodies"][name]
    bodies.append((b["time"][:], b["position"][:], float(f.attrs.get("body.%s.half_height" % name, 0))))
steps = sorted((k for k in f if k.startswith("Step#")), key=lambda k: int(k[5:]))
rng = np.random.default_rng(1)
print("time (s)  density / material's - 1")
for k in steps[::every]:
    g = f[k]
    t = float(np.ravel(g.attrs["TimeValue"])[0])
    x = np.stack([g["x"][:], g["y"][:], g["z"][:]], 1)
    col = np.floor(x[:, :2] / (2 * s)).astype(np.int64)
    key = col[:, 0] * 1000003 + col[:, 1]
    order = np.lexsort((x[:, 2], key))
    top = np.r_[key[order][1:] != key[order][:-1], True]
    median = np.median(x[order][top][:, 2])
    ok = (x[:, 2] >= lo[2] + rc) & (x[:, 2] <= median - rc)
    ok &= np.all(x[:, :2] >= lo[:2] + rc, 1) & np.all(x[:, :2] <= hi[:2] - rc, 1)
    for bt, bp, R in bodies:
        c = bp[max(np.searchsorted(bt, t, side="right") - 1, 0)]
        ok &= np.linalg.norm(x - c, axis=1) >= R + rc
    idx = np.nonzero(ok)[0]
    if len(idx) == 0:
        continue
    sample = rng.choice(idx, min(400, len(idx)), replace=False)
    dens = []
    for i in sample:
        d2 = ((x - x[i]) ** 2).sum(1)
        u = 1 - d2[d2 < rc * rc] / (rc * rc)
        dens.append((u * u).sum() * s ** 3 / (32 * np.pi / 105 * rc ** 3))
    print("%8.3f  %+.4f" % (t, np.mean(dens) - 1))
