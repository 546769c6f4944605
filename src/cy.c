/* cy.c - Carreau-Yasuda non-Newtonian SPH with pressure projection and implicit viscosity
 * (the second paper: Zhang, Ban, Wang, Liu, "A Symmetry Particle Method towards Implicit
 * Non-Newtonian Fluids", Symmetry 9(2), 26, 2017: Eq. 3, 9-26, Algorithms 1 and 2).
 *
 * One step (Algorithm 2):
 *   1. neighbours (cy_neighbours; the shared grid if periodic), densities
 *      rho_i = sum_j m W_ij + walls (Eq. 6) and the per-particle factors S_i of Eq. 20-21;
 *   2. v* = v + dt g (Eq. 11);
 *   3. pressure projection (Algorithm 1): predicted densities rho*_i = rho_i + dt sum_j m
 *      (v_i - v_j).grad W_ij (Eq. 19), per-particle stiffness k_i from Eq. 21, velocity
 *      change -dt sum_j m (k_i/rho_i + k_j/rho_j) grad W_ij; repeated until the mean
 *      density error is below eta and at least min_pressure_iterations times -> v**;
 *   4. viscosity: strain rate D_i = L_i + L_i^T, L_i = (1/rho_i) sum_j m (v_j - v_i) (x)
 *      grad W_ij (Eq. 9, 22), nu_i = Carreau-Yasuda(g_i) (Eq. 3), g_i = sqrt(D_i:D_i / 2);
 *      viscous acceleration with the pair viscosity (see below); explicit (forward Euler)
 *      or implicit (backward Euler, nu frozen at its value from v**, solved matrix-free by
 *      conjugate gradients to |r| <= cg_tolerance |b|, Eq. 23-26);
 *   5. x += dt v; collisions with the shared collider stage; v from the position change.
 *
 * Choices where the text is garbled or silent (each one physically consistent):
 * - Eq. 20-21, the free surface, the projection's relaxation and warm start: see
 *   cy_pressure.c.
 * - Shear rate: sqrt(D:D / 2), which is |du/dy| in simple shear (the paper's Frobenius norm
 *   sqrt(D:D) is sqrt(2) larger, which only rescales K).
 * - Eq. 24 as printed drops mu_inf and the "1 +"; the implicit step here keeps the full
 *   Eq. 3 and linearises by freezing nu over the step (one Picard step).
 * - The viscous force is Morris et al.'s (1997) SPH Laplacian with the pair viscosity
 *   mu_i + mu_j (the usual generalised-Newtonian SPH form), not the divergence of the SPH
 *   stress of Eq. 10: that is a first derivative of a first derivative, blind to velocities
 *   alternating from particle to particle; with it, plane Poiseuille flow came out with
 *   layers alternating and 4x too fast (measured). Morris' operator is symmetric negative
 *   semi-definite (pair weights m (mu_i + mu_j) (r.grad W) / (rho_i rho_j (r^2 + 0.01 h^2))),
 *   so I - dt (viscous operator) is symmetric positive definite and CG applies. For the
 *   plane shear flows of the tests it is exact: div(mu grad v) = div(mu D) there.
 * - viscosity_form central replaces Morris' pair force by Monaghan's (1997, 2005) central one,
 *   a_i = sum_j (d + 2) m (mu_i + mu_j) / (rho_i rho_j) F_ij (x_ij . u_ij) x_ij / |x_ij|^2,
 *   F_ij = (x_ij . grad W_ij) / (|x_ij|^2 + 0.01 h^2), d = 3: Morris' weight, along x_ij. For
 *   uniform rho and nu that is 2 (d + 2) nu sum_j (m / rho) (u_ij . x_ij) grad W_ij /
 *   (|x_ij|^2 + 0.01 h^2), whose Taylor expansion is nu (lap u + 2 grad div u): nu lap u for
 *   divergence-free flow, as Morris' 2 nu sum_j (m / rho) F_ij u_ij (test_cy pins both
 *   constants with a sinusoidal shear). The pair forces lie along x_ij, so angular momentum is
 *   conserved and a rigid rotation feels none. The implicit operator's blocks are
 *   w_ij x_ij x_ij^T (still symmetric negative semi-definite: CG applies); a wall's lattice
 *   gives the 3 x 3 block sum_b over its mirror particles (tables by distance). Its fourth
 *   moment over the neighbours is not isotropic on the cubic lattice at h = 2 spacings: shear
 *   along the lattice axes sees 0.69 nu (0.93 at 3 spacings, as Morris at 4).
 * - cfl splits a step into CFL-limited substeps (cy_step).
 * - Walls: see cy_walls.c.
 */
