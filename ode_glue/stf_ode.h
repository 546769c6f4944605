/* stf_ode.h - two-way coupling of a libstf fluid with ODE rigid bodies.
 *
 * For an ODE user: create a coupler for your world and space, attach the bodies the fluid
 * should feel, and call stf_ode_step with your loop's dt instead of dWorldStep.
 *
 *   stf_ode *c = stf_ode_create(world, space, fluid);
 *   stf_ode_attach_body(c, ball, NULL, err, sizeof err); // its geoms become colliders
 *   stf_ode_set_collide(c, my_collide, my_app);          // optional: your own contacts
 *   while (running) stf_ode_step(c, 1.0 / 60);           // split into stable substeps
 *   stf_ode_destroy(c);
 *
 * stf_ode_step(c, dt) splits dt into m equal substeps (stf_ode_substeps: the fluid's CFL
 * and stiffness limits, and how far bodies and particles may move past thin solids), and
 * for each substep: reads each attached geom's pose and velocity into its collider, steps
 * the fluid, turns the impulses the fluid gave each body into force and torque (J/dt) with
 * dBodyAddForce/dBodyAddTorque, makes ODE's contacts (the collision hook, or the
 * coupler's own collision of `space`), steps the world with the substep (dWorldStep or
 * dWorldQuickStep) and empties the coupler's contact group. ode_glue/README.md is the
 * contract in full: what is read and written, what the app may do between steps.
 * Momentum given to the particles equals momentum taken from the bodies, and so does angular
 * momentum: a particle pushed out of a body without a change of velocity (the overlap
 * removal) moves the body back by m delta / M, and the body takes the angular momentum
 * m delta × v (v relative to the body's centre) as a couple (stf_fluid_collider_shift).
 *
 * Every def below has a default function (fields filled by name) and is checked field by
 * field when given: a bad field is an error naming it, never clamped. */
#ifndef STF_ODE_H
#define STF_ODE_H

#include <ode/ode.h>

#include "stf.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct stf_ode stf_ode;

typedef struct stf_ode_attach_def {
    double friction; /* Coulomb friction coefficient of particle contacts, [0,1]; 0.2 */
    int stick;       /* 1: section 3.3 boundary treatment at this body's surface, 0: none;
                        0 */
} stf_ode_attach_def;

STF_API stf_ode_attach_def stf_ode_default_attach_def(void);
/* 0, or -1 with a message naming the bad field ("attach def: friction = 2: ..."). */
STF_API int stf_ode_check_attach_def(const stf_ode_attach_def *def, char *err, size_t errlen);

/* Surface of the coupler's own ODE contacts (body-body, body-static geom), made when no
 * collision hook is set (stf_ode_set_collide). ODE's dContactBounce, SoftERP and SoftCFM
 * modes are on. */
typedef struct stf_ode_contact_def {
    double mu;         /* Coulomb friction coefficient, >= 0 (dInfinity allowed); 0.8 */
    double bounce;     /* restitution, [0,1]; 0.1 */
    double bounce_vel; /* m/s, >= 0: slowest approach that bounces; 0.05 */
    double soft_erp;   /* contact error reduction, (0,1]; 0.2 */
    double soft_cfm;   /* contact constraint force mixing, >= 0 (finite); 1e-5 */
    int max_contacts;  /* contact points per geom pair, 1..STF_ODE_MAX_CONTACTS; 8 */
} stf_ode_contact_def;
#define STF_ODE_MAX_CONTACTS 64

STF_API stf_ode_contact_def stf_ode_default_contact_def(void);
/* 0, or -1 with a message naming the bad field. */
STF_API int stf_ode_check_contact_def(const stf_ode_contact_def *def, char *err, size_t errlen);

