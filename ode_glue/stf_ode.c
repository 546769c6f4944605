/* stf_ode.c - the coupler: ODE geoms as fluid colliders, fluid impulses as ODE forces. */
#include "stf_ode.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct attachment {
    dGeomID geom;     /* 0 for a container */
    dBodyID body;     /* 0 for a fixed solid */
    double offset[3]; /* container: frame origin in the body frame (or world when fixed) */
    int collider;     /* index in the fluid */
} attachment;

struct stf_ode {
    dWorldID world;
    dSpaceID space;
    dJointGroupID contacts;
    stf_fluid *fluid;
    stf_ode_contact_def contact;
    int n, cap;
    attachment *att;
    /* per attachment: force (N) and torque about the body centre (N m) of the last step */
    double *force, *torque;
};

stf_ode_attach_def stf_ode_default_attach_def(void)
{
    stf_ode_attach_def d = {0.2, 0};
    return d;
}

stf_ode_contact_def stf_ode_default_contact_def(void)
{
    stf_ode_contact_def d = {0.8, 0.1, 0.2, 1e-5, 8};
    return d;
}

stf_ode *stf_ode_create(dWorldID world, dSpaceID space, stf_fluid *fluid)
{
    stf_ode *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    c->world = world;
    c->space = space;
    c->fluid = fluid;
    c->contacts = dJointGroupCreate(0);
    c->contact = stf_ode_default_contact_def();
    return c;
}

void stf_ode_destroy(stf_ode *c)
{
    if (!c) return;
    dJointGroupDestroy(c->contacts);
    free(c->att);
    free(c->force);
    free(c->torque);
    free(c);
}

void stf_ode_set_contact(stf_ode *c, const stf_ode_contact_def *def) { c->contact = *def; }

static int push(stf_ode *c, attachment a, char *err, size_t errlen)
{
    if (c->n == c->cap) {
        int cap = c->cap ? 2 * c->cap : 8;
        attachment *att = realloc(c->att, (size_t)cap * sizeof *att);
        double *f = realloc(c->force, (size_t)cap * 3 * sizeof *f);
        double *t = realloc(c->torque, (size_t)cap * 3 * sizeof *t);
        if (att) c->att = att;
        if (f) c->force = f;
        if (t) c->torque = t;
        if (!att || !f || !t) {
            snprintf(err, errlen, "out of memory");
            return -1;
        }
        c->cap = cap;
    }
    memset(c->force + 3 * c->n, 0, 3 * sizeof *c->force);
    memset(c->torque + 3 * c->n, 0, 3 * sizeof *c->torque);
    c->att[c->n++] = a;
    return 0;
}

/* Fills the collider shape of an ODE geom; -1 if the class has no analytic collider. */
static int shape_of_geom(dGeomID g, stf_collider_def *d)
{
    switch (dGeomGetClass(g)) {
    case dSphereClass:
        d->shape = STF_SHAPE_SPHERE;
        d->radius = dGeomSphereGetRadius(g);
        return 0;
    case dBoxClass: {
        dVector3 len;
        dGeomBoxGetLengths(g, len);
        d->shape = STF_SHAPE_BOX;
        for (int a = 0; a < 3; a++) d->half[a] = 0.5 * len[a];
        return 0;
    }
    case dCapsuleClass:
    case dCylinderClass: {
        dReal r, l;
        if (dGeomGetClass(g) == dCapsuleClass) dGeomCapsuleGetParams(g, &r, &l);
        else dGeomCylinderGetParams(g, &r, &l);
        d->shape = dGeomGetClass(g) == dCapsuleClass ? STF_SHAPE_CAPSULE : STF_SHAPE_CYLINDER;
        d->radius = r;
        d->half_length = 0.5 * l; /* ODE gives the full length along local z */
        return 0;
    }
    case dPlaneClass: {
        dVector4 p;
        dGeomPlaneGetParams(g, p); /* a x + b y + c z = d, solid below */
        d->shape = STF_SHAPE_PLANE;
        for (int a = 0; a < 3; a++) d->normal[a] = p[a];
        d->offset = p[3];
        return 0;
    }
    default:
        return -1;
    }
}