#include "cy_internal.h"
#include "state.h"

#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ----------------------------------------------------------------------- parameters */

#define FAIL(...)                                                                             \
    do {                                                                                      \
        snprintf(err, errlen, __VA_ARGS__);                                                   \
        return -1;                                                                            \
    } while (0)

int cy_check_def(const stf_fluid_def *d, char *err, size_t errlen)
{
    const stf_cy_def *c = &d->cy;
    if (d->effects & ~(unsigned)STF_EFFECT_GRAVITY)
        FAIL("effects: the carreau_yasuda model runs gravity and its own solver only");
    if (!(c->mu0 >= 0 && isfinite(c->mu0))) FAIL("mu0: must be >= 0 (got %g)", c->mu0);
    if (!(c->mu_inf >= 0 && isfinite(c->mu_inf))) FAIL("mu_inf: must be >= 0 (got %g)", c->mu_inf);
    if (!(c->K >= 0 && isfinite(c->K))) FAIL("K: must be >= 0 (got %g)", c->K);
    if (!(c->alpha > 0 && isfinite(c->alpha))) FAIL("alpha: must be > 0 (got %g)", c->alpha);
    if (!(c->n > 0 && isfinite(c->n))) FAIL("n: must be > 0 (got %g)", c->n);
    if (!(c->eta > 0 && c->eta < 1)) FAIL("eta: must be in (0,1) (got %g)", c->eta);
    if (c->min_pressure_iterations < 1)
        FAIL("min_pressure_iterations: must be >= 1 (got %d)", c->min_pressure_iterations);
    if (c->max_pressure_iterations < c->min_pressure_iterations)
        FAIL("max_pressure_iterations: must be >= min_pressure_iterations (got %d)",
             c->max_pressure_iterations);
    if (c->viscosity_solver != STF_VISCOSITY_IMPLICIT && c->viscosity_solver != STF_VISCOSITY_EXPLICIT)
        FAIL("viscosity_solver: must be implicit or explicit (got %d)", c->viscosity_solver);
    if (c->viscosity_form != STF_VISCOSITY_MORRIS && c->viscosity_form != STF_VISCOSITY_CENTRAL)
        FAIL("viscosity_form: must be morris or central (got %d)", c->viscosity_form);
    if (!(c->cg_tolerance > 0 && c->cg_tolerance < 1))
        FAIL("cg_tolerance: must be in (0,1) (got %g)", c->cg_tolerance);
    if (c->max_cg_iterations < 1) FAIL("max_cg_iterations: must be >= 1 (got %d)", c->max_cg_iterations);
    if (!(c->warm_start >= 0 && c->warm_start <= 1))
        FAIL("warm_start: must be in [0,1] (got %g)", c->warm_start);
    if (!(c->relaxation >= 0 && c->relaxation <= 1))
        FAIL("relaxation: must be in (0,1], or 0 for 1 (got %g)", c->relaxation);
    if (!(c->dt_max >= 0 && isfinite(c->dt_max))) FAIL("dt_max: must be >= 0 s (got %g)", c->dt_max);
    if (c->dt_max > 0 && !(c->cfl > 0)) FAIL("dt_max: only with cfl");
    if (!(c->cfl >= 0 && c->cfl < 1)) FAIL("cfl: must be in (0,1), or 0 for off (got %g)", c->cfl);
    double h = d->h > 0 ? d->h : 2 * d->spacing;
    for (int a = 0; a < 3; a++) {
        if (!(d->periodic[a] >= 0 && isfinite(d->periodic[a])))
            FAIL("periodic: must be >= 0 (got %g)", d->periodic[a]);
        if (d->periodic[a] > 0 && d->periodic[a] < 3 * h)
            FAIL("periodic: a period must be >= 3 h = %g m (got %g)", 3 * h, d->periodic[a]);
        if (!isfinite(d->periodic_origin[a])) FAIL("periodic_origin: must be finite");
    }
    return 0;
}

