/* stf_io.h - libstf_io: scene files (YAML), run output (HDF5 + XDMF) and run metrics.
 *
 * The fluid library (stf.h, libstf) reads and writes no file format; this library does, on
 * top of it: a scene file becomes an stf_scene (the fluid's definition, its blocks, the
 * container, the bodies and the expectations), which ode_glue/stf_sim.c runs. Its other
 * parts (src/io/h5io.h: the output file; src/io/metrics.h: the metrics of a run) are used
 * by the `stf` tool. Link with stf::stf_io (CMake) or `pkg-config --libs stf_io`. */
#ifndef STF_IO_H
#define STF_IO_H

#include <stddef.h>

#include "stf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------- scene files (YAML) */

enum stf_motion {
    STF_MOTION_DYNAMIC = 0,   /* moved by ODE under forces (needs mass > 0) */
    STF_MOTION_KINEMATIC = 1, /* moved by a prescribed velocity / vibration */
    STF_MOTION_STATIC = 2,    /* never moves */
};

typedef struct stf_block {
    double lo[3], hi[3]; /* m: opposite corners of the box filled with particles */
    double velocity[3];  /* m/s: initial velocity of its particles */
    double radius;       /* m: > 0 makes the block a ball of this radius around center
                            (lo, hi are then its bounding box); 0: the box [lo, hi] */
    double center[3];    /* m: centre of a ball block */
    int line, col;       /* where it was given (1-based), for messages */
} stf_block;

typedef struct stf_vibration {
    double axis[3];      /* unit direction of the displacement */
    double amplitude;    /* m, >= 0 (0: no vibration) */
    double frequency;    /* Hz, > 0 */
    double jitter;       /* relative random change of the frequency, [0,1) */
    double jitter_period;/* s, how often the frequency is redrawn (> 0) */
    unsigned seed;       /* random seed of the frequency changes */
} stf_vibration;

typedef struct stf_body_def {
    char name[64];          /* unique, [A-Za-z0-9_] */
    stf_collider_def shape; /* shape, friction, stick (points owned by the scene) */
    int motion;             /* enum stf_motion */
    double mass;            /* kg (> 0 for dynamic); 0 with density > 0: from the volume */
    double density;         /* kg/m^3, used when mass is 0 */
    double position[3];     /* m, centre */
    double quaternion[4];   /* orientation (w, x, y, z), normalised on load */
    double velocity[3];     /* m/s */
    double angular_velocity[3]; /* rad/s */
    stf_vibration vibration;    /* kinematic bodies only */
    int line, col;
} stf_body_def;

typedef struct stf_container_def {
    int present;            /* 0: the scene has no container */
    double size[3];         /* m: inner size (x, y, height); open top; floor at position.z */
    double wall;            /* m: wall and floor thickness (> 0) */
    double position[3];     /* m: centre of the floor's top face */
    double friction;        /* [0,1] */
    int stick;              /* 1: section 3.3 boundary treatment at its walls */
    int motion;             /* enum stf_motion */
    double mass;            /* kg, dynamic containers */
    stf_vibration vibration;
} stf_container_def;

typedef struct stf_expectation {
    char key[96];   /* metric key: "bounces", "ball.sink_time", "fluid.finger_height" */
    char op[3];     /* one of "<", "<=", ">", ">=", "==" */
    double value;   /* threshold, in the metric's unit */
    int line, col;
} stf_expectation;

typedef struct stf_scene {
    char path[512];         /* file it came from */
    char *text;             /* the effective scene (after --set/--unset) as YAML text */
    char name[64];
    double duration;        /* s, simulated time (> 0) */
    double dt;              /* s, substep (> 0) */
    double frame_rate;      /* frames written per simulated second (> 0) */
    double bounce_min_rise; /* m, 0: a quarter of the spacing */
    stf_fluid_def fluid;
    int nblocks;
    stf_block *blocks;
    char blocks_note[768];  /* "" or which fluid blocks share a volume (legal: their particles
                               sit on each other at twice the density, a stress case; usually
                               a mistake, so `stf run` prints it and a failed settling names it) */
    stf_container_def container;
    int nbodies;
    stf_body_def *bodies;
    int nexpect;
    stf_expectation *expect;
    double *points;         /* storage of convex points of all bodies */
    double settle;          /* s: the fluid settles this long around the bodies held still
                               before t = 0 (fluid.settle, ode_glue/stf_sim.c); 0: none */
    int dt_fixed;           /* 1: every substep is dt; 0 (default): adaptive substeps of at
                               most dt (ode_glue/stf_sim.c, scenes/README.md) */
} stf_scene;

/* One --set KEY=VALUE (value != NULL) or --unset KEY (value == NULL), applied in order. */
typedef struct stf_override {
    const char *key;   /* dotted path: "effects.history.q", "bodies.0.mass" */
    const char *value; /* a YAML scalar or flow sequence, NULL to remove the key */
} stf_override;

/* The most steps of dt a run takes (a duration, a frame interval, fluid.settle): beyond, a
 * step count would not fit the counters of a run and its file (and would not end). */
#define STF_MAX_STEPS 1000000000L

/* The steps of a run of `duration` seconds at dt: round(duration / dt). -1 with the reason
 * in err when that is not a count a run can take (1 .. STF_MAX_STEPS), or duration or dt is
 * not a finite number > 0. The scene loader holds a scene's own duration to it; a tool that
 * runs a scene for another duration (stf run --duration) holds that one. */
STF_API long stf_run_steps(double duration, double dt, char *err, size_t errlen);

/* Loads and checks a scene. Returns 0; or 2 (bad input) with
 * "FILE:LINE:COL: KEY: what is wrong (allowed: ...)" in err. */
STF_API int stf_scene_load(const char *path, const stf_override *ov, int nov, stf_scene **out, char *err,
                   size_t errlen);
/* Same from a string; name is used in messages as the file name. */
STF_API int stf_scene_load_string(const char *name, const char *text, const stf_override *ov, int nov,
                          stf_scene **out, char *err, size_t errlen);
STF_API void stf_scene_free(stf_scene *s);

#ifdef __cplusplus
}
#endif
#endif
