# ball_profile.py - the fluid under a body, shell by shell: for each time asked, the particles
# below the body's centre (direction within 60 degrees of straight down), binned by their
# distance from its surface in half spacings: their count, their mean velocity along the
# direction from the centre (v.n), the body's own (U.n), and the share whose history
# stiffness is above the onset (khist > 0). Shows how thick the fluid that moves with a
# sinking body is and whether it is jammed (scenes/README.md, the bowling ball).
#   /usr/bin/python3 tests/ball_profile.py OUT.h5 BODY T1,T2,...
import sys
import h5py
import numpy as np

f = h5py.File(sys.argv[1], "r")
name = sys.argv[2]
s = float(f.attrs["spacing"])
R = float(f.attrs["body.%s.half_height" % name])
b = f["bodies"][name]
bt, bp, bv = b["time"][:], b["position"][:], b["velocity"][:]
steps = sorted((k for k in f if k.startswith("Step#")), key=lambda k: int(k[5:]))
tv = np.array([float(np.ravel(f[k].attrs["TimeValue"])[0]) for k in steps])
for t in (float(a) for a in sys.argv[3].split(",")):
    j = int(np.argmin(abs(tv - t)))
    g = f[steps[j]]
    i = int(np.argmin(abs(bt - tv[j])))
    c, U = bp[i], bv[i]
    x = np.stack([g["x"][:], g["y"][:], g["z"][:]], 1)
    v = np.stack([g["vx"][:], g["vy"][:], g["vz"][:]], 1)
    kh = g["khist"][:]
    d = x - c
    r = np.linalg.norm(d, axis=1)
    n = d / r[:, None]
    below = n[:, 2] < -0.5
    print("t = %.2f s: centre z %.4f m, velocity %s m/s" % (tv[j], c[2], np.round(U, 4)))
    print("  from the surface (spacings)  particles   v.n (m/s)   U.n (m/s)   khist > 0")
    for lo in np.arange(0, 8, 0.5):
        m = below & (r - R >= lo * s) & (r - R < (lo + 0.5) * s)
        if m.sum() == 0:
            continue
        vn = (v[m] * n[m]).sum(1).mean()
        un = (U * n[m]).sum(1).mean()
        print("  %4.1f - %4.1f  %20d   %+9.4f   %+9.4f   %6.0f%%" % (lo, lo + 0.5, m.sum(), vn, un, 100 * (kh[m] > 0).mean()))
