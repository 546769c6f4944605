/* cy_density.c - the Carreau-Yasuda model's density pass over the pair lists: Eq. 6, the
 * density rho_i = sum_j m W_ij (+ the walls' part, cy_walls.c) with the cubic spline of
 * support h (cy_internal.h, here branch-free for vector code); the pair gradients grad W_ij
 * every later pass reads (Eq. 19, Algorithm 1, Eq. 9 and 22); the factor S_i of Eq. 20-21,
 * the denominator of Eq. 21's stiffness k_i (cy_pressure.c); and the pair weights of the
 * viscous operator (Morris' Laplacian or the central form, cy_viscosity.c). One call per
 * particle, in the step's first pass (cy.c, cy_substep). */
#include "cy_internal.h"

#include <math.h>

/* x_i - x_j with the nearest periodic image; returns |r|. */
static double pair_vec(const stf_fluid *f, int i, int j, double r[3])
{
    for (int a = 0; a < 3; a++) {
        double d = f->x[3 * i + a] - f->x[3 * j + a];
        double L = f->def.periodic[a];
        if (L > 0) d -= L * floor(d / L + 0.5);
        r[a] = d;
    }
    return sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
}

/* rho_i (Eq. 6), the pair gradients, and S_i of Eq. 20-21. The pairs go in chunks of
 * CHUNK: their vectors, then the kernel terms (kernel_terms), then the sums in list order. */
#define CHUNK 64

/* The kernel terms of nk pair vectors R: W, S = (dW/dr) / r (0 at r = 0) and
 * L = S r^2 / (r^2 + 0.01 h^2). The cubic spline and its derivative inline and branch-free
 * (the nearest neighbours sit at q = 1/2 where kernel_w and kernel_dw switch branch): with
 * a = max(1 - q, 0), b = max(1/2 - q, 0), W = kw (2 a^3 - 8 b^3), dW/dr = kd (4 b^2 - a^2).
 * no-trapping-math lets gcc turn the selects into masks and the loop into vector code (two
 * square roots and divisions at a time); no floating-point trap is enabled anywhere. */
#if defined(__GNUC__) && !defined(__clang__)
#define NO_TRAPPING_MATH __attribute__((optimize("no-trapping-math")))
#else
#define NO_TRAPPING_MATH
#endif
static NO_TRAPPING_MATH void
kernel_terms(int nk, double R[3][CHUNK], double *restrict W, double *restrict S,
             double *restrict L, double h)
{
    double ih = 1.0 / h, kw = 8.0 / (PI * h * h * h), kd = 48.0 / (PI * h * h * h * h);
    double eps = 0.01 * h * h, tiny = 1e-12 * h;
    for (int k = 0; k < nk; k++) {
        double l2 = R[0][k] * R[0][k] + R[1][k] * R[1][k] + R[2][k] * R[2][k];
        double len = sqrt(l2), q = len * ih, qa = 1 - q, qb = 0.5 - q;
        qa = qa < 0 ? 0 : qa;
        qb = qb < 0 ? 0 : qb;
        double far = len < tiny ? tiny : len;
        double inv = 1.0 / (far * (l2 + eps));
        W[k] = kw * (2 * qa * qa * qa - 8 * qb * qb * qb);
        S[k] = len < tiny ? 0 : kd * (4 * qb * qb - qa * qa) * inv * (l2 + eps);
        L[k] = S[k] * l2 * len * inv;
    }
}

void stf_cy_density_one(stf_fluid *f, int i)
{
    cy_state *c = f->cy;
    double h = f->h, m = f->mass, rho = c->rho[i] + m * kernel_w(0, h);
    double sum[3] = {c->mirror * c->gw[3 * i], c->mirror * c->gw[3 * i + 1],
                     c->mirror * c->gw[3 * i + 2]}, sq = 0;
    const int32_t *nb = c->dense ? c->nbt + (size_t)i * (size_t)c->nbs
                                 : grid_row(&f->grid, i);
    int cnt = c->dense ? c->nbc[i] : f->grid.count[i];
    cy_pair *pr = c->pair + c->off[i];
    float *lp = c->lap + c->off[i];
    int periodic = is_periodic(f), central = f->def.cy.viscosity_form == STF_VISCOSITY_CENTRAL;
    double eps = 0.01 * h * h;
    const double *x = f->x, *xi = x + 3 * i;
    double R[3][CHUNK], W[CHUNK], S[CHUNK], L[CHUNK];
    for (int k0 = 0; k0 < cnt; k0 += CHUNK) {
        int nk = cnt - k0 < CHUNK ? cnt - k0 : CHUNK;
        for (int k = 0; k < nk; k++) {
            int j = nb[k0 + k];
            double r[3];
            if (periodic) pair_vec(f, i, j, r);
            else
                for (int e = 0; e < 3; e++) r[e] = xi[e] - x[3 * j + e];
            R[0][k] = r[0], R[1][k] = r[1], R[2][k] = r[2];
        }
        kernel_terms(nk, R, W, S, L, h);
        for (int k = 0; k < nk; k++) {
            double s = S[k], l2 = 0;
            rho += m * W[k];
            pr[k0 + k].j = nb[k0 + k];
            for (int a3 = 0; a3 < 3; a3++) {
                pr[k0 + k].g[a3] = (float)(s * R[a3][k]);
                sum[a3] += m * s * R[a3][k];
                l2 += R[a3][k] * R[a3][k];
            }
            sq += m * m * s * s * l2;
            lp[k0 + k] = !central ? (float)(m * L[k])
                         : s != 0 ? (float)(5 * m / (s * (l2 + eps))) : 0.0f;
        }
    }
    c->rho[i] = rho;
    c->irho[i] = 1.0 / rho;
    c->S[i] = sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2] + sq;
}
