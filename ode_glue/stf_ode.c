/* stf_ode.c - the coupler: ODE geoms as fluid colliders, fluid impulses as ODE forces, an
 * app's step split into stable substeps. */
#include "stf_ode.h"
#include "stf_ode_internal.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct attachment {
    dGeomID geom;     /* 0 for a container */
    dBodyID body;     /* 0 for a fixed solid */
    double offset[3]; /* container: frame origin in the body frame (or world when fixed) */
    int collider;     /* index in the fluid */
    /* the split's view (stf_ode_substeps) */
    int bounded;      /* 1: a geom of finite size (inradius, bound below); 0: plane, container */
    double inradius;  /* m: largest sphere inside the geom about its origin */
    double reach;     /* m: radius of the smallest sphere holding the geom about its origin */
    double wall;      /* container: wall thickness (m), and diag its inner box's diagonal */
    double diag;
    double peak;      /* m/s: stf_ode_set_peak_speed's bound (0: none) */
    /* the added-mass stabilisation's view (stabilise_light_body): the geom's volume and the
       volume of the band a spacing wide outside it (m^3; 0: unbounded) */
    double vol, vol_band;
} attachment;

struct stf_ode {
    dWorldID world;
    dSpaceID space;
    dJointGroupID contacts;
    stf_fluid *fluid;
    double h, k_press, spacing; /* the fluid's interaction radius, k/h (1/s^2), spacing (m) */
    double nu_implicit;         /* m^2/s: the largest viscosity an implicit solve spreads (0: none) */
    stf_ode_contact_def contact;
    stf_ode_step_def step;
    stf_ode_collide_fn collide;
    void *collide_data;
    stf_ode_stats stats;
    char failure[256];
    int n, cap;
    attachment *att;
    /* per attachment: force (N) and torque about the body centre (N m) of the last substep,
       and their impulses (N s, N m s) summed over the last stf_ode_step's substeps */
    double *force, *torque, *imp, *aimp;
    /* per attachment, STF_ODE_PARTS rows of 3: the force by part (stf_ode_body_fluid_force_parts)
       of the last substep (N), and its impulse over the last stf_ode_step (N s) */
    double *part, *pimp;
    int *ids;       /* scratch, cap: the colliders of one body's geoms (stabilise_light_body) */
    double step_dt; /* s, the last stf_ode_step's dt (0 before the first) */
};

static void fail(stf_ode *c, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->failure, sizeof c->failure, fmt, ap);
    va_end(ap);
}

stf_ode_attach_def stf_ode_default_attach_def(void)
{
    stf_ode_attach_def d = {.friction = 0.2, .stick = 0};
    return d;
}

int stf_ode_check_attach_def(const stf_ode_attach_def *d, char *err, size_t errlen)
{
    if (!(d->friction >= 0 && d->friction <= 1)) {
        snprintf(err, errlen, "attach def: friction = %g: must be in [0, 1] (Coulomb "
                 "coefficient of particle contacts)", d->friction);
        return -1;
    }
    if (d->stick != 0 && d->stick != 1) {
        snprintf(err, errlen, "attach def: stick = %d: must be 0 or 1", d->stick);
        return -1;
    }
    return 0;
}

stf_ode_contact_def stf_ode_default_contact_def(void)
{
    stf_ode_contact_def d = {.mu = 0.8, .bounce = 0.1, .bounce_vel = 0.05, .soft_erp = 0.2,
                             .soft_cfm = 1e-5, .max_contacts = 8};
    return d;
}

int stf_ode_check_contact_def(const stf_ode_contact_def *d, char *err, size_t errlen)
{
    const char *bad = NULL, *why = NULL;
    double v = 0;
    if (!(d->mu >= 0)) bad = "mu", v = d->mu, why = "must be >= 0 (dInfinity allowed)";
    else if (!(d->bounce >= 0 && d->bounce <= 1))
        bad = "bounce", v = d->bounce, why = "must be in [0, 1]";
    else if (!(d->bounce_vel >= 0 && isfinite(d->bounce_vel)))
        bad = "bounce_vel", v = d->bounce_vel, why = "must be >= 0 m/s and finite";
    else if (!(d->soft_erp > 0 && d->soft_erp <= 1))
        bad = "soft_erp", v = d->soft_erp, why = "must be in (0, 1]";
    else if (!(d->soft_cfm >= 0 && isfinite(d->soft_cfm)))
        bad = "soft_cfm", v = d->soft_cfm, why = "must be >= 0 and finite";
    if (bad) {
        snprintf(err, errlen, "contact def: %s = %g: %s", bad, v, why);
        return -1;
    }
    if (d->max_contacts < 1 || d->max_contacts > STF_ODE_MAX_CONTACTS) {
        snprintf(err, errlen, "contact def: max_contacts = %d: must be in 1..%d", d->max_contacts,
                 STF_ODE_MAX_CONTACTS);
        return -1;
    }
    return 0;
}

