/* test_gauss_seidel.c - the springs as compliant constraints (relaxation gauss_seidel,
 * src/gauss_seidel.c) and the density projection:
 *
 *  exact pair    one spring of gain c = dt^2 k (1 - L/h), stretched by e: one sweep leaves
 *                e / (1 + c), for a soft spring (Clavet's e (1 - c) to first order) and for
 *                one a million times stiffer (no overshoot: it closes, it does not flip);
 *                with the dashpot of relaxation time tau, XPBD's damped update exactly (it
 *                acts on a new spring's approach too).
 *  momentum      a sheared, jittered block with every internal effect, the history springs
 *                thousands of times stiffer than the Jacobi form can hold at this step, and
 *                sum m v is conserved to round-off over 200 steps.
 *  stiff and stable  the same block at that stiffness stays finite and gains no kinetic
 *                energy, where the Jacobi form needs substeps.
 *  threads       1 and 2 threads give the same state bit for bit (the colours).
 *  liquid creep  a spring below the onset creeps at liquid_plasticity, one above it at
 *                plasticity: Clavet's L + dt alpha (r - L) exactly, with each rate.
 */
#define _POSIX_C_SOURCE 200809L
#include "stf.h"
#include "fluid.h" /* the springs' rest lengths (liquid_creep) */
#include "test_util.h"

#include <omp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static char err[512];

static unsigned long long rng_state = 0x2545f4914f6cdd1dull;
static double urand(void) { return test_urand(&rng_state); }

static stf_fluid *make(const stf_fluid_def *d)
{
    stf_fluid *f = NULL;
    if (stf_fluid_create(d, &f, err, sizeof err) != 0) {
        CHECK(0, "stf_fluid_create: %s", err);
        return NULL;
    }
    return f;
}

/* Particles 0 and 1, 0.6 h apart on the x axis, receding from each other at u each. */
static void add_receding_pair(stf_fluid *f, double h, double u)
{
    double a[3] = {0, 0, 0}, b[3] = {0.6 * h, 0, 0}, va[3] = {-u, 0, 0}, vb[3] = {u, 0, 0};
    stf_fluid_add_particle(f, a, va);
    stf_fluid_add_particle(f, b, vb);
}

/* Two particles 0.6 h apart moving apart at u each: the spring made at the first step
 * (rest length L = its length then, no plastic creep) is stretched by 2 u dt at the next
 * prediction. */
static void exact_pair(double k_min, double tau)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.effects = STF_EFFECT_SPRINGS;
    d.relaxation = STF_RELAX_GAUSS_SEIDEL;
    d.k_min = k_min;
    d.plasticity = 0;
    d.spring_damping = tau;
    stf_fluid *f = make(&d);
    if (!f) return;
    double h = 2 * d.spacing, dt = 1e-3, u = 0.01;
    add_receding_pair(f, h, u);
    /* the XPBD update of one spring of rest length Lr at separation r that approached by du
       in the step: r + 2 dlambda, dlambda = (-(r - Lr) - g du) / ((1 + g) 2 + 2/c) */
    double g = tau / dt, r0 = 0.6 * h, Lr = r0 + 2 * u * dt; /* made at its length, step 1 */
    double c = dt * dt * k_min * (1 - Lr / h);
#define XPBD(r, du) ((r) + 2 * (-((r) - Lr) - g * (du)) / ((1 + g) * 2 + 2 / c))
    CHECK(stf_fluid_step(f, dt) == 0, "step 1: %s", stf_fluid_failure(f));
    double x[6], v[6];
    stf_fluid_get_positions(f, x);
    double want1 = XPBD(Lr, 2 * u * dt); /* the new spring: no strain, only the dashpot */
    CHECK(fabs((x[3] - x[0]) - want1) <= 1e-12 * h, "step 1: separation %.17g, want %.17g",
          x[3] - x[0], want1);
    double sep1 = x[3] - x[0];
    stf_fluid_get_velocities(f, v);
    double e = (v[3] - v[0]) * dt; /* the approach in the next prediction */
    CHECK(stf_fluid_step(f, dt) == 0, "step 2: %s", stf_fluid_failure(f));
    stf_fluid_get_positions(f, x);
    double want = XPBD(sep1 + e, e);
