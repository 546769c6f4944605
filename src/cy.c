/* cy.c - Carreau-Yasuda non-Newtonian SPH with pressure projection and implicit viscosity
 * (the second paper: Zhang, Ban, Wang, Liu, "A Symmetry Particle Method towards Implicit
 * Non-Newtonian Fluids", Symmetry 9(2), 26, 2017: Eq. 3, 9-26, Algorithms 1 and 2).
 *
 * This file: the model's set-up (its parameters, the solver's arrays), one step of
 * Algorithm 2 (cy_substep) and the CFL substeps of a coupled step (stf_cy_step), the solver's
 * statistics, its effective parameters and its checkpoints. The stages of a step, each in
 * its own file (the solver's state is in cy_internal.h):
 *   1. neighbours (stf_cy_neighbours.c; the shared grid if periodic), densities
 *      rho_i = sum_j m W_ij + walls (Eq. 6) and the per-particle factors S_i of Eq. 20-21
 *      (cy_density.c; the walls' part, cy_walls.c);
 *   2. v* = v + dt g (Eq. 11; here, in the same pass);
 *   3. pressure projection (Algorithm 1, cy_pressure.c): predicted densities rho*_i = rho_i
 *      + dt sum_j m (v_i - v_j).grad W_ij (Eq. 19), per-particle stiffness k_i from Eq. 21,
 *      velocity change -dt sum_j m (k_i/rho_i + k_j/rho_j) grad W_ij; repeated until the mean
 *      density error is below eta and at least min_pressure_iterations times -> v**;
 *   4. viscosity (cy_viscosity.c): strain rate D_i = L_i + L_i^T, L_i = (1/rho_i) sum_j m
 *      (v_j - v_i) (x) grad W_ij (Eq. 9, 22), nu_i = Carreau-Yasuda(g_i) (Eq. 3),
 *      g_i = sqrt(D_i:D_i / 2); viscous acceleration with the pair viscosity; explicit
 *      (forward Euler) or implicit (backward Euler, nu frozen at its value from v**, solved
 *      matrix-free by conjugate gradients to |r| <= cg_tolerance |b|, Eq. 23-26); the walls'
 *      impulses back to the colliders (cy_walls.c);
 *   5. x += dt v; collisions with the shared collider stage; v from the position change.
 *
 * Choices where the text is garbled or silent (each one physically consistent) are explained
 * in the file that makes them:
 * - Eq. 20-21, the free surface, the projection's relaxation and warm start: cy_pressure.c;
 * - the shear rate, Eq. 24, the viscous force (Morris' Laplacian, not Eq. 10) and its
 *   central form: cy_viscosity.c;
 * - walls as half-spaces of lattice particles, not boundary particles: cy_walls.c;
 * - the neighbour search: stf_cy_neighbours.c;
 * - here: cfl splits a step into CFL-limited substeps (stf_cy_step).
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

int stf_cy_check_def(const stf_fluid_def *d, char *err, size_t errlen)
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
    if (c->pressure_solver != STF_PRESSURE_JACOBI && c->pressure_solver != STF_PRESSURE_CG)
        FAIL("pressure_solver: must be jacobi or cg (got %d)", c->pressure_solver);
    if (c->wall_pressure < STF_WALL_PRESSURE_OWN || c->wall_pressure > STF_WALL_PRESSURE_HYDROSTATIC)
        FAIL("wall_pressure: must be own, mirror or hydrostatic (got %d)", c->wall_pressure);
    if (c->pressure_gradient < STF_PRESSURE_GRADIENT_SYMMETRIC || c->pressure_gradient > STF_PRESSURE_GRADIENT_OFFSET)
        FAIL("pressure_gradient: must be symmetric, local_minimum or offset (got %d)", c->pressure_gradient);
    if (c->pressure_gradient != STF_PRESSURE_GRADIENT_SYMMETRIC && c->pressure_solver != STF_PRESSURE_JACOBI)
        FAIL("pressure_gradient: %s needs pressure_solver jacobi (conjugate gradients need the "
             "symmetric form's symmetric matrix)", stf_pressure_gradient_name(c->pressure_gradient));
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

/* ----------------------------------------------------------------------- creation */