stf_ode_step_def stf_ode_default_step_def(void)
{
    stf_ode_step_def d = {.adaptive = 1, .max_substeps = 64, .stepper = STF_ODE_WORLD_STEP,
                          .quick_iterations = 20};
    return d;
}

int stf_ode_check_step_def(const stf_ode_step_def *d, char *err, size_t errlen)
{
    if (d->adaptive != 0 && d->adaptive != 1)
        return snprintf(err, errlen, "step def: adaptive = %d: must be 0 or 1", d->adaptive), -1;
    if (d->max_substeps < 1 || d->max_substeps > 1000000)
        return snprintf(err, errlen, "step def: max_substeps = %d: must be in 1..1000000",
                        d->max_substeps), -1;
    if (d->stepper != STF_ODE_WORLD_STEP && d->stepper != STF_ODE_QUICK_STEP)
        return snprintf(err, errlen, "step def: stepper = %d: must be STF_ODE_WORLD_STEP (0) or "
                        "STF_ODE_QUICK_STEP (1)", d->stepper), -1;
    if (d->quick_iterations < 1)
        return snprintf(err, errlen, "step def: quick_iterations = %d: must be >= 1",
                        d->quick_iterations), -1;
    return 0;
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
    c->step = stf_ode_default_step_def();
    stf_fluid_def fd;
    stf_fluid_get_def(fluid, &fd);
    c->h = fd.h > 0 ? fd.h : 2.0 * fd.spacing;
    c->k_press = (fd.effects & STF_EFFECT_PRESSURE) ? fd.k / c->h : 0.0;
    c->spacing = fd.spacing;
    /* the Carreau-Yasuda model's implicit viscosity reaches sqrt(nu dt) within a substep */
    if (fd.model == STF_MODEL_CARREAU_YASUDA && fd.cy.viscosity_solver == STF_VISCOSITY_IMPLICIT)
        c->nu_implicit = fmax(fd.cy.mu0, fd.cy.mu_inf);
    return c;
}

void stf_ode_destroy(stf_ode *c)
{
    if (!c) return;
    dJointGroupDestroy(c->contacts);
    free(c->att);
    free(c->ids);
    free(c->force);
    free(c->torque);
    free(c->imp);
    free(c->aimp);
    free(c->part);
    free(c->pimp);
    free(c);
}

int stf_ode_set_contact(stf_ode *c, const stf_ode_contact_def *def, char *err, size_t errlen)
{
    if (stf_ode_check_contact_def(def, err, errlen) != 0) return -1;
    c->contact = *def;
    return 0;
}

int stf_ode_set_step(stf_ode *c, const stf_ode_step_def *def, char *err, size_t errlen)
{
    if (stf_ode_check_step_def(def, err, errlen) != 0) return -1;
    c->step = *def;
    return 0;
}

void stf_ode_set_collide(stf_ode *c, stf_ode_collide_fn fn, void *data)
{
    c->collide = fn;
    c->collide_data = fn ? data : NULL;
}

void stf_ode_get_stats(const stf_ode *c, stf_ode_stats *st) { *st = c->stats; }
const char *stf_ode_failure(const stf_ode *c) { return c->failure; }

void stf_ode_set_peak_speed(stf_ode *c, dBodyID body, double speed)
{
    for (int k = 0; k < c->n; k++)
        if (c->att[k].body == body) c->att[k].peak = speed;
}

