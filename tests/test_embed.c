/* test_embed.c - the fluid inside an ODE application's own loop (ode_glue/stf_ode.h): app
 * steps of 1/60 and 1/30 s split into stable substeps, the app's own contacts through the
 * collision hook, dWorldQuickStep, and the defs' checks. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "stf_sim.h"
#include "test_util.h"
#include "sim_util.h"

/* The stability tests' pool (tests/scenes/stab_pool.yaml): 864 particles of 1 cm in a
 * 12 x 12 cm container, every effect on, a 2.5 cm ball thrown in at 2 m/s. */
static const char *const pool_scene =
    "name: embed_pool\n"
    "duration: 0.4\n"
    "dt: 0.001\n"
    "fluid:\n"
    "  spacing: 0.01\n"
    "  density: 1270\n"
    "  blocks:\n"
    "    - {min: [-0.06, -0.06, 0.0], max: [0.06, 0.06, 0.06]}\n"
    "effects:\n"
    "  gravity: {g: [0, 0, -9.81]}\n"
    "  viscosity: {sigma: 10.0}\n"
    "  pressure: {k: 1000, k_near: 200}\n"
    "  springs: {k_min: 100, yield_ratio: 0.0, plasticity: 2.0}\n"
    "  history: {q: 0.5, d: 50, k_hist: 200000, reference_spacing: 0.02}\n"
    "  boundary_stick: {stick: 200}\n"
    "container:\n"
    "  size: [0.12, 0.12, 0.2]\n"
    "  wall: 0.02\n"
    "  friction: 0.2\n"
    "bodies:\n"
    "  - {name: ball, shape: sphere, radius: 0.025, density: 1370, position: [0, 0, 0.12],\n"
    "     velocity: [0.3, 0, -2.0], friction: 0.3}\n";

enum { MAXS = 4096 };
typedef struct path {
    int n;
    double t[MAXS], x[MAXS][3];
    stf_ode_stats st;
    int ok;
} path;

/* The pool scene stepped by an app at dt for T seconds (stf_ode_step on the scene's world,
 * the coupler colliding its space): the ball's centre after every step. */
static void run_pool(double dt, double T, path *p)
{
    stf_scene *sc;
    stf_sim *s = load_sim("embed_pool.yaml", pool_scene, &sc);
    p->n = 0;
    p->ok = 0;
    if (!s) return;
    int steps = (int)lround(T / dt);
    const dReal *x0 = dBodyGetPosition(s->bodies[0]);
    p->t[0] = 0;
    memcpy(p->x[0], (double[3]){x0[0], x0[1], x0[2]}, sizeof p->x[0]);
    p->n = 1;
    p->ok = 1;
    for (int k = 0; k < steps && p->n < MAXS; k++) {
        if (stf_ode_step(s->coupler, dt) != 0) {
            CHECK(0, "app step %d of %g s: %s", k, dt, stf_ode_failure(s->coupler));
            p->ok = 0;
            break;
        }
        const dReal *x = dBodyGetPosition(s->bodies[0]);
        p->t[p->n] = (k + 1) * dt;
        for (int a = 0; a < 3; a++) p->x[p->n][a] = x[a];
        p->n++;
    }
    stf_ode_get_stats(s->coupler, &p->st);
    stf_sim_destroy(s);
    stf_scene_free(sc);
}

/* The ball's centre of path p at time t (linear between p's steps). */
static void at(const path *p, double t, double x[3])
{
    int k = 0;
    while (k + 2 < p->n && p->t[k + 1] < t) k++;
    double u = (t - p->t[k]) / (p->t[k + 1] - p->t[k]);
    for (int a = 0; a < 3; a++) x[a] = p->x[k][a] + u * (p->x[k + 1][a] - p->x[k][a]);
}

/* Largest distance between two paths at the steps of b. */
static double path_gap(const path *a, const path *b, double *when)
{
    double worst = 0;
    for (int k = 1; k < b->n; k++) {
        double xa[3];
        at(a, b->t[k], xa);
        double d = sqrt((xa[0] - b->x[k][0]) * (xa[0] - b->x[k][0]) +
                        (xa[1] - b->x[k][1]) * (xa[1] - b->x[k][1]) +
                        (xa[2] - b->x[k][2]) * (xa[2] - b->x[k][2]));
        if (d > worst) worst = d, *when = b->t[k];
    }
    return worst;
}

