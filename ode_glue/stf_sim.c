/* stf_sim.c - builds an ODE world, the fluid and their coupling from a scene. */
#include "stf_sim.h"

#include "stf_ode_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void ode_init_once(void)
{
    static int done;
    if (!done) {
        dInitODE2(0);
        dAllocateODEDataForThread((unsigned)dAllocateMaskAll);
        done = 1;
    }
}

static double shape_volume(const stf_collider_def *d)
{
    const double pi = 3.14159265358979323846;
    switch (d->shape) {
    case STF_SHAPE_SPHERE: return 4.0 / 3.0 * pi * d->radius * d->radius * d->radius;
    case STF_SHAPE_BOX: return 8.0 * d->half[0] * d->half[1] * d->half[2];
    case STF_SHAPE_CAPSULE:
        return pi * d->radius * d->radius * (2 * d->half_length + 4.0 / 3.0 * d->radius);
    case STF_SHAPE_CYLINDER: return pi * d->radius * d->radius * 2 * d->half_length;
    default: return 0;
    }
}

static dGeomID make_geom(dSpaceID space, const stf_collider_def *d)
{
    switch (d->shape) {
    case STF_SHAPE_SPHERE: return dCreateSphere(space, d->radius);
    case STF_SHAPE_BOX: return dCreateBox(space, 2 * d->half[0], 2 * d->half[1], 2 * d->half[2]);
    case STF_SHAPE_CAPSULE: return dCreateCapsule(space, d->radius, 2 * d->half_length);
    case STF_SHAPE_CYLINDER: return dCreateCylinder(space, d->radius, 2 * d->half_length);
    default: return 0;
    }
}

static void set_mass(dMass *m, const stf_collider_def *d, double mass)
{
    switch (d->shape) {
    case STF_SHAPE_SPHERE: dMassSetSphereTotal(m, mass, d->radius); break;
    case STF_SHAPE_BOX: dMassSetBoxTotal(m, mass, 2 * d->half[0], 2 * d->half[1], 2 * d->half[2]); break;
    case STF_SHAPE_CAPSULE: dMassSetCapsuleTotal(m, mass, 3, d->radius, 2 * d->half_length); break;
    default: dMassSetCylinderTotal(m, mass, 3, d->radius, 2 * d->half_length); break;
    }
}

static int make_body(stf_sim *s, int k, char *err, size_t errlen)
{
    const stf_body_def *b = &s->scene->bodies[k];
    if (b->shape.shape == STF_SHAPE_CONVEX) {
        snprintf(err, errlen, "%s:%d:%d: bodies.%d.shape: convex bodies are not supported in "
                 "scene files yet (allowed: sphere, box, capsule, cylinder)",
                 s->scene->path, b->line, b->col, k);
        return 2;
    }
    dBodyID body = dBodyCreate(s->world);
    dGeomID g = make_geom(s->space, &b->shape);
    dGeomSetBody(g, body);
    dBodySetPosition(body, b->position[0], b->position[1], b->position[2]);
    dQuaternion q = {b->quaternion[0], b->quaternion[1], b->quaternion[2], b->quaternion[3]};
    dBodySetQuaternion(body, q);
    dBodySetLinearVel(body, b->velocity[0], b->velocity[1], b->velocity[2]);
    dBodySetAngularVel(body, b->angular_velocity[0], b->angular_velocity[1], b->angular_velocity[2]);
    if (b->motion == STF_MOTION_DYNAMIC) {
        double mass = b->mass > 0 ? b->mass : b->density * shape_volume(&b->shape);
        dMass m;
        set_mass(&m, &b->shape, mass);
        dBodySetMass(body, &m);
    } else {
        dBodySetKinematic(body);
    }
    dBodySetAutoDisableFlag(body, 0);
    s->bodies[k] = body;
    stf_ode_attach_def ad = {.friction = b->shape.friction, .stick = b->shape.stick};
    if (stf_ode_attach_body(s->coupler, body, &ad, err, errlen) != 0) return 2;
    return 0;
}

/* Bodies that start inside each other (deeper than a micrometre, ODE's own contact test),
 * where at least one of them moves: ODE would throw them apart in the first step. Two static
 * or kinematic bodies may overlap (a fixed compound of parts). Returns 0, or 2 with err. */
