/* stf_cy_neighbours.c - the Carreau-Yasuda model's neighbour lists: every particle's neighbours
 * within h, found by its own search for a fluid that is not periodic (stf_cy_neighbours) or taken
 * from the shared grid (grid.c, periodic fluids), and laid out compactly (CSR) for the passes
 * of the step (stf_cy_pair_offsets). The second paper (Algorithm 2, step 1) only says that the
 * neighbours are found; the search is ours.
 *
 * Why not grid.c's search: both find the same neighbours (r < h), but the order of a list is
 * that of its search (here row by row along x over cells h/XCELLS long, there by the 27 hashed
 * cells of h + skin, each bucket in particle order), every sum over a list (density, S_i,
 * pressure, strain rate, viscosity) is added up in that order, and a different order changes
 * the rounding: the results would not stay bit-identical (tried on scenes/cy_dam_break.yaml:
 * with the shared grid's lists its particles are 70 um off after 0.05 s, 6 cm after 0.25 s). */
#include "cy_internal.h"

#include <math.h>
#include <omp.h>
#include <string.h>

/* Room for the pair arrays of `pairs` pairs. 0 / -1. */
static int reserve_pairs(cy_state *c, size_t pairs)
{
    if (pairs <= c->pair_cap) return 0;
    pairs += pairs / 4 + 64;
    cy_pair *q = realloc(c->pair, pairs * sizeof *q);
    if (!q) return -1;
    c->pair = q;
    float *l = realloc(c->lap, pairs * sizeof *l);
    if (!l) return -1;
    c->lap = l;
    c->pair_cap = pairs;
    return 0;
}

/* Compact offsets of the grid's neighbour lists (serial: a prefix sum) and room for them. */
int stf_cy_pair_offsets(stf_fluid *f)
{
    cy_state *c = f->cy;
    size_t total = 0;
    const int32_t *count = c->dense ? c->nbc : f->grid.count;
    for (int i = 0; i < f->n; i++) {
        c->off[i] = (int32_t)total;
        total += (size_t)count[i];
    }
    if (total > INT32_MAX) return -1;
    c->off[f->n] = (int32_t)total;
    return reserve_pairs(c, total);
}

/* Every particle's neighbours within h (r < h), for a fluid that is not periodic: the
 * particles are counting-sorted into a dense grid of cells over their bounding box, h across
 * (y, z) and h / XCELLS along x, with a sorted copy of their positions. Around a particle,
 * the 3 x 3 rows (along x) are visited, each over the cells within the sphere's chord at the
 * row's distance from the particle: one contiguous run of the sorted copy (no hashing, no
 * indirection, the distance tests stream). At the dam break that is 100 candidates per
 * particle against 216 in 27 cells of size h (and 5% less time, A/B); cells of h/2 in all
 * three directions (25 rows) cost more: such a cell holds about one particle at h = 2
 * spacings. The lists are rebuilt every substep (at the dam break's speeds the Verlet lists
 * of the shared grid were rebuilt at 97% of the substeps anyway). The list order (row by
 * row, cell by cell, particle index within a cell) depends on the positions only: the same
 * for any thread count. Returns 1 (c->nbt, c->nbc hold the lists), 0 when the box has too
 * many cells for the particles (far-flung particles: the shared hashed grid is used
 * instead), -1 out of memory. */