/* App steps of 1/60 and 1/30 s follow the path of the 1 ms run. The ball falls 3.5 cm, sinks
 * into the pool, bounces back up 3 cm (the fluid stiffens) and settles at 0.3 s.
 * Tolerance: fluid (symplectic Euler) and ODE (semi-implicit Euler) are first-order in the
 * substep, x_dt = x + C dt. The 0.5 ms run measures C: |x_1ms - x_0.5ms| = C 0.5 ms, and a
 * run of substeps no longer than dt_max lies within C (dt_max - 1 ms) of the 1 ms path.
 * Measured: 0.5 ms vs 1 ms 5.2 mm; 1/60 s (substeps of at most 2.08 ms) 3.6 mm against a
 * bound of 11 mm; 1/30 s (2.22 ms) 9.2 mm against 13 mm. Where the ball comes to rest is a
 * balance of its weight and the fluid's support, resolved to about half a spacing
 * (test_coupling's Archimedes tests): the final heights within 5 mm (measured 0.1, 2 mm). */
static void test_app_steps(void)
{
    static path fine, ref, p60, p30;
    const double T = 0.4, spacing = 0.01;
    run_pool(0.0005, T, &fine);
    run_pool(0.001, T, &ref);
    run_pool(1.0 / 60, T, &p60);
    run_pool(1.0 / 30, T, &p30);
    if (!fine.ok || !ref.ok || !p60.ok || !p30.ok) return;
    double w0 = 0, w60 = 0, w30 = 0;
    double e0 = path_gap(&fine, &ref, &w0), e60 = path_gap(&ref, &p60, &w60),
           e30 = path_gap(&ref, &p30, &w30);
    const path *all[4] = {&fine, &ref, &p60, &p30};
    for (int k = 0; k < 4; k++)
        printf("app steps of %.4g s: %ld steps, %ld substeps of %.3g to %.3g ms, %ld capped; "
               "ball at rest at z = %.4f m\n", all[k]->t[1], all[k]->st.steps, all[k]->st.substeps,
               1e3 * all[k]->st.dt_min, 1e3 * all[k]->st.dt_max, all[k]->st.capped,
               all[k]->x[all[k]->n - 1][2]);
    double C = e0 / 0.0005, b60 = C * (p60.st.dt_max - 0.001), b30 = C * (p30.st.dt_max - 0.001);
    printf("ball path: 0.5 ms vs 1 ms %.3g mm (t %.3f s); 1/60 s vs 1 ms %.3g mm (t %.3f s, "
           "bound %.3g mm); 1/30 s vs 1 ms %.3g mm (t %.3f s, bound %.3g mm)\n", 1e3 * e0, w0,
           1e3 * e60, w60, 1e3 * b60, 1e3 * e30, w30, 1e3 * b30);
    CHECK(p60.st.substeps > p60.st.steps && p30.st.substeps > p30.st.steps,
          "the app steps were not split (%ld and %ld substeps)", p60.st.substeps, p30.st.substeps);
    CHECK(e60 <= b60, "1/60 s: the ball's path is %g m off the 1 ms path (bound %g m)", e60, b60);
    CHECK(e30 <= b30, "1/30 s: the ball's path is %g m off the 1 ms path (bound %g m)", e30, b30);
    double zr = ref.x[ref.n - 1][2];
    CHECK_NEAR(p60.x[p60.n - 1][2], zr, 0.5 * spacing, "1/60 s: rest height");
    CHECK_NEAR(p30.x[p30.n - 1][2], zr, 0.5 * spacing, "1/30 s: rest height");
}

/* Unsplit, the same 1/60 s step is 14 times past the pressure's stability bound (k/h dt^2 =
 * 5e4 / 3600 = 14; measured unstable from 0.45): the fluid blows up. */