static int check_body_overlaps(const stf_sim *s, char *err, size_t errlen)
{
    const stf_scene *sc = s->scene;
    for (int k = 1; k < sc->nbodies; k++)
        for (int j = 0; j < k; j++) {
            if (sc->bodies[j].motion != STF_MOTION_DYNAMIC && sc->bodies[k].motion != STF_MOTION_DYNAMIC)
                continue;
            dGeomID a = dBodyGetFirstGeom(s->bodies[j]), b = dBodyGetFirstGeom(s->bodies[k]);
            if (!a || !b) continue;
            dContactGeom c[8];
            int nc = dCollide(a, b, 8, c, sizeof c[0]);
            double depth = 0;
            for (int e = 0; e < nc; e++) depth = c[e].depth > depth ? c[e].depth : depth;
            if (depth > 1e-6) {
                const stf_body_def *bk = &sc->bodies[k];
                snprintf(err, errlen, "%s:%d:%d: bodies.%d.position: the body '%s' starts inside "
                         "bodies.%d ('%s'), %.3g m deep: move one of them",
                         sc->path, bk->line, bk->col, k, bk->name, j, sc->bodies[j].name, depth);
                return 2;
            }
        }
    return 0;
}

/* The container's floor and walls as ODE boxes (for the bodies), and as one container
 * collider (for the fluid). */
static int make_container(stf_sim *s, char *err, size_t errlen)
{
    const stf_container_def *c = &s->scene->container;
    double w = c->wall, X = c->size[0], Y = c->size[1], H = c->size[2];
    const double *p = c->position;
    struct { double c[3], l[3]; } part[5] = {
        {{0, 0, -w / 2}, {X + 2 * w, Y + 2 * w, w}},
        {{-(X + w) / 2, 0, H / 2}, {w, Y + 2 * w, H}},
        {{(X + w) / 2, 0, H / 2}, {w, Y + 2 * w, H}},
        {{0, -(Y + w) / 2, H / 2}, {X, w, H}},
        {{0, (Y + w) / 2, H / 2}, {X, w, H}},
    };
    dBodyID body = 0;
    double com[3] = {0, 0, 0}; /* a dynamic container's centre of mass in its frame */
    if (c->motion != STF_MOTION_STATIC) {
        body = dBodyCreate(s->world);
        if (c->motion == STF_MOTION_DYNAMIC) {
            /* The walls and floor, uniform: ODE wants the centre of mass at the body's
               origin, so the body sits there and the container's frame (the floor's top
               face) is offset from it. */
            double vol = 0;
            for (int k = 0; k < 5; k++) vol += part[k].l[0] * part[k].l[1] * part[k].l[2];
            dMass m, mk;
            dMassSetZero(&m);
            for (int k = 0; k < 5; k++) {
                const double *l = part[k].l;
                dMassSetBoxTotal(&mk, c->mass * l[0] * l[1] * l[2] / vol, l[0], l[1], l[2]);
                dMassTranslate(&mk, part[k].c[0], part[k].c[1], part[k].c[2]);
                dMassAdd(&m, &mk);
            }
            for (int a = 0; a < 3; a++) com[a] = m.c[a];
            dMassTranslate(&m, -com[0], -com[1], -com[2]);
            dBodySetMass(body, &m);
        } else {
            dBodySetKinematic(body);
        }
        dBodySetPosition(body, p[0] + com[0], p[1] + com[1], p[2] + com[2]);
        dBodySetAutoDisableFlag(body, 0);
    }
    /* Across a periodic axis (scene key container.periodic) the fluid wraps at the inner
       box's faces: those walls are left out of ODE and moved 2 h beyond the seams for the
       fluid, out of reach of every particle (the wall terms and collisions act within h) */
    const double *per = s->scene->fluid.periodic;
    double h = s->scene->fluid.h > 0 ? s->scene->fluid.h : 2 * s->scene->fluid.spacing;
    double fluid_size[3] = {X + (per[0] > 0 ? 4 * h : 0), Y + (per[1] > 0 ? 4 * h : 0), H};
    for (int k = 0; k < 5; k++) {
        if ((k == 1 || k == 2) && per[0] > 0) continue;
        if ((k == 3 || k == 4) && per[1] > 0) continue;
        dGeomID g = dCreateBox(s->space, part[k].l[0], part[k].l[1], part[k].l[2]);
        if (body) {
            dGeomSetBody(g, body);
            dGeomSetOffsetPosition(g, part[k].c[0] - com[0], part[k].c[1] - com[1],
                                   part[k].c[2] - com[2]);
        } else {
            dGeomSetPosition(g, p[0] + part[k].c[0], p[1] + part[k].c[1], p[2] + part[k].c[2]);
        }
    }
    s->container = body;
    memcpy(s->container_base, p, sizeof s->container_base);
    stf_ode_attach_def ad = {.friction = c->friction, .stick = c->stick};
    double origin[3] = {-com[0], -com[1], -com[2]};
    if (stf_ode_attach_container(s->coupler, body, body ? origin : p, fluid_size, w, &ad, err,
                                 errlen) != 0)
        return 2;
    return 0;
}