int stf_cy_create(stf_fluid *f)
{
    cy_state *c = calloc(1, sizeof *c);
    if (!c) return -1;
    stf_cy_tables(f, c);
    c->mirror = f->def.cy.wall_pressure == STF_WALL_PRESSURE_OWN ? 1.0 : 2.0;
    c->hydro = f->def.cy.wall_pressure == STF_WALL_PRESSURE_HYDROSTATIC;
    c->wall_div = f->def.cy.pressure_gradient == STF_PRESSURE_GRADIENT_OFFSET ? 2.0 : c->mirror;
    /* The mirrored wall's pressure holds the fluid at half a spacing under any head (its
       lattice's first layer is there), so the collision stage is a backstop inside that: at
       half a spacing too it would stop every particle the pressure brings to the wall,
       carrying that pressure as one-sided contacts that brake a moving body (a sphere of 2
       spacings at density ratio 2, 10 cm deep: 1.4 rho V g on its contacts, sinking at 7
       mm/s; 0 and 18-35 mm/s with the contacts at 0.3 spacings; tests/README.md). The own
       wall holds nothing by itself: its contacts stay at half a spacing, bodies' too (at a
       quarter spacing a held sphere of 2 spacings felt 0.70 rho V g). */
    f->contact = f->contact_body = (c->mirror > 1 ? 0.3 : 0.5) * f->def.spacing;
    f->cy = c;
    for (int a = 0; a < 3; a++) {
        f->grid.period[a] = f->def.periodic[a];
        f->grid.origin[a] = f->def.periodic_origin[a];
    }
    return 0;
}

void stf_cy_free(stf_fluid *f)
{
    cy_state *c = f->cy;
    if (!c) return;
    void *arrays[] = {c->rho, c->S,   c->kappa,  c->ktot,   c->rhostar, c->gw,  c->qw,  c->wv,
                      c->nu,  c->b,   c->dv,     c->r,      c->p,       c->Ap,  c->kr,  c->irho,
                      c->mu,  c->lw,  c->lwv, c->lwm, c->hw,    c->sx,     c->pair,    c->lap, c->off, c->cstart,
                      c->cellof, c->sid, c->nbt, c->nbc,    c->hit, c->wlist};
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
        grow_i32(&c->wlist, N) || grow_i32(&c->nbc, N) || grow_i32(&c->nbt, N * (size_t)c->nbs))
        return -1;
    if (grow(&c->sx, 3 * N) || grow(&c->kr, N) || grow(&c->irho, N) || grow(&c->mu, N) ||
        grow(&c->rho, N) || grow(&c->S, N) || grow(&c->kappa, N) || grow(&c->ktot, N) ||
        grow(&c->rhostar, N) || grow(&c->gw, 3 * N) || grow(&c->qw, N) || grow(&c->wv, 9 * N) ||
        grow(&c->nu, N) || grow(&c->b, 3 * N) || grow(&c->dv, 3 * N) || grow(&c->r, 3 * N) ||
        grow(&c->p, 3 * N) || grow(&c->Ap, 3 * N) || grow(&c->lw, N) || grow(&c->lwv, 3 * N) ||
        grow(&c->lwm, 9 * N) || grow(&c->hw, 3 * N))
        return -1;
    char *hit = realloc(c->hit, N);
    if (!hit) return -1;
    c->hit = hit;
    c->cap = n;
    return 0;
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

/* The walls' terms, the density and S_i of particle i, and its warm start: w times the last
 * step's pressure. */
static void density_one(stf_fluid *f, int i, double w)
{
    cy_state *c = f->cy;
    stf_cy_walls_one(f, i);
    stf_cy_density_one(f, i);
    c->kappa[i] = w * c->ktot[i];
    c->kr[i] = c->kappa[i] * c->irho[i];
    c->ktot[i] = 0;
}

/* Algorithm 1 with the scene's solver. */
static void project(stf_fluid *f, double dt, double w)
{
    if (f->def.cy.pressure_solver == STF_PRESSURE_CG) stf_cy_pressure_project_cg(f, dt, w);
    else stf_cy_pressure_project(f, dt, w);
}

