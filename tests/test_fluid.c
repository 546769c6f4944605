/* test_fluid.c - physics of the fluid step (src/fluid.c and the effect stages):
 *
 *  momentum     without gravity and colliders every internal effect (viscosity, double
 *               density relaxation, plastic springs, history stiffness) acts in equal and
 *               opposite pairs, so sum m v is conserved to round-off.
 *  containment  a block thrown violently into a tall container stays inside its inner box
 *               (to half a spacing, the collision margin) and stays finite.
 *  effects off  an effect that is off allocates nothing; k_hist = 0 reduces the history
 *               springs exactly to Clavet's model (bit-identical run).
 *  determinism  the same scene gives the same state hash, with 1 or 2 threads.
 *  spring search  a particle marked complete has a spring to every neighbour, and skipping
 *               the search for new springs where nothing can be found gives the same run as
 *               searching everywhere (bit-identical), while skipping most searches.
 *  dt           a blob dropped on a floor (history memory given in seconds) converges as dt
 *               shrinks: the centre-of-mass trajectory changes less from dt/2 to dt/4 than
 *               from dt to dt/2.
 *  check_def    stf_fluid_check_def names the member of the def it refuses (what the scene
 *               loader maps back to a scene key), for the Clavet and the Carreau-Yasuda fields.
 */
#define _POSIX_C_SOURCE 200809L
#include "stf.h"
#include "fluid.h" /* springs and grid internals (test_spring_search) */
#include "test_util.h"

#include <omp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char err[512];

static unsigned long long rng_state = 0x9e3779b97f4a7c15ull;
static double urand(void) { return test_urand(&rng_state); }

static stf_fluid *make_fluid(const stf_fluid_def *d)
{
    stf_fluid *f = NULL;
    if (stf_fluid_create(d, &f, err, sizeof err) != 0) {
        CHECK(0, "stf_fluid_create: %s", err);
        return NULL;
    }
    return f;
}

/* An open-top container whose floor's top face is at the origin. */
static int add_container(stf_fluid *f, double hx, double hy, double hz, double friction)
{
    stf_collider_def c = stf_default_collider_def();
    c.shape = STF_SHAPE_CONTAINER;
    c.half[0] = hx, c.half[1] = hy, c.half[2] = hz;
    c.wall = 0.03;
    c.friction = friction;
    c.stick = 1;
    int id = stf_fluid_add_collider(f, &c, err, sizeof err);
    CHECK(id >= 0, "add container: %s", err);
    return id;
}

static int run(stf_fluid *f, int steps, double dt)
{
    for (int s = 0; s < steps; s++)
        if (stf_fluid_step(f, dt) != 0) {
            CHECK(0, "step %d failed: %s", s, stf_fluid_failure(f));
            return -1;
        }
    return 0;
}

/* ------------------------------------------------------------------- momentum */

static void momentum(const double *v, int n, double m, double P[3], double *absP)
{
    P[0] = P[1] = P[2] = 0;
    *absP = 0;
    for (int i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) P[a] += m * v[3 * i + a];
        *absP += m * sqrt(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
    }
}

static void test_momentum(void)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.effects = STF_EFFECT_VISCOSITY | STF_EFFECT_PRESSURE | STF_EFFECT_SPRINGS |
                STF_EFFECT_HISTORY | STF_EFFECT_BOUNDARY_STICK;
    d.beta = 0.5; /* the quadratic viscosity term too */
    stf_fluid *f = make_fluid(&d);
    if (!f) return;
    const double s = d.spacing;
    /* 9x9x9 lattice, shear flow v_x = 4 z / m plus a rotation-free bulk drift and random
       jitter of 0.3 m/s in every component, so every pair term is exercised. */
    for (int c = 0; c < 9; c++)
        for (int b = 0; b < 9; b++)
            for (int a = 0; a < 9; a++) {
                double x[3] = {a * s, b * s, c * s};
                double v[3] = {0.2 + 4.0 * (x[2] - 0.04) + 0.3 * urand(), -0.1 + 0.3 * urand(),
                               0.05 + 0.3 * urand()};
                stf_fluid_add_particle(f, x, v);
            }
    int n = stf_fluid_count(f);
    double m = stf_fluid_particle_mass(f);
    double *v = malloc((size_t)n * 3 * sizeof *v);
    double P0[3], A0, P[3], A;
    double *v_init = malloc((size_t)n * 3 * sizeof *v_init);
    stf_fluid_get_velocities(f, v);
    stf_fluid_get_velocities(f, v_init);
    momentum(v, n, m, P0, &A0);
    double worst = 0;
    for (int s2 = 0; s2 < 200; s2++) {
        if (run(f, 1, 1e-3) != 0) break;
        stf_fluid_get_velocities(f, v);
        momentum(v, n, m, P, &A);
        for (int a = 0; a < 3; a++) {
            double rel = fabs(P[a] - P0[a]) / A0;
            if (rel > worst) worst = rel;
        }
    }
    for (int a = 0; a < 3; a++)
        CHECK(fabs(P[a] - P0[a]) <= 1e-10 * A0, "momentum[%d]: %.17g -> %.17g (sum m|v| %.6g)", a,
              P0[a], P[a], A0);
    /* the test is not vacuous: the internal effects did change the velocities a lot */
    double change = 0;
    for (int i = 0; i < 3 * n; i++) change += m * fabs(v[i] - v_init[i]);
    CHECK(change > 0.1 * A0, "sum m|v - v0| = %.6g against sum m|v0| = %.6g: the effects did little",
          change, A0);
    CHECK(stf_fluid_spring_count(f) > 0, "no springs formed");
    printf("momentum: %d particles, 200 steps, worst |dP|/sum m|v| = %.3g; sum m|v| %.4g -> %.4g, "
           "sum m|v-v0| %.4g\n", n, worst, A0, A, change);
    free(v);
    free(v_init);
    stf_fluid_destroy(f);
}