static int make_fluid(stf_sim *s, char *err, size_t errlen)
{
    const stf_scene *sc = s->scene;
    char msg[256];
    if (stf_fluid_create(&sc->fluid, &s->fluid, msg, sizeof msg) != 0) {
        snprintf(err, errlen, "%s: fluid: %s", sc->path, msg);
        return 2;
    }
    for (int k = 0; k < sc->nblocks; k++) {
        const stf_block *b = &sc->blocks[k];
        int added = b->radius > 0 ? stf_fluid_add_ball(s->fluid, b->center, b->radius, b->velocity)
                                  : stf_fluid_add_block(s->fluid, b->lo, b->hi, b->velocity);
        if (added <= 0) {
            snprintf(err, errlen, "%s:%d:%d: fluid.blocks.%d: holds no particle at this spacing "
                     "(or more than 10^8)", sc->path, b->line, b->col, k);
            return 2;
        }
    }
    return 0;
}

/* The peak speed (m/s) of a vibration: vibrate() sets a kinematic body's velocity at the
 * start of each substep, after the split is chosen (stf_ode_set_peak_speed). */
static double vibration_peak(const stf_vibration *v)
{
    if (!(v->amplitude > 0)) return 0;
    return 2.0 * 3.14159265358979323846 * v->frequency * (1.0 + v->jitter) * v->amplitude;
}

/* The bodies' blow-up detector: bounds no physical motion of the scene reaches.
 *   speed: every speed in the scene comes from its initial speeds (bodies, fluid blocks),
 *     the drive of vibrating solids (a wall moving at u throws what it hits at up to 2 u) and
 *     the fall through gravity over at most the scene's extent L (the diagonal of the box
 *     holding the container, the blocks and the bodies): v_scene = v0 + 2 u + sqrt(2 |g| L).
 *     The bound is 10 v_scene (an order of magnitude of margin for energy the fluid stored
 *     elastically and gives back at once), at least 0.01 h / dt (a scene at rest without
 *     gravity: numerical drift is not a blow-up).
 *   fluid force: weight and buoyancy, (M + rho_f V) |g|, plus the dynamic pressure of the
 *     fluid at v_scene on the body's bounding cross-section A = pi r_bound^2 with the
 *     coefficient 2 (a stagnation pressure rho v^2 / 2 over the front at four times the
 *     area: above both the steady drag, C_d < 1 for Re > 10, and a sphere's water-entry slam,
 *     whose peak force coefficient is about 0.9: Moghisi and Squire, "An experimental
 *     investigation of the initial force of impact on a sphere striking a liquid surface",
 *     J. Fluid Mech. 1981), plus Stokes' drag 3 pi mu d v_scene with the largest viscosity
 *     the fluid shows at the shear rate v_scene / spacing (the Carreau-Yasuda law; the Clavet
 *     fluid's solid-like response is a contact: covered by the next term); all times 10. At
 *     least the force that changes the body's velocity by its speed bound in one step,
 *     M v_bound / dt (what an impact on fluid that turned solid can do).
 * Kinematic and static bodies are driven, not pushed: not checked (bounds 0). The shapes'
 * radii are those the coupler's split uses (stf_collider_extent): the bounding radius r_bound
 * here, the inradius for the rotation's part of the speed checked (s->spin_radius). 0, or -1
 * when out of memory. */
static int body_bounds(stf_sim *s)
{
    const stf_scene *sc = s->scene;
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300}, v0 = 0, u = 0;
    double *bound = calloc((size_t)sc->nbodies + 1, sizeof *bound);
    if (!bound) return -1;
    for (int k = 0; k < sc->nbodies; k++)
        if (stf_collider_extent(&sc->bodies[k].shape, &s->spin_radius[k], &bound[k]) != 0)
            s->spin_radius[k] = bound[k] = 0; /* not a bounded shape: not checked */
#define STF_GROW(P, R)                                                                        \
    for (int a_ = 0; a_ < 3; a_++) {                                                          \
        lo[a_] = fmin(lo[a_], (P)[a_] - (R));                                                 \
        hi[a_] = fmax(hi[a_], (P)[a_] + (R));                                                 \
    }
    for (int k = 0; k < sc->nblocks; k++) {
        const stf_block *b = &sc->blocks[k];
        STF_GROW(b->lo, 0.0);
        STF_GROW(b->hi, 0.0);
        v0 = fmax(v0, sqrt(b->velocity[0] * b->velocity[0] + b->velocity[1] * b->velocity[1] +
                           b->velocity[2] * b->velocity[2]));
    }
    if (sc->container.present) {
        const stf_container_def *c = &sc->container;
        double a[3] = {c->position[0] - 0.5 * c->size[0] - c->wall,
                       c->position[1] - 0.5 * c->size[1] - c->wall, c->position[2] - c->wall};
        double b[3] = {c->position[0] + 0.5 * c->size[0] + c->wall,
                       c->position[1] + 0.5 * c->size[1] + c->wall, c->position[2] + c->size[2]};
        STF_GROW(a, 0.0);
        STF_GROW(b, 0.0);
        if (c->motion == STF_MOTION_KINEMATIC) u = fmax(u, vibration_peak(&c->vibration));
    }
    for (int k = 0; k < sc->nbodies; k++) {
        const stf_body_def *b = &sc->bodies[k];
        STF_GROW(b->position, bound[k]);
        const double *w = b->angular_velocity;
        v0 = fmax(v0, sqrt(b->velocity[0] * b->velocity[0] + b->velocity[1] * b->velocity[1] +
                           b->velocity[2] * b->velocity[2]) +
                          sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * bound[k]);
        if (b->motion == STF_MOTION_KINEMATIC) u = fmax(u, vibration_peak(&b->vibration));
    }
