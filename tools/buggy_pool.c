/* buggy_pool.c - ODE's buggy demo (demo_buggy: a chassis on three wheels with hinge2
 * suspension, the front wheel driven and steered, the car in a space of its own inside the
 * world's space, a tilted box for a ramp) run headless, with a pool of shear-thickening
 * fluid at the top of the ramp: the car climbs the ramp, drops into the pool and drives
 * through it.
 *
 * It is an ODE program of the usual shape, scaled to a model car (a 24 cm chassis, 5 cm
 * wheels) under real gravity: its own world, spaces, contact group and nearCallback, and a
 * 60 Hz loop that sets the motors and advances the world. The fluid adds (marked FLUID):
 * the fluid and its container, a coupler attaching the car's bodies, the loop's collision
 * moved into a hook the coupler calls once per substep, and stf_ode_step in place of
 * dWorldStep. The car is driven by a script instead of the keyboard (full speed ahead,
 * straight). Nothing is drawn: it prints the car's state every quarter second.
 *
 *   buggy_pool [--check] [--quick]
 *
 * --check: exits 1 unless the run behaved as physics says (see check() below); --quick:
 * dWorldQuickStep instead of dWorldStep. Exits 0, 1 (a check failed), 3 (a numerical
 * failure). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include <ode/ode.h>

#include "stf_ode.h" /* FLUID */

/* the car (demo_buggy's chassis at a third of its size, on larger wheels: the belly, at
 * the wheels' centres, must clear the pool's rim as the front wheel drops in) */
#define LENGTH 0.24 /* chassis length, m */
#define WIDTH 0.16  /* chassis width, m */
#define HEIGHT 0.06 /* chassis height, m */
#define RADIUS 0.06 /* wheel radius, m */
#define STARTX -0.3 /* chassis start, m */
#define STARTZ (RADIUS + 0.5 * HEIGHT + 0.005)
#define CMASS 1.0 /* chassis mass, kg */
#define WMASS 0.1 /* wheel mass, kg */
#define SPEED 12.0 /* front wheel's motor speed, rad/s (0.72 m/s) */
#define TORQUE 0.6 /* most torque of the motor, N m */

/* the pool: inner size, wall, depth of the fluid; its floor's top face on the ground. Its
 * rim is lower than a wheel's radius. */
#define POOLX 0.45 /* centre x, m */
static const double pool_size[3] = {0.4, 0.3, 0.045}, pool_wall = 0.02, pool_depth = 0.04;
#define SPACING 0.02 /* fluid particle spacing, m */

#define HZ 60        /* the loop's rate */
#define DURATION 2.0 /* s */

static dWorldID world;
static dSpaceID space, car_space;
static dJointGroupID contactgroup;
static dBodyID body[4];   /* chassis, front wheel, two back wheels */
static dJointID joint[3]; /* joint[0] is the front wheel */
static dGeomID ground, ramp;
static dGeomID pool_geom[5]; /* the container for ODE: floor and four walls */

/* Called by dSpaceCollide for two geoms that may touch: the car against the ground, the ramp
 * and the pool (the car's own parts do not collide). */
static void nearCallback(void *data, dGeomID o1, dGeomID o2)
{
    if (dGeomIsSpace(o1) || dGeomIsSpace(o2)) { /* the car's space against a static geom */
        if (o1 == (dGeomID)car_space && o2 == (dGeomID)car_space) return;
        dSpaceCollide2(o1, o2, data, &nearCallback);
        return;
    }
    dBodyID b1 = dGeomGetBody(o1), b2 = dGeomGetBody(o2);
    if ((b1 != 0) == (b2 != 0)) return; /* both static, or both parts of the car */
    enum { N = 10 };
    dContact contact[N];
    int n = dCollide(o1, o2, N, &contact[0].geom, sizeof(dContact));
    for (int i = 0; i < n; i++) {
        contact[i].surface.mode = dContactSlip1 | dContactSlip2 | dContactSoftERP |
                                  dContactSoftCFM | dContactApprox1;
        contact[i].surface.mu = dInfinity;
        contact[i].surface.slip1 = 0.01;
        contact[i].surface.slip2 = 0.01;
        contact[i].surface.soft_erp = 0.5;
        contact[i].surface.soft_cfm = 1e-4;
        dJointID c = dJointCreateContact(world, contactgroup, &contact[i]);
        dJointAttach(c, b1, b2);
    }
}

/* FLUID: the loop's collision, called by the coupler before each ODE substep. The app keeps
 * its own contact group: the last substep's contacts go first. */
static long collisions;
static void collide(void *data, dJointGroupID coupler_group, double dt)
{
    (void)data, (void)coupler_group, (void)dt;
    dJointGroupEmpty(contactgroup);
    dSpaceCollide(space, 0, &nearCallback);
    collisions++;
}

