/* gauss_seidel.c - the springs (Clavet Alg. 3 with the history stiffness of Eq. 6) as
 * compliant distance constraints, relaxed Gauss-Seidel over coloured cells.
 *
 * Why. Clavet et al. apply each spring's displacement at once, pair after pair (Gauss-Seidel),
 * which is what let the shear-thickening paper run at a 33 ms step. The Jacobi form
 * (springs.c) gathers every spring's displacement from the same positions: stable only while
 * dt^2 sum_j k_ij (1 - L/h) stays below about 1, so a jammed spring network as stiff as the
 * paper's impact needs (an effective modulus of order 100 kPa: a 7 kg ball stopped within
 * R/2) saturates at a 1 ms step and its stiffness then depends on the step.
 *
 * The constraint. For the spring (i, j) of rest length L and gain c = dt^2 k_ij (1 - L/h)
 * (Clavet's: the pair's separation error shrinks by c per step, half on each side), the
 * compliant form (XPBD: Macklin, Mueller, Chentanez, "XPBD: position-based simulation of
 * compliant constrained dynamics", MIG 2016) with C = r - L, alpha = 2 / c (unit masses):
 *     dlambda = (-C - alpha lambda) / (2 + alpha),  lambda += dlambda,
 *     x_i -= dlambda n,  x_j += dlambda n   (n from i to j),
 * moves the pair by c / (1 + c) of its error in the first sweep: Clavet's c for a soft spring,
 * never more than the whole error for a stiff one (a rigid rod at any step), so the history
 * stiffness may be as large as the material needs at any dt. Further sweeps converge to the
 * implicit solution of the compliant network (lambda carries what earlier sweeps did).
 * Every update moves a pair by equal and opposite amounts: linear momentum is exact.
 *
 * Damping (springs.damping = tau, ours). A jammed network as stiff as a solid, pushed each
 * step by the pressure relaxation after it, chatters: at k_hist 4e7 the resting pool's
 * particles kept moving at 3-6 cm/s, and that motion kept their history stiffness high (the
 * fractional derivative of a noise), so the fluid never softened. XPBD's constraint damping
 * (Macklin et al., section 4.1) puts a dashpot of coefficient tau K beside each spring of
 * stiffness K (Kelvin-Voigt, relaxation time tau): with gamma = tau / dt,
 *     dlambda = (-C - alpha lambda - gamma n.(dx_j - dx_i)) / ((1 + gamma) 2 + alpha),
 * dx the moves since the step's start. A time in seconds: the same dashpot at any dt; it
 * damps the grid-scale modes of a stiff spring (omega tau >> 1) and leaves the slow ones (a
 * bouncing ball's, omega tau << 1) as they are. 0: none.
 *
 * Parallel and deterministic. The particles are binned in cells at least as wide as the
 * longest spring; a particle's springs reach only the 3 x 3 x 3 cells about its own, so cells
 * whose indices differ by at least 3 along some axis touch disjoint particles. The 27 colours
 * (cx mod 3, cy mod 3, cz mod 3) are swept in turn, the cells of a colour in parallel, each
 * cell's particles in index order, each particle's springs to higher indices in list order:
 * the same result for any thread count. The cells are binned from the positions the longest
 * spring was measured at, so every spring joins neighbouring cells (a component of its
 * length is below the cell size); the sweep moves particles but not their cells, so which
 * particles a cell touches stays fixed. */
#include "gauss_seidel.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "fluid.h"

enum { GS_COLOURS = 27 };

void stf_gs_free(stf_gs *g)
{
    free(g->cell_of);
    free(g->start);
    free(g->members);
    free(g->colour_cells);
    free(g->lambda);
    memset(g, 0, sizeof *g);
}

static int grow(void **p, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap) return 0;
    size_t c = need + need / 2 + 16;
    void *q = realloc(*p, c * elem);
    if (!q) return -1;
    *p = q;
    *cap = c;
    return 0;
}