#undef STF_GROW
    double L = 0, g2 = 0;
    for (int a = 0; a < 3; a++) {
        if (hi[a] > lo[a]) L += (hi[a] - lo[a]) * (hi[a] - lo[a]);
        if (sc->fluid.effects & STF_EFFECT_GRAVITY)
            g2 += sc->fluid.gravity[a] * sc->fluid.gravity[a];
    }
    L = sqrt(L);
    double g = sqrt(g2), h = sc->fluid.h > 0 ? sc->fluid.h : 2 * sc->fluid.spacing;
    double vs = v0 + 2 * u + sqrt(2 * g * L);
    double vb = fmax(10 * vs, 0.01 * h / sc->dt), rho = sc->fluid.density;
    double mu = 0;
    if (sc->fluid.model == STF_MODEL_CARREAU_YASUDA)
        mu = rho * fmax(stf_cy_viscosity(&sc->fluid.cy, vs / sc->fluid.spacing),
                        fmax(sc->fluid.cy.mu0, sc->fluid.cy.mu_inf));
    for (int k = 0; k < sc->nbodies; k++) {
        if (sc->bodies[k].motion != STF_MOTION_DYNAMIC || !(bound[k] > 0)) continue;
        dMass m;
        dBodyGetMass(s->bodies[k], &m);
        double r = bound[k], V = shape_volume(&sc->bodies[k].shape);
        double A = 3.14159265358979323846 * r * r;
        double F = (m.mass + rho * V) * g + 2 * rho * A * vs * vs +
                   3 * 3.14159265358979323846 * mu * 2 * r * vs;
        s->speed_bound[k] = vb;
        s->force_bound[k] = fmax(10 * F, m.mass * vb / sc->dt);
    }
    free(bound);
    return 0;
}

int stf_sim_create(const stf_scene *scene, stf_sim **out, char *err, size_t errlen)
{
    return stf_sim_create_until(scene, NULL, NULL, out, err, errlen);
}

