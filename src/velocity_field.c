/* velocity_field.c - the velocity field over a length in metres (history.smoothing, ours).
 *
 * With history.velocity smoothed and a smoothing length L > 0, Eq. 3 remembers the fluid's
 * velocity averaged over L instead of over the particle's kernel neighbours. Why: a jammed
 * region moves as a block and the shear concentrates at its edge, in the thinnest band the
 * averaged field can resolve. With the kernel's average that band is one spacing wide, so a
 * body creeping through jammed fluid shears its neighbours at the onset when it moves at about
 * the onset's rate times one spacing: the creep speed, and with it the bowling ball's sinking,
 * scaled with the spacing (scenes/README.md, the bowling ball). Averaged over L the band is
 * L wide whatever the spacing, and a body creeps at the onset rate times L.
 *
 * The average is a particle-in-cell round trip on a lattice of cell L: each particle spreads
 * its velocity and a unit weight over the 8 corners of its cell with trilinear weights, and
 * reads back the ratio of the two sums at its own position with the same weights (a
 * tent filter of half-width L each way, standard deviation L / sqrt(3) along each axis; a
 * uniform velocity comes back exactly, a linear one exactly in the bulk). The spreading runs
 * in particle order on one thread, so the sums and the result are the same for any thread
 * count; it is O(n) and cheaper than a pass over the neighbours. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fluid.h"

/* The lattice of cell 1/inv from origin with dim nodes along each axis: the 8 corners of the
 * cell holding point p and their trilinear weights. */
typedef struct lattice {
    double origin[3], inv;
    long dim[3];
} lattice;

static inline void corners(const lattice *g, const double *p, size_t node[8], double w[8])
{
    double fr[3];
    size_t base = 0, stride[3] = {1, (size_t)g->dim[0], (size_t)(g->dim[0] * g->dim[1])};
    for (int a = 0; a < 3; a++) {
        double u = (p[a] - g->origin[a]) * g->inv;
        long c = (long)u;
        if (c > g->dim[a] - 2) c = g->dim[a] - 2; /* the top face of the box: the last cell */
        fr[a] = u - (double)c;
        base += (size_t)c * stride[a];
    }
    for (int k = 0; k < 8; k++) {
        w[k] = ((k & 1) ? fr[0] : 1 - fr[0]) * ((k & 2) ? fr[1] : 1 - fr[1]) *
               ((k & 4) ? fr[2] : 1 - fr[2]);
        node[k] = base + ((k & 1) ? stride[0] : 0) + ((k & 2) ? stride[1] : 0) +
                  ((k & 4) ? stride[2] : 0);
    }
}

int stf_fluid_field_velocity(stf_fluid *f, double *out)
{
    int n = f->n;
    const double *x = f->x, *v = f->v;
    double L = f->def.history_smoothing, inv = 1.0 / L;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            double c = x[3 * i + a];
            lo[a] = c < lo[a] ? c : lo[a];
            hi[a] = c > hi[a] ? c : hi[a];
        }
    lattice g = {.inv = inv};
    double nodes = 1;
    for (int a = 0; a < 3; a++) {
        g.origin[a] = floor(lo[a] * inv) * L; /* on multiples of L: the lattice does not drift */
        g.dim[a] = (long)floor((hi[a] - g.origin[a]) * inv) + 2;
        nodes *= (double)g.dim[a];
    }
    if (!(nodes <= 1.0e8)) {
        snprintf(f->failure, sizeof f->failure,
                 "step %ld (t = %.6g s), effect history (smoothing): the fluid spans "
                 "[%.3g, %.3g] x [%.3g, %.3g] x [%.3g, %.3g] m, %.3g cells of %g m",
                 f->steps + 1, f->time, lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], nodes, L);
        return -1;
    }
    size_t nc = (size_t)nodes;
    if (nc > f->field_cap) {
        double *w = realloc(f->field_w, nc * sizeof *w);
        if (!w) return -2;
        f->field_w = w;
        double *m = realloc(f->field_v, 3 * nc * sizeof *m);
        if (!m) return -2;
        f->field_v = m;
        f->field_cap = nc;
    }
    double *W = f->field_w, *V = f->field_v;
    memset(W, 0, nc * sizeof *W);
    memset(V, 0, 3 * nc * sizeof *V);
    for (int i = 0; i < n; i++) { /* spread, in particle order */
        size_t node[8];
        double w[8];
        corners(&g, x + 3 * i, node, w);
        for (int k = 0; k < 8; k++) {
            W[node[k]] += w[k];
            for (int a = 0; a < 3; a++) V[3 * node[k] + (size_t)a] += w[k] * v[3 * i + a];
        }
    }
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) { /* gather: a particle's own weight keeps the sum > 0 */
        size_t node[8];
        double w[8], sw = 0, m[3] = {0, 0, 0};
        corners(&g, x + 3 * i, node, w);
        for (int k = 0; k < 8; k++) {
            sw += w[k] * W[node[k]];
            for (int a = 0; a < 3; a++) m[a] += w[k] * V[3 * node[k] + (size_t)a];
        }
        for (int a = 0; a < 3; a++) out[3 * i + a] = m[a] / sw;
    }
    return 0;
}