double stf_cy_viscosity(const stf_cy_def *c, double g)
{
    /* Eq. 3 */
    double t = pow(c->K * g, c->alpha);
    return c->mu_inf + (c->mu0 - c->mu_inf) * pow(1.0 + t, (c->n - 1.0) / c->alpha);
}

/* ----------------------------------------------------------------------- creation */

int cy_create(stf_fluid *f)
{
    cy_state *c = calloc(1, sizeof *c);
    if (!c) return -1;
    cy_tables(f, c);
    f->cy = c;
    for (int a = 0; a < 3; a++) {
        f->grid.period[a] = f->def.periodic[a];
        f->grid.origin[a] = f->def.periodic_origin[a];
    }
    return 0;
}

void cy_free(stf_fluid *f)
{
    cy_state *c = f->cy;
    if (!c) return;
    void *arrays[] = {c->rho, c->S,   c->kappa,  c->ktot,   c->rhostar, c->gw,  c->qw,  c->wv,
                      c->nu,  c->b,   c->dv,     c->r,      c->p,       c->Ap,  c->kr,  c->irho,
                      c->mu,  c->lw,  c->lwv, c->lwm,    c->sx,     c->pair,    c->lap, c->off, c->cstart,
                      c->cellof, c->sid, c->nbt, c->nbc,    c->hit};
    for (size_t k = 0; k < sizeof arrays / sizeof *arrays; k++) free(arrays[k]);
    free(c);
    f->cy = NULL;
}

static int reserve(stf_fluid *f, int n)
{
    cy_state *c = f->cy;
    size_t N = (size_t)n;
    if (n <= c->cap) return 0;
    if (c->nbs == 0) c->nbs = 64;
    if (grow_i32(&c->off, N + 1) || grow_i32(&c->cellof, N) || grow_i32(&c->sid, N) ||
        grow_i32(&c->nbc, N) || grow_i32(&c->nbt, N * (size_t)c->nbs))
        return -1;
    if (grow(&c->sx, 3 * N) || grow(&c->kr, N) || grow(&c->irho, N) || grow(&c->mu, N) ||
        grow(&c->rho, N) || grow(&c->S, N) || grow(&c->kappa, N) || grow(&c->ktot, N) ||
        grow(&c->rhostar, N) || grow(&c->gw, 3 * N) || grow(&c->qw, N) || grow(&c->wv, 9 * N) ||
        grow(&c->nu, N) || grow(&c->b, 3 * N) || grow(&c->dv, 3 * N) || grow(&c->r, 3 * N) ||
        grow(&c->p, 3 * N) || grow(&c->Ap, 3 * N) || grow(&c->lw, N) || grow(&c->lwv, 3 * N) ||
        grow(&c->lwm, 9 * N))
        return -1;
    char *hit = realloc(c->hit, N);
    if (!hit) return -1;
    c->hit = hit;
    c->cap = n;
    return 0;
}
/* ------------------------------------------------------------------------ viscosity */

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
static void viscosity_solve(stf_fluid *f, double dt)
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


/* ------------------------------------------------------------------------- the step */