/* The motors, as demo_buggy's simLoop sets them each step. */
static void drive(double speed, double steer)
{
    dJointSetHinge2Param(joint[0], dParamVel2, -speed);
    dJointSetHinge2Param(joint[0], dParamFMax2, TORQUE);
    double v = steer - dJointGetHinge2Angle1(joint[0]);
    if (v > 0.1) v = 0.1;
    if (v < -0.1) v = -0.1;
    dJointSetHinge2Param(joint[0], dParamVel, 10.0 * v);
    dJointSetHinge2Param(joint[0], dParamFMax, 0.2);
    dJointSetHinge2Param(joint[0], dParamLoStop, -0.75);
    dJointSetHinge2Param(joint[0], dParamHiStop, 0.75);
    dJointSetHinge2Param(joint[0], dParamFudgeFactor, 0.1);
}

static void build_car(void)
{
    static const dVector3 yunit = {0, 1, 0}, zunit = {0, 0, 1};
    dMass m;
    body[0] = dBodyCreate(world);
    dBodySetPosition(body[0], STARTX, 0, STARTZ);
    dMassSetBox(&m, 1, LENGTH, WIDTH, HEIGHT);
    dMassAdjust(&m, CMASS);
    dBodySetMass(body[0], &m);
    dGeomID box = dCreateBox(0, LENGTH, WIDTH, HEIGHT);
    dGeomSetBody(box, body[0]);
    dGeomID sphere[3];
    for (int i = 1; i <= 3; i++) {
        body[i] = dBodyCreate(world);
        dQuaternion q;
        dQFromAxisAndAngle(q, 1, 0, 0, 0.5 * M_PI);
        dBodySetQuaternion(body[i], q);
        dMassSetSphere(&m, 1, RADIUS);
        dMassAdjust(&m, WMASS);
        dBodySetMass(body[i], &m);
        sphere[i - 1] = dCreateSphere(0, RADIUS);
        dGeomSetBody(sphere[i - 1], body[i]);
    }
    double wz = STARTZ - 0.5 * HEIGHT;
    dBodySetPosition(body[1], STARTX + 0.5 * LENGTH, 0, wz);
    dBodySetPosition(body[2], STARTX - 0.5 * LENGTH, 0.5 * WIDTH + RADIUS, wz);
    dBodySetPosition(body[3], STARTX - 0.5 * LENGTH, -0.5 * WIDTH - RADIUS, wz);
    for (int i = 0; i < 3; i++) { /* hinge2: steering axis z, wheel axis y */
        joint[i] = dJointCreateHinge2(world, 0);
        dJointAttach(joint[i], body[0], body[i + 1]);
        const dReal *a = dBodyGetPosition(body[i + 1]);
        dJointSetHinge2Anchor(joint[i], a[0], a[1], a[2]);
        dJointSetHinge2Axes(joint[i], zunit, yunit);
        dJointSetHinge2Param(joint[i], dParamSuspensionERP, 0.4);
        dJointSetHinge2Param(joint[i], dParamSuspensionCFM, 0.01);
    }
    for (int i = 1; i < 3; i++) { /* back wheels do not steer */
        dJointSetHinge2Param(joint[i], dParamLoStop, 0);
        dJointSetHinge2Param(joint[i], dParamHiStop, 0);
    }
    /* the car's own space in the world's space */
    car_space = dSimpleSpaceCreate(space);
    dSpaceSetCleanup(car_space, 1);
    dSpaceAdd(car_space, box);
    for (int i = 0; i < 3; i++) dSpaceAdd(car_space, sphere[i]);
}

/* The ramp (demo_buggy's tilted box) rising to just above the pool's near wall. */
static void build_ground(void)
{
    ground = dCreatePlane(space, 0, 0, 1, 0);
    const double th = 0.15, L = 0.6, T = 0.1, top = pool_size[2];
    const double x_end = POOLX - 0.5 * pool_size[0] - pool_wall; /* the wall's outer face */
    ramp = dCreateBox(space, L, 0.5, T);
    dMatrix3 R;
    dRFromAxisAndAngle(R, 0, 1, 0, -th);
    dGeomSetRotation(ramp, R);
    /* the upper end's top edge at (x_end, top) */
    dGeomSetPosition(ramp, x_end - 0.5 * L * cos(th) + 0.5 * T * sin(th), 0,
                     top - 0.5 * L * sin(th) - 0.5 * T * cos(th));
    /* the pool for ODE: a floor and four walls of boxes */
    const double X = pool_size[0], Y = pool_size[1], H = pool_size[2], w = pool_wall;
    struct { double c[3], l[3]; } part[5] = {
        {{0, 0, -w / 2}, {X + 2 * w, Y + 2 * w, w}},
        {{-(X + w) / 2, 0, H / 2}, {w, Y + 2 * w, H}},
        {{(X + w) / 2, 0, H / 2}, {w, Y + 2 * w, H}},
        {{0, -(Y + w) / 2, H / 2}, {X, w, H}},
        {{0, (Y + w) / 2, H / 2}, {X, w, H}},
    };
    for (int k = 0; k < 5; k++) {
        pool_geom[k] = dCreateBox(space, part[k].l[0], part[k].l[1], part[k].l[2]);
        dGeomSetPosition(pool_geom[k], POOLX + part[k].c[0], part[k].c[1], part[k].c[2]);
    }
}