#define XCELLS 4
int stf_cy_neighbours(stf_fluid *f)
{
    cy_state *c = f->cy;
    int n = f->n;
    double h = f->h, h2 = h * h, reach2 = h2 * (1 + 1e-9); /* pruning a hair wider */
    double inv[3] = {XCELLS / h, 1.0 / h, 1.0 / h}; /* cells of h/XCELLS along x, h across */
    double lo0 = INFINITY, lo1 = INFINITY, lo2 = INFINITY;
    double hi0 = -INFINITY, hi1 = -INFINITY, hi2 = -INFINITY;
    const double *x = f->x;
#pragma omp parallel for schedule(static) reduction(min : lo0, lo1, lo2)                           \
    reduction(max : hi0, hi1, hi2)
    for (int i = 0; i < n; i++) {
        const double *p = x + 3 * i; /* positions are finite (stf_fluid_check) */
        lo0 = p[0] < lo0 ? p[0] : lo0, hi0 = p[0] > hi0 ? p[0] : hi0;
        lo1 = p[1] < lo1 ? p[1] : lo1, hi1 = p[1] > hi1 ? p[1] : hi1;
        lo2 = p[2] < lo2 ? p[2] : lo2, hi2 = p[2] > hi2 ? p[2] : hi2;
    }
    if (n == 0) return 0;
    double lo[3] = {lo0, lo1, lo2}, span[3] = {hi0 - lo0, hi1 - lo1, hi2 - lo2};
    int dim[3];
    double cells = 1;
    /* at most 16 cells per particle (+ 65536): a few spray particles far out make the box
       large, and then the cells along x are coarsened (to h/2, then h) before giving up */
    for (;;) {
        cells = 1;
        for (int a = 0; a < 3; a++) {
            if (!(span[a] * inv[a] < 1e6)) return 0;
            dim[a] = (int)floor(span[a] * inv[a]) + 1;
            cells *= dim[a];
        }
        if (cells <= 16.0 * n + 65536) break;
        if (inv[0] * h < 1.5) return 0;
        inv[0] *= 0.5;
    }
    size_t ncell = (size_t)cells;
    if (ncell + 1 > c->cell_cap) {
        int32_t *cb = realloc(c->cstart, (ncell + 1) * sizeof *cb);
        if (!cb) return -1;
        c->cstart = cb;
        c->cell_cap = ncell + 1;
    }
    int32_t *cst = c->cstart, *cellof = c->cellof, *sid = c->sid;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        int k[3];
        for (int a = 0; a < 3; a++) {
            int u = (int)((x[3 * i + a] - lo[a]) * inv[a]);
            k[a] = u < 0 ? 0 : u >= dim[a] ? dim[a] - 1 : u;
        }
        cellof[i] = (k[2] * dim[1] + k[1]) * dim[0] + k[0];
    }
    /* counting sort (serial: stable, and short next to the search) */
    memset(cst, 0, (ncell + 1) * sizeof *cst);
    for (int i = 0; i < n; i++) cst[cellof[i] + 1]++;
    for (size_t b = 0; b < ncell; b++) cst[b + 1] += cst[b];
    for (int i = 0; i < n; i++) sid[cst[cellof[i]]++] = i;
    for (size_t b = ncell; b > 0; b--) cst[b] = cst[b - 1];
    cst[0] = 0;
    double *sx = c->sx, *sy = sx + n, *sz = sy + n;
#pragma omp parallel for schedule(static)
    for (int k = 0; k < n; k++) {
        int i = sid[k];
        sx[k] = x[3 * i], sy[k] = x[3 * i + 1], sz[k] = x[3 * i + 2];
    }
    for (;;) {
        int most = 0, stride = c->nbs;
        /* in cell order: the particles of a cell scan the same runs, in cache */
#pragma omp parallel for schedule(static) reduction(max : most)
        for (int si = 0; si < n; si++) {
            int i = sid[si];
            int cell = cellof[i], ky = cell / dim[0] % dim[1],
                kz = cell / dim[0] / dim[1];
            double px = sx[si], py = sy[si], pz = sz[si];
            int32_t *out = c->nbt + (size_t)i * (size_t)stride;
            int cnt = 0, last = stride - 1;
            for (int z = kz > 0 ? kz - 1 : 0; z <= kz + 1 && z < dim[2]; z++) {
                /* distance from the particle to the layer of rows z (zero in its own) */
                double dz = z < kz ? pz - (lo[2] + (z + 1) * h) : z > kz ? lo[2] + z * h - pz : 0;
                dz = dz > 0 ? dz : 0;
                for (int y = ky > 0 ? ky - 1 : 0; y <= ky + 1 && y < dim[1]; y++) {
                    double dy = y < ky   ? py - (lo[1] + (y + 1) * h)
                                : y > ky ? lo[1] + y * h - py
                                         : 0;
                    dy = dy > 0 ? dy : 0;
                    double rest = reach2 - dy * dy - dz * dz;
                    if (rest <= 0) continue;
                    /* the row's cells within the sphere's chord at that distance */
                    double rx = sqrt(rest) + 1e-9 * h;
                    double u0 = (px - rx - lo[0]) * inv[0], u1 = (px + rx - lo[0]) * inv[0];
                    int x0 = u0 > 0 ? (int)u0 : 0, x1 = u1 < dim[0] - 1 ? (int)u1 : dim[0] - 1;
                    if (x1 < x0) continue;
                    int row = (z * dim[1] + y) * dim[0];
                    for (int k = cst[row + x0], e = cst[row + x1 + 1]; k < e; k++) {
                        double ex = sx[k] - px, ey = sy[k] - py, ez = sz[k] - pz;
                        /* branch-free append; past the stride the last slot is
                           overwritten, and the lists are widened and redone */
                        out[cnt < last ? cnt : last] = sid[k];
                        cnt += (ex * ex + ey * ey + ez * ez < h2) & (sid[k] != i);
                    }
                }
            }
            c->nbc[i] = cnt;
            most = cnt > most ? cnt : most;
        }
        if (most < c->nbs) return 1;
        /* compressed regions: widen every list and redo (rare, deterministic) */
        int wide = most + most / 2 + 1;
        if (grow_i32(&c->nbt, (size_t)c->cap * (size_t)wide)) return -1;
        c->nbs = wide;
    }
}