static void wrap_positions(stf_fluid *f)
{
    for (int a = 0; a < 3; a++) {
        double L = f->def.periodic[a], o = f->def.periodic_origin[a];
        if (!(L > 0)) continue;
        for (int i = 0; i < f->n; i++) {
            double s = L * floor((f->x[3 * i + a] - o) / L);
            f->x[3 * i + a] -= s;
            f->xprev[3 * i + a] -= s;
        }
    }
}

static int cy_substep(stf_fluid *f, double dt)
{
    cy_state *c = f->cy;
    int n = f->n;
    double t0 = omp_get_wtime();
    /* Particles are re-sorted along the Morton curve (memory locality) every
       reorder_interval substeps (with the shared grid of a periodic fluid: when its
       candidates are rebuilt anyway, at most that often, as in stf_fluid_step). */
    if (grid_due(&f->grid, f->x, n, f->h) && f->steps >= f->next_reorder) {
        if (grid_sort(&f->grid, f->x, n, f->h) != 0) goto oom;
        if (c->warm_n == n) { /* the warm start's pressures follow their particles */
            for (int i = 0; i < n; i++) c->kappa[i] = c->ktot[f->grid.order[i]];
            memcpy(c->ktot, c->kappa, (size_t)n * sizeof *c->ktot);
        }
        if (fluid_permute(f, f->grid.order) != 0) goto oom;
        f->next_reorder = f->steps + f->reorder_interval;
    }
    if (reserve(f, n) != 0) goto oom;
    int dense = is_periodic(f) ? 0 : cy_neighbours(f);
    if (dense < 0) goto oom;
    c->dense = dense;
    if (!dense && grid_build(&f->grid, f->x, n, f->h) != 0) goto oom;
    if (cy_pair_offsets(f) != 0) goto oom;
    f->stage_seconds[STAGE_GRID] += omp_get_wtime() - t0;
    t0 = omp_get_wtime();
    /* one pass: walls, density and S_i, the warm start's k_i, gravity (Eq. 11), and the
       positions at the substep's start (xprev) */
    double w = c->warm_n == n ? f->def.cy.warm_start : 0, g[3] = {0, 0, 0};
    if (has(f, STF_EFFECT_GRAVITY))
        for (int a = 0; a < 3; a++) g[a] = f->def.gravity[a];
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        cy_walls_one(f, i);
        cy_density_one(f, i);
        c->kappa[i] = w * c->ktot[i];
        c->kr[i] = c->kappa[i] * c->irho[i];
        c->ktot[i] = 0;
        for (int a = 0; a < 3; a++) {
            f->v[3 * i + a] += dt * g[a];
            f->xprev[3 * i + a] = f->x[3 * i + a];
        }
    }
    cy_pressure_project(f, dt, w);
    f->stage_seconds[STAGE_PRESSURE] += omp_get_wtime() - t0;
    /* positions are unchanged so far (xprev = x, set in the density pass): the checks look
       at the velocities */
    if (fluid_check(f, "carreau_yasuda pressure projection")) return -1;
    t0 = omp_get_wtime();
    viscosity_solve(f, dt);
    cy_wall_reactions(f, dt);
    f->stage_seconds[STAGE_VISCOSITY] += omp_get_wtime() - t0;
    if (fluid_check(f, f->def.cy.viscosity_solver == STF_VISCOSITY_EXPLICIT
                           ? "carreau_yasuda viscosity (explicit)"
                           : "carreau_yasuda viscosity (implicit)"))
        return -1;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < 3 * n; i++) f->x[i] += dt * f->v[i];
    t0 = omp_get_wtime();
    collide_all(f, dt);
#pragma omp parallel for schedule(static)
    for (int i = 0; i < 3 * n; i++) f->v[i] = (f->x[i] - f->xprev[i]) / dt;
    f->stage_seconds[STAGE_COLLIDE] += omp_get_wtime() - t0;
    if (fluid_check(f, "collisions")) return -1;
    wrap_positions(f);
    f->time += dt;
    f->steps++;
    return 0;
oom:
    snprintf(f->failure, sizeof f->failure, "step %ld (t = %.6g s): out of memory", f->steps + 1,
             f->time);
    return -1;
}