int stf_sim_create_until(const stf_scene *scene, int (*stop)(void *arg), void *arg,
                         stf_sim **out, char *err, size_t errlen)
{
    ode_init_once();
    *out = NULL;
    stf_sim *s = calloc(1, sizeof *s);
    if (!s) return snprintf(err, errlen, "out of memory"), 2;
    s->scene = scene;
    int nb = scene->nbodies;
    s->bodies = calloc((size_t)nb + 1, sizeof *s->bodies);
    s->phase = calloc((size_t)nb + 1, sizeof *s->phase);
    s->freq = calloc((size_t)nb + 1, sizeof *s->freq);
    s->rng = calloc((size_t)nb + 1, sizeof *s->rng);
    s->fluid_impulse = calloc(3 * (size_t)nb + 1, sizeof *s->fluid_impulse);
    s->fluid_parts = calloc(3 * STF_ODE_PARTS * (size_t)nb + 1, sizeof *s->fluid_parts);
    s->speed_bound = calloc((size_t)nb + 1, sizeof *s->speed_bound);
    s->force_bound = calloc((size_t)nb + 1, sizeof *s->force_bound);
    s->spin_radius = calloc((size_t)nb + 1, sizeof *s->spin_radius);
    if (!s->bodies || !s->phase || !s->freq || !s->rng || !s->fluid_impulse || !s->fluid_parts ||
        !s->speed_bound || !s->force_bound || !s->spin_radius) {
        stf_sim_destroy(s);
        return snprintf(err, errlen, "out of memory"), 2;
    }
    s->world = dWorldCreate();
    s->space = dHashSpaceCreate(0);
    int rc = make_fluid(s, err, errlen);
    if (rc) goto fail;
    const double *g = scene->fluid.gravity;
    if (scene->fluid.effects & STF_EFFECT_GRAVITY) dWorldSetGravity(s->world, g[0], g[1], g[2]);
    else dWorldSetGravity(s->world, 0, 0, 0);
    s->coupler = stf_ode_create(s->world, s->space, s->fluid);
    if (!s->coupler) {
        snprintf(err, errlen, "out of memory");
        rc = 2;
        goto fail;
    }
    stf_ode_step_def sd = stf_ode_default_step_def();
    sd.adaptive = !scene->dt_fixed;
    if (stf_ode_set_step(s->coupler, &sd, err, errlen) != 0) {
        rc = 2;
        goto fail;
    }
    if (scene->container.present && (rc = make_container(s, err, errlen))) goto fail;
    for (int k = 0; k < nb; k++)
        if ((rc = make_body(s, k, err, errlen))) goto fail;
    if ((rc = check_body_overlaps(s, err, errlen))) goto fail;
    for (int k = 0; k <= nb; k++) {
        const stf_vibration *v = k < nb ? &scene->bodies[k].vibration : &scene->container.vibration;
        s->freq[k] = v->frequency;
        s->rng[k] = v->seed * 2654435761u + 1u;
    }
    for (int k = 0; k < nb; k++)
        if (scene->bodies[k].motion == STF_MOTION_KINEMATIC)
            stf_ode_set_peak_speed(s->coupler, s->bodies[k],
                                   vibration_peak(&scene->bodies[k].vibration));
    if (s->container && scene->container.motion == STF_MOTION_KINEMATIC)
        stf_ode_set_peak_speed(s->coupler, s->container, vibration_peak(&scene->container.vibration));
    int before = stf_fluid_count(s->fluid);
    s->removed = stf_ode_remove_overlaps(s->coupler);
    if (before > 0 && s->removed >= before) { /* the bodies fill the fluid: nothing to simulate */
        snprintf(err, errlen, "%s: bodies: the bodies overlap every one of the fluid's %d "
                 "particles (all removed at set-up): move them out of fluid.blocks",
                 scene->path, before);
        rc = 2;
        goto fail;
    }
    if (body_bounds(s) != 0) {
        snprintf(err, errlen, "out of memory");
        rc = 2;
        goto fail;
    }
    if (scene->settle > 0) {
        /* fluid.settle: the fluid's blocks are a lattice without pressure, a fluid in free
           fall, not at rest: before t = 0 it settles into the pressure that holds it up,
           around the bodies held still, its motions damped with a time constant of an eighth
           of the settling time (so they fall by e^-8) */
        int n = (int)lround(scene->settle / scene->dt);
        int settled = stf_ode_settle_until(s->coupler, scene->dt, n, scene->settle / 8, stop, arg);
        if (settled == 1) {
            snprintf(err, errlen, "%s: fluid.settle: interrupted while the fluid settled (before "
                     "t = 0): nothing was simulated", scene->path);
            rc = 130;
            goto fail;
        }
        if (settled != 0) {
            snprintf(err, errlen, "%s: fluid.settle: the settling failed: %s%s%s", scene->path,
                     stf_fluid_failure(s->fluid), scene->blocks_note[0] ? "; note: " : "",
                     scene->blocks_note);
            rc = 3;
            goto fail;
        }
    }
    s->ngeoms = dSpaceGetNumGeoms(s->space);
    s->geoms = calloc((size_t)s->ngeoms + 1, sizeof *s->geoms);
    if (!s->geoms) {
        snprintf(err, errlen, "out of memory");
        rc = 2;
        goto fail;
    }
    for (int k = 0; k < s->ngeoms; k++) s->geoms[k] = dSpaceGetGeom(s->space, k);
    *out = s;
    return 0;
fail:
    stf_sim_destroy(s);
    return rc;
}

void stf_sim_destroy(stf_sim *s)
{
    if (!s) return;
    stf_ode_destroy(s->coupler);
    if (s->space) dSpaceDestroy(s->space);
    if (s->world) dWorldDestroy(s->world);
    stf_fluid_destroy(s->fluid);
    free(s->bodies);
    free(s->phase);
    free(s->freq);
    free(s->rng);
    free(s->fluid_impulse);
    free(s->fluid_parts);
    free(s->speed_bound);
    free(s->force_bound);
    free(s->spin_radius);
    free(s->geoms);
    free(s);
}

static double uniform(unsigned *state)
{
    *state = *state * 1664525u + 1013904223u;
    return (*state >> 8) / 16777216.0;
}

/* Drives a kinematic body along its vibration: x = x0 + A sin(phase) axis, with the
 * frequency redrawn every jitter_period seconds (the paper's random frequency changes). */
