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
 * (see stf_cy_pressure_project), or for conjugate gradients (pressure_solver cg, ours: see
 * stf_cy_pressure_project_cg, below). With pressure_gradient local_minimum (ours) the
 * particles feel the pressures offset by their neighbourhood's least (grad_min_at). */
#include "cy_internal.h"

#include <math.h>
#include <string.h>

/* u = (G y)_i: the velocity change -dt u of the pressures y = k / rho at particle i (Algorithm
 * 1's last loop; the conjugate gradients below). */
static void grad_at(const stf_fluid *f, const double *y, int i, double u[3])
{
    const cy_state *c = f->cy;
    double m = f->mass, yi = y[i], d[3] = {0, 0, 0};
    const cy_pair *pr = c->pair + c->off[i], *end = c->pair + c->off[i + 1];
    for (; pr < end; pr++) {
        double w = yi + y[pr->j];
        d[0] += w * pr->g[0];
        d[1] += w * pr->g[1];
        d[2] += w * pr->g[2];
    }
    for (int a = 0; a < 3; a++) u[a] = m * d[a] + c->mirror * yi * c->gw[3 * i + a];
}

/* The same with the pressures offset by the least of particle i's and its neighbours'
 * (pressure_gradient local_minimum, ours): u = sum_j m (y_j - y_min) grad W_ij. Every pair
 * still pushes apart (y_j >= y_min), as in the moving particle semi-implicit method's gradient
 * (Koshizuka and Oka 1996), but a pressure that is uniform over the neighbourhood pushes no
 * particle. In the symmetric form, y sum_j m grad W_ij of an irregular neighbourhood is a
 * restoring force proportional to the absolute pressure: it resists every rearrangement of
 * the packing, as a granular medium's friction grows with its confining pressure, and it held
 * a sphere 10 cm deep in a thin oil (tests/README.md, "A denser sphere in a thin fluid").
 * Within h of a wall (G_w,i not zero) the particle keeps the symmetric form: there the
 * absolute pressure is what the wall and the particle exchange, equal and opposite, so a body
 * feels its buoyancy as with the symmetric form (with the offset form at the walls too, the
 * walls' reactions of the absolute pressure no longer matched where the particles sit: a held
 * sphere of 2 spacings 10 cm deep felt 0.83 rho V g). Not linear in y: the Jacobi projection
 * re-applies the whole pressure each iteration (apply_kappa).
 *
 * pressure_gradient offset (ours): the offset form at the walls too, the walls' sites carrying
 * y_i - y_min (their hydrostatic difference is the fixed push c->hw). The packing around a body
 * is then free of the absolute pressure as well: with the symmetric form there, a sphere moving
 * at 10 mm/s in a thin oil felt a resistance that grew with its depth and with the distance it
 * had moved, not with its speed (a granular packing's friction, tests/README.md, "Moving
 * through a deep fluid"). Bodies then take their pressure force from the fluid's pressure on
 * their surface (cy_walls.c, surface_pressure), not from the particles' wall terms. */
static void grad_min_at(const stf_fluid *f, const double *y, int i, double u[3])
{
    const cy_state *c = f->cy;
    const double *G = c->gw + 3 * i;
    int walls = G[0] != 0 || G[1] != 0 || G[2] != 0;
    if (walls && f->def.cy.pressure_gradient != STF_PRESSURE_GRADIENT_OFFSET) {
        grad_at(f, y, i, u);
        return;
    }
    double lo = y[i], d[3] = {0, 0, 0}, gs[3] = {0, 0, 0};
    const cy_pair *pr = c->pair + c->off[i], *end = c->pair + c->off[i + 1];
    for (; pr < end; pr++) {
        double yj = y[pr->j];
        lo = yj < lo ? yj : lo;
        d[0] += yj * pr->g[0], d[1] += yj * pr->g[1], d[2] += yj * pr->g[2];
        gs[0] += pr->g[0], gs[1] += pr->g[1], gs[2] += pr->g[2];
    }
    for (int a = 0; a < 3; a++) u[a] = f->mass * (d[a] - lo * gs[a]) + c->mirror * (y[i] - lo) * G[a];
}

static void grad_one(const stf_fluid *f, const double *y, double *u, int i)
{
    grad_at(f, y, i, u + 3 * i);
}

/* (D u)_i = m sum_j (u_i - u_j).grad W_ij + u_i.G_w,i (Eq. 19's divergence), the walls' term
 * weighted by c->wall_div: the push's weight, except with pressure_gradient offset and the own
 * wall, where an approach to the wall counts twice, as the mirror's (ours). There a particle's
 * own pressure does not push it (grad_min_at) and the wall pushes with y_i - y_min once, while
 * with weight 1 its approach to the wall and its departure from its neighbours cancel in rho*_i:
 * nothing resisted a particle sliding into the wall, and a still column blew up from its walls
 * (src/README.md, the `offset` entry; tests/README.md, "Which wall `offset` wants"). */