static int push(stf_ode *c, attachment a, char *err, size_t errlen)
{
    /* the per-attachment arrays and the doubles each attachment has in them */
    double **arr[6] = {&c->force, &c->torque, &c->imp, &c->aimp, &c->part, &c->pimp};
    const size_t width[6] = {3, 3, 3, 3, 3 * STF_ODE_PARTS, 3 * STF_ODE_PARTS};
    if (c->n == c->cap) {
        int cap = c->cap ? 2 * c->cap : 8;
        attachment *att = realloc(c->att, (size_t)cap * sizeof *att);
        if (att) c->att = att;
        int *ids = realloc(c->ids, (size_t)cap * sizeof *ids);
        if (ids) c->ids = ids;
        int ok = att != NULL && ids != NULL;
        for (int q = 0; q < 6; q++) {
            double *p = realloc(*arr[q], (size_t)cap * width[q] * sizeof *p);
            if (p) *arr[q] = p;
            else ok = 0;
        }
        if (!ok) {
            snprintf(err, errlen, "out of memory");
            return -1;
        }
        c->cap = cap;
    }
    for (int q = 0; q < 6; q++) memset(*arr[q] + width[q] * (size_t)c->n, 0, width[q] * sizeof **arr[q]);
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

/* 1 when geom g is attached already (a second collider would double its forces). */
static int is_attached(const stf_ode *c, dGeomID g)
{
    for (int k = 0; k < c->n; k++)
        if (c->att[k].geom == g) return 1;
    return 0;
}

static int attach(stf_ode *c, dGeomID g, stf_collider_def *cd, const stf_ode_attach_def *def,
                  char *err, size_t errlen)
{
    if (is_attached(c, g)) {
        snprintf(err, errlen, "geom %p is attached already", (void *)g);
        return -1;
    }
    stf_ode_attach_def ad = def ? *def : stf_ode_default_attach_def();
    if (stf_ode_check_attach_def(&ad, err, errlen) != 0) return -1;
    cd->friction = ad.friction;
    cd->stick = ad.stick;
    int id = stf_fluid_add_collider(c->fluid, cd, err, errlen);
    if (id < 0) return -1;
    /* planes are not placeable: their collider frame is the world */
    attachment a = {.geom = g, .body = cd->shape == STF_SHAPE_PLANE ? 0 : dGeomGetBody(g),
                    .collider = id};
    double bound;
    if (stf_collider_extent(cd, &a.inradius, &bound) == 0) {
        a.bounded = 1;
        a.reach = bound;
        if (stf_collider_volumes(cd, c->spacing, &a.vol, &a.vol_band) != 0) a.vol = a.vol_band = 0;
    }
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
    if (!body) {
        snprintf(err, errlen, "body is 0: attach a body made with dBodyCreate");
        return -1;
    }
    /* every geom checked before any is attached: a body is attached whole or not at all (a
       bad def fails the first attach, before anything is attached) */
    for (dGeomID g = dBodyGetFirstGeom(body); g; g = dBodyGetNextGeom(g)) {
        stf_collider_def cd = stf_default_collider_def();
        if (shape_of_geom(g, &cd) != 0) {
            snprintf(err, errlen, "geom class %d of the body: no fluid collider (nothing "
                     "attached; attach its geoms one by one, convex ones with "
                     "stf_ode_attach_convex)", dGeomGetClass(g));
            return -1;
        }
        if (is_attached(c, g)) {
            snprintf(err, errlen, "the body's geom %p is attached already (nothing attached)",
                     (void *)g);
            return -1;
        }
    }
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
    stf_ode_attach_def ad = def ? *def : stf_ode_default_attach_def();
    if (stf_ode_check_attach_def(&ad, err, errlen) != 0) return -1;
    stf_collider_def cd = stf_default_collider_def();
    cd.shape = STF_SHAPE_CONTAINER;
    for (int a = 0; a < 2; a++) cd.half[a] = 0.5 * size[a];
    cd.half[2] = 0.5 * size[2];
    cd.wall = wall;
    cd.friction = ad.friction;
    cd.stick = ad.stick;
    int id = stf_fluid_add_collider(c->fluid, &cd, err, errlen);
    if (id < 0) return -1;
    attachment a = {.body = body, .offset = {pos[0], pos[1], pos[2]}, .collider = id,
                    .wall = wall,
                    .diag = sqrt(size[0] * size[0] + size[1] * size[1] + size[2] * size[2])};
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

/* The inverse of the symmetric 3x3 matrix m (xx yy zz xy xz yz); 0, or -1 when it is
 * singular to within 1e-9 of its scale. */
static int inverse_sym3(const double m[6], double inv[9])
{
    double a = m[0], b = m[1], c = m[2], d = m[3], e = m[4], f = m[5];
    double c00 = b * c - f * f, c01 = e * f - d * c, c02 = d * f - b * e;
    double det = a * c00 + d * c01 + e * c02, scale = (a + b + c) / 3;
    if (!(fabs(det) > 1e-9 * scale * scale * scale)) return -1;
    double c11 = a * c - e * e, c12 = d * e - a * f, c22 = a * b - d * d;
    double r[9] = {c00, c01, c02, c01, c11, c12, c02, c12, c22};
    for (int q = 0; q < 9; q++) inv[q] = r[q] / det;
    return 0;
}

/* The added-mass stabilisation (ours). The coupling is explicit: the fluid's reaction to the
 * body's velocity in one substep moves the body in the next. The fluid a body drags along
 * answers a velocity change du with an impulse of about -E du, and a body of mass M then
 * changes its velocity by -(E / M) du in the next substep: the velocity alternates from
 * substep to substep, decaying only while E < M. E is about half the displaced fluid's mass
 * for a sphere in a continuum; in the particle fluid it is about the whole of it (rho V):
 * measured, a sphere of 1.5 spacings half as dense as the Carreau-Yasuda fluid still shook
 * with M + A = rho V, and was quiet with 2 rho V (tests/README.md, "Light bodies"). So a
 * body whose mass is under 2 E, E = rho V_w (V_w its volume times its wetted share: the
 * particles within a spacing of its surface over the number a submerged one has), takes its
 * velocity change as if it had the mass M + A = 2 E: the loop's factor E / (M + A) is then
 * about 1/2. A viscosity solved implicitly (the Carreau-Yasuda model's) moves the fluid
 * within L = sqrt(nu dt) of the surface with the body in the substep, so where L exceeds the
 * spacing E is at least the mass of the fluid within L. The rotation is the same loop: the
 * fluid in the band turns with the body's surface (its moment of inertia about the body's
 * centre, I_f, was 19 times the body's for a sphere of 3 spacings a quarter as dense as a
 * fluid of 0.01 m^2/s, which spun up to 700 rad/s in 9 ms), so a body whose moment of
 * inertia (the mean of its principal ones) is under 2 I_f takes the fluid's torque as if it
 * were 2 I_f. The impulse and angular impulse held back go to the particles in the band as a
 * velocity and a rotation about their centre (the fluid moves with the body as an added
 * mass does), so momentum and angular momentum are kept to round-off. A steady state
 * (floating, a terminal velocity) is unchanged; a transient is slower by (2 E + E) / (M + E).
 * A body of several geoms (k its first) is one body here: their volumes and bands add (where
 * geoms overlap, the overlap counts twice: a larger E, more stabilisation), its band is every
 * particle within it of any of them, F and T are the body's. */
static void stabilise_light_body(stf_ode *c, int k, double dt, double F[3], double T[3])
{
    const attachment *a = &c->att[k];
    const dReal *com = dBodyGetPosition(a->body);
    double X[3] = {com[0], com[1], com[2]}, vol = 0, vol_band = 0, far = 0;
    int nids = 0;
    for (int j = k; j < c->n; j++) {
        const attachment *b = &c->att[j];
        if (b->body != a->body) continue;
        if (!(b->vol > 0) || !(b->vol_band > 0)) return; /* a geom without a volume */
        vol += b->vol, vol_band += b->vol_band;
        const dReal *p = dGeomGetPosition(b->geom);
        double d[3] = {p[0] - X[0], p[1] - X[1], p[2] - X[2]};
        far = fmax(far, b->reach + sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]));
        c->ids[nids++] = b->collider;
    }
    dMass m;
    dBodyGetMass(a->body, &m);
    double s = c->spacing, mp = stf_fluid_particle_mass(c->fluid), rho = mp / (s * s * s);
    double Ib = (m.I[0] + m.I[5] + m.I[10]) / 3; /* ODE's 3x4 rows: the diagonal */
    double reach = sqrt(c->nu_implicit * dt), band = s;
    /* a body heavier than any wetting can ask for skips the pass over the particles: the
       band's fluid (at most 1.5 times its nominal mass) turns at most at the bounding radius */
    far += s;
    if (reach <= s && m.mass >= 2 * rho * vol && Ib >= 2 * (2.0 / 3.0) * 1.5 * rho * vol_band * far * far)
        return;
    double sum[3], sum2[6];
    int wetted = stf_fluid_collider_band(c->fluid, c->ids, nids, s, X, sum, sum2), count = wetted;
    double wet = fmin(1.0, wetted * s * s * s / vol_band), E = rho * vol * wet;
    /* a viscosity solved implicitly moves the fluid within L = sqrt(nu dt) of the surface with
       the body in the substep: E is at least that fluid's mass, and the band is L wide */
    if (reach > s) {
        band = reach;
        count = stf_fluid_collider_band(c->fluid, c->ids, nids, band, X, sum, sum2);
        E = fmax(E, count * mp);
    }
    if (count < 4) return;
    double A = 2 * E - m.mass;
    /* the band's centre (relative to X), its inertia about X (mean of the principal ones)
       and its inertia tensor about its centre */
    double cen[3] = {sum[0] / count, sum[1] / count, sum[2] / count};
    double If = mp * 2.0 / 3.0 * (sum2[0] + sum2[1] + sum2[2]);
    double Ar = 2 * If - Ib;
    if (!(A > 0) && !(Ar > 0)) return;
    double cov[6] = {sum2[0] - count * cen[0] * cen[0], sum2[1] - count * cen[1] * cen[1],
                     sum2[2] - count * cen[2] * cen[2], sum2[3] - count * cen[0] * cen[1],
                     sum2[4] - count * cen[0] * cen[2], sum2[5] - count * cen[1] * cen[2]};
    double tr = cov[0] + cov[1] + cov[2], Ic[6], inv[9];
    Ic[0] = mp * (tr - cov[0]), Ic[1] = mp * (tr - cov[1]), Ic[2] = mp * (tr - cov[2]);
    Ic[3] = -mp * cov[3], Ic[4] = -mp * cov[4], Ic[5] = -mp * cov[5];
    if (inverse_sym3(Ic, inv) != 0) return; /* a band of particles in a line: left as it is */
    dVector3 g = {0, 0, 0, 0};
    if (dBodyGetGravityMode(a->body)) dWorldGetGravity(c->world, g); /* the body's own weight */
    double D[3] = {0, 0, 0}, H[3] = {0, 0, 0}, dv[3], L[3], w[3];
    for (int q = 0; q < 3 && A > 0; q++) {
        double held = F[q] - m.mass * (F[q] - A * g[q]) / (m.mass + A); /* N */
        F[q] -= held;
        D[q] = held * dt;
    }
    for (int q = 0; q < 3 && Ar > 0; q++) {
        double held = T[q] * Ar / (Ib + Ar); /* N m */
        T[q] -= held;
        H[q] = held * dt;
    }
    /* the uniform velocity carries D and the moment cen × D about X; the rotation about the
       band's centre the rest of H */
    for (int q = 0; q < 3; q++) dv[q] = D[q] / (count * mp);
    L[0] = H[0] - (cen[1] * D[2] - cen[2] * D[1]);
    L[1] = H[1] - (cen[2] * D[0] - cen[0] * D[2]);
    L[2] = H[2] - (cen[0] * D[1] - cen[1] * D[0]);
    for (int q = 0; q < 3; q++) w[q] = inv[3 * q] * L[0] + inv[3 * q + 1] * L[1] + inv[3 * q + 2] * L[2];
    double C[3] = {X[0] + cen[0], X[1] + cen[1], X[2] + cen[2]};
    stf_fluid_collider_band_push(c->fluid, c->ids, nids, band, C, dv, w);
}