static void vibrate(stf_sim *s, dBodyID body, int k, const stf_vibration *v, const double base[3],
                    double t, double dt)
{
    if (!body || v->amplitude <= 0) return;
    if (v->jitter > 0 && floor((t + dt) / v->jitter_period) > floor(t / v->jitter_period))
        s->freq[k] = v->frequency * (1.0 + v->jitter * (2.0 * uniform(&s->rng[k]) - 1.0));
    double omega = 2.0 * 3.14159265358979323846 * s->freq[k];
    double ph0 = s->phase[k], ph1 = ph0 + omega * dt;
    s->phase[k] = ph1;
    /* velocity that lands exactly on the next position, so ODE's integration stays on path */
    double u = v->amplitude * (sin(ph1) - sin(ph0)) / dt;
    double p = v->amplitude * sin(ph0);
    dBodySetPosition(body, base[0] + p * v->axis[0], base[1] + p * v->axis[1], base[2] + p * v->axis[2]);
    dBodySetLinearVel(body, u * v->axis[0], u * v->axis[1], u * v->axis[2]);
}

/* The blow-up detector of the bodies (bounds: body_bounds): after substep j of m of the
 * step, the fluid's force on each dynamic body (the coupling stage) and its speed after
 * ODE's step (the rigid-body stage). -1 with s->failure set when one is beyond its bound. */
static int check_bodies(stf_sim *s, int j, int m, double dt)
{
    const stf_scene *sc = s->scene;
    for (int k = 0; k < sc->nbodies; k++) {
        if (!(s->speed_bound[k] > 0)) continue;
        double f[3], torque[3];
        stf_ode_substep_force(s->coupler, s->bodies[k], f, torque);
        const dReal *v = dBodyGetLinearVel(s->bodies[k]), *w = dBodyGetAngularVel(s->bodies[k]);
        double F = sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
        double V = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) +
                   sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * s->spin_radius[k];
        const char *stage = NULL, *what = NULL;
        double val = 0, lim = 0;
        if (!(F <= s->force_bound[k])) /* false for NaN too */
            stage = "coupling (the fluid's force on the body)", what = "fluid force", val = F,
            lim = s->force_bound[k];
        else if (!(V <= s->speed_bound[k]))
            stage = "rigid-body step (ODE)", what = "speed", val = V, lim = s->speed_bound[k];
        if (!stage) continue;
        snprintf(s->failure, sizeof s->failure,
                 "step %ld (t = %.6g s, substep %d of %d): body '%s' blew up after stage '%s': "
                 "%s %.4g %s, beyond its physical bound %.4g %s", s->steps + 1,
                 s->time + (j + 1) * dt, j + 1, m, sc->bodies[k].name, stage, what, val,
                 what[0] == 's' ? "m/s" : "N", lim, what[0] == 's' ? "m/s" : "N");
        return -1;
    }
    return 0;
}

const char *stf_sim_failure(const stf_sim *s)
{
    if (s->failure[0]) return s->failure; /* a body's */
    const char *c = stf_ode_failure(s->coupler); /* the fluid's, or ODE's step */
    return c[0] ? c : stf_fluid_failure(s->fluid);
}

