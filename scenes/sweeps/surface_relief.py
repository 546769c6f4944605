#!/usr/bin/python3
"""surface_relief.py - the surface of a vibrated layer (scenes/README.md, "Vibration"), beyond
fluid.finger_height: per frame of the second half of the run, the columns (2 spacings wide)
of the fluid body (particles connected by neighbours closer than 1.5 spacings, as in
src/io/metrics.h), then
  finger / hole: 95th percentile minus median, median minus 5th percentile (all columns,
                 and without the ring of columns along the container walls)
  persistent:    each column's height above its frame's median, averaged over the frames;
                 95th percentile minus median of that map (printed with --map)
The column grid starts at x = y = 0 (stf report starts it at the lowest particle), so the
finger heights differ from fluid.finger_height by a few millimetres.
usage: /usr/bin/python3 surface_relief.py OUT.h5 [OUT.h5 ...] [--map]   (needs h5py, numpy)"""
import sys
import h5py
import numpy as np

LINK = 1.5  # spacings, STF_LINK_SPACINGS


def frames(path):
    f = h5py.File(path, "r")
    s = float(f.attrs["spacing"])
    lo = np.array([f.attrs["container_%s0" % a] for a in "xyz"])
    hi = np.array([f.attrs["container_%s1" % a] for a in "xyz"])
    keys = sorted((k for k in f if k.startswith("Step#")), key=lambda k: int(k[5:]))
    for k in keys[len(keys) // 2:]:
        g = f[k]
        yield np.stack([g["x"][:], g["y"][:], g["z"][:]], 1), s, lo, hi


def body(x, link):
    """The pieces with >= a tenth of the particles, and the largest (union-find on cells)."""
    n = len(x)
    parent = list(range(n))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    cells = {}
    for i, c in enumerate(map(tuple, np.floor(x / link).astype(int))):
        cells.setdefault(c, []).append(i)
    for c, idx in cells.items():
        for d in np.ndindex(3, 3, 3):
            other = cells.get((c[0] + d[0] - 1, c[1] + d[1] - 1, c[2] + d[2] - 1))
            for i in idx:
                for j in other or ():
                    if j > i and np.sum((x[i] - x[j]) ** 2) < link * link:
                        a, b = root(i), root(j)
                        if a != b:
                            parent[a] = b
    r = np.array([root(i) for i in range(n)])
    u, cnt = np.unique(r, return_counts=True)
    keep = set(u[cnt * 10 >= n]) | {u[np.argmax(cnt)]}
    return x[np.isin(r, list(keep))]


def columns(x, w):
    out = {}
    for (a, b), z in zip(map(tuple, np.floor(x[:, :2] / w).astype(int)), x[:, 2]):
        out[(a, b)] = max(out.get((a, b), -np.inf), z)
    return out


def spread(h):
    h = np.asarray(h)
    return np.percentile(h, 95) - np.median(h), np.median(h) - np.percentile(h, 5)


def main(paths, show_map):
    for path in paths:
        allc, inner, rel, cnt, free = [], [], {}, {}, []
        for x, s, lo, hi in frames(path):
            x = x[np.all((x >= lo - s) & (x <= hi + s), 1)]  # not escaped
            b = body(x, LINK * s)
            free.append(len(x) - len(b))
            w = 2 * s
            col = columns(b, w)
            i0, i1 = int(np.floor(lo[0] / w)), int(np.floor((hi[0] - 1e-9) / w))
            j0, j1 = int(np.floor(lo[1] / w)), int(np.floor((hi[1] - 1e-9) / w))
            allc.append(spread(list(col.values())))
            inner.append(spread([v for (i, j), v in col.items() if i0 < i < i1 and j0 < j < j1]))
            med = np.median(list(col.values()))
            for k, v in col.items():
                rel[k] = rel.get(k, 0.0) + v - med
                cnt[k] = cnt.get(k, 0) + 1
        nf = len(allc)
        avg = {k: rel[k] / cnt[k] for k in rel if cnt[k] > nf / 2}
        pf, ph = spread(list(avg.values()))
        a, i = np.mean(allc, 0) * 100, np.mean(inner, 0) * 100
        print(f"{path}: free particles {np.mean(free):.0f}; finger / hole (cm): all columns "
              f"{a[0]:.2f} / {a[1]:.2f}, without the wall ring {i[0]:.2f} / {i[1]:.2f}; "
              f"persistent relief {100 * pf:.2f} / {100 * ph:.2f}")
        if show_map:
            ks = np.array(list(avg))
            for j in range(ks[:, 1].max(), ks[:, 1].min() - 1, -1):
                print(" ".join(f"{100 * avg[(i, j)]:5.1f}" if (i, j) in avg else "    ."
                               for i in range(ks[:, 0].min(), ks[:, 0].max() + 1)))


if __name__ == "__main__":
    args = sys.argv[1:]
    if not [a for a in args if a != "--map"]:
        sys.exit(__doc__)
    main([a for a in args if a != "--map"], "--map" in args)
