/* pressure.c - Clavet's double density relaxation (Alg. 2), Jacobi form.
 *
 * Densities are kernel sums rho_i = sum (1-r/h)^2 and rho_near_i = sum (1-r/h)^3 over the
 * neighbours; P = k (rho - rho0), P_near = k_near rho_near. Clavet moves i and j apart by
 * D/2 each while visiting i; visiting j later adds j's own D. Gathering both halves at once,
 * particle i moves by -dt^2/2 ((P_i+P_j)(1-q) + (Pn_i+Pn_j)(1-q)^2) along r_ij/r. */
#include <math.h>

#include "fluid.h"

static void density_one(stf_fluid *f, int i)
{
    const double *x = f->x;
    double h = f->h, rho = 0, rho_near = 0;
    const int32_t *nb = f->grid.nbr + (size_t)i * f->grid.stride;
    for (int k = 0; k < f->grid.count[i]; k++) {
        int j = nb[k];
        double rx = x[3 * j] - x[3 * i], ry = x[3 * j + 1] - x[3 * i + 1],
               rz = x[3 * j + 2] - x[3 * i + 2];
        double r2 = rx * rx + ry * ry + rz * rz;
        if (r2 >= h * h) continue;
        double a = 1.0 - sqrt(r2) / h;
        rho += a * a;
        rho_near += a * a * a;
    }
    /* Store pressures, not densities: both halves of a pair need them. */
    f->rho[i] = f->def.k * (rho - f->rest_density);
    f->rho_near[i] = f->def.k_near * rho_near;
}

static void relax_one(stf_fluid *f, int i, double dt)
{
    const double *x = f->x, *P = f->rho, *Pn = f->rho_near;
    double h = f->h, dx = 0, dy = 0, dz = 0;
    const int32_t *nb = f->grid.nbr + (size_t)i * f->grid.stride;
    for (int k = 0; k < f->grid.count[i]; k++) {
        int j = nb[k];
        double rx = x[3 * j] - x[3 * i], ry = x[3 * j + 1] - x[3 * i + 1],
               rz = x[3 * j + 2] - x[3 * i + 2];
        double r = sqrt(rx * rx + ry * ry + rz * rz);
        if (r >= h || r <= 1e-12 * h) continue;
        double a = 1.0 - r / h;
        double D = 0.5 * dt * dt * ((P[i] + P[j]) * a + (Pn[i] + Pn[j]) * a * a) / r;
        dx -= D * rx;
        dy -= D * ry;
        dz -= D * rz;
    }
    f->dx[3 * i] = dx;
    f->dx[3 * i + 1] = dy;
    f->dx[3 * i + 2] = dz;
}

void pressure_relax(stf_fluid *f, double dt)
{
    int n = f->n;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) density_one(f, i);
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) relax_one(f, i, dt);
#pragma omp parallel for schedule(static)
    for (int i = 0; i < 3 * n; i++) f->x[i] += f->dx[i];
}