static int cy_substep(stf_fluid *f, double dt)
{
    cy_state *c = f->cy;
    int n = f->n;
    double t0 = omp_get_wtime();
    /* Particles are re-sorted along the Morton curve (memory locality) every
       reorder_interval substeps (with the shared grid of a periodic fluid: when its
       candidates are rebuilt anyway, at most that often, as in stf_fluid_step). */
    if (stf_grid_due(&f->grid, f->x, n, f->h) && f->steps >= f->next_reorder) {
        if (stf_grid_sort(&f->grid, f->x, n, f->h) != 0) goto oom;
        if (c->warm_n == n) { /* the warm start's pressures follow their particles */
            for (int i = 0; i < n; i++) c->kappa[i] = c->ktot[f->grid.order[i]];
            memcpy(c->ktot, c->kappa, (size_t)n * sizeof *c->ktot);
        }
        if (stf_fluid_permute(f, f->grid.order) != 0) goto oom;
        f->next_reorder = f->steps + f->reorder_interval;
    }
    if (reserve(f, n) != 0) goto oom;
    int dense = is_periodic(f) ? 0 : stf_cy_neighbours(f);
    if (dense < 0) goto oom;
    c->dense = dense;
    if (!dense && stf_grid_build(&f->grid, f->x, n, f->h) != 0) goto oom;
    if (stf_cy_pair_offsets(f) != 0) goto oom;
    f->stage_seconds[STAGE_GRID] += omp_get_wtime() - t0;
    t0 = omp_get_wtime();
    /* one pass: walls, density and S_i, the warm start's k_i, gravity (Eq. 11), and the
       positions at the substep's start (xprev) */
    double w = c->warm_n == n ? f->def.cy.warm_start : 0, g[3] = {0, 0, 0};
    stf_cy_sphere_tables(f);
    if (has(f, STF_EFFECT_GRAVITY))
        for (int a = 0; a < 3; a++) g[a] = f->def.gravity[a];
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        density_one(f, i, w);
        for (int a = 0; a < 3; a++) {
            f->v[3 * i + a] += dt * (g[a] + c->hw[3 * i + a]);
            f->xprev[3 * i + a] = f->x[3 * i + a];
        }
    }
    project(f, dt, w);
    f->stage_seconds[STAGE_PRESSURE] += omp_get_wtime() - t0;
    /* positions are unchanged so far (xprev = x, set in the density pass): the checks look
       at the velocities */
    if (stf_fluid_check(f, "carreau_yasuda pressure projection")) return -1;
    t0 = omp_get_wtime();
    stf_cy_viscosity_solve(f, dt);
    stf_cy_wall_reactions(f, dt, 1);
    f->stage_seconds[STAGE_VISCOSITY] += omp_get_wtime() - t0;
    if (stf_fluid_check(f, f->def.cy.viscosity_solver == STF_VISCOSITY_EXPLICIT
                           ? "carreau_yasuda viscosity (explicit)"
                           : "carreau_yasuda viscosity (implicit)"))
        return -1;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < 3 * n; i++) f->x[i] += dt * f->v[i];
    t0 = omp_get_wtime();
    stf_collide_all(f, dt);
#pragma omp parallel for schedule(static)
    for (int i = 0; i < 3 * n; i++) f->v[i] = (f->x[i] - f->xprev[i]) / dt;
    f->stage_seconds[STAGE_COLLIDE] += omp_get_wtime() - t0;
    if (stf_fluid_check(f, "collisions")) return -1;
    wrap_positions(f);
    f->time += dt;
    f->steps++;
    return 0;
oom:
    snprintf(f->failure, sizeof f->failure, "step %ld (t = %.6g s): out of memory", f->steps + 1,
             f->time);
    return -1;
}

/* The Clavet model's pressure stage as a projection (ours; cy.h). The Clavet pipeline has
 * predicted x = xprev + dt v and moved it by the springs; the projection wants the density at
 * the step's start and the velocity that leads to the prediction, so the positions go back to
 * xprev with v = (x - xprev) / dt, Algorithm 1 corrects v (from the last step's pressure
 * times warm_start, or zero), and the positions follow v again. The walls' impulses go to the
 * colliders. What follows in the Clavet step (collisions, boundary stick) acts on the
 * projected positions. */
int stf_cy_pressure_stage(stf_fluid *f, double dt)
{
    cy_state *c = f->cy;
    int n = f->n;
    if (reserve(f, n) != 0) return -1;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < 3 * n; i++) {
        f->v[i] = (f->x[i] - f->xprev[i]) / dt;
        f->x[i] = f->xprev[i];
    }
    /* the shared grid was built at xprev this step: its lists serve when the dense grid
       does not fit */
    int dense = stf_cy_neighbours(f);
    if (dense < 0) return -1;
    c->dense = dense;
    if (stf_cy_pair_offsets(f) != 0) return -1;
    double w = c->warm_n == n ? f->def.cy.warm_start : 0;
    stf_cy_sphere_tables(f);
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        density_one(f, i, w);
        for (int a = 0; a < 3; a++) f->v[3 * i + a] += dt * c->hw[3 * i + a];
    }
    project(f, dt, w);
    stf_cy_wall_reactions(f, dt, 0);
    c->stats.substeps = 1;
    c->stats.dt_min = c->stats.dt_max = dt;
    c->stats.pressure_iterations_total = c->stats.pressure_iterations_max =
        c->stats.pressure_iterations;
    c->stats.density_error_sum = c->stats.density_error_max = c->stats.density_error;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < 3 * n; i++) f->x[i] = f->xprev[i] + dt * f->v[i];
    return 0;
}

void stf_cy_follow_order(stf_fluid *f, const int32_t *perm)
{
    cy_state *c = f->cy;
    if (!c || c->warm_n != f->n) return;
    for (int i = 0; i < f->n; i++) c->kappa[i] = c->ktot[perm[i]];
    memcpy(c->ktot, c->kappa, (size_t)f->n * sizeof *c->ktot);
}

