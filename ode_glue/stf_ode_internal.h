/* stf_ode_internal.h - the coupler's entry points for stf_sim.c (not installed). stf_sim
 * takes the same substeps as stf_ode_step (stf_ode_substeps) but works between them (it
 * drives its kinematic bodies, checks its bodies for a blow-up and may stop at an interrupt),
 * so it steps them one by one. */
#ifndef STF_ODE_INTERNAL_H
#define STF_ODE_INTERNAL_H

#include "stf_ode.h"

/* One coupled substep of exactly dt (no split): what stf_ode_step does m times. */
int stf_ode_substep(stf_ode *c, double dt);
/* The force and torque of body's colliders over the last substep (N, N m). */
void stf_ode_substep_force(const stf_ode *c, dBodyID body, double force[3], double torque[3]);
/* The same force by part (stf_ode_body_fluid_force_parts) over the last substep (N). */
void stf_ode_substep_force_parts(const stf_ode *c, dBodyID body, double parts[STF_ODE_PARTS][3]);
/* A kinematic body whose velocity the caller changes between substeps (a vibration): the
 * largest speed (m/s) its material reaches, taken by the thin-solid limit when larger than
 * its current speed. */
void stf_ode_set_peak_speed(stf_ode *c, dBodyID body, double speed);

#endif