/* ----------------------------------------------------------- projection pressure */

/* The mean number density of a column's bulk over the lattice's (1/s^3), minus 1: each
 * particle at least rc = 3 spacings from the walls, the floor and the surface (its highest
 * particle) counts its neighbours within rc with the smooth weight (1 - d^2/rc^2)^2, divided by
 * that weight's integral; the estimator of the run metrics' density_error (src/io/metrics.c),
 * independent of either pressure's kernel. */
static double bulk_density_error(const stf_fluid *f, double half, double s)
{
    int n = stf_fluid_count(f);
    double *x = malloc((size_t)n * 3 * sizeof *x), top = -INFINITY, rc = 3 * s, sum = 0;
    stf_fluid_get_positions(f, x);
    for (int i = 0; i < n; i++) top = x[3 * i + 2] > top ? x[3 * i + 2] : top;
    int m = 0;
    for (int i = 0; i < n; i++) {
        const double *p = x + 3 * i;
        if (fabs(p[0]) > half - rc || fabs(p[1]) > half - rc || p[2] < rc || p[2] > top - rc)
            continue;
        double cnt = 0;
        for (int j = 0; j < n; j++) {
            double d2 = 0;
            for (int a = 0; a < 3; a++) d2 += (x[3 * j + a] - p[a]) * (x[3 * j + a] - p[a]);
            double u = 1 - d2 / (rc * rc);
            cnt += d2 < rc * rc ? u * u : 0.0;
        }
        sum += cnt * s * s * s / (32.0 * 3.14159265358979323846 / 105.0 * rc * rc * rc);
        m++;
    }
    free(x);
    return m > 0 ? sum / m - 1 : NAN;
}

/* A column of the cornstarch liquid (pressure and viscosity at the material's values) left to
 * rest under gravity for 1 s from the lattice: its bulk's density error (the mean of 10
 * samples over the last 0.1 s) and its rms speed at the end. */
static double column_density(int mode, int packing, double *rms)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.effects = STF_EFFECT_GRAVITY | STF_EFFECT_VISCOSITY | STF_EFFECT_PRESSURE;
    d.spacing = 0.02, d.density = 1290, d.jitter = 0;
    d.material_spacing = 0.02, d.sigma = 10, d.k = 4000, d.k_near = 800; /* the material's */
    d.pressure_mode = mode;
    d.rest_packing = packing;
    d.cy.eta = 1e-3, d.cy.pressure_solver = STF_PRESSURE_CG;
    d.cy.wall_pressure = STF_WALL_PRESSURE_MIRROR, d.cy.warm_start = 1;
    stf_fluid *f = make_fluid(&d);
    if (!f) return NAN;
    add_container(f, 0.1, 0.1, 0.4, 0.2);
    stf_fluid_add_block(f, (double[3]){-0.1, -0.1, 0}, (double[3]){0.1, 0.1, 0.32},
                        (double[3]){0, 0, 0});
    double e = 0;
    run(f, 900, 1e-3);
    for (int k = 0; k < 10; k++) {
        run(f, 10, 1e-3);
        e += bulk_density_error(f, 0.1, d.spacing) / 10;
    }
    int n = stf_fluid_count(f);
    double *v = malloc((size_t)n * 3 * sizeof *v), v2 = 0;
    stf_fluid_get_velocities(f, v);
    for (int i = 0; i < 3 * n; i++) v2 += v[i] * v[i];
    *rms = sqrt(v2 / n);
    free(v);
    stf_fluid_destroy(f);
    return e;
}

/* A 9^3 lattice with random velocities (from the stream at seed) about a still sphere of
 * 2.5 spacings, every internal effect on and the projection as the pressure; *id is the
 * sphere's collider. */
static stf_fluid *projection_blob(unsigned long long seed, int *id)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.effects = STF_EFFECT_VISCOSITY | STF_EFFECT_PRESSURE | STF_EFFECT_SPRINGS |
                STF_EFFECT_HISTORY | STF_EFFECT_BOUNDARY_STICK;
    d.pressure_mode = STF_PRESSURE_PROJECTION;
    d.cy.eta = 1e-3, d.cy.pressure_solver = STF_PRESSURE_CG;
    d.cy.wall_pressure = STF_WALL_PRESSURE_MIRROR;
    stf_fluid *f = make_fluid(&d);
    if (!f) return NULL;
    stf_collider_def sph = stf_default_collider_def();
    sph.shape = STF_SHAPE_SPHERE, sph.radius = 0.025, sph.friction = 0, sph.stick = 0;
    *id = stf_fluid_add_collider(f, &sph, err, sizeof err);
    CHECK(*id >= 0, "sphere: %s", err);
    if (*id < 0) {
        stf_fluid_destroy(f);
        return NULL;
    }
    static const double eye[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    stf_fluid_set_collider_state(f, *id, (double[3]){0.04, 0.04, 0.04}, eye,
                                 (double[3]){0, 0, 0}, (double[3]){0, 0, 0});
    const double s = d.spacing;
    rng_state = seed;
    for (int c = 0; c < 9; c++)
        for (int b = 0; b < 9; b++)
            for (int a = 0; a < 9; a++) {
                double x[3] = {a * s, b * s, c * s};
                double v[3] = {0.2 + 0.3 * urand(), -0.1 + 0.3 * urand(), 0.05 + 0.3 * urand()};
                stf_fluid_add_particle(f, x, v);
            }
    stf_fluid_remove_inside(f, *id);
    return f;
}