static void test_unsplit_fails(void)
{
    stf_scene *sc;
    stf_sim *s = load_sim("embed_pool.yaml", pool_scene, &sc);
    if (!s) return;
    char err[256];
    stf_ode_step_def sd = stf_ode_default_step_def();
    sd.adaptive = 0;
    CHECK(stf_ode_set_step(s->coupler, &sd, err, sizeof err) == 0, "%s", err);
    int failed_at = -1;
    for (int k = 0; k < 24 && failed_at < 0; k++)
        if (stf_ode_step(s->coupler, 1.0 / 60) != 0) failed_at = k;
    printf("unsplit 1/60 s steps: %s at step %d\n", stf_ode_failure(s->coupler), failed_at);
    CHECK(failed_at >= 0, "24 unsplit steps of 1/60 s ran: the split is not what keeps it stable");
    CHECK(strstr(stf_ode_failure(s->coupler), "blew up") != NULL, "failure: %s",
          stf_ode_failure(s->coupler));
    stf_sim_destroy(s);
    stf_scene_free(sc);
    /* With max_substeps 4 the first step asks for 8 (the pressure: (1/60) sqrt(5e4 / 0.25)
       = 7.5) and takes 4, counted as capped, not hidden. */
    s = load_sim("embed_pool.yaml", pool_scene, &sc);
    if (!s) return;
    sd = stf_ode_default_step_def();
    sd.max_substeps = 4;
    CHECK(stf_ode_set_step(s->coupler, &sd, err, sizeof err) == 0, "%s", err);
    int want = stf_ode_substeps(s->coupler, 1.0 / 60);
    stf_ode_step(s->coupler, 1.0 / 60);
    stf_ode_stats st;
    stf_ode_get_stats(s->coupler, &st);
    printf("max_substeps 4: %d substeps planned, %ld taken, %ld capped\n", want, st.substeps,
           st.capped);
    CHECK(want == 4 && st.substeps == 4 && st.capped == 1, "planned %d, took %ld, capped %ld", want,
          st.substeps, st.capped);
    stf_sim_destroy(s);
    stf_scene_free(sc);
}

/* ------------------------------------------------------------ the app's own contacts */

typedef struct app {
    dWorldID world;
    dSpaceID space;
    dJointGroupID group; /* the app's own contact group */
    long calls;          /* collision hook calls */
    int make_contacts;   /* 0: the hook makes none (the control) */
} app;

static void app_near(void *data, dGeomID g1, dGeomID g2)
{
    app *a = data;
    dBodyID b1 = dGeomGetBody(g1), b2 = dGeomGetBody(g2);
    if (!b1 && !b2) return;
    dContact ct[4];
    int n = dCollide(g1, g2, 4, &ct[0].geom, sizeof(dContact));
    for (int i = 0; i < n; i++) {
        ct[i].surface.mode = dContactSoftCFM | dContactApprox1;
        ct[i].surface.mu = 0.6;
        ct[i].surface.soft_cfm = 1e-6;
        dJointAttach(dJointCreateContact(a->world, a->group, &ct[i]), b1, b2);
    }
}

static void app_collide(void *data, dJointGroupID contacts, double dt)
{
    app *a = data;
    a->calls++;
    dJointGroupEmpty(a->group); /* the last substep's contacts */
    if (a->make_contacts) dSpaceCollide(a->space, a, app_near);
}

/* A steel box (4 x 4 x 2 cm) on the floor of a fixed container under 6 cm of fluid, the floor
 * an ODE box the app collides: stepped at 1/60 s for 1 s. Returns the box's drift from
 * 0.3 s to 1 s (m) and its final height in *z. */
static double box_on_floor(int make_contacts, int stepper, app *out, stf_ode_stats *st, double *z)
{
    const double spacing = 0.01, L = 0.12, depth = 0.06, hz = 0.01;
    app a = {.world = dWorldCreate(), .space = dHashSpaceCreate(0), .group = dJointGroupCreate(0),
             .make_contacts = make_contacts};
    dWorldSetGravity(a.world, 0, 0, -9.81);
    stf_fluid_def d = stf_default_fluid_def();
    d.effects = STF_EFFECT_GRAVITY | STF_EFFECT_VISCOSITY | STF_EFFECT_PRESSURE;
    d.spacing = spacing;
    d.jitter = 0;
    char err[256];
    stf_fluid *f = NULL;
    CHECK(stf_fluid_create(&d, &f, err, sizeof err) == 0, "%s", err);
    if (!f) return 0;
    stf_fluid_add_block(f, (double[3]){-L / 2, -L / 2, 0}, (double[3]){L / 2, L / 2, depth},
                        (double[3]){0, 0, 0});
    dGeomID floor_geom = dCreateBox(a.space, L + 0.04, L + 0.04, 0.02);
    dGeomSetPosition(floor_geom, 0, 0, -0.01);
    dBodyID box = dBodyCreate(a.world);
    dMass m;
    dMassSetBoxTotal(&m, 7800 * 0.04 * 0.04 * 2 * hz, 0.04, 0.04, 2 * hz);
    dBodySetMass(box, &m);
    dBodySetPosition(box, 0.003, -0.002, hz);
    dGeomSetBody(dCreateBox(a.space, 0.04, 0.04, 2 * hz), box);
    /* the coupler gets the space too: with a hook it must not collide it itself */
    stf_ode *c = stf_ode_create(a.world, a.space, f);
    CHECK(stf_ode_attach_container(c, 0, (double[3]){0, 0, 0}, (double[3]){L, L, 3 * depth}, 0.02,
                                   NULL, err, sizeof err) == 0, "%s", err);
    CHECK(stf_ode_attach_body(c, box, NULL, err, sizeof err) == 0, "%s", err);
    stf_ode_step_def sd = stf_ode_default_step_def();
    sd.stepper = stepper;
    sd.quick_iterations = 30;
    CHECK(stf_ode_set_step(c, &sd, err, sizeof err) == 0, "%s", err);
    stf_ode_remove_overlaps(c);
    stf_ode_set_collide(c, app_collide, &a);
    double start[3] = {0, 0, 0};
    for (int k = 0; k < 60; k++) {
        if (stf_ode_step(c, 1.0 / 60) != 0) {
            CHECK(0, "step %d: %s", k, stf_ode_failure(c));
            break;
        }
        if (k == 17) memcpy(start, dBodyGetPosition(box), sizeof start);
    }
    dJointGroupEmpty(a.group);
    if (stepper == STF_ODE_QUICK_STEP)
        CHECK(dWorldGetQuickStepNumIterations(a.world) == 30, "quick step iterations %d",
              dWorldGetQuickStepNumIterations(a.world));
    const dReal *e = dBodyGetPosition(box);
    double dx[3] = {e[0] - start[0], e[1] - start[1], e[2] - start[2]};
    double drift = sqrt(dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2]);
    *z = e[2];
    stf_ode_get_stats(c, st);
    *out = a;
    stf_ode_destroy(c);
    stf_fluid_destroy(f);
    dJointGroupDestroy(a.group);
    dSpaceDestroy(a.space);
    dWorldDestroy(a.world);
    return drift;
}