static double div_one(const stf_fluid *f, const double *u, int i)
{
    const cy_state *c = f->cy;
    double d0 = 0, d1 = 0, d2 = 0;
    const cy_pair *pr = c->pair + c->off[i], *end = c->pair + c->off[i + 1];
    const double *ui = u + 3 * i;
    for (; pr < end; pr++) {
        const double *uj = u + 3 * pr->j;
        d0 += (ui[0] - uj[0]) * pr->g[0];
        d1 += (ui[1] - uj[1]) * pr->g[1];
        d2 += (ui[2] - uj[2]) * pr->g[2];
    }
    const double *G = c->gw + 3 * i;
    double w = c->wall_div;
    return f->mass * (d0 + d1 + d2) + w * ui[0] * G[0] + w * ui[1] * G[1] + w * ui[2] * G[2];
}

/* rho*_i (Eq. 19) from the velocities v: rho_i + dt (D v - the walls' v_w . m grad W). */
static double predict_one(const stf_fluid *f, const double *v, int i, double dt)
{
    return f->cy->rho[i] + dt * (div_one(f, v, i) - f->cy->wall_div * f->cy->qw[i]);
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
    double u[3];
    grad_at(f, c->kr, i, u);
    for (int a = 0; a < 3; a++) f->v[3 * i + a] -= dt * u[a];
    c->ktot[i] += c->kappa[i];
}

static double mean_error(const stf_fluid *f)
{
    const cy_state *c = f->cy;
    double sum = 0; /* serial: the same result for any thread count */
    for (int i = 0; i < f->n; i++) sum += c->rhostar[i] > c->rho0 ? c->rhostar[i] - c->rho0 : 0;
    return f->n > 0 ? sum / f->n / c->rho0 : 0;
}

/* Adds this iteration's kappa to the pressure and sets the velocities from it. Symmetric:
 * the change of kappa alone, in place (pressure_dv_one). The offset forms (local_minimum,
 * offset): not linear in the pressure, so the whole pressure y = ktot / rho (in the scratch
 * c->b) from the velocities before the projection (v0, in c->dv). */
static void apply_kappa(stf_fluid *f, double dt, int offset_form)
{
    cy_state *c = f->cy;
    int n = f->n;
    if (!offset_form) {
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++) pressure_dv_one(f, i, dt);
        return;
    }
    double *v0 = c->dv, *y = c->b;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        c->ktot[i] += c->kappa[i];
        y[i] = c->ktot[i] * c->irho[i];
    }
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        double u[3];
        grad_min_at(f, y, i, u);
        for (int a = 0; a < 3; a++) f->v[3 * i + a] = v0[3 * i + a] - dt * u[a];
    }
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
    int offset_form = f->def.cy.pressure_gradient != STF_PRESSURE_GRADIENT_SYMMETRIC; /* local_minimum, offset */
    if (offset_form) memcpy(c->dv, f->v, (size_t)n * 3 * sizeof *f->v);
    if (w > 0) apply_kappa(f, dt, offset_form); /* the warm start (kappa: the density pass's) */
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) predict_kappa_one(f, f->v, i, dt, omega);
    do {
        apply_kappa(f, dt, offset_form);
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

/* ------------------------------------------------ conjugate gradients (pressure_solver cg)
 *
 * Ours, not the paper's. Algorithm 1's equations are linear in y_i = k_i / rho_i: the velocity
 * change is -dt G y, (G y)_i = sum_j m (y_i + y_j) grad W_ij + y_i G_w,i (the walls' gradient
 * sum), and it changes rho*_i by -dt^2 (D G y)_i, D u = sum_j m (u_i - u_j).grad W_ij +
 * u_i.G_w,i. By the antisymmetry of grad W_ij, D is the transpose of G, so A = D G is symmetric
 * positive semi-definite, with Eq. 20-21's S_i its diagonal: Jacobi's k_i is one Jacobi sweep
 * of A y = (rho* - rho0) / dt^2, and it carries a correction about one neighbour shell per
 * iteration, so a column N particles deep needs many sweeps to rebuild its hydrostatic
 * pressure from zero (the settling sphere's tank, 32 deep: 27.5 a step at eta 1e-3). Here
 * each step solves the active set to eta by conjugate gradients with S_i as the
 * preconditioner, from the last step's pressure (warm_start), the active set being the
 * particles with pressure or compression (2.0 iterations a step in the same tank). A particle
 * whose pressure would fall below zero is set to zero (no tension) and leaves the set, which is
 * solved again, at most four rounds. The iterations may lower the pressure where the fluid
 * expands; this does not stop the particle-scale velocity noise a still column keeps (about
 * 4 mm/s rms at dt = 2 ms with either solver: tests/README.md). */

/* Serial sums: the same result for any thread count. */
static double dot(const double *a, const double *b, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++) s += a[i] * b[i];
    return s;
}

