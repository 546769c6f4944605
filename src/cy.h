/* cy.h - internal: the Carreau-Yasuda non-Newtonian SPH solver (the second paper).
 *
 * A fluid whose def.model is STF_MODEL_CARREAU_YASUDA steps with stf_cy_step instead of the
 * Clavet pipeline. It shares the particles, the neighbour grid, the colliders (and so the
 * ODE coupling), the failure checks and the output with the Clavet model. */
#ifndef STF_CY_H
#define STF_CY_H

#include "fluid.h"

/* Checks the Carreau-Yasuda fields of def. Returns 0, or -1 with a message naming the field. */
int stf_cy_check_def(const stf_fluid_def *def, char *err, size_t errlen);
/* Creates f->cy (rest density, wall tables). Returns 0 or -1 (out of memory). */
int stf_cy_create(stf_fluid *f);
void stf_cy_free(stf_fluid *f);
/* One step of Algorithm 2 (with Algorithm 1 inside). Returns 0, or -1 with f->failure. */
int stf_cy_step(stf_fluid *f, double dt);
/* The Clavet model's pressure stage with def.pressure_mode projection (ours): the velocities
 * (x - xprev) / dt that gravity, viscosity and the springs predicted are projected at the
 * step's start positions xprev with the second paper's Algorithm 1 (solver, tolerance and
 * walls of def.cy), and the positions become xprev + dt v. Returns 0, or -1 out of memory. */
int stf_cy_pressure_stage(stf_fluid *f, double dt);
/* The warm-start pressures follow a reordering of the particles (perm: new index -> old). */
void stf_cy_follow_order(stf_fluid *f, const int32_t *perm);
/* Appends the model's effective parameters as YAML lines. Returns the length written. */
int stf_cy_describe(const stf_fluid *f, char *buf, size_t len);
/* Checkpoints: the warm-start pressures (state.h). 0, or -1 (with a message on load). */
struct stf_state;
int stf_cy_save_state(const stf_fluid *f, struct stf_state *s);
int stf_cy_load_state(stf_fluid *f, const struct stf_state *s, char *err, size_t errlen);

#endif