#undef XPBD
    CHECK(fabs((x[3] - x[0]) - want) <= 1e-12 * h,
          "k_min %g, tau %g: separation %.17g, want %.17g (c = %g)", k_min, tau, x[3] - x[0], want, c);
    if (tau == 0) /* without the dashpot: the stretch left is e / (1 + c) */
        CHECK(fabs((x[3] - x[0] - Lr) - (sep1 + e - Lr) / (1 + c)) <= 1e-12 * h,
              "k_min %g: the stretch closes by c/(1+c)", k_min);
    CHECK_NEAR(x[0] + x[3], 0.6 * h, 1e-15, "the pair's centre stays put");
    printf("exact pair: k_min %g, c = %.3g, tau %g s: stretch %.3g -> %.3g\n", k_min, c, tau,
           sep1 + e - Lr, x[3] - x[0] - Lr);
    stf_fluid_destroy(f);
}

/* A 9 x 9 x 9 jittered block in shear with random velocities (no gravity, no walls). */
static stf_fluid *sheared_block(double k_hist)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.effects = STF_EFFECT_VISCOSITY | STF_EFFECT_PRESSURE | STF_EFFECT_SPRINGS | STF_EFFECT_HISTORY;
    d.relaxation = STF_RELAX_GAUSS_SEIDEL;
    d.iterations = 2;
    d.memory = 0.05;
    d.k_hist = k_hist;
    stf_fluid *f = make(&d);
    if (!f) return NULL;
    double s = d.spacing;
    rng_state = 0x2545f4914f6cdd1dull;
    for (int c = 0; c < 9; c++)
        for (int b = 0; b < 9; b++)
            for (int a = 0; a < 9; a++) {
                double x[3] = {a * s + 0.2 * s * urand(), b * s + 0.2 * s * urand(), c * s + 0.2 * s * urand()};
                double v[3] = {0.2 + 4.0 * (x[2] - 0.04) + 0.3 * urand(), -0.1 + 0.3 * urand(),
                               0.05 + 0.3 * urand()};
                stf_fluid_add_particle(f, x, v);
            }
    return f;
}

/* Momentum, sum m |v| and kinetic energy. */
static void momentum_of(stf_fluid *f, double P[3], double *A, double *ke)
{
    int n = stf_fluid_count(f);
    double m = stf_fluid_particle_mass(f), *v = malloc((size_t)n * 3 * sizeof *v);
    stf_fluid_get_velocities(f, v);
    P[0] = P[1] = P[2] = *A = *ke = 0;
    for (int i = 0; i < n; i++) {
        double s2 = 0;
        for (int a = 0; a < 3; a++) P[a] += m * v[3 * i + a], s2 += v[3 * i + a] * v[3 * i + a];
        *A += m * sqrt(s2);
        *ke += 0.5 * m * s2;
    }
    free(v);
}

static void momentum_and_stability(void)
{
    /* k_hist 1e8: kh of order 1e6-1e7 1/s^2 in this shear, dt^2 k of 1-10 per spring, tens
       summed over a particle's springs: the Jacobi form saturates by far */
    stf_fluid *f = sheared_block(1e8);
    if (!f) return;
    double P0[3], A0, ke0, P[3], A, ke, worst = 0;
    momentum_of(f, P0, &A0, &ke0);
    int ok = 1;
    for (int s = 0; s < 200 && ok; s++) {
        ok = stf_fluid_step(f, 1e-3) == 0;
        CHECK(ok, "step %d: %s", s, stf_fluid_failure(f));
        momentum_of(f, P, &A, &ke);
        if (ke > worst) worst = ke;
    }
    for (int a = 0; a < 3; a++)
        CHECK(fabs(P[a] - P0[a]) <= 1e-10 * A0, "momentum[%d]: %.17g -> %.17g (sum m|v| %.6g)", a,
              P0[a], P[a], A0);
    /* no energy from nowhere: viscosity, plastic flow and the projection only take kinetic
       energy away; the jittered block's pressure holds some potential energy (its kernel
       densities scatter about the rest density: the block without history springs, either
       relaxation, peaks at 1.2 times its initial kinetic energy), which a stiff network
       that released energy it does not hold would exceed */
    CHECK(worst <= 1.25 * ke0, "largest kinetic energy %.4g J over 200 steps against %.4g J at start",
          worst, ke0);
    CHECK(stf_fluid_spring_gain(f) == 0, "gauss_seidel: no spring gain limits the step (got %g)",
          stf_fluid_spring_gain(f));
    printf("momentum: worst |dP| / sum m|v| = %.3g; largest kinetic energy %.3g (start %.3g) J\n",
           fmax(fabs(P[0] - P0[0]), fmax(fabs(P[1] - P0[1]), fabs(P[2] - P0[2]))) / A0, worst, ke0);
    stf_fluid_destroy(f);
}