/* 1 when attachment k is the first of its body's, and that body is dynamic. */
static int first_of_body(const stf_ode *c, int k)
{
    dBodyID b = c->att[k].body;
    if (!b || dBodyIsKinematic(b)) return 0;
    for (int j = 0; j < k; j++)
        if (c->att[j].body == b) return 0;
    return 1;
}

/* Gives body a's share of the fluid's reaction as force and torque over dt. */
static void apply_reaction(stf_ode *c, int k, double dt)
{
    const attachment *a = &c->att[k];
    double J[3], M[3], *F = c->force + 3 * k, *T = c->torque + 3 * k;
    double *P = c->part + 3 * STF_ODE_PARTS * k;
    stf_fluid_collider_impulse(c->fluid, a->collider, J, M);
    memset(F, 0, 3 * sizeof *F);
    memset(T, 0, 3 * sizeof *T);
    memset(P, 0, 3 * STF_ODE_PARTS * sizeof *P);
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
    double parts[STF_PARTS][3];
    stf_fluid_collider_impulse_parts(c->fluid, a->collider, parts);
    for (int p = 0; p < STF_PARTS; p++)
        for (int q = 0; q < 3; q++) P[3 * p + q] = parts[p][q] / dt;
    if (J[0] != 0 || J[1] != 0 || J[2] != 0 || S[0] != 0 || S[1] != 0 || S[2] != 0) {
        dBodyEnable(a->body); /* a body the fluid pushes must not fall asleep */
        dBodyAddForce(a->body, F[0], F[1], F[2]);
        dBodyAddTorque(a->body, T[0], T[1], T[2]);
    }
}