/* How stf_ode_step splits an app step and steps ODE. */
enum stf_ode_stepper {
    STF_ODE_WORLD_STEP = 0, /* dWorldStep: ODE's direct (big matrix) solver */
    STF_ODE_QUICK_STEP = 1, /* dWorldQuickStep with quick_iterations iterations */
};
typedef struct stf_ode_step_def {
    int adaptive;         /* 1: split each step into stable substeps (stf_ode_substeps);
                             0: one substep of the whole dt, whatever it is; 1 */
    int max_substeps;     /* most substeps of one step, 1..1000000; 64. A step whose limits
                             ask for more takes max_substeps (counted in
                             stf_ode_stats.capped: a larger dt than the fluid can take) */
    int stepper;          /* enum stf_ode_stepper; STF_ODE_WORLD_STEP */
    int quick_iterations; /* dWorldQuickStep iterations, >= 1, set on the world
                             (dWorldSetQuickStepNumIterations) before each quick step; 20 */
} stf_ode_step_def;

STF_API stf_ode_step_def stf_ode_default_step_def(void);
STF_API int stf_ode_check_step_def(const stf_ode_step_def *def, char *err, size_t errlen);

/* What the steps took (stf_ode_get_stats). */
typedef struct stf_ode_stats {
    long steps;          /* stf_ode_step calls that succeeded */
    long substeps;       /* coupled substeps taken (each one fluid step and one ODE step) */
    double dt_min;       /* s, shortest substep taken (0 before the first) */
    double dt_max;       /* s, longest substep taken (0 before the first) */
    int last_substeps;   /* substeps of the last stf_ode_step (0 before the first) */
    double last_dt;      /* s, their length: the last step's dt / last_substeps */
    long capped;         /* steps whose limits asked for more than max_substeps */
    long collide_calls;  /* calls of the collision hook */
} stf_ode_stats;

/* The collision hook: called once per substep, after the fluid's forces are on the bodies
 * and before the ODE step of dt seconds. It makes the app's contacts (dSpaceCollide with its
 * own nearCallback and surface). Contact joints may go to `contacts`, the coupler's group,
 * emptied after each ODE step, or to the app's own group, which the app then empties at the
 * start of each hook call (and once after its last step). */
typedef void (*stf_ode_collide_fn)(void *data, dJointGroupID contacts, double dt);

/* The coupler does not own world, space or fluid. space may be 0: then the coupler makes no
 * ODE contacts of its own (a collision hook, or none). NULL when out of memory. */
STF_API stf_ode *stf_ode_create(dWorldID world, dSpaceID space, stf_fluid *fluid);
STF_API void stf_ode_destroy(stf_ode *c);
/* Each returns 0, or -1 with a message naming the bad field (the coupler keeps its def). */
STF_API int stf_ode_set_contact(stf_ode *c, const stf_ode_contact_def *def, char *err, size_t errlen);
STF_API int stf_ode_set_step(stf_ode *c, const stf_ode_step_def *def, char *err, size_t errlen);
/* fn NULL: back to the coupler's own collision of `space`. */
STF_API void stf_ode_set_collide(stf_ode *c, stf_ode_collide_fn fn, void *data);

/* Couples every geom of body (sphere, box, capsule, cylinder, plane; convex via
 * stf_ode_attach_convex). def may be NULL for the defaults. Returns 0, -1 with err: a geom of
 * another class, or one attached already, and nothing is attached. A geom is attached at
 * most once (each attach function refuses a second time). */
STF_API int stf_ode_attach_body(stf_ode *c, dBodyID body, const stf_ode_attach_def *def, char *err,
                        size_t errlen);
/* Couples one geom; a geom with no body is a fixed wall. */
STF_API int stf_ode_attach_geom(stf_ode *c, dGeomID geom, const stf_ode_attach_def *def, char *err,
                        size_t errlen);
/* A convex geom: ODE does not hand its points back, so pass them (body frame, 3*n). */
STF_API int stf_ode_attach_convex(stf_ode *c, dGeomID geom, const double *points, int npoints,
                          const stf_ode_attach_def *def, char *err, size_t errlen);
/* An open-top container following body (0 for a fixed one at pos): inner size (x, y,
 * height) in m, wall thickness in m, frame origin at the centre of the floor's top face.
 * The fluid sees its inside as free and the walls as solid; ODE sees it through the geoms
 * the caller gave the body (or the static geoms it made). */
