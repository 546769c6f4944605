/* fluid.h - internal state of a fluid, shared by the effect files. */
#ifndef STF_FLUID_INTERNAL_H
#define STF_FLUID_INTERNAL_H

#include "collider.h"
#include "grid.h"
#include "history.h"
#include "springs.h"
#include "stf.h"

#define WALL_BINS 64

/* Indices of the per-stage timers (stf_fluid_effect_seconds). */
enum stage {
    STAGE_GRID,
    STAGE_GRAVITY,
    STAGE_VISCOSITY,
    STAGE_SPRINGS,
    STAGE_HISTORY,
    STAGE_PRESSURE,
    STAGE_COLLIDE,
    STAGE_BOUNDARY,
    STAGE_COUNT
};

struct stf_fluid {
    stf_fluid_def def;
    double h;            /* interaction radius, m */
    double contact;      /* the collision stage's contact radius at the container and planes, m */
    double contact_body; /* ... and at every other collider (bodies), m (collider.c:collide_one) */
    double mass;         /* particle mass, kg */
    double rest_density; /* kernel rest density used (def's, or the lattice's) */
    double rest_near;    /* near density below which near-pressure is 0 (no tension) */
    double lattice;      /* the blocks' lattice spacing, m: def.spacing, or with rest: liquid the
                            spacing whose lattice has the liquid's rest density as kernel sum */

    int n, cap;
    double *x, *v, *xprev; /* 3n, interleaved */
    double *dx;            /* 3n scratch: displacements / impulses being gathered */
    double *dproj;         /* 3n scratch: a collider's overlap removal per particle, m */
    char *hit;             /* n scratch: particle touched the collider being processed */
    int32_t *id;           /* persistent particle ids */
    int next_id;

    stf_grid grid;       /* neighbours within h, rebuilt every step */
    stf_springs springs; /* allocated only with the springs effect */
    struct stf_gs *gs;   /* Gauss-Seidel springs (relaxation: gauss_seidel) */
    stf_history hist;    /* allocated only with the history effect */
    double *rho, *rho_near; /* n each, pressure effect only */
    float *khist_mean;      /* n: mean history stiffness of a particle's springs, 1/s^2 */
    double *Dprev;          /* 3n, springs.passive: the history's D of the step before */
    int Dprev_ok;           /* 1 when Dprev holds it (not before the history's first step) */
    double *field_w, *field_v; /* history.smoothing's lattice: weights and velocity sums */
    size_t field_cap;          /* nodes allocated */

    /* Solid walls as a half-space of lattice particles (pressure.c): kernel density, near
       density, the normal sums of (1-q) and (1-q)^2, and the second moments of (1-q) normal
       and along the wall, tabulated by distance to the wall. */
    double wall_table[6][WALL_BINS + 1];
    double grad_p[3]; /* hydrostatic pressure gradient (Clavet units per m), 0 without gravity */
    int ncolliders, collider_cap;
    collider *colliders;

    struct cy_state *cy; /* Carreau-Yasuda solver (cy.c), NULL for the Clavet model */

    double time;
    double dt_now;       /* length of the step being taken, s */
    long steps;
    long reorder_interval; /* least steps between re-sorting particles by cell */
    long next_reorder;     /* re-sort at the first neighbour rebuild from this step on */
    double stage_seconds[STAGE_COUNT];
    char failure[256];
};

/* The effect stages (one file each). */
void stf_viscosity_apply(stf_fluid *f, double dt);               /* viscosity.c */
void stf_pressure_relax(stf_fluid *f, double dt);                /* pressure.c */
void stf_pressure_wall_table(stf_fluid *f);                       /* pressure.c */
void stf_collide_all(stf_fluid *f, double dt);                   /* collider.c */
void stf_boundary_stick(stf_fluid *f, double dt);                /* boundary.c */

/* history.velocity smoothed: the velocity field at each particle as the density kernel sees
 * it, the Shepard average sum_j w_ij v_j / sum_j w_ij over the particle and its neighbours
 * (the grid's current rows), w = (1 - r/h)^2, 1 for the particle itself. A linear field is
 * kept where the neighbourhood is symmetric (the bulk); a particle's own grid-scale jitter
 * is averaged out. Into out (3n). */
void stf_fluid_smoothed_velocity(const stf_fluid *f, double *out);

/* history.smoothing > 0: the velocity field averaged over that length, into out (3n)
 * (src/velocity_field.c). Returns 0; -1 with f->failure written when the fluid spans more
 * than 1e8 cells; -2 when out of memory. */
int stf_fluid_field_velocity(stf_fluid *f, double *out);

/* Checks every particle after a stage named effect; on a blow-up or NaN writes the failure
 * message and returns -1. */
int stf_fluid_check(stf_fluid *f, const char *effect);

/* Permutes every per-particle array by perm (new index -> old index). Returns 0, or -1
 * when out of memory (then nothing has moved, unless the history ring's copy failed). */
int stf_fluid_permute(stf_fluid *f, const int32_t *perm);

static inline int has(const stf_fluid *f, unsigned effect) { return (f->def.effects & effect) != 0; }

/* 1 when the Clavet model's pressure stage is the projection (stf_cy_pressure_stage). */
static inline int projects(const stf_fluid *f)
{
    return f->def.model == STF_MODEL_CLAVET_STF && stf_def_projects(&f->def);
}

/* The hot neighbour loops get an AVX2 clone on x86-64 with GCC, chosen at load time. Same
 * results as the plain version: in ISO C mode GCC contracts no multiply-add into an FMA, and
 * the loops add up in the same order. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define STF_VECTOR_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define STF_VECTOR_CLONES
#endif

#endif