static void test_projection(void)
{
    /* 1. incompressible: the column's bulk within 1% of the material's density; the
       relaxation at the lattice's rest density compresses it more */
    double rms_relax, rms_proj, rms_liquid;
    double e_relax = column_density(STF_PRESSURE_RELAX, STF_REST_LATTICE, &rms_relax);
    double e_proj = column_density(STF_PRESSURE_PROJECTION, STF_REST_LATTICE, &rms_proj);
    double e_liquid = column_density(STF_PRESSURE_RELAX, STF_REST_LIQUID, &rms_liquid);
    CHECK(fabs(e_proj) <= 0.01, "projection: the column's bulk density is off by %+.2f%%",
          100 * e_proj);
    CHECK(fabs(e_relax) > 2 * fabs(e_proj), "relaxation %+.2f%% against projection %+.2f%%: the "
          "projection should hold the density better", 100 * e_relax, 100 * e_proj);
    printf("projection: a 0.32 m column at rest after 1 s, bulk density %+.2f%% (rms speed %.1f "
           "mm/s); Clavet's relaxation %+.2f%% (rms %.1f mm/s), at the liquid's rest density "
           "%+.2f%% (rms %.1f mm/s)\n",
           100 * e_proj, 1000 * rms_proj, 100 * e_relax, 1000 * rms_relax, 100 * e_liquid,
           1000 * rms_liquid);
    /* 1b. the relaxation at the liquid's rest density (rest: liquid) holds the density as well:
       the lattice's kernel sum is what compressed it, not the finite stiffness */
    CHECK(fabs(e_liquid) <= 0.01, "relaxation with rest: liquid: the column's bulk density is off "
          "by %+.2f%%", 100 * e_liquid);

    /* 2. momentum: the projection's pair terms are antisymmetric, and what the walls give the
       particles goes back to the colliders: fluid plus colliders keep their momentum */
    unsigned long long seed = rng_state;
    int id;
    stf_fluid *f = projection_blob(seed, &id);
    if (!f) return;
    int n = stf_fluid_count(f);
    double m = stf_fluid_particle_mass(f), P0[3], A0, P[3], A, J[3] = {0, 0, 0};
    double *v = malloc((size_t)n * 3 * sizeof *v);
    stf_fluid_get_velocities(f, v);
    momentum(v, n, m, P0, &A0);
    double wall = 0;
    for (int k = 0; k < 100; k++) {
        if (run(f, 1, 1e-3) != 0) break;
        double imp[3], mom[3];
        stf_fluid_collider_impulse(f, id, imp, mom);
        for (int a = 0; a < 3; a++) J[a] += imp[a];
        wall += sqrt(imp[0] * imp[0] + imp[1] * imp[1] + imp[2] * imp[2]);
    }
    stf_fluid_get_velocities(f, v);
    momentum(v, n, m, P, &A);
    for (int a = 0; a < 3; a++)
        CHECK(fabs(P[a] + J[a] - P0[a]) <= 1e-10 * A0,
              "fluid + sphere momentum[%d]: %.17g -> %.17g (sum m|v| %.6g)", a, P0[a], P[a] + J[a],
              A0);
    CHECK(wall > 1e-3 * A0, "the sphere took %.3g N s in all: the walls did little", wall);
    stf_solver_stats st;
    stf_fluid_solver_stats(f, &st);
    CHECK(st.pressure_iterations >= 1, "projection: %d iterations", st.pressure_iterations);
    printf("projection momentum: %d particles and a sphere, 100 steps, |dP| %.3g of sum m|v| %.4g; "
           "the sphere took %.3g N s\n", n,
           fabs(P[0] + J[0] - P0[0]) + fabs(P[1] + J[1] - P0[1]) + fabs(P[2] + J[2] - P0[2]), A0,
           wall);
    free(v);
    /* 3. the same run with 2 threads is bit-identical (the solver's sums are serial, every
       particle's terms gathered in list order) */
    uint64_t h1 = stf_fluid_hash(f);
    stf_fluid_destroy(f);
    stf_set_threads(2);
    stf_fluid *g = projection_blob(seed, &id);
    if (g) {
        run(g, 100, 1e-3);
        CHECK(stf_fluid_hash(g) == h1, "projection: 2 threads %016llx against 1 thread %016llx",
              (unsigned long long)stf_fluid_hash(g), (unsigned long long)h1);
        stf_fluid_destroy(g);
    }
    stf_set_threads(1);
}

/* -------------------------------------------------------------- spring search */

/* The momentum test's sheared, jittered lattice: springs form and break all the time. */
static stf_fluid *shear_lattice(int always)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.effects = STF_EFFECT_VISCOSITY | STF_EFFECT_PRESSURE | STF_EFFECT_SPRINGS |
                STF_EFFECT_HISTORY;
    stf_fluid *f = make_fluid(&d);
    if (!f) return NULL;
    rng_state = 0x1234567ull;
    const double s = d.spacing;
    for (int c = 0; c < 9; c++)
        for (int b = 0; b < 9; b++)
            for (int a = 0; a < 9; a++) {
                double x[3] = {a * s, b * s, c * s};
                double v[3] = {4.0 * (x[2] - 0.04) + 0.3 * urand(), 0.3 * urand(), 0.3 * urand()};
                stf_fluid_add_particle(f, x, v);
            }
    f->springs.search_always = always;
    return f;
}