/* Bins the particles in cells of size cs; returns 0, -1 out of memory. Falls back to one
 * cell (a serial sweep, the same for any thread count) when the box would need too many. */
static int gs_bin(stf_gs *g, const double *x, int n, double cs)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(lo[a], x[3 * i + a]);
            hi[a] = fmax(hi[a], x[3 * i + a]);
        }
    long dim[3] = {1, 1, 1};
    double total = 1;
    for (int a = 0; a < 3 && n > 0; a++) {
        double d = floor((hi[a] - lo[a]) / cs) + 1;
        if (!isfinite(d)) d = 1e30;
        total *= d;
        dim[a] = d < 1e9 ? (long)d : 1;
    }
    int serial = !(total <= 8.0 * n + 4096.0);
    if (serial) dim[0] = dim[1] = dim[2] = 1;
    size_t ncell = (size_t)(dim[0] * dim[1] * dim[2]);
    if (grow((void **)&g->cell_of, &g->cap_n, (size_t)n + 1, sizeof *g->cell_of)) return -1;
    size_t capm = g->cap_m;
    if (grow((void **)&g->members, &capm, (size_t)n + 1, sizeof *g->members)) return -1;
    g->cap_m = capm;
    size_t capc = g->cap_c;
    if (grow((void **)&g->start, &capc, ncell + 1, sizeof *g->start)) return -1;
    size_t capcc = g->cap_cc;
    if (grow((void **)&g->colour_cells, &capcc, ncell + 1, sizeof *g->colour_cells)) return -1;
    g->cap_c = capc, g->cap_cc = capcc;
    memcpy(g->dim, dim, sizeof dim);
    memset(g->start, 0, (ncell + 1) * sizeof *g->start);
    for (int i = 0; i < n; i++) {
        long c = 0;
        if (!serial) {
            long ci[3];
            for (int a = 0; a < 3; a++) {
                double u = floor((x[3 * i + a] - lo[a]) / cs);
                ci[a] = u < 0 ? 0 : u >= dim[a] ? dim[a] - 1 : (long)u;
            }
            c = (ci[2] * dim[1] + ci[1]) * dim[0] + ci[0];
        }
        g->cell_of[i] = (int32_t)c;
        g->start[c + 1]++;
    }
    for (size_t c = 0; c < ncell; c++) g->start[c + 1] += g->start[c];
    /* members in particle order within a cell (a stable counting sort) */
    for (int i = 0; i < n; i++) g->members[g->start[g->cell_of[i]]++] = i;
    for (size_t c = ncell; c > 0; c--) g->start[c] = g->start[c - 1];
    g->start[0] = 0;
    /* the non-empty cells of each colour, colour by colour */
    size_t m = 0;
    for (int col = 0; col < GS_COLOURS; col++) {
        g->colour_start[col] = (int32_t)m;
        int ox = col % 3, oy = (col / 3) % 3, oz = col / 9;
        for (long cz = oz; cz < dim[2]; cz += 3)
            for (long cy = oy; cy < dim[1]; cy += 3)
                for (long cx = ox; cx < dim[0]; cx += 3) {
                    long c = (cz * dim[1] + cy) * dim[0] + cx;
                    if (g->start[c + 1] > g->start[c]) g->colour_cells[m++] = (int32_t)c;
                }
    }
    g->colour_start[GS_COLOURS] = (int32_t)m;
    return 0;
}