static int attach(stf_ode *c, dGeomID g, stf_collider_def *cd, const stf_ode_attach_def *def,
                  char *err, size_t errlen)
{
    stf_ode_attach_def ad = def ? *def : stf_ode_default_attach_def();
    cd->friction = ad.friction;
    cd->stick = ad.stick;
    int id = stf_fluid_add_collider(c->fluid, cd, err, errlen);
    if (id < 0) return -1;
    /* planes are not placeable: their collider frame is the world */
    attachment a = {g, cd->shape == STF_SHAPE_PLANE ? 0 : dGeomGetBody(g), {0, 0, 0}, id};
    if (push(c, a, err, errlen) != 0) return -1;
    return 0;
}

int stf_ode_attach_geom(stf_ode *c, dGeomID geom, const stf_ode_attach_def *def, char *err,
                        size_t errlen)
{
    stf_collider_def cd = stf_default_collider_def();
    if (shape_of_geom(geom, &cd) != 0) {
        snprintf(err, errlen, "geom class %d: no fluid collider (use stf_ode_attach_convex for "
                              "convex geoms)", dGeomGetClass(geom));
        return -1;
    }
    return attach(c, geom, &cd, def, err, errlen);
}

int stf_ode_attach_convex(stf_ode *c, dGeomID geom, const double *points, int npoints,
                          const stf_ode_attach_def *def, char *err, size_t errlen)
{
    stf_collider_def cd = stf_default_collider_def();
    cd.shape = STF_SHAPE_CONVEX;
    cd.points = points;
    cd.npoints = npoints;
    return attach(c, geom, &cd, def, err, errlen);
}

int stf_ode_attach_body(stf_ode *c, dBodyID body, const stf_ode_attach_def *def, char *err,
                        size_t errlen)
{
    int attached = 0;
    for (dGeomID g = dBodyGetFirstGeom(body); g; g = dBodyGetNextGeom(g)) {
        if (stf_ode_attach_geom(c, g, def, err, errlen) != 0) return -1;
        attached++;
    }
    if (!attached) {
        snprintf(err, errlen, "body has no geoms: give it a shape before attaching it");
        return -1;
    }
    return 0;
}

int stf_ode_attach_container(stf_ode *c, dBodyID body, const double pos[3], const double size[3],
                             double wall, const stf_ode_attach_def *def, char *err, size_t errlen)
{
    stf_collider_def cd = stf_default_collider_def();
    cd.shape = STF_SHAPE_CONTAINER;
    for (int a = 0; a < 2; a++) cd.half[a] = 0.5 * size[a];
    cd.half[2] = 0.5 * size[2];
    cd.wall = wall;
    stf_ode_attach_def ad = def ? *def : stf_ode_default_attach_def();
    cd.friction = ad.friction;
    cd.stick = ad.stick;
    int id = stf_fluid_add_collider(c->fluid, &cd, err, errlen);
    if (id < 0) return -1;
    attachment a = {0, body, {pos[0], pos[1], pos[2]}, id};
    return push(c, a, err, errlen);
}

/* Reads an attachment's pose and velocity from ODE into its collider. */
static void sync_collider(stf_ode *c, const attachment *a)
{
    double pos[3], rot[9], vel[3] = {0, 0, 0}, w[3] = {0, 0, 0};
    static const double eye[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    if (a->geom && dGeomGetClass(a->geom) == dPlaneClass) {
        stf_fluid_set_collider_state(c->fluid, a->collider, (double[3]){0, 0, 0}, eye, vel, w);
        return;
    }
    const dReal *R;
    if (a->geom) {
        const dReal *p = dGeomGetPosition(a->geom);
        for (int k = 0; k < 3; k++) pos[k] = p[k];
        R = dGeomGetRotation(a->geom);
    } else if (a->body) {
        dVector3 p;
        dBodyGetRelPointPos(a->body, a->offset[0], a->offset[1], a->offset[2], p);
        for (int k = 0; k < 3; k++) pos[k] = p[k];
        R = dBodyGetRotation(a->body);
    } else {
        stf_fluid_set_collider_state(c->fluid, a->collider, a->offset, eye, vel, w);
        return;
    }
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < 3; k++) rot[3 * r + k] = R[4 * r + k]; /* ODE rows are padded to 4 */
    if (a->body) {
        dVector3 pv;
        dBodyGetPointVel(a->body, pos[0], pos[1], pos[2], pv);
        const dReal *av = dBodyGetAngularVel(a->body);
        for (int k = 0; k < 3; k++) vel[k] = pv[k], w[k] = av[k];
    }
    stf_fluid_set_collider_state(c->fluid, a->collider, pos, rot, vel, w);
}