static void test_spring_search(void)
{
    stf_fluid *f = shear_lattice(0), *g = shear_lattice(1);
    if (!f || !g) return;
    long complete = 0, searched = 0, seen = 0, wrong = 0;
    for (int step = 0; step < 150; step++) {
        if (run(f, 1, 1e-3) != 0 || run(g, 1, 1e-3) != 0) break;
        /* complete: every neighbour (this step's rows) is a partner after the step */
        const stf_springs *sp = &f->springs;
        for (int i = 0; i < f->n; i++) {
            seen++;
            searched += !sp->complete[i] || f->grid.gained[i];
            if (!sp->complete[i]) continue;
            complete++;
            const int32_t *row = grid_row(&f->grid, i);
            const int32_t *p = sp->partner + (size_t)i * (size_t)sp->stride;
            for (int k = 0; k < f->grid.count[i]; k++) {
                int found = 0;
                for (int m = 0; m < sp->count[i] && !found; m++) found = p[m] == row[k];
                wrong += !found;
            }
        }
    }
    CHECK(wrong == 0, "%ld neighbours of complete particles have no spring", wrong);
    CHECK(complete > seen / 4, "only %ld of %ld particle-steps complete", complete, seen);
    CHECK(searched < seen, "every search was made (%ld of %ld)", searched, seen);
    CHECK(stf_fluid_hash(f) == stf_fluid_hash(g), "skipping searches changed the run");
    CHECK(stf_fluid_spring_count(f) > 0, "no springs");
    printf("spring search: %ld of %ld particle-steps searched (the rest skipped), %ld complete\n",
           searched, seen, complete);
    stf_fluid_destroy(f);
    stf_fluid_destroy(g);
}

/* ---------------------------------------------------------------- containment */

static void test_containment(void)
{
    stf_fluid_def d = stf_default_fluid_def(); /* every effect on */
    stf_fluid *f = make_fluid(&d);
    if (!f) return;
    const double hx = 0.1, hy = 0.08, hz = 1.0; /* walls 2 m tall: v^2/2g = 2.5 m for 7 m/s */
    add_container(f, hx, hy, hz, 0.2);
    const double s = d.spacing;
    double lo[3] = {-0.09, -0.07, 0.02}, hi[3] = {0.0, 0.01, 0.10}, v0[3] = {5.0, 0.0, -5.0};
    int n = stf_fluid_add_block(f, lo, hi, v0);
    CHECK(n == 9 * 8 * 8, "block gave %d particles", n);
    double *x = malloc((size_t)n * 3 * sizeof *x);
    double worst_out = -1e9, zmax = 0;
    int bad = 0;
    for (int step = 0; step < 1500 && !bad; step++) {
        if (run(f, 1, 1e-3) != 0) break;
        stf_fluid_get_positions(f, x);
        for (int i = 0; i < n; i++) {
            const double *p = x + 3 * i;
            if (!(isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]))) {
                CHECK(0, "step %d: particle %d not finite", step, i);
                bad = 1;
                break;
            }
            /* how far outside the inner box (negative: inside) */
            double out = fabs(p[0]) - hx;
            if (fabs(p[1]) - hy > out) out = fabs(p[1]) - hy;
            if (-p[2] > out) out = -p[2];
            if (p[2] - 2 * hz > out) out = p[2] - 2 * hz;
            if (out > worst_out) worst_out = out;
            if (p[2] > zmax) zmax = p[2];
            if (out > 0.5 * s) {
                CHECK(0, "step %d: particle %d at (%g, %g, %g) is %g m outside the container", step,
                      i, p[0], p[1], p[2], out);
                bad = 1;
                break;
            }
        }
    }
    CHECK(stf_fluid_steps(f) == 1500, "only %ld steps", stf_fluid_steps(f));
    printf("containment: %d particles, 1500 steps, furthest outside the inner box %.3g m "
           "(allowed %.3g), highest z %.3g m\n",
           n, worst_out, 0.5 * s, zmax);
    free(x);
    stf_fluid_destroy(f);
}

/* ------------------------------------------------------------------ effects off */

static stf_fluid *drop_scene_onset(unsigned effects, double k_hist, double k_onset)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.effects = effects;
    d.k_hist = k_hist;
    d.k_onset = k_onset;
    stf_fluid *f = make_fluid(&d);
    if (!f) return NULL;
    add_container(f, 0.06, 0.06, 0.2, 0.2);
    double lo[3] = {-0.05, -0.05, 0.0}, hi[3] = {0.05, 0.05, 0.06}, v0[3] = {0.5, 0.2, -1.0};
    stf_fluid_add_block(f, lo, hi, v0);
    return f;
}

static stf_fluid *drop_scene(unsigned effects, double k_hist)
{
    return drop_scene_onset(effects, k_hist, 0.0);
}

