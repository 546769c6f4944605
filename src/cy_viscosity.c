/* cy_viscosity.c - the viscosity step of the second paper (step 4 of Algorithm 2): the
 * strain rate D_i = L_i + L_i^T, L_i = (1/rho_i) sum_j m (v_j - v_i) (x) grad W_ij (Eq. 9, 22;
 * the walls' part from cy_walls.c); the Carreau-Yasuda viscosity nu_i of the shear rate
 * g_i = sqrt(D_i:D_i / 2) (Eq. 3); the viscous acceleration (in place of Eq. 10, below),
 * explicit (forward Euler) or implicit (backward Euler, Eq. 23-26: nu frozen at its value from
 * v**, solved matrix-free by conjugate gradients to |r| <= cg_tolerance |b|). Where the paper
 * is garbled or silent:
 *
 * Shear rate: sqrt(D:D / 2), which is |du/dy| in simple shear (the paper's Frobenius norm
 * sqrt(D:D) is sqrt(2) larger, which only rescales K).
 *
 * Eq. 24 as printed drops mu_inf and the "1 +"; the implicit step here keeps the full
 * Eq. 3 and linearises by freezing nu over the step (one Picard step).
 *
 * The viscous force is Morris et al.'s (1997) SPH Laplacian with the pair viscosity
 * mu_i + mu_j (the usual generalised-Newtonian SPH form), not the divergence of the SPH
 * stress of Eq. 10: that is a first derivative of a first derivative, blind to velocities
 * alternating from particle to particle; with it, plane Poiseuille flow came out with
 * layers alternating and 4x too fast (measured). Morris' operator is symmetric negative
 * semi-definite (pair weights m (mu_i + mu_j) (r.grad W) / (rho_i rho_j (r^2 + 0.01 h^2))),
 * so I - dt (viscous operator) is symmetric positive definite and CG applies. For the
 * plane shear flows of the tests it is exact: div(mu grad v) = div(mu D) there.
 *
 * viscosity_form central replaces Morris' pair force by Monaghan's (1997, 2005) central one,
 * a_i = sum_j (d + 2) m (mu_i + mu_j) / (rho_i rho_j) F_ij (x_ij . u_ij) x_ij / |x_ij|^2,
 * F_ij = (x_ij . grad W_ij) / (|x_ij|^2 + 0.01 h^2), d = 3: Morris' weight, along x_ij. For
 * uniform rho and nu that is 2 (d + 2) nu sum_j (m / rho) (u_ij . x_ij) grad W_ij /
 * (|x_ij|^2 + 0.01 h^2), whose Taylor expansion is nu (lap u + 2 grad div u): nu lap u for
 * divergence-free flow, as Morris' 2 nu sum_j (m / rho) F_ij u_ij (test_cy pins both
 * constants with a sinusoidal shear). The pair forces lie along x_ij, so angular momentum is
 * conserved and a rigid rotation feels none. The implicit operator's blocks are
 * w_ij x_ij x_ij^T (still symmetric negative semi-definite: CG applies); a wall's lattice
 * gives the 3 x 3 block sum_b over its mirror particles (tables by distance). Its fourth
 * moment over the neighbours is not isotropic on the cubic lattice at h = 2 spacings: shear
 * along the lattice axes sees 0.69 nu (0.93 at 3 spacings, as Morris at 4). */
#include "cy_internal.h"

#include <math.h>
#include <string.h>

double stf_cy_viscosity(const stf_cy_def *c, double g)
{
    /* Eq. 3 */
    double t = pow(c->K * g, c->alpha);
    return c->mu_inf + (c->mu0 - c->mu_inf) * pow(1.0 + t, (c->n - 1.0) / c->alpha);
}

/* D_i = L_i + L_i^T, L_i = (1/rho_i) [sum_j m (u_j - u_i) (x) grad W_ij + (v_w - u_i) (x) G_w]
 * (Eq. 9, 22). */
static void strain_one(const stf_fluid *f, const double *u, int i, double d[6])
{
    const cy_state *c = f->cy;
    double L[9] = {0}, m = f->mass;
    const cy_pair *pr = c->pair + c->off[i], *end = c->pair + c->off[i + 1];
    const double *ui = u + 3 * i;
    for (; pr < end; pr++) {
        const double *uj = u + 3 * pr->j;
        for (int a = 0; a < 3; a++) {
            double du = m * (uj[a] - ui[a]);
            for (int b = 0; b < 3; b++) L[3 * a + b] += du * pr->g[b];
        }
    }
    const double *G = c->gw + 3 * i;
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            L[3 * a + b] += c->wv[9 * i + 3 * a + b] - ui[a] * G[b];
    double inv = c->irho[i];
    d[0] = 2 * L[0] * inv;
    d[1] = 2 * L[4] * inv;
    d[2] = 2 * L[8] * inv;
    d[3] = (L[1] + L[3]) * inv;
    d[4] = (L[2] + L[6]) * inv;
    d[5] = (L[5] + L[7]) * inv;
}