/* FLUID: oobleck (the stability tests' parameters at a 2 cm spacing) filling the pool to
 * pool_depth. */
static stf_fluid *make_fluid(char *err, size_t errlen)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.spacing = SPACING;
    d.density = 1270;
    d.gravity[0] = 0, d.gravity[1] = 0, d.gravity[2] = -9.81;
    d.sigma = 10, d.beta = 0;
    d.k = 1000, d.k_near = 200;
    d.k_min = 100, d.yield_ratio = 0, d.plasticity = 2;
    d.q = 0.5, d.d = 50, d.k_hist = 200000, d.reference_spacing = 0.02;
    d.stick = 200;
    stf_fluid *f;
    if (stf_fluid_create(&d, &f, err, errlen) != 0) return NULL;
    double lo[3] = {POOLX - 0.5 * pool_size[0], -0.5 * pool_size[1], 0};
    double hi[3] = {POOLX + 0.5 * pool_size[0], 0.5 * pool_size[1], pool_depth};
    stf_fluid_add_block(f, lo, hi, (double[3]){0, 0, 0});
    return f;
}

/* What the run saw, for --check. */
typedef struct record {
    double force_dry;  /* N: largest fluid force on the car while it was short of the pool */
    double impulse_wet[3];   /* N s: the fluid's impulse on the car from the first touch */
    double impulse_entry[3]; /* N s: the same over the first quarter second */
    double x_max;            /* m: furthest the front wheel's centre got */
    int wet_steps;           /* steps since the first touch */
    int steps, substeps_max;
    long substeps;
} record;

/* The car's centre of mass velocity and the fluid's force on all its bodies. */
static void car_state(stf_ode *c, double v[3], double f[3])
{
    double p[3] = {0, 0, 0}, M = 0;
    f[0] = f[1] = f[2] = 0;
    for (int i = 0; i < 4; i++) {
        dMass m;
        dBodyGetMass(body[i], &m);
        const dReal *u = dBodyGetLinearVel(body[i]);
        double fi[3], ti[3];
        stf_ode_body_fluid_force(c, body[i], fi, ti);
        for (int a = 0; a < 3; a++) p[a] += m.mass * u[a], f[a] += fi[a];
        M += m.mass;
    }
    for (int a = 0; a < 3; a++) v[a] = p[a] / M;
}

/* The physics the run must show:
 * - no fluid force on the car before its front wheel is within reach (h, 2 spacings) of the
 *   fluid: the particles act only within h;
 * - the car drives onto the pool: the front wheel's centre gets a radius past the near
 *   wall's inner face (its bottom on the pool's floor, under the fluid's surface);
 * - the fluid resists the entry: over the first quarter second of touching it, the fluid's
 *   impulse on the car points against its motion (the car pushes the fluid ahead; the
 *   fluid's reaction on it is backwards, whatever the thickening does later);
 * - the fluid holds the car up: from the first touch on, its impulse on the car points up
 *   (the wheels' and chassis' support: the fluid is below them). */
static int check(const record *r)
{
    int ok = 1;
    const double inner = POOLX - 0.5 * pool_size[0];
    if (r->force_dry != 0)
        printf("check: a fluid force of %g N on the dry car\n", r->force_dry), ok = 0;
    if (!(r->x_max > inner + RADIUS))
        printf("check: the front wheel got to x = %.3f m, not into the pool (inner face %.3f m)\n",
               r->x_max, inner), ok = 0;
    if (!(r->impulse_entry[0] < 0))
        printf("check: entering, the fluid's impulse on the car is %g N s along its motion\n",
               r->impulse_entry[0]), ok = 0;
    if (!(r->impulse_wet[2] > 0))
        printf("check: the fluid's impulse on the car in the pool is %g N s up\n",
               r->impulse_wet[2]), ok = 0;
    if (!(r->substeps_max > 1))
        printf("check: no step of 1/%d s was split (%d substeps at most)\n", HZ,
               r->substeps_max), ok = 0;
    if (collisions != r->substeps)
        printf("check: %ld collision hook calls for %ld substeps\n", collisions, r->substeps),
            ok = 0;
    return ok;
}