STF_API int stf_ode_attach_container(stf_ode *c, dBodyID body, const double pos[3], const double size[3],
                             double wall, const stf_ode_attach_def *def, char *err, size_t errlen);

/* Removes the particles inside attached solids: before the first step, and after the app
 * moves a body into the fluid between steps (the particles it lands on would otherwise be
 * pushed out in one substep and throw it back; ode_glue/README.md). Returns the number
 * removed. */
STF_API int stf_ode_remove_overlaps(stf_ode *c);

/* Advances fluid and world by dt seconds (> 0, finite) in stf_ode_substeps(c, dt) equal
 * substeps, each coupled (see the top of this file). Returns 0; -1 on a numerical failure
 * of the fluid, a bad dt or an ODE step that failed (stf_ode_failure tells what). After a
 * failure the state is that of the substep that failed: stop. */
STF_API int stf_ode_step(stf_ode *c, double dt);
/* The number of substeps stf_ode_step(c, dt) would take now (1 with adaptive 0), from the
 * state as it is: m = ceil of the largest of
 *   stiffness   dt sqrt(k_eff / 0.25), k_eff (1/s^2) the larger of the pressure's k/h and
 *               the spring network's gain of the last fluid step over its dt^2;
 *   CFL         v_max dt / (0.5 h), v_max the fastest particle;
 *   thin solids (v_max + v_solid) dt / (spacing/2 + T), T a solid's inradius, or the
 *               container's wall (half of it when stf_wall_two_sided), v_solid the
 *               solid's speed plus its rotation at its bounding radius;
 *   body travel |v| dt / (0.5 r), r a dynamic body's geom inradius;
 * at most max_substeps. The same function splits the `stf run` steps. */
STF_API int stf_ode_substeps(const stf_ode *c, double dt);
/* What the steps took so far. */
STF_API void stf_ode_get_stats(const stf_ode *c, stf_ode_stats *st);
/* The last failure, "" before any. */
STF_API const char *stf_ode_failure(const stf_ode *c);

/* The force (N) and torque (N m, about the body's centre) the fluid put on body over the last
 * stf_ode_step: its substeps' impulses over dt; zero for a body that is not attached. */
STF_API void stf_ode_body_fluid_force(const stf_ode *c, dBodyID body, double force[3], double torque[3]);
/* The same force (N) by the part that gave it: the fluid's stages (STF_PART_PRESSURE,
 * _VISCOSITY, _CONTACT, _STICK of stf.h) and the added-mass stabilisation's share
 * (STF_ODE_PART_ADDED_MASS: what it held back from a light body and gave the fluid beside it,
 * with its sign on the body). The parts sum to stf_ode_body_fluid_force's force. */
enum { STF_ODE_PART_ADDED_MASS = STF_PARTS, STF_ODE_PARTS };
STF_API void stf_ode_body_fluid_force_parts(const stf_ode *c, dBodyID body,
                                            double parts[STF_ODE_PARTS][3]);

/* Lets the fluid settle around the attached solids held still (their velocities taken as
 * zero, ODE not stepped) for `steps` steps of dt, each split into substeps as stf_ode_step
 * splits it (stf_ode_substeps), every velocity damped by exp(-substep / tau) after each
 * substep, then sets the fluid's clock back to 0: the fluid starts at rest
 * with the pressure that holds it up (scene key fluid.settle). 0, or -1 on a numerical
 * failure (stf_ode_failure). */
STF_API int stf_ode_settle(stf_ode *c, double dt, int steps, double tau);
/* stf_ode_settle that asks stop(arg) before each of its steps (an interrupt: a long settling
 * ends within one fluid step). Returns 1 when stop answered non-zero: the fluid is then part
 * settled, its clock not reset. stop may be NULL. */
STF_API int stf_ode_settle_until(stf_ode *c, double dt, int steps, double tau,
                                 int (*stop)(void *arg), void *arg);

#ifdef __cplusplus
}
#endif

#endif