int stf_sim_step(stf_sim *s)
{
    const stf_scene *sc = s->scene;
    if (s->failure[0]) return -1;
    /* the coupler's split, the same as stf_ode_step's (adaptive off for dt_control: fixed) */
    int m = stf_ode_substeps(s->coupler, sc->dt);
    double dt = m == 1 ? sc->dt : sc->dt / m;
    stf_solver_stats *acc = &s->step_stats;
    memset(acc, 0, sizeof *acc);
    memset(s->fluid_impulse, 0, 3 * (size_t)sc->nbodies * sizeof *s->fluid_impulse);
    memset(s->fluid_parts, 0, 3 * STF_ODE_PARTS * (size_t)sc->nbodies * sizeof *s->fluid_parts);
    for (int j = 0; j < m; j++) {
        double t = s->time + j * dt;
        for (int k = 0; k < sc->nbodies; k++)
            if (sc->bodies[k].motion == STF_MOTION_KINEMATIC)
                vibrate(s, s->bodies[k], k, &sc->bodies[k].vibration, sc->bodies[k].position, t, dt);
        if (sc->container.present && sc->container.motion == STF_MOTION_KINEMATIC)
            vibrate(s, s->container, sc->nbodies, &sc->container.vibration, s->container_base, t,
                    dt);
        if (stf_ode_substep(s->coupler, dt) != 0) {
            /* named as a body's failure is: the run's step and the substep within it (the
               fluid counts its own steps, one per substep) */
            const char *c = stf_ode_failure(s->coupler), *fl = stf_fluid_failure(s->fluid);
            int fluid = fl[0] && (!c[0] || !strcmp(c, fl));
            snprintf(s->failure, sizeof s->failure, "step %ld (t = %.6g s, substep %d of %d): %s%s",
                     s->steps + 1, s->time + (j + 1) * dt, j + 1, m, fluid ? "the fluid's " : "",
                     fluid ? fl : c);
            return -1;
        }
        if (check_bodies(s, j, m, dt) != 0) return -1;
        for (int k = 0; k < sc->nbodies; k++) {
            double f[3], torque[3], parts[STF_ODE_PARTS][3];
            stf_ode_substep_force(s->coupler, s->bodies[k], f, torque);
            stf_ode_substep_force_parts(s->coupler, s->bodies[k], parts);
            for (int a = 0; a < 3; a++) s->fluid_impulse[3 * k + a] += f[a] * dt;
            for (int p = 0; p < STF_ODE_PARTS; p++)
                for (int a = 0; a < 3; a++)
                    s->fluid_parts[3 * (STF_ODE_PARTS * k + p) + a] += parts[p][a] * dt;
        }
        /* A projection's statistics add up; the Carreau-Yasuda solver also splits the coupled
         * step again by its own CFL: count the substeps the fluid took. */
        double lo = dt, hi = dt;
        long taken = 1;
        if (stf_def_projects(&sc->fluid)) {
            stf_solver_stats st;
            stf_fluid_solver_stats(s->fluid, &st);
            if (st.substeps > 0) taken = st.substeps, lo = st.dt_min, hi = st.dt_max;
            stf_solver_stats_merge(acc, &st); /* the same merge as stf_cy_step's substeps */
        }
        s->substeps += taken;
        if (s->dt_min == 0 || lo < s->dt_min) s->dt_min = lo;
        if (hi > s->dt_max) s->dt_max = hi;
        /* an interrupt between substeps: a step may hold many (m up to 64, each with the
           Carreau-Yasuda solver's own CFL substeps) */
        if (j + 1 < m && s->stop && s->stop(s->stop_arg)) {
            s->substep_in_step = j + 1;
            s->substep_count = m;
            return 1;
        }
    }
    s->steps++;
    s->time = (double)s->steps * sc->dt;
    return 0;
}

void stf_sim_body_state(const stf_sim *s, int k, double pos[3], double quat[4], double vel[3],
                        double angvel[3], double force[3])
{
    dBodyID b = s->bodies[k];
    const dReal *p = dBodyGetPosition(b), *q = dBodyGetQuaternion(b), *v = dBodyGetLinearVel(b),
                *w = dBodyGetAngularVel(b);
    for (int a = 0; a < 3; a++) pos[a] = p[a], vel[a] = v[a], angvel[a] = w[a];
    for (int a = 0; a < 4; a++) quat[a] = q[a];
    for (int a = 0; a < 3; a++) force[a] = s->fluid_impulse[3 * k + a] / s->scene->dt;
}

void stf_sim_body_force_parts(const stf_sim *s, int k, double parts[STF_ODE_PARTS][3])
{
    for (int p = 0; p < STF_ODE_PARTS; p++)
        for (int a = 0; a < 3; a++)
            parts[p][a] = s->fluid_parts[3 * (STF_ODE_PARTS * k + p) + a] / s->scene->dt;
}

/* ---------------------------------------------------------------------- checkpoints */

/* ODE bodies in checkpoint order: the scene's bodies, then the container's (if it moves). */
static int ode_body_count(const stf_sim *s) { return s->scene->nbodies + (s->container != 0); }
static dBodyID ode_body(const stf_sim *s, int k)
{
    return k < s->scene->nbodies ? s->bodies[k] : s->container;
}