/* Viscous acceleration of the velocity field u: Morris et al.'s (1997) SPH Laplacian with
 * the pair viscosity (mu_i + mu_j), mu = rho nu,
 *   a_i = sum_j m (mu_i + mu_j) / (rho_i rho_j) (r_ij . grad W_ij) / (r^2 + 0.01 h^2) (u_i - u_j),
 * plus the walls (mirror particles of viscosity mu_i moving with Morris' mirror velocity);
 * the walls' own velocity enters only when with_walls (the affine part of the operator).
 * This replaces the divergence of the SPH stress of Eq. 10 (see the file comment). */
static void viscous_one(const stf_fluid *f, const double *u, int i, int with_walls, double *out)
{
    const cy_state *c = f->cy;
    double a[3] = {0, 0, 0}, mi = c->mu[i];
    const cy_pair *pr = c->pair + c->off[i];
    const float *lp = c->lap + c->off[i];
    const double *ui = u + 3 * i;
    const double *mu = c->mu, *irho = c->irho;
    if (f->def.cy.viscosity_form == STF_VISCOSITY_CENTRAL) {
        /* a_i = sum_j (d + 2) m (mu_i + mu_j) / (rho_i rho_j) F_ij (x_ij . u_ij) x_ij / r^2
           (F as Morris'), i.e. lp g (g . u_ij) with g = grad W_ij along x_ij */
        for (int k = 0, cnt = c->off[i + 1] - c->off[i]; k < cnt; k++) {
            int j = pr[k].j;
            const double *uj = u + 3 * j;
            const float *g = pr[k].g;
            double gu = g[0] * (ui[0] - uj[0]) + g[1] * (ui[1] - uj[1]) + g[2] * (ui[2] - uj[2]);
            double w = lp[k] * (mi + mu[j]) * irho[j] * gu; /* / rho_i below */
            for (int e = 0; e < 3; e++) a[e] += w * g[e];
        }
        const double *M = c->lwm + 9 * i;
        double ww = wall_visc(c, i);
        for (int e = 0; e < 3; e++)
            out[3 * i + e] = a[e] * irho[i] +
                             ww * (M[3 * e] * ui[0] + M[3 * e + 1] * ui[1] + M[3 * e + 2] * ui[2] -
                                   (with_walls ? c->lwv[3 * i + e] : 0));
        return;
    }
    for (int k = 0, cnt = c->off[i + 1] - c->off[i]; k < cnt; k++) {
        int j = pr[k].j;
        const double *uj = u + 3 * j;
        double w = lp[k] * (mi + mu[j]) * irho[j]; /* / rho_i below */
        for (int e = 0; e < 3; e++) a[e] += w * (ui[e] - uj[e]);
    }
    for (int e = 0; e < 3; e++) a[e] *= c->irho[i];
    double ww = wall_visc(c, i);
    for (int e = 0; e < 3; e++)
        out[3 * i + e] = a[e] + ww * (c->lw[i] * ui[e] - (with_walls ? c->lwv[3 * i + e] : 0));
}

/* out = u - dt * (viscous acceleration of u without the walls' velocity). */
static void apply_system(stf_fluid *f, const double *u, double dt, double *out)
{
    int n = f->n;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        viscous_one(f, u, i, 0, out);
        for (int e = 3 * i; e < 3 * i + 3; e++) out[e] = u[e] - dt * out[e];
    }
}

static double dot(const double *a, const double *b, int n)
{
    double s = 0; /* serial: deterministic for any thread count */
    for (int i = 0; i < n; i++) s += a[i] * b[i];
    return s;
}

