/* stf_sim.h - a scene file made real: an ODE world with the scene's container and bodies,
 * the fluid, and the coupler between them. Used by the `stf` tool and the tests; an ODE user
 * embedding the fluid uses stf_ode.h directly instead. */
#ifndef STF_SIM_H
#define STF_SIM_H

#include "state.h"
#include "stf_io.h"
#include "stf_ode.h"

typedef struct stf_sim {
    const stf_scene *scene;
    dWorldID world;
    dSpaceID space;
    stf_fluid *fluid;
    stf_ode *coupler;
    dBodyID *bodies;        /* one per scene body */
    dBodyID container;      /* 0 when the container is static */
    double container_base[3];
    double *phase;          /* vibration phase per body (+1 for the container), rad */
    double *freq;           /* current vibration frequency, Hz */
    unsigned *rng;
    double *fluid_impulse;  /* per body, 3 each: the fluid's impulse over the last step (N s) */
    double *fluid_parts;    /* per body, STF_ODE_PARTS x 3: that impulse by part (N s) */
    int removed;            /* particles removed at set-up because they overlapped bodies */
    long steps;             /* steps of the scene's dt taken */
    double time;            /* s, steps * dt */
    long substeps;          /* substeps taken (>= steps; more when adaptive control split steps,
                               or the Carreau-Yasuda solver by its CFL: the fluid's substeps) */
    double dt_min, dt_max;  /* s, shortest and longest substep taken (0 before the first) */
    dGeomID *geoms;         /* the space's geoms in their order after creation (checkpoints
                               name a geom by its index here) */
    int ngeoms;
    /* the Carreau-Yasuda solver's statistics over all the fluid's substeps of the last
       stf_sim_step (adaptive control may take several fluid steps, each its own CFL
       substeps): substeps and the *_total/_sum fields summed, the *_max fields the largest,
       the per-substep fields those of the last substep */
    stf_solver_stats step_stats;
    /* Interrupts (`stf run`'s SIGINT/SIGTERM): when set, stop is asked between the substeps
       of a step; a non-zero answer ends stf_sim_step there (it returns 1) */
    int (*stop)(void *arg);
    void *stop_arg;
    int substep_in_step;    /* after a stopped step: substeps of it taken, of substep_count */
    int substep_count;
    /* The bodies' blow-up detector (stf_sim_step): per body, the largest speed (m/s) and
       fluid force (N) any physical motion of the scene can reach, set at creation (see
       body_bounds in stf_sim.c); 0: not checked (kinematic and static bodies) */
    double *speed_bound, *force_bound;
    double *spin_radius;    /* m, per body: the rotation's speed is counted at this radius (the
                               shape's inradius) */
    char failure[512];      /* why the last stf_sim_step failed, "" when it did not */
} stf_sim;

/* Builds the simulation. Returns 0; 2 with a message for a scene that cannot be built. */
int stf_sim_create(const stf_scene *scene, stf_sim **out, char *err, size_t errlen);
/* stf_sim_create whose fluid.settle asks stop(arg) before each of its steps (`stf run`'s
 * interrupts: a settling of many seconds ends within one fluid step). Returns as
 * stf_sim_create; 3 with a message when the settling failed, 130 when stop answered non-zero
 * (*out is then NULL). */
int stf_sim_create_until(const stf_scene *scene, int (*stop)(void *arg), void *arg,
                         stf_sim **out, char *err, size_t errlen);
void stf_sim_destroy(stf_sim *s);
/* One step of the scene's dt: one substep, or (adaptive control, the default) m >= 1 equal
 * substeps of dt/m chosen from the velocity (CFL), the effective stiffness and the thin
 * solids: the split of stf_ode_step (stf_ode_substeps, stf_ode.h), each substep checked by
 * the bodies' blow-up detector. Returns 0; -1 on a numerical failure of the fluid or of a
 * body (a dynamic body faster than its speed bound or pushed by more than its force bound:
 * stf_sim_failure says which, at which step, substep and stage); 1 when s->stop asked to
 * stop between two substeps (the step is then incomplete: s->steps and s->time are those of
 * the last whole step, the fluid's and the bodies' state that of substep s->substep_in_step
 * of s->substep_count). */
int stf_sim_step(stf_sim *s);
/* The message of the last failure (the fluid's or a body's), "" if none. */
const char *stf_sim_failure(const stf_sim *s);
/* A body's state: position (m), quaternion (w,x,y,z), velocity (m/s), angular velocity
 * (rad/s), and the fluid's force on it (N), its mean over the last step: the impulse of all
 * the step's substeps divided by the scene's dt. */
void stf_sim_body_state(const stf_sim *s, int k, double pos[3], double quat[4], double vel[3],
                        double angvel[3], double force[3]);
/* That force by part (stf_ode_body_fluid_force_parts), over the same step (N). */
void stf_sim_body_force_parts(const stf_sim *s, int k, double parts[STF_ODE_PARTS][3]);

/* Checkpoints (`stf run --resume`): adds the run's state to st (the fluid's, the bodies'
 * poses and velocities, the space's geom order, the vibration phases and random states, the
 * step counters), borrowing arrays of s: write st before the next step. 0 / -1 (out of
 * memory). */
int stf_sim_save_state(const stf_sim *s, stf_state *st);
/* Loads a state saved from a simulation built from the same scene into s, freshly created:
 * the next stf_sim_step continues bit for bit. 0, or -1 with a message. */
int stf_sim_load_state(stf_sim *s, const stf_state *st, char *err, size_t errlen);

#endif