/* One coupled step of length dt: a single substep, or with cfl > 0 substeps of equal length
 * within dt whose count is set, at each substep's start, by the CFL condition
 * dt_sub <= min(dt_max, cfl h / v_max) on the remaining time (so the last one is not a
 * sliver). The
 * colliders' impulses add up over the substeps (they were cleared by stf_fluid_step). */
int cy_step(stf_fluid *f, double dt)
{
    cy_state *c = f->cy;
    stf_solver_stats *st = &c->stats;
    double cfl = f->def.cy.cfl, left = dt, t_end = f->time + dt;
    st->substeps = 0;
    st->dt_min = dt;
    st->dt_max = 0;
    st->cfl_number = 0;
    st->pressure_iterations_total = 0;
    st->density_error_sum = st->density_error_max = 0;
    st->pressure_iterations_max = st->viscosity_iterations_max = 0;
    st->viscosity_iterations_total = 0;
    while (left > 1e-9 * dt) {
        double sub = left, vmax = stf_fluid_max_speed(f);
        if (cfl > 0) {
            double most = f->def.cy.dt_max > 0 ? f->def.cy.dt_max : left;
            if (vmax * most > cfl * f->h) most = cfl * f->h / vmax;
            if (most < left) sub = left / ceil(left / most * (1 - 1e-12));
        }
        f->dt_now = sub;
        /* the shared grid's Verlet skin (periodic fluids): the default (0.25 h) when the
           lists can last two substeps or more; else they are rebuilt every substep anyway,
           and a thin skin (0.02 h) halves the candidates to search and filter */
        f->grid.skin = 4 * vmax * sub > 0.25 * f->h ? 0.02 : 0;
        if (cy_substep(f, sub) != 0) return -1;
        st->substeps++;
        st->dt_min = sub < st->dt_min ? sub : st->dt_min;
        st->dt_max = sub > st->dt_max ? sub : st->dt_max;
        double cn = vmax * sub / f->h;
        st->cfl_number = cn > st->cfl_number ? cn : st->cfl_number;
        st->pressure_iterations_total += st->pressure_iterations;
        st->viscosity_iterations_total += st->viscosity_iterations;
        if (st->pressure_iterations > st->pressure_iterations_max)
            st->pressure_iterations_max = st->pressure_iterations;
        if (st->viscosity_iterations > st->viscosity_iterations_max)
            st->viscosity_iterations_max = st->viscosity_iterations;
        st->density_error_sum += st->density_error;
        st->density_error_max = st->density_error > st->density_error_max ? st->density_error
                                                                          : st->density_error_max;
        left -= sub;
    }
    f->time = t_end; /* no round-off drift from the substeps */
    f->dt_now = dt;
    return 0;
}

/* -------------------------------------------------------------------------- access */

void stf_fluid_solver_stats(const stf_fluid *f, stf_solver_stats *st)
{
    if (f->cy) *st = f->cy->stats;
    else memset(st, 0, sizeof *st);
}

void stf_fluid_get_pressures(const stf_fluid *f, double *p)
{
    const cy_state *c = f->cy;
    for (int i = 0; i < f->n; i++)
        p[i] = c && i < c->cap && f->steps > 0 ? c->ktot[i] * c->rho[i] : 0.0;
}

double stf_fluid_cy_rest_density(const stf_fluid *f) { return f->cy ? f->cy->rho0 : 0.0; }