/* The viscosity of the step from the strain rate of v (Eq. 3), in c->nu. */
static void viscosity_field(stf_fluid *f, const double *v)
{
    cy_state *c = f->cy;
    int n = f->n;
    const stf_cy_def *cd = &f->def.cy;
    if (cd->n == 1 || cd->K == 0 || cd->mu0 == cd->mu_inf) { /* Eq. 3 is constant: Newtonian */
        double nu = stf_cy_viscosity(cd, 0);
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++) {
            c->nu[i] = nu;
            c->mu[i] = c->rho[i] * nu;
        }
        c->stats.min_viscosity = c->stats.max_viscosity = nu;
        return;
    }
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        double d[6];
        strain_one(f, v, i, d);
        double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] +
                    2 * (d[3] * d[3] + d[4] * d[4] + d[5] * d[5]);
        c->nu[i] = stf_cy_viscosity(&f->def.cy, sqrt(0.5 * dd));
        c->mu[i] = c->rho[i] * c->nu[i];
    }
    double lo = n ? c->nu[0] : 0, hi = lo;
    for (int i = 1; i < n; i++) {
        lo = c->nu[i] < lo ? c->nu[i] : lo;
        hi = c->nu[i] > hi ? c->nu[i] : hi;
    }
    c->stats.min_viscosity = lo;
    c->stats.max_viscosity = hi;
}

/* Viscosity step from v** (in f->v): explicit, or implicit by conjugate gradients on
 * (I - dt A) dv = dt a(v**), dv the velocity change, A the viscous operator. The walls'
 * impulses are those of a(u), u (left in c->r for wall_reactions) v** (explicit) or
 * v** + dv (implicit). Explicit: v = v** + dt a(u), whose pair terms cancel exactly, so the
 * fluid's momentum changes only by the walls' part, which the colliders get back. Implicit:
 * dv = dt a(u) - res, res = b - (I - dt A) dv the CG residual (up to cg_tolerance |b|), and
 * v = u + mean(res):
 * the residual's mean is taken out, so the momentum balances as well (with dv alone, the
 * fluid and a body lost 5e-4 of the momentum they exchanged at the default tolerance,
 * test_cy), while a stiff mode keeps the CG solution's small error (v = v** + dt a(u)
 * would multiply it by dt A). */
void stf_cy_viscosity_solve(stf_fluid *f, double dt)
{
    cy_state *c = f->cy;
    int n = f->n, N = 3 * n;
    viscosity_field(f, f->v);
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) viscous_one(f, f->v, i, 1, c->b);
    c->stats.viscosity_iterations = 0;
    c->stats.viscosity_residual = 0;
    memcpy(c->r, f->v, (size_t)N * sizeof *c->r); /* u = v** */
    if (f->def.cy.viscosity_solver == STF_VISCOSITY_EXPLICIT) {
#pragma omp parallel for schedule(static)
        for (int i = 0; i < N; i++) f->v[i] += dt * c->b[i];
        return;
    }
#pragma omp parallel for schedule(static)
    for (int i = 0; i < N; i++) c->b[i] *= dt;
    double bb = dot(c->b, c->b, N);
    if (bb > 0) {
        double *x = c->dv, *r = c->r, *p = c->p, *Ap = c->Ap;
        memcpy(x, c->b, (size_t)N * sizeof *x); /* start from the explicit step */
        apply_system(f, x, dt, Ap);
        for (int i = 0; i < N; i++) r[i] = c->b[i] - Ap[i];
        memcpy(p, r, (size_t)N * sizeof *p);
        double rr = dot(r, r, N), tol2 = f->def.cy.cg_tolerance * f->def.cy.cg_tolerance * bb;
        int it = 0;
        while (rr > tol2 && it < f->def.cy.max_cg_iterations) {
            apply_system(f, p, dt, Ap);
            double pAp = dot(p, Ap, N);
            if (!(pAp > 0)) break;
            double al = rr / pAp;
#pragma omp parallel for schedule(static)
            for (int i = 0; i < N; i++) {
                x[i] += al * p[i];
                r[i] -= al * Ap[i];
            }
            double rr2 = dot(r, r, N);
#pragma omp parallel for schedule(static)
            for (int i = 0; i < N; i++) p[i] = r[i] + rr2 / rr * p[i];
            rr = rr2;
            it++;
        }
        c->stats.viscosity_iterations = it;
        c->stats.viscosity_residual = sqrt(rr / bb);
        /* the true residual's mean (serial sums: any thread count), then u and v = u + mean */
        apply_system(f, x, dt, Ap);
        double mean[3] = {0, 0, 0};
        for (int i = 0; i < n; i++)
            for (int e = 0; e < 3; e++) mean[e] += c->b[3 * i + e] - Ap[3 * i + e];
        for (int e = 0; e < 3; e++) mean[e] /= n;
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++)
            for (int e = 3 * i; e < 3 * i + 3; e++) {
                r[e] = f->v[e] + x[e];
                f->v[e] = r[e] + mean[e - 3 * i];
            }
    }
}