/* The added-mass stabilisation of each dynamic body, on its force and torque (the sums over
 * its geoms, apply_reaction's): what it holds back acts on the body as one more force and
 * torque, booked as its first geom's added-mass part. */
static void stabilise_bodies(stf_ode *c, double dt)
{
    for (int k = 0; k < c->n; k++) {
        if (!first_of_body(c, k)) continue;
        dBodyID b = c->att[k].body;
        double F[3] = {0, 0, 0}, T[3] = {0, 0, 0}, F0[3], T0[3], dF[3], dT[3];
        for (int j = k; j < c->n; j++) {
            if (c->att[j].body != b) continue;
            for (int q = 0; q < 3; q++) F[q] += c->force[3 * j + q], T[q] += c->torque[3 * j + q];
        }
        memcpy(F0, F, sizeof F0);
        memcpy(T0, T, sizeof T0);
        stabilise_light_body(c, k, dt, F, T);
        int any = 0;
        for (int q = 0; q < 3; q++) {
            dF[q] = F[q] - F0[q], dT[q] = T[q] - T0[q];
            any |= dF[q] != 0 || dT[q] != 0;
        }
        if (!any) continue;
        double *P = c->part + 3 * STF_ODE_PARTS * k + 3 * STF_ODE_PART_ADDED_MASS;
        for (int q = 0; q < 3; q++) {
            c->force[3 * k + q] += dF[q], c->torque[3 * k + q] += dT[q];
            P[q] = dF[q];
        }
        dBodyEnable(b);
        dBodyAddForce(b, dF[0], dF[1], dF[2]);
        dBodyAddTorque(b, dT[0], dT[1], dT[2]);
    }
}

