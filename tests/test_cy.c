/* test_cy.c - fast checks of the Carreau-Yasuda model (the physics is in cy_validate.c):
 * Eq. 3 and its limits, the rest density of the lattice, a block at rest staying at rest,
 * a periodic box seeing the same neighbourhoods as an infinite lattice, the scene keys. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "test_util.h"
#include "stf.h"

static void test_viscosity_law(void)
{
    stf_cy_def c = stf_default_fluid_def().cy;
    c.mu0 = 2.0, c.mu_inf = 0.1, c.K = 0.5, c.alpha = 2, c.n = 1;
    CHECK_NEAR(stf_cy_viscosity(&c, 123.0), 2.0, 1e-15, "n = 1 is Newtonian with mu0");
    c.n = 0.5;
    CHECK_NEAR(stf_cy_viscosity(&c, 0.0), 2.0, 1e-15, "zero shear gives mu0");
    CHECK_NEAR(stf_cy_viscosity(&c, 1e12), 0.1, 1e-4, "infinite shear gives mu_inf (thinning)");
    /* Eq. 3 by hand at g = 4: (1 + (0.5*4)^2)^(-0.25) */
    CHECK_NEAR(stf_cy_viscosity(&c, 4.0), 0.1 + 1.9 * pow(5.0, -0.25), 1e-14, "Eq. 3");
    c.n = 1.5;
    CHECK(stf_cy_viscosity(&c, 10.0) > stf_cy_viscosity(&c, 1.0), "n > 1 thickens");
    c.n = 0.5;
    CHECK(stf_cy_viscosity(&c, 10.0) < stf_cy_viscosity(&c, 1.0), "n < 1 thins");
}

static stf_fluid *make(stf_fluid_def *d)
{
    char err[256];
    stf_fluid *f = NULL;
    if (stf_fluid_create(d, &f, err, sizeof err) != 0) fprintf(stderr, "%s\n", err);
    return f;
}

/* A fully periodic block without gravity is an infinite lattice at its rest density: it
 * must stay exactly at rest, and its rest density is the physical density to 1%. */
static void test_block_at_rest(void)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.model = STF_MODEL_CARREAU_YASUDA;
    d.effects = 0;
    d.spacing = 0.02, d.density = 1000, d.jitter = 0;
    d.cy.mu0 = d.cy.mu_inf = 0.01;
    for (int a = 0; a < 3; a++) d.periodic[a] = 0.12, d.periodic_origin[a] = 0;
    stf_fluid *f = make(&d);
    CHECK(f != NULL, "create");
    if (!f) return;
    stf_fluid_add_block(f, (double[3]){0, 0, 0}, (double[3]){0.12, 0.12, 0.12}, (double[3]){0, 0, 0});
    double rho0 = stf_fluid_cy_rest_density(f);
    printf("cy: rest density of the lattice %.3f kg/m^3 (density 1000)\n", rho0);
    CHECK(fabs(rho0 / 1000 - 1) < 0.01, "rest density %g", rho0);
    for (int k = 0; k < 20; k++) CHECK(stf_fluid_step(f, 1e-3) == 0, "step %d", k);
    int n = stf_fluid_count(f);
    double *v = malloc((size_t)n * 3 * sizeof *v), vmax = 0;
    stf_fluid_get_velocities(f, v);
    for (int i = 0; i < 3 * n; i++) vmax = fabs(v[i]) > vmax ? fabs(v[i]) : vmax;
    CHECK(vmax < 1e-12, "periodic lattice at rest moved: %g m/s", vmax);
    stf_solver_stats st;
    stf_fluid_solver_stats(f, &st);
    CHECK(st.pressure_iterations == 2, "iterations %d (the minimum is 2)", st.pressure_iterations);
    CHECK(st.density_error < 1e-12, "density error %g", st.density_error);
    char buf[2048];
    stf_fluid_describe(f, buf, sizeof buf);
    CHECK(strstr(buf, "model: carreau_yasuda") && strstr(buf, "mu0: 0.01"), "describe: %s", buf);
    free(v);
    stf_fluid_destroy(f);
}

/* A block falling into a container: the same state bit for bit with 1 and 2 threads (every
 * loop gathers per particle; the sums over particles are serial). */