static void test_effects_off(void)
{
    const unsigned all = STF_EFFECT_GRAVITY | STF_EFFECT_VISCOSITY | STF_EFFECT_PRESSURE |
                         STF_EFFECT_SPRINGS | STF_EFFECT_HISTORY | STF_EFFECT_BOUNDARY_STICK;
    const unsigned nohist = all & ~(unsigned)STF_EFFECT_HISTORY;
    const unsigned nosprings = all & ~(unsigned)(STF_EFFECT_HISTORY | STF_EFFECT_SPRINGS);

    stf_fluid *off = drop_scene(nosprings, 0);
    stf_fluid *on = drop_scene(all, 1e4);
    if (!off || !on) return;
    run(off, 20, 1e-3);
    run(on, 20, 1e-3);
    CHECK(stf_fluid_effect_bytes(off, STF_EFFECT_SPRINGS) == 0, "springs off: %zu bytes",
          stf_fluid_effect_bytes(off, STF_EFFECT_SPRINGS));
    CHECK(stf_fluid_effect_bytes(off, STF_EFFECT_HISTORY) == 0, "history off: %zu bytes",
          stf_fluid_effect_bytes(off, STF_EFFECT_HISTORY));
    CHECK(stf_fluid_spring_count(off) == 0, "springs off: %ld springs", stf_fluid_spring_count(off));
    CHECK(stf_fluid_history_steps(off) == 0, "history off: window %d", stf_fluid_history_steps(off));
    CHECK(stf_fluid_effect_bytes(on, STF_EFFECT_SPRINGS) > 0, "springs on: no storage");
    CHECK(stf_fluid_effect_bytes(on, STF_EFFECT_HISTORY) > 0, "history on: no storage");
    CHECK(stf_fluid_spring_count(on) > 0, "springs on: no springs");
    CHECK(stf_fluid_history_steps(on) == stf_default_fluid_def().d, "history window %d",
          stf_fluid_history_steps(on));
    /* history storage: at least 12 bytes per particle per kept step (float32 velocities) */
    CHECK(stf_fluid_effect_bytes(on, STF_EFFECT_HISTORY) >=
              (size_t)stf_fluid_count(on) * 12u * (size_t)stf_default_fluid_def().d,
          "history holds %zu bytes for %d particles x %d steps",
          stf_fluid_effect_bytes(on, STF_EFFECT_HISTORY), stf_fluid_count(on),
          stf_default_fluid_def().d);
    /* pressure off too: nothing for it either */
    stf_fluid *bare = drop_scene(STF_EFFECT_GRAVITY, 0);
    if (bare) {
        run(bare, 5, 1e-3);
        CHECK(stf_fluid_effect_bytes(bare, STF_EFFECT_PRESSURE) == 0, "pressure off: %zu bytes",
              stf_fluid_effect_bytes(bare, STF_EFFECT_PRESSURE));
        CHECK(stf_fluid_effect_bytes(on, STF_EFFECT_PRESSURE) > 0, "pressure on: no storage");
        stf_fluid_destroy(bare);
    }
    stf_fluid_destroy(off);
    stf_fluid_destroy(on);

    /* k_hist = 0: the history term k_hist * |D^q x_i - D^q x_j| vanishes, the boundary
       factor k_min / (k_min + stick * 0) is exactly 1, so the run must be Clavet's model
       bit for bit. */
    stf_fluid *a = drop_scene(all, 0.0), *b = drop_scene(nohist, 0.0), *c = drop_scene(all, 1e4);
    if (!a || !b || !c) return;
    run(a, 300, 1e-3);
    run(b, 300, 1e-3);
    run(c, 300, 1e-3);
    CHECK(stf_fluid_hash(a) == stf_fluid_hash(b),
          "k_hist = 0 with history (%016llx) differs from history off (%016llx)",
          (unsigned long long)stf_fluid_hash(a), (unsigned long long)stf_fluid_hash(b));
    /* ... and the comparison can tell: with k_hist > 0 the run does differ */
    CHECK(stf_fluid_hash(c) != stf_fluid_hash(b), "k_hist = 1e4 gives the same run as no history");
    float *k = malloc((size_t)stf_fluid_count(a) * sizeof *k);
    stf_fluid_get_history_stiffness(a, k);
    double kmax = 0;
    for (int i = 0; i < stf_fluid_count(a); i++) kmax = k[i] > kmax ? k[i] : kmax;
    CHECK(kmax == 0, "k_hist = 0: history stiffness %g", kmax);
    stf_fluid_get_history_stiffness(c, k);
    kmax = 0;
    for (int i = 0; i < stf_fluid_count(c); i++) kmax = k[i] > kmax ? k[i] : kmax;
    CHECK(kmax > 0, "k_hist = 1e4: no history stiffness");
    /* ... and with no thickened spring the section 3.3 stage leaves every particle as it is
       (the liquid's wall is the collision stage's): the run without the stage is the same
       bit for bit */
    stf_fluid *nostick = drop_scene(all & ~(unsigned)STF_EFFECT_BOUNDARY_STICK, 0.0);
    if (nostick) {
        run(nostick, 300, 1e-3);
        CHECK(stf_fluid_hash(nostick) == stf_fluid_hash(a),
              "k_hist = 0: boundary stick on (%016llx) differs from off (%016llx)",
              (unsigned long long)stf_fluid_hash(a), (unsigned long long)stf_fluid_hash(nostick));
        stf_fluid_destroy(nostick);
    }

    /* k_onset above every history stiffness the run reaches: no spring thickens and no wall
       sticks, so the run is again Clavet's model bit for bit; an onset at half the peak
       stiffness of run c changes the run but keeps some thickening. */
    stf_fluid *hi = drop_scene_onset(all, 1e4, 1e12), *mid = drop_scene_onset(all, 1e4, 0.5 * kmax);
    if (hi && mid) {
        run(hi, 300, 1e-3);
        run(mid, 300, 1e-3);
        CHECK(stf_fluid_hash(hi) == stf_fluid_hash(b),
              "k_onset = 1e12 (%016llx) differs from history off (%016llx)",
              (unsigned long long)stf_fluid_hash(hi), (unsigned long long)stf_fluid_hash(b));
        CHECK(stf_fluid_hash(mid) != stf_fluid_hash(b) && stf_fluid_hash(mid) != stf_fluid_hash(c),
              "k_onset = %g gives the run without onset or without history", 0.5 * kmax);
    }
    stf_fluid_destroy(hi);
    stf_fluid_destroy(mid);
    free(k);
    stf_fluid_destroy(a);
    stf_fluid_destroy(b);
    stf_fluid_destroy(c);
}

/* ------------------------------------------------------------------ determinism */

static uint64_t determinism_run(int threads)
{
    if (threads > 0) stf_set_threads(threads);
    stf_fluid *f = drop_scene(STF_EFFECT_GRAVITY | STF_EFFECT_VISCOSITY | STF_EFFECT_PRESSURE |
                                  STF_EFFECT_SPRINGS | STF_EFFECT_HISTORY |
                                  STF_EFFECT_BOUNDARY_STICK,
                              1e4);
    if (!f) return 0;
    run(f, 150, 1e-3);
    uint64_t h = stf_fluid_hash(f);
    stf_fluid_destroy(f);
    return h;
}

