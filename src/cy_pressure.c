/* cy_pressure.c - the pressure projection of the second paper's Algorithm 1 (step 3 of
 * Algorithm 2): the predicted density rho*_i of Eq. 19 from the velocities, the per-particle
 * stiffness k_i of Eq. 21 from it (with S_i of Eq. 20-21, cy_density.c), the velocity change
 * -dt sum_j m (k_i/rho_i + k_j/rho_j) grad W_ij (+ the walls, cy_walls.c), repeated until the
 * mean density error is below eta (at least min_pressure_iterations times). Where the paper is
 * garbled or silent:
 *
 * Eq. 20-21 as printed have k_i = (rho0 - rho*)/(dt^2 alpha_i), alpha_i = rho_i (...);
 * dimensions and the sign of Eq. 20 give k_i = (rho*_i - rho0) rho_i / (dt^2 S_i) with
 * S_i = |sum_j m grad W_ij|^2 + sum_j |m grad W_ij|^2: k_i is then p_i / rho_i (m^2/s^2), the
 * velocity update of Algorithm 1 is the symmetric SPH pressure force, and the pressure of
 * a particle is rho_i times the sum of its k_i over the iterations.
 *
 * Free surface: only compression is corrected (rho* below rho0 counts as rho0), so the
 * projection never pulls particles together; the density error is the mean compression.
 *
 * The projection is Jacobi with the full k_i of Eq. 21 (no relaxation), from zero
 * pressure each step, as Algorithm 1, unless the scene asks for relaxation and warm_start
 * (see stf_cy_pressure_project). */
#include "cy_internal.h"

/* rho*_i (Eq. 19) from the velocities v. */
static double predict_one(const stf_fluid *f, const double *v, int i, double dt)
{
    const cy_state *c = f->cy;
    double d0 = 0, d1 = 0, d2 = 0, m = f->mass;
    const cy_pair *pr = c->pair + c->off[i], *end = c->pair + c->off[i + 1];
    const double *vi = v + 3 * i;
    for (; pr < end; pr++) {
        const double *vj = v + 3 * pr->j;
        d0 += (vi[0] - vj[0]) * pr->g[0];
        d1 += (vi[1] - vj[1]) * pr->g[1];
        d2 += (vi[2] - vj[2]) * pr->g[2];
    }
    const double *G = c->gw + 3 * i;
    double div = m * (d0 + d1 + d2) + vi[0] * G[0] + vi[1] * G[1] + vi[2] * G[2] - c->qw[i];
    return c->rho[i] + dt * div;
}

/* rho*_i from v, and the next iteration's k_i from it (Eq. 21; only compression is
 * corrected, scaled by the relaxation omega), with kappa_i / rho_i. */
static void predict_kappa_one(const stf_fluid *f, const double *v, int i, double dt, double omega)
{
    cy_state *c = f->cy;
    double rs = predict_one(f, v, i, dt);
    c->rhostar[i] = rs;
    double k = c->S[i] > 0 ? (rs - c->rho0) * c->rho[i] / (dt * dt * c->S[i]) : 0;
    c->kappa[i] = k > 0 ? omega * k : 0;
    c->kr[i] = c->kappa[i] * c->irho[i];
}

/* Algorithm 1's last loop for the current kappa: v_i += -dt sum_j m (k_i/rho_i + k_j/rho_j)
 * grad W_ij (+ the walls), and the particle's total. Only kappa / rho of the neighbours is
 * read, so v_i is updated in place. */
static void pressure_dv_one(stf_fluid *f, int i, double dt)
{
    cy_state *c = f->cy;
    double m = f->mass, ki = c->kr[i], d[3] = {0, 0, 0};
    const cy_pair *pr = c->pair + c->off[i], *end = c->pair + c->off[i + 1];
    const double *kr = c->kr;
    for (; pr < end; pr++) {
        double w = ki + kr[pr->j];
        d[0] += w * pr->g[0];
        d[1] += w * pr->g[1];
        d[2] += w * pr->g[2];
    }
    for (int a = 0; a < 3; a++) f->v[3 * i + a] -= dt * (m * d[a] + ki * c->gw[3 * i + a]);
    c->ktot[i] += c->kappa[i];
}

static double mean_error(const stf_fluid *f)
{
    const cy_state *c = f->cy;
    double sum = 0; /* serial: the same result for any thread count */
    for (int i = 0; i < f->n; i++) sum += c->rhostar[i] > c->rho0 ? c->rhostar[i] - c->rho0 : 0;
    return f->n > 0 ? sum / f->n / c->rho0 : 0;
}

/* Algorithm 1: k_i from Eq. 21 for every particle (Jacobi), applied together, until the mean
 * compression is below eta and at least min_pressure_iterations were done. The paper starts
 * each step from zero pressure. With warm_start w > 0 the step first applies w times the
 * last step's total (a pressure: ktot does not depend on dt, so it carries over a change of
 * substep length), then the iterations only add pressure where there is compression, as
 * from zero. The part not carried (1 - w) keeps an over-pressure from persisting; letting
 * the iterations lower the pressure instead was tried earlier and made a fluid at rest
 * unstable within 0.4 s. relaxation (omega) scales each iteration's k_i: Jacobi with the full
 * k_i overshoots where the neighbours are compressed too (their corrections add to the
 * particle's own), and an overshoot becomes expansion that is not corrected (no tension) and
 * falls back as a harder compression: at dt = 5 ms the 1 m dam break column blew up from its
 * floor layer with omega = 1 and ran with omega = 0.5 and warm_start 0.5 (measured).
 * kappa, kr and ktot were set by the density pass (the warm start, or zero). Each iteration
 * is two neighbour passes: the velocity change, then rho* with the next k_i. */
void stf_cy_pressure_project(stf_fluid *f, double dt, double w)
{
    cy_state *c = f->cy;
    int n = f->n, iter = 0;
    double err, omega = f->def.cy.relaxation > 0 ? f->def.cy.relaxation : 1.0;
    if (w > 0) {
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++) pressure_dv_one(f, i, dt);
    }
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) predict_kappa_one(f, f->v, i, dt, omega);
    do {
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++) pressure_dv_one(f, i, dt);
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++) predict_kappa_one(f, f->v, i, dt, omega);
        err = mean_error(f);
        iter++;
    } while ((err > f->def.cy.eta || iter < f->def.cy.min_pressure_iterations) &&
             iter < f->def.cy.max_pressure_iterations);
    c->warm_n = n;
    c->stats.pressure_iterations = iter;
    c->stats.density_error = err;
}