static uint64_t falling_block_hash(int threads)
{
    stf_set_threads(threads);
    stf_fluid_def d = stf_default_fluid_def();
    d.model = STF_MODEL_CARREAU_YASUDA;
    d.effects = STF_EFFECT_GRAVITY;
    d.spacing = 0.02, d.density = 1000, d.jitter = 0;
    d.cy.mu0 = 0.5, d.cy.mu_inf = 0.001, d.cy.n = 0.5;
    stf_fluid *f = make(&d);
    if (!f) return 0;
    stf_collider_def c = stf_default_collider_def();
    c.shape = STF_SHAPE_CONTAINER;
    c.half[0] = c.half[1] = 0.1, c.half[2] = 0.2;
    char err[256];
    int id = stf_fluid_add_collider(f, &c, err, sizeof err);
    double rot[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, z[3] = {0, 0, 0};
    stf_fluid_set_collider_state(f, id, z, rot, z, z);
    stf_fluid_add_block(f, (double[3]){-0.1, -0.1, 0.05}, (double[3]){0.0, 0.1, 0.15}, z);
    for (int k = 0; k < 40; k++) CHECK(stf_fluid_step(f, 1e-3) == 0, "step %d", k);
    uint64_t h = stf_fluid_hash(f);
    stf_fluid_destroy(f);
    return h;
}

static void test_threads(void)
{
    uint64_t h1 = falling_block_hash(1), h2 = falling_block_hash(2);
    CHECK(h1 == h2 && h1 != 0, "1 and 2 threads differ: %llx vs %llx", (unsigned long long)h1,
          (unsigned long long)h2);
}

static void test_bad_defs(void)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.model = STF_MODEL_CARREAU_YASUDA;
    char err[256];
    stf_fluid *f;
    CHECK(stf_fluid_create(&d, &f, err, sizeof err) != 0 && strstr(err, "effects"),
          "Clavet effects with the CY model: %s", err);
    d.effects = STF_EFFECT_GRAVITY;
    d.cy.n = 0;
    CHECK(stf_fluid_create(&d, &f, err, sizeof err) != 0 && strstr(err, "n:"), "n = 0: %s", err);
    d.cy.n = 1;
    d.periodic[0] = 0.01;
    CHECK(stf_fluid_create(&d, &f, err, sizeof err) != 0 && strstr(err, "periodic"),
          "short period: %s", err);
    d = stf_default_fluid_def();
    d.periodic[0] = 1;
    CHECK(stf_fluid_create(&d, &f, err, sizeof err) != 0 && strstr(err, "periodic"),
          "periodic Clavet: %s", err);
}

static void test_scene_keys(void)
{
    const char *ok = "duration: 1\nfluid:\n  model: carreau_yasuda\n  spacing: 0.05\n"
                     "  blocks: [{min: [0, 0, 0], max: [0.2, 0.2, 0.2]}]\n"
                     "effects:\n  gravity: {}\n  carreau_yasuda: {mu0: 0.5, mu_inf: 0.01, K: 2, "
                     "alpha: 1.5, n: 0.7, eta: 0.005, viscosity_solver: explicit, "
                     "cg_tolerance: 1e-6, min_pressure_iterations: 3, max_pressure_iterations: 50, "
                     "max_cg_iterations: 77}\n";
    stf_scene *s = NULL;
    char err[512];
    CHECK(stf_scene_load_string("ok.yaml", ok, NULL, 0, &s, err, sizeof err) == 0, "%s", err);
    if (s) {
        const stf_cy_def *c = &s->fluid.cy;
        CHECK(s->fluid.model == STF_MODEL_CARREAU_YASUDA, "model");
        CHECK(c->mu0 == 0.5 && c->mu_inf == 0.01 && c->K == 2 && c->alpha == 1.5 && c->n == 0.7 &&
                  c->eta == 0.005 && c->cg_tolerance == 1e-6 && c->min_pressure_iterations == 3 &&
                  c->max_pressure_iterations == 50 && c->max_cg_iterations == 77 &&
                  c->viscosity_solver == STF_VISCOSITY_EXPLICIT,
              "keys not read");
        CHECK(s->fluid.jitter == 0, "CY blocks start on the lattice (jitter %g)", s->fluid.jitter);
        stf_scene_free(s);
    }
    stf_override ov = {"effects.carreau_yasuda.eta", "1.5"};
    CHECK(stf_scene_load_string("ok.yaml", ok, &ov, 1, &s, err, sizeof err) == 2 &&
              strstr(err, "--set effects.carreau_yasuda.eta=1.5: effects.carreau_yasuda.eta: must be in (0,1)"),
          "eta = 1.5: %s", err);
    stf_override ov2 = {"effects.carreau_yasuda.min_pressure_iterations", "60"};
    CHECK(stf_scene_load_string("ok.yaml", ok, &ov2, 1, &s, err, sizeof err) == 2 &&
              strstr(err, "max_pressure_iterations must be >= min_pressure_iterations"),
          "min > max: %s", err);
}

int main(void)
{
    test_viscosity_law();
    test_block_at_rest();
    test_bad_defs();
    test_scene_keys();
    test_threads();
    return test_result("test_cy");
}