/* The mean density error of the residuals res = (rho* - rho0) / dt^2, a fraction of rho0. */
static double residual_error(const double *res, int n, double dt, double rho0)
{
    double sum = 0;
    for (int i = 0; i < n; i++) sum += fabs(res[i]);
    return n > 0 ? sum * dt * dt / n / rho0 : 0;
}

/* v -= dt G y (the particles' velocity change for the pressures y = k / rho) and
 * ktot += rho y; y is zero outside the active set. u is scratch (3n). */
static void apply_pressure(stf_fluid *f, const double *y, double *u, double scale, double dt)
{
    cy_state *c = f->cy;
    int n = f->n;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) grad_one(f, y, u, i);
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) f->v[3 * i + a] -= dt * scale * u[3 * i + a];
        c->ktot[i] += scale * y[i] * c->rho[i];
    }
}

void stf_cy_pressure_project_cg(stf_fluid *f, double dt, double w)
{
    cy_state *c = f->cy;
    int n = f->n, iter = 0, maxit = f->def.cy.max_pressure_iterations;
    double eta = f->def.cy.eta, err = 0, idt2 = 1.0 / (dt * dt);
    /* scratch: res, z (in b), dir, its image A dir (in p, Ap); G dir (dv, 3n); active (hit) */
    double *res = c->b, *z = c->b + n, *dir = c->p, *Ad = c->Ap, *u = c->dv;
    char *act = c->hit;
    if (w > 0) { /* the warm start: w times the last step's pressure (kappa, set by the density pass) */
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++) dir[i] = c->kr[i];
        apply_pressure(f, dir, u, 1.0, dt);
    }
    for (int round = 0; round < 4; round++) {
        /* the active set and its residual (rho* - rho0) / dt^2 from the velocities */
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++) {
            double rs = predict_one(f, f->v, i, dt);
            c->rhostar[i] = rs;
            act[i] = (char)(c->S[i] > 0 && (c->ktot[i] > 0 || rs > c->rho0));
            res[i] = act[i] ? (rs - c->rho0) * idt2 : 0;
            z[i] = act[i] ? res[i] / c->S[i] : 0;
            dir[i] = z[i];
        }
        err = residual_error(res, n, dt, c->rho0);
        if (err <= eta && (round > 0 || iter >= f->def.cy.min_pressure_iterations)) break;
        double rz = dot(res, z, n);
        while (iter < maxit && rz > 0) {
#pragma omp parallel for schedule(static)
            for (int i = 0; i < n; i++) grad_one(f, dir, u, i);
#pragma omp parallel for schedule(static)
            for (int i = 0; i < n; i++) Ad[i] = act[i] ? div_one(f, u, i) : 0;
            double dAd = dot(dir, Ad, n);
            if (!(dAd > 0)) break;
            double alpha = rz / dAd;
#pragma omp parallel for schedule(static)
            for (int i = 0; i < n; i++) {
                for (int a = 0; a < 3; a++) f->v[3 * i + a] -= dt * alpha * u[3 * i + a];
                c->ktot[i] += alpha * dir[i] * c->rho[i];
                res[i] -= alpha * Ad[i];
                z[i] = act[i] ? res[i] / c->S[i] : 0;
            }
            iter++;
            err = residual_error(res, n, dt, c->rho0);
            if (err <= eta && iter >= f->def.cy.min_pressure_iterations) break;
            double rz1 = dot(res, z, n), beta = rz1 / rz;
            rz = rz1;
#pragma omp parallel for schedule(static)
            for (int i = 0; i < n; i++) dir[i] = z[i] + beta * dir[i];
        }
        /* no tension: a negative pressure is taken back to zero, and that particle leaves
           the set on the next round */
        int neg = 0;
        for (int i = 0; i < n; i++) {
            dir[i] = c->ktot[i] < 0 ? -c->ktot[i] * c->irho[i] : 0;
            neg |= c->ktot[i] < 0;
        }
        if (neg) apply_pressure(f, dir, u, 1.0, dt);
        for (int i = 0; i < n; i++)
            if (c->ktot[i] < 0) c->ktot[i] = 0; /* rounding */
        if (iter >= maxit) break;
    }
    /* the density error of the result, as the Jacobi projection reports it */
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) c->rhostar[i] = predict_one(f, f->v, i, dt);
    c->warm_n = n;
    c->stats.pressure_iterations = iter;
    c->stats.density_error = mean_error(f);
}