/* The hook is called once per substep, and its contacts hold the box on the floor (with
 * dWorldStep and with dWorldQuickStep); without them it falls through: the fluid's container
 * is not an ODE geom, and the coupler leaves the space to the hook. */
static void test_collision_hook(void)
{
    const double spacing = 0.01, hz = 0.01;
    const char *name[2] = {"dWorldStep", "dWorldQuickStep"};
    for (int q = 0; q < 2; q++) {
        app a;
        stf_ode_stats st;
        double z, drift = box_on_floor(1, q ? STF_ODE_QUICK_STEP : STF_ODE_WORLD_STEP, &a, &st, &z);
        printf("collision hook, %s: %ld calls for %ld substeps of %ld steps (%.3g to %.3g ms); "
               "box drift %.3g mm from 0.3 to 1 s, at z = %.5f m (resting height %.3f)\n", name[q],
               a.calls, st.substeps, st.steps, 1e3 * st.dt_min, 1e3 * st.dt_max, 1e3 * drift, z,
               hz);
        CHECK(a.calls == st.substeps && st.collide_calls == st.substeps,
              "%ld hook calls (%ld counted) for %ld substeps", a.calls, st.collide_calls,
              st.substeps);
        CHECK(st.steps == 60 && st.substeps > st.steps, "%ld substeps of %ld steps", st.substeps,
              st.steps);
        /* Tolerance: a quarter of a spacing. The fluid's lattice noise pushes on the box's
           faces; a box that slid or sank would go centimetres (free fall: 4.9 m in 1 s). */
        CHECK(drift < 0.25 * spacing, "%s: the box moved %g m", name[q], drift);
        CHECK(fabs(z - hz) < 0.25 * spacing, "%s: the box is at z = %g m, not on the floor",
              name[q], z);
    }
    app a;
    stf_ode_stats st;
    double z;
    box_on_floor(0, STF_ODE_WORLD_STEP, &a, &st, &z);
    printf("collision hook making no contacts: the box at z = %.3f m after 1 s\n", z);
    CHECK(z < -hz, "without the hook's contacts the box stayed at z = %g m", z);
}

/* ------------------------------------------------------------ the defs' checks */

static void expect_bad(int rc, const char *err, const char *field)
{
    CHECK(rc == -1 && strstr(err, field) != NULL, "rc %d, message '%s' does not name %s", rc, err,
          field);
}