/* Gives body a's share of the fluid's reaction as force and torque over dt. */
static void apply_reaction(stf_ode *c, int k, double dt)
{
    const attachment *a = &c->att[k];
    double J[3], M[3], *F = c->force + 3 * k, *T = c->torque + 3 * k;
    stf_fluid_collider_impulse(c->fluid, a->collider, J, M);
    memset(F, 0, 3 * sizeof *F);
    memset(T, 0, 3 * sizeof *T);
    if (!a->body) return;
    /* moment about the collider origin -> torque about the body's centre of mass */
    double cp[3];
    if (a->geom) {
        const dReal *p = dGeomGetPosition(a->geom);
        for (int q = 0; q < 3; q++) cp[q] = p[q];
    } else {
        dVector3 p;
        dBodyGetRelPointPos(a->body, a->offset[0], a->offset[1], a->offset[2], p);
        for (int q = 0; q < 3; q++) cp[q] = p[q];
    }
    const dReal *com = dBodyGetPosition(a->body), *w = dBodyGetAngularVel(a->body);
    double r[3] = {cp[0] - com[0], cp[1] - com[1], cp[2] - com[2]}, S[3], u[3];
    double tot[3] = {M[0] + r[1] * J[2] - r[2] * J[1], M[1] + r[2] * J[0] - r[0] * J[2],
                     M[2] + r[0] * J[1] - r[1] * J[0]};
    /* The overlap removal's couple took the particles' velocities relative to the collider
       origin's, vel = V + w × r; the shift (move_bodies) makes up m delta × V: the couple's
       missing -S × (w × r) goes with it. */
    stf_fluid_collider_shift(c->fluid, a->collider, S);
    u[0] = w[1] * r[2] - w[2] * r[1], u[1] = w[2] * r[0] - w[0] * r[2], u[2] = w[0] * r[1] - w[1] * r[0];
    tot[0] -= S[1] * u[2] - S[2] * u[1];
    tot[1] -= S[2] * u[0] - S[0] * u[2];
    tot[2] -= S[0] * u[1] - S[1] * u[0];
    for (int q = 0; q < 3; q++) F[q] = J[q] / dt, T[q] = tot[q] / dt;
    if (J[0] != 0 || J[1] != 0 || J[2] != 0 || S[0] != 0 || S[1] != 0 || S[2] != 0) {
        dBodyEnable(a->body); /* a body the fluid pushes must not fall asleep */
        dBodyAddForce(a->body, F[0], F[1], F[2]);
        dBodyAddTorque(a->body, T[0], T[1], T[2]);
    }
}

/* Moves each dynamic body by -shift / M, shift the mass-weighted overlap removal of its
 * colliders (stf_fluid_collider_shift): particles pushed out of a body without momentum
 * move the body back by as much as they carry, so the centre of mass of fluid and body
 * stays where it was and the angular momentum M X × V with it. The body's momentum
 * moves too, by the step's fluid impulse J, which dWorldStep adds before it moves the
 * body: M s × (V + J/M) = -shift × V + s × J; a torque takes s × J back. */
static void move_bodies(stf_ode *c, double dt)
{
    for (int k = 0; k < c->n; k++) {
        dBodyID b = c->att[k].body;
        int first = b && !dBodyIsKinematic(b);
        for (int j = 0; j < k && first; j++) first = c->att[j].body != b;
        if (!first) continue; /* once per dynamic body, with all its colliders */
        double S[3] = {0, 0, 0}, J[3] = {0, 0, 0};
        for (int j = k; j < c->n; j++) {
            if (c->att[j].body != b) continue;
            double s[3], Jj[3], Mj[3];
            stf_fluid_collider_shift(c->fluid, c->att[j].collider, s);
            stf_fluid_collider_impulse(c->fluid, c->att[j].collider, Jj, Mj);
            for (int q = 0; q < 3; q++) S[q] += s[q], J[q] += Jj[q];
        }
        if (S[0] == 0 && S[1] == 0 && S[2] == 0) continue;
        dMass m;
        dBodyGetMass(b, &m);
        const dReal *X = dBodyGetPosition(b);
        double s[3] = {-S[0] / m.mass, -S[1] / m.mass, -S[2] / m.mass}, *T = c->torque + 3 * k;
        double t[3] = {-(s[1] * J[2] - s[2] * J[1]) / dt, -(s[2] * J[0] - s[0] * J[2]) / dt,
                       -(s[0] * J[1] - s[1] * J[0]) / dt};
        dBodySetPosition(b, X[0] + s[0], X[1] + s[1], X[2] + s[2]);
        dBodyAddTorque(b, t[0], t[1], t[2]);
        for (int q = 0; q < 3; q++) T[q] += t[q];
    }
}