static void test_determinism(void)
{
    uint64_t h1 = determinism_run(2), h2 = determinism_run(2);
    CHECK(h1 == h2, "same scene twice: %016llx vs %016llx", (unsigned long long)h1,
          (unsigned long long)h2);
    uint64_t t1 = determinism_run(1);
    CHECK(t1 == h1, "1 thread %016llx vs 2 threads %016llx", (unsigned long long)t1,
          (unsigned long long)h1);
    stf_set_threads(1);
}

/* Particles emitted in the middle of a run (stf_fluid_add_particle) and then others removed
 * (stf_fluid_remove_inside) before the next step, with every effect on and a history window
 * long enough for the ring's row map (d >= 256; the particles re-sorted before): the run goes
 * on, exactly the particles inside the collider go (by id), and the bits are the same with 1,
 * 2 and 3 threads (3: thread ranges of unequal length). */
static uint64_t emit_remove_run(int threads, int *removed, int *bad_ids)
{
    stf_set_threads(threads);
    stf_fluid_def d = stf_default_fluid_def();
    d.k_hist = 1e4;
    d.d = 300;
    stf_fluid *f = make_fluid(&d);
    if (!f) return 0;
    add_container(f, 0.06, 0.06, 0.2, 0.2);
    double lo[3] = {-0.05, -0.05, 0.0}, hi[3] = {0.05, 0.05, 0.05}, v0[3] = {0.3, 0.1, -0.5};
    stf_fluid_add_block(f, lo, hi, v0);
    stf_collider_def c = stf_default_collider_def();
    c.shape = STF_SHAPE_SPHERE, c.radius = 0.02;
    int sph = stf_fluid_add_collider(f, &c, err, sizeof err);
    CHECK(sph >= 0, "sphere: %s", err);
    double away[3] = {0, 0, 1.0}, into[3] = {0.0, 0.0, 0.02};
    stf_fluid_set_collider_state(f, sph, away, NULL, NULL, NULL);
    run(f, 60, 1e-3);
    for (int k = 0; k < 12; k++) { /* an emitter: a stream from above */
        double x[3] = {-0.03 + 0.005 * k, 0.01, 0.08}, v[3] = {0, 0, -0.5};
        CHECK(stf_fluid_add_particle(f, x, v) >= 0, "emit");
    }
    int n = stf_fluid_count(f);
    double *x = malloc((size_t)n * 3 * sizeof *x);
    int32_t *id = malloc((size_t)n * sizeof *id), *id2 = malloc((size_t)n * sizeof *id2);
    char *gone = calloc((size_t)n + 12, 1);
    stf_fluid_get_positions(f, x);
    stf_fluid_get_ids(f, id);
    stf_fluid_set_collider_state(f, sph, into, NULL, NULL, NULL);
    int inside = 0;
    for (int i = 0; i < n; i++) /* remove_inside's rule: closer than half a spacing */
        if (stf_fluid_collider_distance(f, sph, x + 3 * i) < 0.5 * d.spacing)
            inside++, gone[id[i]] = 1;
    *removed = stf_fluid_remove_inside(f, sph);
    CHECK(*removed == inside && inside > 0, "removed %d, %d inside", *removed, inside);
    stf_fluid_get_ids(f, id2);
    *bad_ids = 0;
    for (int i = 0; i < stf_fluid_count(f); i++) *bad_ids += gone[id2[i]];
    stf_fluid_set_collider_state(f, sph, away, NULL, NULL, NULL);
    run(f, 60, 1e-3);
    uint64_t h = stf_fluid_hash(f);
    free(x), free(id), free(id2), free(gone);
    stf_fluid_destroy(f);
    return h;
}

static void test_emit_remove(void)
{
    int r1, r2, r3, b1, b2, b3;
    uint64_t h1 = emit_remove_run(1, &r1, &b1), h2 = emit_remove_run(2, &r2, &b2),
             h3 = emit_remove_run(3, &r3, &b3);
    stf_set_threads(1);
    CHECK(b1 == 0 && b2 == 0 && b3 == 0, "removed particles still there: %d %d %d", b1, b2, b3);
    CHECK(h1 == h2 && h1 == h3, "emit then remove: 1 thread %016llx, 2 %016llx, 3 %016llx",
          (unsigned long long)h1, (unsigned long long)h2, (unsigned long long)h3);
    printf("test_fluid: 12 particles emitted, %d removed before the next step (d = 300): 1, 2 "
           "and 3 threads bit-identical\n", r1);
}

/* ------------------------------------------------------------- dt convergence */

#define T_END 0.3
#define T_SAMPLE 0.005
#define NSAMPLE 60 /* T_END / T_SAMPLE */

/* Centre-of-mass height of a 6x6x6 blob dropped from 0.1 m, sampled every T_SAMPLE. */
static void blob_drop(double dt, double com[NSAMPLE + 1], int *window)
{
    stf_fluid_def d = stf_default_fluid_def(); /* every effect on */
    d.memory = 0.05;                           /* s: d = memory / dt */
    d.d = 7;                                   /* ignored */
    stf_fluid *f = make_fluid(&d);
    if (!f) return;
    add_container(f, 0.1, 0.1, 0.2, 0.2);
    double lo[3] = {-0.03, -0.03, 0.1}, hi[3] = {0.03, 0.03, 0.16}, v0[3] = {0, 0, 0};
    int n = stf_fluid_add_block(f, lo, hi, v0);
    CHECK(n == 216, "blob has %d particles", n);
    double *x = malloc((size_t)n * 3 * sizeof *x);
    long per = lround(T_SAMPLE / dt);
    for (int k = 0; k <= NSAMPLE; k++) {
        if (k > 0 && run(f, (int)per, dt) != 0) break;
        stf_fluid_get_positions(f, x);
        double z = 0;
        for (int i = 0; i < n; i++) z += x[3 * i + 2];
        com[k] = z / n;
    }
    *window = stf_fluid_history_steps(f);
    free(x);
    stf_fluid_destroy(f);
}

