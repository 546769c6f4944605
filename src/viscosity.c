/* viscosity.c - Clavet's pairwise viscosity impulses (Alg. 5), Jacobi form.
 *
 * Clavet applies each pair's impulse in turn (Gauss-Seidel); here every particle gathers the
 * halves of its pairs from the velocities at the start of the stage, so the result does not
 * depend on thread scheduling, and each pair's two halves are exact negatives (momentum is
 * conserved to round-off). */
#include <math.h>

#include "fluid.h"

/* Chunks of neighbours: the arithmetic in a loop the compiler vectorizes (AVX2 where the
 * processor has it: the same results), gathering the neighbours' positions and velocities
 * straight from the arrays (see pressure.c), then summed in list order. */
#define VISC_CHUNK 64

STF_VECTOR_CLONES
static void gather_one(stf_fluid *f, int i, double dt)
{
    const double *x = f->x, *v = f->v;
    double h = f->h, inv_h = 1.0 / h, sigma = f->def.sigma, beta = f->def.beta, tiny = 1e-12 * h;
    double half_dt = 0.5 * dt;
    double ax = 0, ay = 0, az = 0;
    grid_prefetch(&f->grid, i + 2, f->n);
    const int32_t *nb = grid_row(&f->grid, i);
    double xi = x[3 * i], yi = x[3 * i + 1], zi = x[3 * i + 2];
    double vxi = v[3 * i], vyi = v[3 * i + 1], vzi = v[3 * i + 2];
    double tx[VISC_CHUNK], ty[VISC_CHUNK], tz[VISC_CHUNK];
    for (int k0 = 0; k0 < f->grid.count[i]; k0 += VISC_CHUNK) {
        int m = f->grid.count[i] - k0 < VISC_CHUNK ? f->grid.count[i] - k0 : VISC_CHUNK;
        const int32_t *js = nb + k0;
        for (int e = 0; e < m; e++) {
            int j = js[e];
            double rx = x[3 * j] - xi, ry = x[3 * j + 1] - yi, rz = x[3 * j + 2] - zi;
            double ux = vxi - v[3 * j], uy = vyi - v[3 * j + 1], uz = vzi - v[3 * j + 2];
            double r = sqrt(rx * rx + ry * ry + rz * rz);
            /* Branch-free (about half the pairs separate, unpredictably): every pair is
               computed (with r kept off 0) and a skipped one adds I = +-0, which leaves the
               sums' bits as they were (they are never -0). */
            double rs = r > tiny ? r : tiny;
            double inv = 1.0 / rs, q = r * inv_h; /* one division */
            /* u: how fast i and j approach each other along their line */
            double u = (ux * rx + uy * ry + uz * rz) * inv;
            double I = half_dt * (1.0 - q) * (sigma * u + beta * u * u) * inv;
            I *= (double)((u > 0) & (r < h) & (r > tiny));
            tx[e] = I * rx, ty[e] = I * ry, tz[e] = I * rz;
        }
        for (int e = 0; e < m; e++) {
            ax -= tx[e];
            ay -= ty[e];
            az -= tz[e];
        }
    }
    f->dx[3 * i] = ax;
    f->dx[3 * i + 1] = ay;
    f->dx[3 * i + 2] = az;
}

void stf_viscosity_apply(stf_fluid *f, double dt)
{
    int n = f->n;
    /* dynamic chunks: the results do not depend on the thread (see stf_pressure_relax) */
#pragma omp parallel for schedule(dynamic, 256)
    for (int i = 0; i < n; i++) gather_one(f, i, dt);
#pragma omp parallel for schedule(static)
    for (int i = 0; i < 3 * n; i++) f->v[i] += f->dx[i];
}