static void near_callback(void *data, dGeomID g1, dGeomID g2)
{
    stf_ode *c = data;
    if (dGeomIsSpace(g1) || dGeomIsSpace(g2)) { /* a space in the space: its geoms */
        dSpaceCollide2(g1, g2, data, near_callback);
        return;
    }
    dBodyID b1 = dGeomGetBody(g1), b2 = dGeomGetBody(g2);
    if (!b1 && !b2) return;
    if (b1 && b2 && dAreConnectedExcluding(b1, b2, dJointTypeContact)) return;
    if ((!b1 || dBodyIsKinematic(b1)) && (!b2 || dBodyIsKinematic(b2))) return;
    enum { MAXC = 32 };
    dContact ct[MAXC];
    int maxc = c->contact.max_contacts < MAXC ? c->contact.max_contacts : MAXC;
    int nc = dCollide(g1, g2, maxc, &ct[0].geom, sizeof(dContact));
    for (int i = 0; i < nc; i++) {
        ct[i].surface.mode = dContactBounce | dContactSoftERP | dContactSoftCFM;
        ct[i].surface.mu = c->contact.mu;
        ct[i].surface.bounce = c->contact.bounce;
        ct[i].surface.bounce_vel = 0.05;
        ct[i].surface.soft_erp = c->contact.soft_erp;
        ct[i].surface.soft_cfm = c->contact.soft_cfm;
        dJointID j = dJointCreateContact(c->world, c->contacts, &ct[i]);
        dJointAttach(j, b1, b2);
    }
}

/* ODE contacts within space and, once each, within every space it holds (dSpaceCollide
 * pairs a sub-space with its neighbours only as one geom). */
static void collide_space(stf_ode *c, dSpaceID space)
{
    dSpaceCollide(space, c, near_callback);
    int n = dSpaceGetNumGeoms(space);
    for (int k = 0; k < n; k++) {
        dGeomID g = dSpaceGetGeom(space, k);
        if (dGeomIsSpace(g)) collide_space(c, (dSpaceID)g);
    }
}

int stf_ode_step(stf_ode *c, double dt)
{
    for (int k = 0; k < c->n; k++) sync_collider(c, &c->att[k]);
    if (stf_fluid_step(c->fluid, dt) != 0) return -1;
    for (int k = 0; k < c->n; k++) apply_reaction(c, k, dt);
    move_bodies(c, dt);
    if (c->space) collide_space(c, c->space);
    dWorldStep(c->world, dt);
    dJointGroupEmpty(c->contacts);
    return 0;
}

int stf_ode_remove_overlaps(stf_ode *c)
{
    int removed = 0;
    for (int k = 0; k < c->n; k++) {
        const attachment *a = &c->att[k];
        sync_collider(c, a);
        if (a->geom == 0) continue; /* a container's inside is where the fluid belongs */
        removed += stf_fluid_remove_inside(c->fluid, a->collider);
    }
    return removed;
}

void stf_ode_body_fluid_force(const stf_ode *c, dBodyID body, double force[3], double torque[3])
{
    memset(force, 0, 3 * sizeof *force);
    memset(torque, 0, 3 * sizeof *torque);
    for (int k = 0; k < c->n; k++) {
        if (c->att[k].body != body) continue;
        for (int q = 0; q < 3; q++) {
            force[q] += c->force[3 * k + q];
            torque[q] += c->torque[3 * k + q];
        }
    }
}

int stf_ode_settle(stf_ode *c, double dt, int steps, double tau)
{
    for (int k = 0; k < c->n; k++) { /* the poses as synced, the velocities zero */
        sync_collider(c, &c->att[k]);
        stf_fluid_hold_collider(c->fluid, c->att[k].collider);
    }
    double keep = exp(-dt / tau);
    for (int s = 0; s < steps; s++) {
        if (stf_fluid_step(c->fluid, dt) != 0) return -1;
        stf_fluid_scale_velocities(c->fluid, keep);
    }
    stf_fluid_reset_clock(c->fluid);
    return 0;
}