static double max_diff(const double *a, const double *b, int upto)
{
    double e = 0;
    for (int k = 0; k <= upto; k++) e = fabs(a[k] - b[k]) > e ? fabs(a[k] - b[k]) : e;
    return e;
}

static void test_dt_convergence(void)
{
    /* dt = 2e-3 is beyond the default parameters' stable step: the free-falling blob's
       internal velocities grow to +-2.5 m/s within 0.04 s (+-10 m/s with pressure alone),
       against +-0.2 m/s at 1e-3, so the series starts at 1e-3. */
    static double com[3][NSAMPLE + 1];
    const double dts[3] = {1e-3, 5e-4, 2.5e-4};
    for (int r = 0; r < 3; r++) {
        int w = -1;
        blob_drop(dts[r], com[r], &w);
        CHECK(w == (int)lround(0.05 / dts[r]), "dt=%g: history window %d steps, want memory/dt", dts[r],
              w);
    }
    if (getenv("STF_TEST_VERBOSE"))
        for (int k = 0; k <= NSAMPLE; k++)
            printf("t=%.3f  %.5f %.5f %.5f\n", k * T_SAMPLE, com[0][k], com[1][k], com[2][k]);
    /* The blob did fall and land: the COM starts at 0.13 m and ends in a puddle. */
    CHECK(com[2][0] > 0.12 && com[2][NSAMPLE] < 0.03, "COM %g -> %g: the blob did not land",
          com[2][0], com[2][NSAMPLE]);

    /* Before contact (the bottom layer reaches the floor's margin at t = 0.143 s) the
       internal forces cancel and the COM follows symplectic Euler exactly:
       z_n = z_0 - g dt^2 n (n+1) / 2, i.e. off from z_0 - g t^2/2 by g t dt / 2 (0.59 mm at
       t = 0.12 s, dt = 1e-3). So up to 0.12 s (the lowest particles are then still 3 cm above
       the floor; at 0.135 s some already touch it at dt = 2.5e-4) the runs differ by exactly
       that: first order, the dt/2-vs-dt/4 difference half the dt-vs-dt/2 one. */
    int k_pre = (int)lround(0.12 / T_SAMPLE);
    for (int r = 0; r < 3; r++)
        for (int k = 0; k <= k_pre; k++) {
            double t = k * T_SAMPLE, nst = t / dts[r];
            /* from the measured start: blocks are jittered off the lattice (def.jitter) */
            double want = com[r][0] - 9.81 * dts[r] * dts[r] * nst * (nst + 1) / 2;
            CHECK(fabs(com[r][k] - want) < 1e-9, "dt=%g t=%g: COM %.12g, free fall gives %.12g",
                  dts[r], t, com[r][k], want);
        }
    double i01 = max_diff(com[0], com[1], k_pre), i12 = max_diff(com[1], com[2], k_pre);
    printf("dt convergence, t <= 0.12 s: max |COM(dt)-COM(dt/2)| = %.3g m, "
           "|COM(dt/2)-COM(dt/4)| = %.3g m (ratio %.3f)\n", i01, i12, i12 / i01);
    CHECK(fabs(i12 / i01 - 0.5) < 1e-3, "free fall: error ratio %g, first order gives 0.5",
          i12 / i01);

    /* The whole 0.3 s, through the splash and the settling puddle. Here the difference is
       set by which particles end up in which layer of the two-layer puddle (one particle
       moving a layer shifts the COM by 1 cm / 216 = 0.05 mm), so successive halvings are
       noisy at the 0.1 mm level (measured 0.73 then 0.92 mm). Against a reference at dt/8,
       the RMS error over the run must still fall from dt to dt/4 (two halvings), and dt/2
       vs dt/4 must agree within half a spacing (5 mm), the particle collision margin. */
    static double ref[NSAMPLE + 1];
    int wref = -1;
    blob_drop(dts[0] / 8, ref, &wref);
    double e01 = max_diff(com[0], com[1], NSAMPLE), e12 = max_diff(com[1], com[2], NSAMPLE);
    double rms[3] = {0, 0, 0};
    for (int r = 0; r < 3; r++) {
        for (int k = 0; k <= NSAMPLE; k++) rms[r] += (com[r][k] - ref[k]) * (com[r][k] - ref[k]);
        rms[r] = sqrt(rms[r] / (NSAMPLE + 1));
    }
    printf("dt convergence, t <= 0.3 s: max |COM(dt)-COM(dt/2)| = %.3g m, "
           "|COM(dt/2)-COM(dt/4)| = %.3g m; RMS vs dt/8: %.3g %.3g %.3g m\n",
           e01, e12, rms[0], rms[1], rms[2]);
    CHECK(rms[2] < rms[0], "error does not shrink with dt: RMS %g at dt/4 >= %g at dt", rms[2],
          rms[0]);
    CHECK(e12 < 0.005, "dt/2 vs dt/4: COM trajectories differ by %g m (tolerance 5 mm = half a "
          "spacing)", e12);
}

/* One refused def: rc -1, *field the member, the message "NAME: ..." (NAME the scene key's). */
static void expect_field(const stf_fluid_def *d, const char *field, const char *message)
{
    char msg[256] = "";
    const char *got = "unset";
    int rc = stf_fluid_check_def(d, msg, sizeof msg, &got);
    CHECK(rc == -1 && got && !strcmp(got, field) && strstr(msg, message) == msg,
          "want field %s and '%s...': rc %d, field %s, message '%s'", field, message, rc,
          got ? got : "NULL", msg);
}