/* Moves each dynamic body by -shift / M, shift the mass-weighted overlap removal of its
 * colliders (stf_fluid_collider_shift): particles pushed out of a body without momentum
 * move the body back by as much as they carry, so the centre of mass of fluid and body
 * stays where it was and the angular momentum M X × V with it. The body's momentum
 * moves too, by the step's impulse J it gets from the fluid (less what the added-mass
 * stabilisation held back), which dWorldStep adds before it moves the body: M s × (V +
 * J/M) = -shift × V + s × J; a torque takes s × J back. (Taken with the fluid's whole
 * impulse, a light body lost s × the held-back impulse each substep: 3e-6 to 3.5e-5 of the
 * angular momentum in test_coupling's exchange cases with bodies of 0.01 kg.) */
static void move_bodies(stf_ode *c, double dt)
{
    for (int k = 0; k < c->n; k++) {
        if (!first_of_body(c, k)) continue; /* once per dynamic body, with all its colliders */
        dBodyID b = c->att[k].body;
        double S[3] = {0, 0, 0}, J[3] = {0, 0, 0};
        for (int j = k; j < c->n; j++) {
            if (c->att[j].body != b) continue;
            double s[3], Jj[3], Mj[3];
            stf_fluid_collider_shift(c->fluid, c->att[j].collider, s);
            stf_fluid_collider_impulse(c->fluid, c->att[j].collider, Jj, Mj);
            /* the impulse the body gets: the fluid's, less what the added-mass stabilisation
               held back and handed to the particles (its part, 0 when it did not act) */
            const double *P = c->part + 3 * STF_ODE_PARTS * j + 3 * STF_ODE_PART_ADDED_MASS;
            for (int q = 0; q < 3; q++) S[q] += s[q], J[q] += Jj[q] + dt * P[q];
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
    dContact ct[STF_ODE_MAX_CONTACTS];
    int nc = dCollide(g1, g2, c->contact.max_contacts, &ct[0].geom, sizeof(dContact));
    for (int i = 0; i < nc; i++) {
        ct[i].surface.mode = dContactBounce | dContactSoftERP | dContactSoftCFM;
        ct[i].surface.mu = c->contact.mu;
        ct[i].surface.bounce = c->contact.bounce;
        ct[i].surface.bounce_vel = c->contact.bounce_vel;
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

int stf_ode_substep(stf_ode *c, double dt)
{
    for (int k = 0; k < c->n; k++) sync_collider(c, &c->att[k]);
    if (stf_fluid_step(c->fluid, dt) != 0) {
        fail(c, "%s", stf_fluid_failure(c->fluid));
        return -1;
    }
    for (int k = 0; k < c->n; k++) apply_reaction(c, k, dt);
    stabilise_bodies(c, dt);
    move_bodies(c, dt);
    if (c->collide) {
        c->stats.collide_calls++;
        c->collide(c->collide_data, c->contacts, dt);
    } else if (c->space) {
        collide_space(c, c->space);
    }
    int ok;
    if (c->step.stepper == STF_ODE_QUICK_STEP) {
        dWorldSetQuickStepNumIterations(c->world, c->step.quick_iterations);
        ok = dWorldQuickStep(c->world, dt);
    } else {
        ok = dWorldStep(c->world, dt);
    }
    dJointGroupEmpty(c->contacts);
    if (!ok) {
        fail(c, "ODE's %s failed (out of memory) at a substep of %g s",
             c->step.stepper == STF_ODE_QUICK_STEP ? "dWorldQuickStep" : "dWorldStep", dt);
        return -1;
    }
    for (int q = 0; q < 3 * c->n; q++)
        c->imp[q] += c->force[q] * dt, c->aimp[q] += c->torque[q] * dt;
    for (int q = 0; q < 3 * STF_ODE_PARTS * c->n; q++) c->pimp[q] += c->part[q] * dt;
    c->stats.substeps++;
    if (c->stats.dt_min == 0 || dt < c->stats.dt_min) c->stats.dt_min = dt;
    if (dt > c->stats.dt_max) c->stats.dt_max = dt;
    return 0;
}

/* Step control. A step of dt is split into m equal substeps when the state asks for it; m = 1
 * (the step as given, bit for bit) otherwise.
 *   CFL:       the fastest particle moves at most CFL_H interaction radii per substep;
 *   stiffness: dt_sub^2 k_eff <= STIFF_MAX, where k_eff (1/s^2) is the larger of the
 *              pressure's k/h and the spring network's, sum_j k_ij (1 - L/h) of the
 *              stiffest particle in the last substep (history stiffness included, which
 *              grows with the strain rate). Under compression the pressure's own term
 *              (P + 2 P_near) / h (stf_fluid_pressure_stiffness) grows past k/h; its excess
 *              over k/h counts PRESS_EXCESS times, because it is read from the last substep
 *              while an impact raises it within the step. Measured: in the bowling scenes at
 *              2 m/s the term stays under 0.77 k/h (nothing changes); a ball thrown at 15 m/s
 *              onto the 1.5 cm pool drives it to 33 k/h and, without it, the pressure stage
 *              blew up in the rebound (t = 0.03 s); with the excess counted 1, 2, 4 and 8
 *              times it blew up at 0.098 s, 0.091 s, at 25 m/s at 0.07 s, and not at all
 *              (15 m/s for 1 s, 25 m/s for 0.3 s).
 * The bounds are measured: the stability test scene (tests/scenes/stab_pool.yaml) runs at
 * dt = 2 ms (k/h dt^2 = 0.2) and blows up at 3 ms (0.45); the bowling scenes never trigger
 * it. The history buffer stays indexed in substeps: while a step is split, its window of d
 * substeps covers d dt/m seconds, and Eq. 3's weights treat the substeps as equal steps (they
 * are, within a step). Keeping the window in seconds would need weights for unequal steps; the
 * split is rare at the CLI's 1 ms (impacts, violent vibration) and short, so we accept the
 * shorter memory meanwhile. An app stepping at 1/60 s splits every step: its fluid's memory
 * of d substeps is d/m of its steps.
 *   bodies:    a dynamic body moves at most BODY_TRAVEL of its inradius per substep. ODE's
 *              contacts are discrete: a body whose centre passes a wall's mid-plane within
 *              one step is pushed out on the far side (measured: a 2.5 cm lead ball at 60 m/s
 *              went through a 2 mm wall at dt = 1 ms; at 40 m/s it did not).
 *   thin solids: a particle moves at most half a spacing plus T relative to each solid per
 *              substep, T the distance from a solid's surface to the point past which it is
 *              pushed out on the far side: a geom's inradius, half the container's wall when
 *              the wall is solid from both sides (stf_wall_two_sided), the whole wall when it
 *              is not (beyond it: outside, free). The collisions leave particles half a
 *              spacing from a solid.
 *              Only thin solids trigger it: with h = 2 spacings, T < spacing / 2 (the CFL
 *              bound is stricter otherwise). The speed is the fastest particle's plus the
 *              solid's. */
static const double CFL_H = 0.5, STIFF_MAX = 0.25, BODY_TRAVEL = 0.5, PRESS_EXCESS = 8.0;

/* The largest speed (m/s) of a solid's material: body velocity, rotation about its centre
 * at radius r, and a kinematic body's peak (stf_ode_set_peak_speed). */
static double solid_speed(dBodyID b, double r, double peak)
{
    if (!b) return 0;
    const dReal *u = dBodyGetLinearVel(b), *w = dBodyGetAngularVel(b);
    double sp = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) +
                sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * r;
    if (dBodyIsKinematic(b) && peak > sp) sp = peak;
    return sp;
}

/* The limits' substep count (unbounded; 1 when nothing asks for more). */
static double substeps_needed(const stf_ode *c, double dt)
{
    double k_eff = c->k_press, last = stf_fluid_last_dt(c->fluid);
    double kp = stf_fluid_pressure_stiffness(c->fluid);
    if (kp > c->k_press) k_eff = c->k_press + PRESS_EXCESS * (kp - c->k_press);
    if (last > 0) {
        double ks = stf_fluid_spring_gain(c->fluid) / (last * last);
        if (ks > k_eff) k_eff = ks;
    }
    double need = sqrt(dt * dt * k_eff / STIFF_MAX);
    double vf = stf_fluid_max_speed(c->fluid), rp = 0.5 * c->spacing;
    double cfl = vf * dt / (CFL_H * c->h);
    if (cfl > need) need = cfl;
    for (int k = 0; k < c->n; k++) {
        const attachment *a = &c->att[k];
        if (!a->geom) { /* a container */
            double thin = (vf + solid_speed(a->body, a->diag, a->peak)) * dt /
                          (rp + (stf_wall_two_sided(a->wall, c->spacing) ? 0.5 : 1.0) * a->wall);
            if (thin > need) need = thin;
            continue;
        }
        if (!a->bounded) continue; /* a plane: no far side */
        double r = a->inradius;
        double reach = a->reach;
        if (a->body) { /* a geom off its body's centre reaches further */
            const dReal *p = dGeomGetPosition(a->geom), *x = dBodyGetPosition(a->body);
            double d[3] = {p[0] - x[0], p[1] - x[1], p[2] - x[2]};
            double off = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            if (off > 0) reach += off;
        }
        double thin = (vf + solid_speed(a->body, reach, a->peak)) * dt / (rp + r);
        if (thin > need) need = thin;
        if (!a->body || dBodyIsKinematic(a->body) || !(r > 0)) continue;
        const dReal *v = dBodyGetLinearVel(a->body);
        double travel = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) * dt / (BODY_TRAVEL * r);
        if (travel > need) need = travel;
    }
    return need;
}

int stf_ode_substeps(const stf_ode *c, double dt)
{
    if (!c->step.adaptive) return 1;
    double need = substeps_needed(c, dt);
    if (!(need > 1.0)) return 1;
    return need >= c->step.max_substeps ? c->step.max_substeps : (int)ceil(need);
}

int stf_ode_step(stf_ode *c, double dt)
{
    if (!(dt > 0) || !isfinite(dt)) {
        fail(c, "stf_ode_step: dt = %g: must be > 0 s and finite", dt);
        return -1;
    }
    int m = 1;
    if (c->step.adaptive) {
        double need = substeps_needed(c, dt);
        if (need > c->step.max_substeps) c->stats.capped++;
        if (need > 1.0) m = need >= c->step.max_substeps ? c->step.max_substeps : (int)ceil(need);
    }
    double sub = m == 1 ? dt : dt / m;
    if (c->n > 0) { /* a coupler with no bodies has no impulse arrays */
        memset(c->imp, 0, 3 * (size_t)c->n * sizeof *c->imp);
        memset(c->aimp, 0, 3 * (size_t)c->n * sizeof *c->aimp);
        memset(c->pimp, 0, 3 * STF_ODE_PARTS * (size_t)c->n * sizeof *c->pimp);
    }
    c->step_dt = 0;
    for (int j = 0; j < m; j++)
        if (stf_ode_substep(c, sub) != 0) return -1;
    c->step_dt = dt;
    c->stats.steps++;
    c->stats.last_substeps = m;
    c->stats.last_dt = sub;
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

void stf_ode_substep_force(const stf_ode *c, dBodyID body, double force[3], double torque[3])
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

void stf_ode_body_fluid_force(const stf_ode *c, dBodyID body, double force[3], double torque[3])
{
    if (c->stats.last_substeps <= 1 || !(c->step_dt > 0)) { /* one substep: its force */
        stf_ode_substep_force(c, body, force, torque);
        return;
    }
    memset(force, 0, 3 * sizeof *force);
    memset(torque, 0, 3 * sizeof *torque);
    for (int k = 0; k < c->n; k++) {
        if (c->att[k].body != body) continue;
        for (int q = 0; q < 3; q++) {
            force[q] += c->imp[3 * k + q] / c->step_dt;
            torque[q] += c->aimp[3 * k + q] / c->step_dt;
        }
    }
}

/* body's parts from src (c->part or c->pimp) times scale */
static void sum_parts(const stf_ode *c, dBodyID body, const double *src, double scale,
                      double parts[STF_ODE_PARTS][3])
{
    memset(parts, 0, STF_ODE_PARTS * sizeof parts[0]);
    for (int k = 0; k < c->n; k++) {
        if (c->att[k].body != body) continue;
        const double *P = src + 3 * STF_ODE_PARTS * k;
        for (int p = 0; p < STF_ODE_PARTS; p++)
            for (int q = 0; q < 3; q++) parts[p][q] += scale * P[3 * p + q];
    }
}

void stf_ode_substep_force_parts(const stf_ode *c, dBodyID body, double parts[STF_ODE_PARTS][3])
{
    sum_parts(c, body, c->part, 1.0, parts);
}

void stf_ode_body_fluid_force_parts(const stf_ode *c, dBodyID body, double parts[STF_ODE_PARTS][3])
{
    if (c->stats.last_substeps <= 1 || !(c->step_dt > 0)) /* one substep: its force */
        sum_parts(c, body, c->part, 1.0, parts);
    else
        sum_parts(c, body, c->pimp, 1.0 / c->step_dt, parts);
}

int stf_ode_settle(stf_ode *c, double dt, int steps, double tau)
{
    return stf_ode_settle_until(c, dt, steps, tau, NULL, NULL);
}

int stf_ode_settle_until(stf_ode *c, double dt, int steps, double tau,
                         int (*stop)(void *arg), void *arg)
{
    for (int k = 0; k < c->n; k++) { /* the poses as synced, the velocities zero */
        sync_collider(c, &c->att[k]);
        stf_fluid_hold_collider(c->fluid, c->att[k].collider);
    }
    for (int s = 0; s < steps; s++) {
        /* split as a step of the run is (stf_ode_substeps): a scene's dt that its run
           takes in substeps is no stabler while the fluid settles */
        int m = stf_ode_substeps(c, dt);
        double sub = dt / m, keep_sub = exp(-sub / tau);
        for (int j = 0; j < m; j++) {
            if (stop && stop(arg)) return 1;
            if (stf_fluid_step(c->fluid, sub) != 0) {
                fail(c, "%s", stf_fluid_failure(c->fluid));
                return -1;
            }
            stf_fluid_scale_velocities(c->fluid, keep_sub);
        }
    }
    stf_fluid_reset_clock(c->fluid);
    stf_fluid_forget_history(c->fluid); /* the start-up's motion is not the material's past */
    return 0;
}