int cy_describe(const stf_fluid *f, char *buf, size_t len)
{
    const stf_cy_def *c = &f->def.cy;
    const double *per = f->def.periodic, *o = f->def.periodic_origin;
    int k = snprintf(buf, len,
                     "periodic: [%.9g, %.9g, %.9g]  # m, the period of each axis (0: none)\n"
                     "periodic_origin: [%.9g, %.9g, %.9g]  # m\n",
                     per[0], per[1], per[2], o[0], o[1], o[2]);
    size_t used = k > 0 && (size_t)k < len ? (size_t)k : len;
    return k + snprintf(buf + used, len - used,
                    "model: carreau_yasuda\nmu0: %.9g  # m^2/s\nmu_inf: %.9g  # m^2/s\n"
                    "K: %.9g  # s\nalpha: %.9g\nn: %.9g\neta: %.9g\n"
                    "min_pressure_iterations: %d\nmax_pressure_iterations: %d\n"
                    "viscosity_solver: %s\nviscosity_form: %s\ncg_tolerance: %.9g\n"
                    "max_cg_iterations: %d\n"
                    "cfl: %.9g\ndt_max: %.9g  # s\nwarm_start: %.9g\nrelaxation: %.9g\n"
                    "rest_density_cy: %.9g  # kg/m^3, kernel sum of the lattice\n",
                    c->mu0, c->mu_inf, c->K, c->alpha, c->n, c->eta, c->min_pressure_iterations,
                    c->max_pressure_iterations,
                    c->viscosity_solver == STF_VISCOSITY_EXPLICIT ? "explicit" : "implicit",
                    c->viscosity_form == STF_VISCOSITY_CENTRAL ? "central" : "morris",
                    c->cg_tolerance, c->max_cg_iterations, c->cfl, c->dt_max, c->warm_start,
                    c->relaxation > 0 ? c->relaxation : 1.0, f->cy ? f->cy->rho0 : 0.0);
}

/* ---------------------------------------------------------------------- checkpoints */

/* The warm start's pressures (ktot) and densities carry over steps; everything else is
 * recomputed by each substep before it is read. */
int cy_save_state(const stf_fluid *f, stf_state *s)
{
    const cy_state *c = f->cy;
    int n = c->cap >= f->n ? f->n : 0; /* no array before the first step */
    stf_state_put_i64(s, "cy.warm_n", c->warm_n);
    stf_state_put_i64(s, "cy.n", n);
    if (n) {
        stf_state_put(s, "cy.ktot", STF_STATE_F64, (size_t)n, c->ktot);
        stf_state_put(s, "cy.rho", STF_STATE_F64, (size_t)n, c->rho);
    }
    return s->failed ? -1 : 0;
}

int cy_load_state(stf_fluid *f, const stf_state *s, char *err, size_t errlen)
{
    cy_state *c = f->cy;
    int64_t warm_n, n;
    if (stf_state_get_i64(s, "cy.warm_n", &warm_n, err, errlen) ||
        stf_state_get_i64(s, "cy.n", &n, err, errlen))
        return -1;
    if ((n != 0 && n != f->n) || (warm_n != 0 && warm_n != f->n)) {
        snprintf(err, errlen, "checkpoint: %s %ld does not match %d particles",
                 n != 0 && n != f->n ? "cy.n" : "cy.warm_n",
                 (long)(n != 0 && n != f->n ? n : warm_n), f->n);
        return -1;
    }
    c->warm_n = (int)warm_n;
    if (n == 0) return 0;
    if (reserve(f, f->n) != 0) {
        snprintf(err, errlen, "checkpoint: out of memory");
        return -1;
    }
    if (stf_state_get(s, "cy.ktot", STF_STATE_F64, (size_t)n, c->ktot, err, errlen) ||
        stf_state_get(s, "cy.rho", STF_STATE_F64, (size_t)n, c->rho, err, errlen))
        return -1;
    /* a damaged file: pressures (sums of k_i >= 0) and densities as a step leaves them */
    for (int i = 0; i < (int)n; i++)
        if (!(c->ktot[i] >= 0 && isfinite(c->ktot[i])) || !(c->rho[i] > 0 && isfinite(c->rho[i]))) {
            snprintf(err, errlen, "checkpoint: %s[%d] is out of range",
                     !(c->ktot[i] >= 0 && isfinite(c->ktot[i])) ? "cy.ktot" : "cy.rho", i);
            return -1;
        }
    return 0;
}