static uint64_t run_hash(int threads)
{
    omp_set_num_threads(threads);
    stf_fluid *f = sheared_block(1e7);
    if (!f) return 0;
    for (int s = 0; s < 60; s++)
        if (stf_fluid_step(f, 1e-3) != 0) break;
    uint64_t h = stf_fluid_hash(f);
    stf_fluid_destroy(f);
    return h;
}

/* Two particles moving apart at u: the spring made at step 1 at length Lr is at r2 when
 * step 2 measures it, and its rest length becomes Lr + dt alpha (r2 - Lr) (yield_ratio 0),
 * alpha the liquid rate below the onset (here: without history, or with an onset no pair
 * reaches) and the material's plasticity above it. */
static void liquid_creep(int history, double onset, double want_alpha)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.effects = STF_EFFECT_SPRINGS | (history ? STF_EFFECT_HISTORY : 0u);
    d.relaxation = STF_RELAX_GAUSS_SEIDEL;
    d.k_min = 1e-6; /* the pair's motion is the prediction's alone */
    d.yield_ratio = 0;
    d.plasticity = 2.0;
    d.liquid_plasticity = 50.0;
    d.k_hist = history ? 1e-3 : 0; /* a stiffness far below the positions' round-off */
    d.k_onset = onset;
    d.memory = 0.01;
    stf_fluid *f = make(&d);
    if (!f) return;
    double h = 2 * d.spacing, dt = 1e-3, u = 0.01;
    add_receding_pair(f, h, u);
    CHECK(stf_fluid_step(f, dt) == 0, "step 1: %s", stf_fluid_failure(f));
    double x[6], v[6];
    stf_fluid_get_positions(f, x);
    stf_fluid_get_velocities(f, v);
    double Lr = f->springs.rest[0], r2 = (x[3] - x[0]) + (v[3] - v[0]) * dt;
    CHECK(stf_fluid_step(f, dt) == 0, "step 2: %s", stf_fluid_failure(f));
    double want = Lr + dt * want_alpha * (r2 - Lr), got = f->springs.rest[0];
    CHECK(fabs(got - want) <= 1e-15 * h, "history %d, onset %g: rest %.17g, want %.17g (alpha %g)",
          history, onset, got, want, want_alpha);
    printf("liquid creep: history %d, onset %g: rest length %.9g -> %.9g m (alpha %g 1/s)\n",
           history, onset, Lr, got, want_alpha);
    stf_fluid_destroy(f);
}

int main(void)
{
    liquid_creep(0, 0, 50.0);    /* no history: every spring is liquid */
    liquid_creep(1, 1e30, 50.0); /* below the onset */
    liquid_creep(1, 0, 2.0);     /* above it (Eq. 6 as written: any history stiffness) */
    exact_pair(100.0, 0);
    exact_pair(1e8, 0);
    exact_pair(1e5, 0.002);
    momentum_and_stability();
    uint64_t h1 = run_hash(1), h2 = run_hash(2);
    CHECK(h1 == h2 && h1 != 0, "1 thread %016llx, 2 threads %016llx", (unsigned long long)h1,
          (unsigned long long)h2);
    printf("threads: %016llx at 1 and 2 threads\n", (unsigned long long)h1);
    return test_result("test_gauss_seidel");
}
