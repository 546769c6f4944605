/* test_cy.c - fast checks of the Carreau-Yasuda model (the physics is in cy_validate.c):
 * Eq. 3 and its limits, the rest density of the lattice, a block at rest staying at rest,
 * a periodic box seeing the same neighbourhoods as an infinite lattice, the scene keys. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "stf_ode.h"
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
static uint64_t falling_block_hash_far(int threads, int far)
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
    /* a few particles 30 m away: the dense neighbour box would be too large, and the shared
       hashed grid (Verlet lists, re-sorts) is used instead */
    if (far) stf_fluid_add_block(f, (double[3]){30, 30, 30}, (double[3]){30.04, 30.04, 30.04}, z);
    for (int k = 0; k < 40; k++) CHECK(stf_fluid_step(f, 1e-3) == 0, "step %d", k);
    uint64_t h = stf_fluid_hash(f);
    stf_fluid_destroy(f);
    return h;
}

static void test_threads(void)
{
    for (int far = 0; far < 2; far++) {
        uint64_t h1 = falling_block_hash_far(1, far), h2 = falling_block_hash_far(2, far),
                 h3 = falling_block_hash_far(3, far);
        CHECK(h1 == h2 && h1 == h3 && h1 != 0, "%s: 1, 2 and 3 threads differ: %llx %llx %llx",
              far ? "shared grid" : "dense lists", (unsigned long long)h1,
              (unsigned long long)h2, (unsigned long long)h3);
    }
    stf_set_threads(1);
}

/* Periodic in x and y, a floor, the warm start with relaxation, CFL substeps, and an
 * obstacle: the same state bit for bit with 1, 2 and 3 threads (3 splits the particles
 * unevenly). */