/* One coupled step of length dt: a single substep, or with cfl > 0 substeps of equal length
 * within dt whose count is set, at each substep's start, by the CFL condition
 * dt_sub <= min(dt_max, cfl h / v_max) on the remaining time (so the last one is not a
 * sliver). The colliders' impulses add up over the substeps (they were cleared by
 * stf_fluid_step), the statistics too (stf_solver_stats_merge, as stf_sim_step adds up the
 * fluid steps of a split coupled step). */
int stf_cy_step(stf_fluid *f, double dt)
{
    cy_state *c = f->cy;
    stf_solver_stats *st = &c->stats;
    double cfl = f->def.cy.cfl, left = dt, t_end = f->time + dt;
    /* no substep yet: the first merge takes the first substep's statistics as they are */
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
        /* the substep's statistics (its own fields as the stages left them in st) */
        stf_solver_stats one = *st;
        one.substeps = 1;
        one.dt_min = one.dt_max = sub;
        one.cfl_number = vmax * sub / f->h;
        one.pressure_iterations_total = one.pressure_iterations_max = st->pressure_iterations;
        one.viscosity_iterations_total = one.viscosity_iterations_max = st->viscosity_iterations;
        one.density_error_sum = one.density_error_max = st->density_error;
        stf_solver_stats_merge(st, &one);
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

/* The one merge of substep statistics: stf_cy_step adds each CFL substep to the step's, and
 * stf_sim_step (../ode_glue/stf_sim.c) each fluid step to the coupled step's. */
void stf_solver_stats_merge(stf_solver_stats *acc, const stf_solver_stats *part)
{
    if (acc->substeps == 0) { /* empty */
        *acc = *part;
        return;
    }
    stf_solver_stats sum = *part; /* the last substep's own fields, and the sums: */
    sum.substeps += acc->substeps;
    sum.pressure_iterations_total += acc->pressure_iterations_total;
    sum.viscosity_iterations_total += acc->viscosity_iterations_total;
    sum.density_error_sum += acc->density_error_sum;
#define STF_MAXF(F) sum.F = acc->F > sum.F ? acc->F : sum.F
    STF_MAXF(density_error_max);
    STF_MAXF(pressure_iterations_max);
    STF_MAXF(viscosity_iterations_max);
    STF_MAXF(cfl_number);
    STF_MAXF(dt_max);
#undef STF_MAXF
    sum.dt_min = acc->dt_min < sum.dt_min ? acc->dt_min : sum.dt_min;
    *acc = sum;
}

void stf_fluid_get_pressures(const stf_fluid *f, double *p)
{
    const cy_state *c = f->cy;
    for (int i = 0; i < f->n; i++)
        p[i] = c && i < c->cap && f->steps > 0 ? c->ktot[i] * c->rho[i] : 0.0;
}

double stf_fluid_cy_rest_density(const stf_fluid *f) { return f->cy ? f->cy->rho0 : 0.0; }

int stf_cy_describe(const stf_fluid *f, char *buf, size_t len)
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
                    "pressure_solver: %s\nwall_pressure: %s\npressure_gradient: %s\nviscosity_solver: %s\n"
                    "viscosity_form: %s\ncg_tolerance: %.9g\n"
                    "max_cg_iterations: %d\n"
                    "cfl: %.9g\ndt_max: %.9g  # s\nwarm_start: %.9g\nrelaxation: %.9g\n"
                    "rest_density_cy: %.9g  # kg/m^3, kernel sum of the lattice\n",
                    c->mu0, c->mu_inf, c->K, c->alpha, c->n, c->eta, c->min_pressure_iterations,
                    c->max_pressure_iterations,
                    stf_pressure_solver_name(c->pressure_solver),
                    stf_wall_pressure_name(c->wall_pressure),
                    stf_pressure_gradient_name(c->pressure_gradient),
                    c->viscosity_solver == STF_VISCOSITY_EXPLICIT ? "explicit" : "implicit",
                    c->viscosity_form == STF_VISCOSITY_CENTRAL ? "central" : "morris",
                    c->cg_tolerance, c->max_cg_iterations, c->cfl, c->dt_max, c->warm_start,
                    c->relaxation > 0 ? c->relaxation : 1.0, f->cy ? f->cy->rho0 : 0.0);
}

/* ---------------------------------------------------------------------- checkpoints */

/* The warm start's pressures (ktot) and densities carry over steps; everything else is
 * recomputed by each substep before it is read. */
int stf_cy_save_state(const stf_fluid *f, stf_state *s)
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

int stf_cy_load_state(stf_fluid *f, const stf_state *s, char *err, size_t errlen)
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