static void test_defs(void)
{
    char err[256];
    stf_ode_contact_def cd = stf_ode_default_contact_def();
    CHECK(stf_ode_check_contact_def(&cd, err, sizeof err) == 0, "default contact def: %s", err);
    cd.mu = dInfinity;
    CHECK(stf_ode_check_contact_def(&cd, err, sizeof err) == 0, "mu = dInfinity: %s", err);
#define BAD_CONTACT(F, V)                                                                         \
    do {                                                                                          \
        stf_ode_contact_def b = stf_ode_default_contact_def();                                    \
        b.F = V;                                                                                  \
        err[0] = 0;                                                                               \
        expect_bad(stf_ode_check_contact_def(&b, err, sizeof err), err, #F " = ");               \
    } while (0)
    BAD_CONTACT(mu, -0.1);
    BAD_CONTACT(mu, NAN);
    BAD_CONTACT(bounce, 1.5);
    BAD_CONTACT(bounce, -0.1);
    BAD_CONTACT(bounce_vel, -1);
    BAD_CONTACT(bounce_vel, INFINITY);
    BAD_CONTACT(soft_erp, 0);
    BAD_CONTACT(soft_erp, 1.1);
    BAD_CONTACT(soft_cfm, -1e-5);
    BAD_CONTACT(soft_cfm, NAN);
    BAD_CONTACT(max_contacts, 0);
    BAD_CONTACT(max_contacts, STF_ODE_MAX_CONTACTS + 1);
    stf_ode_attach_def ad = stf_ode_default_attach_def();
    CHECK(stf_ode_check_attach_def(&ad, err, sizeof err) == 0, "default attach def: %s", err);
    ad.friction = 1.2;
    expect_bad(stf_ode_check_attach_def(&ad, err, sizeof err), err, "friction = ");
    ad.friction = NAN;
    expect_bad(stf_ode_check_attach_def(&ad, err, sizeof err), err, "friction = ");
    ad = stf_ode_default_attach_def();
    ad.stick = 2;
    expect_bad(stf_ode_check_attach_def(&ad, err, sizeof err), err, "stick = ");
    stf_ode_step_def sd = stf_ode_default_step_def();
    CHECK(stf_ode_check_step_def(&sd, err, sizeof err) == 0, "default step def: %s", err);
#define BAD_STEP(F, V)                                                                            \
    do {                                                                                          \
        stf_ode_step_def b = stf_ode_default_step_def();                                          \
        b.F = V;                                                                                  \
        err[0] = 0;                                                                               \
        expect_bad(stf_ode_check_step_def(&b, err, sizeof err), err, #F " = ");                  \
    } while (0)
    BAD_STEP(adaptive, 2);
    BAD_STEP(max_substeps, 0);
    BAD_STEP(stepper, 2);
    BAD_STEP(quick_iterations, 0);

    /* the setters and the attach functions check too, and keep what they had */
    dWorldID w = dWorldCreate();
    dSpaceID s = dHashSpaceCreate(0);
    stf_fluid_def fd = stf_default_fluid_def();
    fd.effects = STF_EFFECT_PRESSURE;
    stf_fluid *f = NULL;
    CHECK(stf_fluid_create(&fd, &f, err, sizeof err) == 0, "%s", err);
    if (!f) return;
    stf_ode *c = stf_ode_create(w, s, f);
    cd = stf_ode_default_contact_def();
    cd.bounce = 2;
    expect_bad(stf_ode_set_contact(c, &cd, err, sizeof err), err, "bounce = ");
    sd = stf_ode_default_step_def();
    sd.max_substeps = -3;
    expect_bad(stf_ode_set_step(c, &sd, err, sizeof err), err, "max_substeps = ");
    dBodyID b = dBodyCreate(w);
    dGeomSetBody(dCreateSphere(s, 0.02), b);
    ad = stf_ode_default_attach_def();
    ad.friction = -1;
    expect_bad(stf_ode_attach_body(c, b, &ad, err, sizeof err), err, "friction = ");
    expect_bad(stf_ode_attach_container(c, 0, (double[3]){0, 0, 0}, (double[3]){0.1, 0.1, 0.1},
                                        0.02, &ad, err, sizeof err), err, "friction = ");
    CHECK(stf_ode_step(c, 0) == -1 && strstr(stf_ode_failure(c), "dt = 0"), "dt 0: %s",
          stf_ode_failure(c));
    CHECK(stf_ode_step(c, NAN) == -1 && strstr(stf_ode_failure(c), "dt = "), "dt NaN: %s",
          stf_ode_failure(c));
    stf_ode_destroy(c);
    stf_fluid_destroy(f);
    dSpaceDestroy(s);
    dWorldDestroy(w);
}

int main(void)
{
    dInitODE2(0);
    test_defs();
    test_collision_hook();
    test_unsplit_fails();
    test_app_steps();
    dCloseODE();
    return test_result("test_embed");
}