static uint64_t periodic_flow_hash(int threads, int solver)
{
    stf_set_threads(threads);
    stf_fluid_def d = stf_default_fluid_def();
    d.model = STF_MODEL_CARREAU_YASUDA;
    d.effects = STF_EFFECT_GRAVITY;
    d.spacing = 0.02, d.density = 1000, d.jitter = 0.2;
    d.gravity[0] = 3, d.gravity[1] = 1, d.gravity[2] = -9.3;
    d.cy.mu0 = 0.2, d.cy.mu_inf = 0.001, d.cy.K = 5, d.cy.n = 0.5;
    d.cy.warm_start = 0.5, d.cy.relaxation = 0.7, d.cy.cfl = 0.3;
    d.cy.viscosity_solver = solver;
    d.periodic[0] = 0.14, d.periodic[1] = 0.12;
    d.periodic_origin[0] = -0.07, d.periodic_origin[1] = -0.06;
    stf_fluid *f = make(&d);
    if (!f) return 0;
    stf_collider_def c = stf_default_collider_def();
    c.shape = STF_SHAPE_BOX;
    c.half[0] = 0.5, c.half[1] = 0.5, c.half[2] = 0.05;
    char err[256];
    int id = stf_fluid_add_collider(f, &c, err, sizeof err);
    CHECK(id >= 0, "%s", err);
    double rot[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, z[3] = {0, 0, 0}, p[3] = {0, 0, -0.05};
    stf_fluid_set_collider_state(f, id, p, rot, z, z);
    stf_collider_def s = stf_default_collider_def();
    s.shape = STF_SHAPE_SPHERE;
    s.radius = 0.025;
    int ids = stf_fluid_add_collider(f, &s, err, sizeof err);
    CHECK(ids >= 0, "%s", err);
    double ps[3] = {0.0, 0.0, 0.03};
    stf_fluid_set_collider_state(f, ids, ps, rot, z, z);
    stf_fluid_add_block(f, (double[3]){-0.07, -0.06, 0.0}, (double[3]){0.07, 0.06, 0.08},
                        (double[3]){0.5, 0, 0});
    for (int k = 0; k < 30; k++) CHECK(stf_fluid_step(f, 4e-3) == 0, "step %d: %s", k, stf_fluid_failure(f));
    stf_solver_stats st;
    stf_fluid_solver_stats(f, &st);
    CHECK(st.substeps >= 1, "substeps %d", st.substeps);
    uint64_t h = stf_fluid_hash(f);
    stf_fluid_destroy(f);
    return h;
}

static void test_threads_periodic(void)
{
    for (int solver = 0; solver < 2; solver++) {
        int sv = solver ? STF_VISCOSITY_EXPLICIT : STF_VISCOSITY_IMPLICIT;
        uint64_t h1 = periodic_flow_hash(1, sv), h2 = periodic_flow_hash(2, sv),
                 h3 = periodic_flow_hash(3, sv);
        CHECK(h1 == h2 && h1 == h3 && h1 != 0, "periodic (%s): 1, 2, 3 threads differ: %llx %llx %llx",
              solver ? "explicit" : "implicit", (unsigned long long)h1, (unsigned long long)h2,
              (unsigned long long)h3);
    }
    stf_set_threads(1);
}

/* Gravity off, no container: an ODE ball shot into a blob of viscous fluid. Whatever the
 * fluid takes, the ball gives (pressure, viscous and collision impulses go back to it), with
 * either viscosity solver. */
static void momentum_case(int solver, double mu0, double cg_tol)
{
    dWorldID w = dWorldCreate();
    dSpaceID sp = dHashSpaceCreate(0);
    dWorldSetGravity(w, 0, 0, 0);
    stf_fluid_def d = stf_default_fluid_def();
    d.model = STF_MODEL_CARREAU_YASUDA;
    d.effects = 0;
    d.spacing = 0.01, d.density = 1000, d.jitter = 0.2;
    d.cy.mu0 = mu0, d.cy.mu_inf = 0.1 * mu0, d.cy.K = 1, d.cy.n = 1.5;
    d.cy.viscosity_solver = solver;
    d.cy.cg_tolerance = cg_tol;
    stf_fluid *f = make(&d);
    if (!f) return;
    stf_fluid_add_block(f, (double[3]){-0.04, -0.04, -0.04}, (double[3]){0.04, 0.04, 0.04},
                        (double[3]){0, 0, 0});
    dBodyID ball = dBodyCreate(w);
    dMass m;
    dMassSetSphereTotal(&m, 0.3, 0.02);
    dBodySetMass(ball, &m);
    dBodySetPosition(ball, -0.07, 0.003, 0.002);
    dGeomSetBody(dCreateSphere(sp, 0.02), ball);
    dBodySetLinearVel(ball, 1.0, 0, 0);
    stf_ode *c = stf_ode_create(w, sp, f);
    char err[256];
    CHECK(stf_ode_attach_body(c, ball, NULL, err, sizeof err) == 0, "%s", err);
    int n = stf_fluid_count(f);
    double *v = malloc((size_t)n * 3 * sizeof *v), p0[3] = {0.3, 0, 0}, p1[3] = {0, 0, 0};
    for (int k = 0; k < 40; k++) CHECK(stf_ode_step(c, 1e-3) == 0, "step %d", k);
    stf_fluid_get_velocities(f, v);
    for (int i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) p1[a] += stf_fluid_particle_mass(f) * v[3 * i + a];
    const dReal *bv = dBodyGetLinearVel(ball);
    double moved = 0.3 - 0.3 * bv[0], e2 = 0;
    for (int a = 0; a < 3; a++) p1[a] += 0.3 * bv[a], e2 += (p1[a] - p0[a]) * (p1[a] - p0[a]);
    printf("cy momentum (%s): ball gave %.4g N s; total changed by %.3g N s\n",
           solver == STF_VISCOSITY_EXPLICIT ? "explicit" : "implicit", moved, sqrt(e2));
    CHECK(moved > 0.01, "the ball hardly touched the fluid (%g N s)", moved);
    CHECK(sqrt(e2) < 1e-9 * 0.3, "%s: total momentum changed by %g N s",
          solver == STF_VISCOSITY_EXPLICIT ? "explicit" : "implicit", sqrt(e2));
    free(v);
    stf_ode_destroy(c);
    stf_fluid_destroy(f);
    dSpaceDestroy(sp);
    dWorldDestroy(w);
}

static void test_momentum(void)
{
    momentum_case(STF_VISCOSITY_IMPLICIT, 0.05, 1e-4);
    momentum_case(STF_VISCOSITY_IMPLICIT, 0.05, 1e-12);
    momentum_case(STF_VISCOSITY_EXPLICIT, 0.002, 1e-4);
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
    test_threads_periodic();
    dInitODE2(0);
    test_momentum();
    dCloseODE();
    return test_result("test_cy");
}