int main(int argc, char **argv)
{
    int do_check = 0, quick = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--check")) do_check = 1;
        else if (!strcmp(argv[i], "--quick")) quick = 1;
        else return fprintf(stderr, "usage: buggy_pool [--check] [--quick]\n"), 2;
    }
    dInitODE2(0);
    world = dWorldCreate();
    space = dHashSpaceCreate(0);
    contactgroup = dJointGroupCreate(0);
    dWorldSetGravity(world, 0, 0, -9.81);
    build_car();
    build_ground();

    char err[256];
    stf_fluid *fluid = make_fluid(err, sizeof err); /* FLUID */
    if (!fluid) return fprintf(stderr, "fluid: %s\n", err), 2;
    stf_ode *coupler = stf_ode_create(world, 0, fluid); /* FLUID: no space, the hook collides */
    stf_ode_step_def sd = stf_ode_default_step_def();
    if (quick) sd.stepper = STF_ODE_QUICK_STEP, sd.quick_iterations = 40;
    double at[3] = {POOLX, 0, 0};
    if (!coupler || stf_ode_set_step(coupler, &sd, err, sizeof err) ||
        stf_ode_attach_container(coupler, 0, at, pool_size, pool_wall, NULL, err, sizeof err) ||
        stf_ode_attach_geom(coupler, ground, NULL, err, sizeof err))
        return fprintf(stderr, "coupler: %s\n", coupler ? err : "out of memory"), 2;
    for (int i = 0; i < 4; i++)
        if (stf_ode_attach_body(coupler, body[i], NULL, err, sizeof err))
            return fprintf(stderr, "coupler: %s\n", err), 2;
    stf_ode_set_collide(coupler, collide, NULL);
    printf("buggy_pool: %d particles of %.0f mm, the car at x = %.2f m, the pool from x = %.2f "
           "m; steps of 1/%d s with %s\n", stf_fluid_count(fluid), 1e3 * SPACING, STARTX,
           POOLX - 0.5 * pool_size[0], HZ, quick ? "dWorldQuickStep" : "dWorldStep");

    record r = {.wet_steps = 0};
    const double dt = 1.0 / HZ, reach = POOLX - 0.5 * pool_size[0] - 2 * SPACING;
    int steps = (int)lround(DURATION * HZ), rc = 0;
    for (int k = 0; k < steps; k++) {
        drive(SPEED, 0);
        if (stf_ode_step(coupler, dt) != 0) { /* FLUID: instead of dWorldStep */
            fprintf(stderr, "step %d: %s\n", k, stf_ode_failure(coupler));
            rc = 3;
            break;
        }
        stf_ode_stats st;
        stf_ode_get_stats(coupler, &st);
        if (st.last_substeps > r.substeps_max) r.substeps_max = st.last_substeps;
        r.substeps = st.substeps;
        double v[3], f[3];
        car_state(coupler, v, f);
        const dReal *x = dBodyGetPosition(body[0]), *xf = dBodyGetPosition(body[1]);
        if (xf[0] > r.x_max) r.x_max = xf[0];
        double fn = sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
        if (xf[0] + RADIUS < reach && fn > r.force_dry) r.force_dry = fn;
        if (r.wet_steps > 0 || fn > 0) {
            r.wet_steps++;
            for (int a = 0; a < 3; a++) {
                r.impulse_wet[a] += f[a] * dt;
                if (r.wet_steps <= HZ / 4) r.impulse_entry[a] += f[a] * dt;
            }
        }
        if ((k + 1) % (HZ / 4) == 0)
            printf("t %.2f s  chassis x %+.3f z %.3f m  v %+.3f %+.3f m/s  fluid force %+7.3f "
                   "%+7.3f N  substeps %d of %.2f ms\n", (k + 1) * dt, x[0], x[2], v[0], v[2],
                   f[0], f[2], st.last_substeps, 1e3 * st.last_dt);
        r.steps = k + 1;
    }
    dJointGroupEmpty(contactgroup);
    printf("buggy_pool: %d steps, %ld substeps (at most %d a step), %ld collision calls; the "
           "front wheel got to x = %.3f m; the fluid's impulse on the car %+.3f %+.3f %+.3f N s "
           "over the first 0.25 s of touching it, %+.3f %+.3f %+.3f N s in all\n", r.steps,
           r.substeps, r.substeps_max, collisions, r.x_max, r.impulse_entry[0],
           r.impulse_entry[1], r.impulse_entry[2], r.impulse_wet[0], r.impulse_wet[1],
           r.impulse_wet[2]);
    if (rc == 0 && do_check && !check(&r)) rc = 1;

    stf_ode_destroy(coupler); /* FLUID */
    stf_fluid_destroy(fluid);
    dJointGroupDestroy(contactgroup);
    dSpaceDestroy(space);
    dWorldDestroy(world);
    dCloseODE();
    return rc;
}
