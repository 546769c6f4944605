/* stf_ode.h - two-way coupling of a libstf fluid with ODE rigid bodies.
 *
 * For an ODE user: create a coupler for your world and space, attach the bodies the fluid
 * should feel, and call stf_ode_step instead of dWorldStep.
 *
 *   stf_ode *c = stf_ode_create(world, space, fluid);
 *   stf_ode_attach_body(c, ball, NULL);     // every geom of the body becomes a collider
 *   for (;;) stf_ode_step(c, 0.001);        // fluid step, forces, dSpaceCollide, dWorldStep
 *   stf_ode_destroy(c);
 *
 * Each step (DESIGN.md, "The substep"): read each attached geom's pose and velocity into its
 * collider, step the fluid, turn the impulses the fluid gave each body into force and torque
 * (J/dt) with dBodyAddForce/dBodyAddTorque, collide the space (ODE's own contacts, e.g. a ball
 * on the container floor), dWorldStep with the same dt, empty the contact group.
 * Momentum given to the particles equals momentum taken from the bodies, and so does angular
 * momentum: a particle pushed out of a body without a change of velocity (the overlap
 * removal) moves the body back by m delta / M, and the body takes the angular momentum
 * m delta × v (v relative to the body's centre) as a couple (stf_fluid_collider_shift). */
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
    int stick;       /* 1: section 3.3 boundary treatment at this body's surface; 0 */
} stf_ode_attach_def;

stf_ode_attach_def stf_ode_default_attach_def(void);

/* Surface of ODE's own contacts (body-body, body-static geom) made by stf_ode_step. */
typedef struct stf_ode_contact_def {
    double mu;       /* Coulomb friction coefficient, >= 0 (dInfinity allowed); 0.8 */
    double bounce;   /* restitution, [0,1]; 0.1 */
    double soft_erp; /* contact error reduction, (0,1]; 0.2 */
    double soft_cfm; /* contact constraint force mixing, >= 0; 1e-5 */
    int max_contacts;/* per geom pair, >= 1; 8 */
} stf_ode_contact_def;

stf_ode_contact_def stf_ode_default_contact_def(void);

/* The coupler does not own world, space or fluid. space may be 0: then stf_ode_step makes
 * no ODE contacts (the caller collides the bodies itself). */
stf_ode *stf_ode_create(dWorldID world, dSpaceID space, stf_fluid *fluid);
void stf_ode_destroy(stf_ode *c);
void stf_ode_set_contact(stf_ode *c, const stf_ode_contact_def *def);

/* Couples every geom of body (sphere, box, capsule, cylinder, plane; convex via
 * stf_ode_attach_convex). def may be NULL for the defaults. Returns 0, -1 with err. */
int stf_ode_attach_body(stf_ode *c, dBodyID body, const stf_ode_attach_def *def, char *err,
                        size_t errlen);
/* Couples one geom; a geom with no body is a fixed wall. */
int stf_ode_attach_geom(stf_ode *c, dGeomID geom, const stf_ode_attach_def *def, char *err,
                        size_t errlen);
/* A convex geom: ODE does not hand its points back, so pass them (body frame, 3*n). */
int stf_ode_attach_convex(stf_ode *c, dGeomID geom, const double *points, int npoints,
                          const stf_ode_attach_def *def, char *err, size_t errlen);
/* An open-top container following body (0 for a fixed one at pos): inner size (x, y,
 * height) in m, wall thickness in m, frame origin at the centre of the floor's top face.
 * The fluid sees its inside as free and the walls as solid; ODE sees it through the geoms
 * the caller gave the body (or the static geoms it made). */
int stf_ode_attach_container(stf_ode *c, dBodyID body, const double pos[3], const double size[3],
                             double wall, const stf_ode_attach_def *def, char *err, size_t errlen);

/* Removes particles that start inside attached solids (call before the first step).
 * Returns the number removed. */
int stf_ode_remove_overlaps(stf_ode *c);

/* One coupled step of dt seconds. Returns 0; -1 on a numerical failure of the fluid
 * (stf_fluid_failure tells what). */
int stf_ode_step(stf_ode *c, double dt);

/* The force (N) and torque (N m, about the body's centre) the fluid put on body during the
 * last step; zero for a body that is not attached. */
void stf_ode_body_fluid_force(const stf_ode *c, dBodyID body, double force[3], double torque[3]);

#ifdef __cplusplus
}
#endif
/* Lets the fluid settle around the attached solids held still (their velocities taken as
 * zero, ODE not stepped) for `steps` fluid steps of dt, every velocity damped by
 * exp(-dt / tau) after each, then sets the fluid's clock back to 0: the fluid starts at rest
 * with the pressure that holds it up (scene key fluid.settle). 0, or -1 on a numerical
 * failure (stf_fluid_failure). */
int stf_ode_settle(stf_ode *c, double dt, int steps, double tau);

#endif