static void test_check_def(void)
{
    stf_fluid_def d = stf_default_fluid_def();
    const char *field = "unset";
    CHECK(stf_fluid_check_def(&d, err, sizeof err, &field) == 0 && field == NULL,
          "the default def: %s", err);
#define BAD_FIELD(member, value, field, message)                                              \
    do {                                                                                      \
        d = stf_default_fluid_def();                                                          \
        d.member = value;                                                                     \
        expect_field(&d, field, message);                                                     \
    } while (0)
    BAD_FIELD(spacing, -1, "spacing", "spacing: must be > 0");
    BAD_FIELD(spacing, 2, "spacing", "spacing: must be > 0 and <= 1 m");
    BAD_FIELD(h, 0.001, "h", "h: must be 0 or in [spacing, 5*spacing]");
    BAD_FIELD(d, 100001, "d", "d: must be >= 1 and <= 100000");
    BAD_FIELD(material_spacing, 2, "material_spacing", "reference_spacing: ");
    BAD_FIELD(sigma, -1, "sigma", "sigma: must be >= 0");
    BAD_FIELD(k, 0, "k", "k: must be > 0");
    BAD_FIELD(spring_damping, 0.1, "spring_damping", "damping: needs relaxation gauss_seidel");
    BAD_FIELD(k_onset, -1, "k_onset", "k_onset: must be >= 0 (got -1)");
    BAD_FIELD(q, 1, "q", "q: must be in (0,1)");
    BAD_FIELD(stick, NAN, "stick", "stick: must be >= 0");
    d = stf_default_fluid_def();
    d.history_mode = STF_HISTORY_FULL, d.d = 0; /* d is the window unless memory > 0 */
    expect_field(&d, "d", "d: must be >= 1");
    d.memory = 1;
    CHECK(stf_fluid_check_def(&d, err, sizeof err, NULL) == 0, "d with memory: %s", err);
    d = stf_default_fluid_def();
    d.material_spacing = 0.02, d.h = 0.02; /* the material scales with h / spacing fixed */
    expect_field(&d, "h", "h: must be 0 (2 spacings) with a reference_spacing");
    d = stf_default_fluid_def();
    d.material_spacing = 0.02, d.reference_spacing = 0.02; /* the newer key is the one kept */
    expect_field(&d, "reference_spacing", "reference_spacing: give the material's");
    /* the Carreau-Yasuda fields (cy_check_def) */
    d = stf_default_fluid_def();
    d.model = STF_MODEL_CARREAU_YASUDA;
    expect_field(&d, "effects", "effects: the carreau_yasuda model");
    d.effects = STF_EFFECT_GRAVITY;
    d.cy.relaxation = 2;
    expect_field(&d, "cy.relaxation", "relaxation: ");
    d.cy.relaxation = 0, d.cy.max_pressure_iterations = 1;
    expect_field(&d, "cy.max_pressure_iterations", "max_pressure_iterations: must be >= min");
    d.cy.max_pressure_iterations = 10001;
    expect_field(&d, "cy.max_pressure_iterations", "max_pressure_iterations: must be <= 10000");
    d.cy.max_pressure_iterations = 100, d.cy.max_cg_iterations = 100001;
    expect_field(&d, "cy.max_cg_iterations", "max_cg_iterations: must be <= 100000");
    d.cy.max_cg_iterations = 200, d.cy.dt_max = 0.01;
    expect_field(&d, "cy.dt_max", "dt_max: only with cfl");
    d.cy.dt_max = 0, d.periodic[1] = 0.01;
    expect_field(&d, "periodic", "periodic: a period must be >= 3 h");
    /* err may be NULL, field too */
    d = stf_default_fluid_def();
    d.jitter = 1;
    CHECK(stf_fluid_check_def(&d, NULL, 0, NULL) == -1, "no buffers");
    d.model = STF_MODEL_CARREAU_YASUDA, d.effects = 0, d.cy.n = 0;
    char tiny[4];
    CHECK(stf_fluid_check_def(&d, tiny, sizeof tiny, &field) == -1 && !strcmp(field, "cy.n") &&
              !strcmp(tiny, "n: "),
          "a short buffer still names the field: %s, '%s'", field, tiny);
#undef BAD_FIELD
}

int main(int argc, char **argv)
{
    /* Threads that sleep rather than spin at barriers: on a machine busy with other tests the
       2-thread runs of test_determinism are otherwise many times slower (measured 54 s
       instead of 0.6 s). libgomp reads the policy at start-up, hence the re-exec. Results do
       not depend on it. */
    if (argc > 0 && !getenv("OMP_WAIT_POLICY")) {
        setenv("OMP_WAIT_POLICY", "passive", 1);
        execv("/proc/self/exe", argv);
        /* no /proc: go on with the default policy */
    }
    /* One thread, except where the thread count is the subject (test_determinism): OpenMP's
       spinning threads are slow on a machine busy with other tests, and results do not
       depend on the count (which test_determinism checks). */
    stf_set_threads(1);
    test_check_def();
    double t0 = omp_get_wtime();
    test_momentum();
    test_projection();
    test_spring_search();
    double t1 = omp_get_wtime();
    test_containment();
    double t2 = omp_get_wtime();
    test_effects_off();
    double t3 = omp_get_wtime();
    test_determinism();
    test_emit_remove();
    double t4 = omp_get_wtime();
    test_dt_convergence();
    double t5 = omp_get_wtime();
    printf("seconds: momentum %.2f, containment %.2f, effects %.2f, determinism %.2f, dt %.2f\n",
           t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4);
    return test_result("test_fluid");
}