/* The spring constraints of particle i to its partners j > i. */
static void relax_springs_of(stf_fluid *f, stf_gs *g, int i, double dt, double khist_scale)
{
    const stf_springs *s = &f->springs;
    double *x = f->x;
    const double *D = f->hist.D, *xp = f->xprev;
    double h = f->h, dt2 = dt * dt, onset = f->def.k_onset, k_min = f->def.k_min;
    double gamma = f->def.spring_damping / dt; /* XPBD's damping, tau / dt */
    size_t row = (size_t)i * (size_t)s->stride;
    const int32_t *p = s->partner + row;
    const double *Ls = s->rest + row;
    double *lam = g->lambda + row;
    for (int k = 0; k < s->count[i]; k++) {
        int j = p[k];
        if (j <= i) continue; /* the pair's other row */
        double rx = x[3 * j] - x[3 * i], ry = x[3 * j + 1] - x[3 * i + 1], rz = x[3 * j + 2] - x[3 * i + 2];
        double r = sqrt(rx * rx + ry * ry + rz * rz);
        if (r <= 1e-12 * h) continue; /* coincident: no direction to pull along */
        double L = Ls[k], kij = k_min;
        if (khist_scale > 0) {
            double ex = D[3 * i] - D[3 * j], ey = D[3 * i + 1] - D[3 * j + 1], ez = D[3 * i + 2] - D[3 * j + 2];
            double kh = khist_scale * sqrt(ex * ex + ey * ey + ez * ez); /* Eq. 6 */
            kij += kh > onset ? kh - onset : 0.0;
        }
        double c = dt2 * kij * (1.0 - L / h);
        if (!(c > 0)) continue;
        double alpha = 2.0 / c;
        /* the pair's approach along the spring since the step's start (its relative
           velocity times dt): the dashpot's share, 0 without damping */
        double du = gamma > 0 ? ((x[3 * j] - xp[3 * j] - x[3 * i] + xp[3 * i]) * rx +
                                 (x[3 * j + 1] - xp[3 * j + 1] - x[3 * i + 1] + xp[3 * i + 1]) * ry +
                                 (x[3 * j + 2] - xp[3 * j + 2] - x[3 * i + 2] + xp[3 * i + 2]) * rz) / r
                              : 0.0;
        double dl = (-(r - L) - alpha * lam[k] - gamma * du) / ((1.0 + gamma) * 2.0 + alpha);
        lam[k] += dl;
        double ux = dl * rx / r, uy = dl * ry / r, uz = dl * rz / r;
        x[3 * i] -= ux, x[3 * i + 1] -= uy, x[3 * i + 2] -= uz;
        x[3 * j] += ux, x[3 * j + 1] += uy, x[3 * j + 2] += uz;
    }
}

int stf_gs_springs(stf_fluid *f, double dt, double khist_scale)
{
    stf_gs *g = f->gs;
    const stf_springs *s = &f->springs;
    int n = f->n;
    /* cells at least as wide as the longest spring now (and as h) */
    double longest = f->h;
#pragma omp parallel for schedule(static) reduction(max : longest)
    for (int i = 0; i < n; i++) {
        const int32_t *p = s->partner + (size_t)i * (size_t)s->stride;
        for (int k = 0; k < s->count[i]; k++) {
            int j = p[k];
            double rx = f->x[3 * j] - f->x[3 * i], ry = f->x[3 * j + 1] - f->x[3 * i + 1],
                   rz = f->x[3 * j + 2] - f->x[3 * i + 2];
            double r = sqrt(rx * rx + ry * ry + rz * rz);
            if (r > longest) longest = r;
        }
    }
    if (gs_bin(g, f->x, n, longest * (1.0 + 1e-9)) != 0) return -1;
    size_t slots = (size_t)s->n_alloc * (size_t)s->stride;
    if (grow((void **)&g->lambda, &g->cap_lambda, slots, sizeof *g->lambda)) return -1;
    memset(g->lambda, 0, slots * sizeof *g->lambda);
    for (int it = 0; it < f->def.iterations; it++)
        for (int col = 0; col < GS_COLOURS; col++) {
            int c0 = g->colour_start[col], c1 = g->colour_start[col + 1];
#pragma omp parallel for schedule(dynamic, 4)
            for (int q = c0; q < c1; q++) {
                int cell = g->colour_cells[q];
                for (int32_t e = g->start[cell]; e < g->start[cell + 1]; e++)
                    relax_springs_of(f, g, g->members[e], dt, khist_scale);
            }
        }
    return 0;
}