int stf_sim_save_state(const stf_sim *s, stf_state *st)
{
    int nb = s->scene->nbodies, no = ode_body_count(s);
    stf_state_put_i64(st, "sim.steps", s->steps);
    stf_state_put_i64(st, "sim.substeps", s->substeps);
    stf_state_put_f64(st, "sim.time", s->time);
    stf_state_put_f64(st, "sim.dt_min", s->dt_min);
    stf_state_put_f64(st, "sim.dt_max", s->dt_max);
    stf_state_put(st, "sim.phase", STF_STATE_F64, (size_t)nb + 1, s->phase);
    stf_state_put(st, "sim.freq", STF_STATE_F64, (size_t)nb + 1, s->freq);
    stf_state_put(st, "sim.rng", STF_STATE_I32, (size_t)nb + 1, s->rng);
    stf_state_put_i64(st, "ode.rand_seed", (int64_t)dRandGetSeed());
    /* pos 3, quaternion 4, velocity 3, angular velocity 3, enabled 1 per body: the rotation
       matrix is ODE's function of the quaternion, so it is not stored */
    double *b = malloc((size_t)(no > 0 ? no : 1) * 14 * sizeof *b);
    /* the geoms' order in the space: the order of collision pairs, so of the contacts */
    int32_t *order = malloc((size_t)(s->ngeoms > 0 ? s->ngeoms : 1) * sizeof *order);
    if (!b || !order) {
        free(b);
        free(order);
        return -1;
    }
    for (int k = 0; k < no; k++) {
        dBodyID body = ode_body(s, k);
        const dReal *p = dBodyGetPosition(body), *q = dBodyGetQuaternion(body),
                    *v = dBodyGetLinearVel(body), *w = dBodyGetAngularVel(body);
        double *r = b + 14 * k;
        for (int a = 0; a < 3; a++) r[a] = p[a], r[7 + a] = v[a], r[10 + a] = w[a];
        for (int a = 0; a < 4; a++) r[3 + a] = q[a];
        r[13] = dBodyIsEnabled(body);
    }
    for (int k = 0; k < s->ngeoms; k++) {
        dGeomID g = dSpaceGetGeom(s->space, k);
        order[k] = -1;
        for (int m = 0; m < s->ngeoms; m++)
            if (s->geoms[m] == g) order[k] = m;
    }
    stf_state_put_owned(st, "ode.bodies", STF_STATE_F64, (size_t)no * 14, b);
    stf_state_put_owned(st, "ode.geom_order", STF_STATE_I32, (size_t)s->ngeoms, order);
    if (stf_fluid_save_state(s->fluid, st) != 0) return -1;
    return st->failed ? -1 : 0;
}

int stf_sim_load_state(stf_sim *s, const stf_state *st, char *err, size_t errlen)
{
    int nb = s->scene->nbodies, no = ode_body_count(s);
    int64_t steps, substeps, seed;
    if (stf_state_get_i64(st, "sim.steps", &steps, err, errlen) ||
        stf_state_get_i64(st, "sim.substeps", &substeps, err, errlen) ||
        stf_state_get_f64(st, "sim.time", &s->time, err, errlen) ||
        stf_state_get_f64(st, "sim.dt_min", &s->dt_min, err, errlen) ||
        stf_state_get_f64(st, "sim.dt_max", &s->dt_max, err, errlen) ||
        stf_state_get(st, "sim.phase", STF_STATE_F64, (size_t)nb + 1, s->phase, err, errlen) ||
        stf_state_get(st, "sim.freq", STF_STATE_F64, (size_t)nb + 1, s->freq, err, errlen) ||
        stf_state_get(st, "sim.rng", STF_STATE_I32, (size_t)nb + 1, s->rng, err, errlen) ||
        stf_state_get_i64(st, "ode.rand_seed", &seed, err, errlen))
        return -1;
    const stf_state_entry *b = stf_state_find(st, "ode.bodies", STF_STATE_F64, (size_t)no * 14);
    const stf_state_entry *o = stf_state_find(st, "ode.geom_order", STF_STATE_I32, (size_t)s->ngeoms);
    if (!b || !o) {
        snprintf(err, errlen, "checkpoint: the bodies or geoms do not match the scene's (%d "
                 "moving bodies, %d geoms)", no, s->ngeoms);
        return -1;
    }
    const int32_t *order = o->data;
    for (int k = 0; k < s->ngeoms; k++) {
        int seen = 0;
        for (int m = 0; m < s->ngeoms; m++) seen += order[m] == k;
        if (seen != 1) {
            snprintf(err, errlen, "checkpoint: ode.geom_order is not a permutation");
            return -1;
        }
    }
    if (stf_fluid_load_state(s->fluid, st, err, errlen) != 0) return -1;
    s->steps = (long)steps;
    s->substeps = (long)substeps;
    dRandSetSeed((unsigned long)seed);
    for (int k = 0; k < no; k++) {
        dBodyID body = ode_body(s, k);
        const double *r = (const double *)b->data + 14 * k;
        dBodySetPosition(body, r[0], r[1], r[2]);
        dQuaternion q = {r[3], r[4], r[5], r[6]};
        dBodySetQuaternion(body, q);
        /* dBodySetQuaternion normalizes, which may move the last bit of a quaternion ODE
           normalized itself: store it as it was, and the rotation ODE derives from it */
        dReal *bq = (dReal *)dBodyGetQuaternion(body), *R = (dReal *)dBodyGetRotation(body);
        for (int a = 0; a < 4; a++) bq[a] = q[a];
        dRfromQ(R, q);
        dBodySetLinearVel(body, r[7], r[8], r[9]);
        dBodySetAngularVel(body, r[10], r[11], r[12]);
        if (r[13] != 0) dBodyEnable(body);
        else dBodyDisable(body);
    }
    for (int k = s->ngeoms - 1; k >= 0; k--) { /* each add goes to the front */
        dGeomID g = s->geoms[order[k]];
        dSpaceRemove(s->space, g);
        dSpaceAdd(s->space, g);
    }
    return 0;
}
