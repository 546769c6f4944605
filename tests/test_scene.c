/* test_scene.c - the YAML scene loader: values land in the right fields, every kind of bad
 * input is reported with FILE:LINE:COL and the dotted key, --set/--unset overrides work, and
 * the effective text round-trips. */
#define _POSIX_C_SOURCE 200809L
#include "stf_io.h"
#include "test_util.h"

#include <dirent.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Line numbers below are part of the tests: keep one key per line. */
static const char *const full_scene =
    "name: drop_test\n"                                            /* 1 */
    "duration: 2.5\n"                                              /* 2 */
    "dt: 0.0005\n"                                                 /* 3 */
    "frame_rate: 30\n"                                             /* 4 */
    "bounce_min_rise: 0.004\n"                                     /* 5 */
    "fluid:\n"                                                     /* 6 */
    "  model: clavet_stf\n"                                        /* 7 */
    "  spacing: 0.02\n"                                            /* 8 */
    "  density: 1200\n"                                            /* 9 */
    "  h: 0.05\n"                                                  /* 10 */
    "  blocks:\n"                                                  /* 11 */
    "    - min: [-0.1, -0.1, 0.0]\n"                               /* 12 */
    "      max: [0.1, 0.1, 0.2]\n"                                 /* 13 */
    "      velocity: [0, 0, -1]\n"                                 /* 14 */
    "    - {min: [-0.05, -0.05, 0.25], max: [0.05, 0.05, 0.3]}\n"  /* 15 */
    "effects:\n"                                                   /* 16 */
    "  gravity: {g: [0, 0, -9.8]}\n"                               /* 17 */
    "  viscosity: {sigma: 0.2, beta: 0.03}\n"                      /* 18 */
    "  pressure: {k: 0.7, k_near: 6, rest_density: 3}\n"           /* 19 */
    "  springs: {k_min: 120, yield_ratio: 0.2, plasticity: 0.4}\n" /* 20 */
    "  history:\n"                                                 /* 21 */
    "    q: 0.6\n"                                                 /* 22 */
    "    d: 150\n"                                                 /* 23 */
    "    k_hist: 7\n"                                              /* 24 */
    "    mode: full\n"                                             /* 25 */
    "  boundary_stick: {stick: 2}\n"                               /* 26 */
    "container:\n"                                                 /* 27 */
    "  size: [0.4, 0.4, 0.5]\n"                                    /* 28 */
    "  wall: 0.03\n"                                               /* 29 */
    "  position: [0, 0, 0]\n"                                      /* 30 */
    "  friction: 0.3\n"                                            /* 31 */
    "  stick: false\n"                                             /* 32 */
    "  motion: kinematic\n"                                        /* 33 */
    "  vibration: {axis: [0, 0, 2], amplitude: 0.001, frequency: 40, jitter: 0.1, "
    "jitter_period: 0.2, seed: 7}\n"                             /* 34 */
    "bodies:\n"                                                  /* 35 */
    "  - name: ball\n"                                           /* 36 */
    "    shape: sphere\n"                                        /* 37 */
    "    radius: 0.05\n"                                         /* 38 */
    "    mass: 0.3\n"                                            /* 39 */
    "    position: [0, 0, 0.6]\n"                                /* 40 */
    "    rotation: [2, 0, 0, 0]\n"                               /* 41 */
    "    velocity: [0, 0, -2]\n"                                 /* 42 */
    "    angular_velocity: [0, 1, 0]\n"                          /* 43 */
    "    friction: 0.5\n"                                        /* 44 */
    "    stick: true\n"                                          /* 45 */
    "  - name: crate\n"                                          /* 46 */
    "    shape: box\n"                                           /* 47 */
    "    size: [0.1, 0.2, 0.3]\n"                                /* 48 */
    "    stick: false\n"                                         /* 49 */
    "    motion: static\n"                                       /* 50 */
    "  - name: rod\n"                                            /* 51 */
    "    shape: capsule\n"                                       /* 52 */
    "    radius: 0.01\n"                                         /* 53 */
    "    length: 0.2\n"                                          /* 54 */
    "    motion: static\n"                                       /* 55 */
    "  - name: gem\n"                                            /* 56 */
    "    shape: convex\n"                                        /* 57 */
    "    points: [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]\n" /* 58 */
    "    motion: static\n"                                       /* 59 */
    "expect:\n"                                                  /* 60 */
    "  bounces: \">= 2\"\n"                                      /* 61 */
    "  ball.sink_time: \"<1.5\"\n"                               /* 62 */
    "  fluid.escaped: 0\n"                                       /* 63 */
    "  time_end: \"== 2.5\"\n";                                  /* 64 */

/* A small valid scene; error cases append to it or replace lines of it. */
#define MIN_HEAD                                                                                   \
    "duration: 1\n"                /* 1 */                                                         \
    "fluid:\n"                     /* 2 */                                                         \
    "  spacing: 0.01\n"            /* 3 */                                                         \
    "  blocks:\n"                  /* 4 */                                                         \
    "    - min: [0, 0, 0]\n"       /* 5 */                                                         \
    "      max: [0.1, 0.1, 0.1]\n" /* 6 */
#define MIN_EFFECTS                                                                                \
    "effects:\n"            /* 7 */                                                                \
    "  springs: {}\n"       /* 8 */                                                                \
    "  history: {q: 0.5}\n" /* 9 */
static const char *const min_scene = MIN_HEAD MIN_EFFECTS;

static const stf_fluid_def *fluid_of(const stf_scene *s)
{
    return &s->fluid;
}

/* original: s came from full_scene itself (not re-emitted text), so positions are known. */
static void check_full_values(const stf_scene *s, int original)
{
    const stf_fluid_def *f = fluid_of(s);
    CHECK(!strcmp(s->name, "drop_test"), "name %s", s->name);
    CHECK_NEAR(s->duration, 2.5, 0, "duration");
    CHECK_NEAR(s->dt, 0.0005, 0, "dt");
    CHECK_NEAR(s->frame_rate, 30, 0, "frame_rate");
    CHECK_NEAR(s->bounce_min_rise, 0.004, 0, "bounce_min_rise");
    CHECK_NEAR(f->spacing, 0.02, 0, "spacing");
    CHECK_NEAR(f->density, 1200, 0, "density");
    CHECK_NEAR(f->h, 0.05, 0, "h");
    CHECK(s->nblocks == 2, "nblocks %d", s->nblocks);
    if (s->nblocks == 2) {
        CHECK_NEAR(s->blocks[0].lo[0], -0.1, 0, "block lo");
        CHECK_NEAR(s->blocks[0].hi[2], 0.2, 0, "block hi");
        CHECK_NEAR(s->blocks[0].velocity[2], -1, 0, "block v");
        CHECK_NEAR(s->blocks[1].velocity[2], 0, 0, "block default v");
        CHECK(!original || (s->blocks[0].line == 12 && s->blocks[0].col == 7), "block0 at %d:%d",
              s->blocks[0].line, s->blocks[0].col);
        CHECK(!original || s->blocks[1].line == 15, "block1 line %d", s->blocks[1].line);
    }
    CHECK(f->effects == (STF_EFFECT_GRAVITY | STF_EFFECT_VISCOSITY | STF_EFFECT_PRESSURE |
                         STF_EFFECT_SPRINGS | STF_EFFECT_HISTORY | STF_EFFECT_BOUNDARY_STICK),
          "effects %#x", f->effects);
    CHECK_NEAR(f->gravity[2], -9.8, 0, "g");
    CHECK_NEAR(f->sigma, 0.2, 0, "sigma");
    CHECK_NEAR(f->beta, 0.03, 0, "beta");
    CHECK_NEAR(f->k, 0.7, 0, "k");
    CHECK_NEAR(f->k_near, 6, 0, "k_near");
    CHECK_NEAR(f->rest_density, 3, 0, "rest_density");
    CHECK_NEAR(f->k_min, 120, 0, "k_min");
    CHECK_NEAR(f->yield_ratio, 0.2, 0, "yield_ratio");
    CHECK_NEAR(f->plasticity, 0.4, 0, "plasticity");
    CHECK_NEAR(f->q, 0.6, 0, "q");
    CHECK(f->d == 150, "d %d", f->d);
    CHECK_NEAR(f->memory, 0, 0, "memory");
    CHECK_NEAR(f->k_hist, 7, 0, "k_hist");
    CHECK(f->history_mode == STF_HISTORY_FULL, "mode %d", f->history_mode);
    CHECK_NEAR(f->stick, 2, 0, "stick");

    const stf_container_def *c = &s->container;
    CHECK(c->present, "container present");
    CHECK_NEAR(c->size[1], 0.4, 0, "size");
    CHECK_NEAR(c->wall, 0.03, 0, "wall");
    CHECK_NEAR(c->friction, 0.3, 0, "friction");
    CHECK(c->stick == 0, "stick %d", c->stick);
    CHECK(c->motion == STF_MOTION_KINEMATIC, "motion %d", c->motion);
    CHECK_NEAR(c->vibration.axis[2], 1, 1e-15, "axis normalised");
    CHECK_NEAR(c->vibration.amplitude, 0.001, 0, "amplitude");
    CHECK_NEAR(c->vibration.frequency, 40, 0, "frequency");
    CHECK_NEAR(c->vibration.jitter, 0.1, 0, "jitter");
    CHECK_NEAR(c->vibration.jitter_period, 0.2, 0, "jitter_period");
    CHECK(c->vibration.seed == 7, "seed %u", c->vibration.seed);

    CHECK(s->nbodies == 4, "nbodies %d", s->nbodies);
    if (s->nbodies != 4) return;
    const stf_body_def *b = &s->bodies[0];
    CHECK(!strcmp(b->name, "ball") && b->shape.shape == STF_SHAPE_SPHERE, "ball");
    CHECK(!original || (b->line == 36 && b->col == 5), "ball at %d:%d", b->line, b->col);
    CHECK_NEAR(b->shape.radius, 0.05, 0, "radius");
    CHECK_NEAR(b->mass, 0.3, 0, "mass");
    CHECK(b->motion == STF_MOTION_DYNAMIC, "ball motion");
    CHECK_NEAR(b->position[2], 0.6, 0, "position");
    CHECK_NEAR(b->quaternion[0], 1, 1e-15, "quaternion normalised");
    CHECK_NEAR(b->velocity[2], -2, 0, "velocity");
    CHECK_NEAR(b->angular_velocity[1], 1, 0, "angular velocity");
    CHECK_NEAR(b->shape.friction, 0.5, 0, "friction");
    CHECK(b->shape.stick == 1, "stick");
    CHECK_NEAR(b->vibration.frequency, 50, 0, "default vibration");
    b = &s->bodies[1];
    CHECK(b->shape.shape == STF_SHAPE_BOX && b->motion == STF_MOTION_STATIC, "crate");
    CHECK_NEAR(b->shape.half[2], 0.15, 1e-15, "half extent");
    CHECK_NEAR(b->shape.friction, 0.2, 0, "default friction");
    CHECK(b->shape.stick == 0, "default stick");
    CHECK_NEAR(b->quaternion[0], 1, 0, "default rotation");
    b = &s->bodies[2];
    CHECK(b->shape.shape == STF_SHAPE_CAPSULE, "rod");
    CHECK_NEAR(b->shape.half_length, 0.1, 1e-15, "half length");
    b = &s->bodies[3];
    CHECK(b->shape.shape == STF_SHAPE_CONVEX && b->shape.npoints == 4, "gem");
    CHECK(b->shape.points == s->points, "gem points");
    if (b->shape.points) CHECK_NEAR(b->shape.points[3 * 3 + 2], 1, 0, "gem point 3 z");

    CHECK(s->nexpect == 4, "nexpect %d", s->nexpect);
    if (s->nexpect != 4) return;
    CHECK(!strcmp(s->expect[0].key, "bounces") && !strcmp(s->expect[0].op, ">="), "expect 0");
    CHECK_NEAR(s->expect[0].value, 2, 0, "expect 0 value");
    CHECK(!original || (s->expect[0].line == 61 && s->expect[0].col == 3), "expect at %d:%d",
          s->expect[0].line, s->expect[0].col);
    CHECK(!strcmp(s->expect[1].key, "ball.sink_time") && !strcmp(s->expect[1].op, "<"), "expect 1");
    CHECK_NEAR(s->expect[1].value, 1.5, 0, "expect 1 value");
    CHECK(!strcmp(s->expect[2].op, "==") && s->expect[2].value == 0, "expect 2 plain number");
    CHECK(!strcmp(s->expect[3].op, "==") && s->expect[3].value == 2.5, "expect 3");
}

static void test_full(void)
{
    char err[512] = "";
    stf_scene *s = NULL;
    int rc = stf_scene_load_string("full.yaml", full_scene, NULL, 0, &s, err, sizeof err);
    CHECK(rc == 0 && s, "full scene: %s", err);
    if (!s) return;
    check_full_values(s, 1);
    CHECK(!strcmp(s->path, "full.yaml"), "path %s", s->path);

    /* The emitted text loads to the same values. */
    stf_scene *again = NULL;
    rc = stf_scene_load_string("again.yaml", s->text, NULL, 0, &again, err, sizeof err);
    CHECK(rc == 0, "round trip: %s\n%s", err, s->text);
    if (again) check_full_values(again, 0);
    stf_scene_free(again);
    stf_scene_free(s);
}

static void test_defaults(void)
{
    char err[512] = "";
    stf_scene *s = NULL;
    int rc = stf_scene_load_string("dir/min.yaml", min_scene, NULL, 0, &s, err, sizeof err);
    CHECK(rc == 0, "min scene: %s", err);
    if (!s) return;
    stf_fluid_def d = stf_default_fluid_def();
    CHECK(!strcmp(s->name, "min"), "default name %s", s->name);
    CHECK_NEAR(s->dt, 0.001, 0, "default dt");
    CHECK_NEAR(s->frame_rate, 60, 0, "default frame rate");
    CHECK(s->fluid.effects == (STF_EFFECT_SPRINGS | STF_EFFECT_HISTORY), "effects %#x",
          s->fluid.effects);
    CHECK_NEAR(s->fluid.q, 0.5, 0, "q");
    CHECK_NEAR(s->fluid.k_min, d.k_min, 0, "default k_min");
    CHECK_NEAR(s->fluid.density, d.density, 0, "default density");
    CHECK(s->fluid.d == d.d, "default d");
    CHECK(!s->container.present && s->nbodies == 0 && s->nexpect == 0, "no optional sections");
    stf_scene_free(s);
}

/* Loads text (with overrides) and expects failure with every `want` in the message. */
static void expect_error(int line, const char *text, const stf_override *ov, int nov,
                         const char *want1, const char *want2)
{
    char err[512] = "";
    stf_scene *s = NULL;
    int rc = stf_scene_load_string("t.yaml", text, ov, nov, &s, err, sizeof err);
    CHECK(rc == 2 && !s, "case at line %d: rc %d", line, rc);
    CHECK(strstr(err, want1) != NULL, "case at line %d: '%s' not in '%s'", line, want1, err);
    if (want2)
        CHECK(strstr(err, want2) != NULL, "case at line %d: '%s' not in '%s'", line, want2, err);
    stf_scene_free(s);
}
#define EXPECT_ERROR(text, want1, want2) expect_error(__LINE__, text, NULL, 0, want1, want2)

static void test_errors(void)
{
    EXPECT_ERROR("fluid:\n  spacing: 0.01\n  blocks: [{min: [0,0,0], max: [1,1,1]}]\neffects: {}\n",
                 "t.yaml:1:1: duration: required key is missing", NULL);
    EXPECT_ERROR("duration: 1\nfluid:\n  blocks: [{min: [0,0,0], max: [1,1,1]}]\neffects: {}\n",
                 "t.yaml:2:1: fluid.spacing: required key is missing", NULL);
    EXPECT_ERROR("duration: abc\n", "t.yaml:1:11: duration: expected a number", NULL);
    EXPECT_ERROR("duration: .nan\n", "t.yaml:1:11: duration: must be a finite number", NULL);
    EXPECT_ERROR("duration: -.inf\n", "t.yaml:1:11: duration: must be a finite number", NULL);
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS "colour: red\n",
                 "t.yaml:10:1: colour: unknown key (allowed: name, duration, dt", "expect)");
    EXPECT_ERROR(
        MIN_HEAD "effects:\n  springs: {k_mn: 1}\n",
        "t.yaml:8:13: effects.springs.k_mn: unknown key (allowed: k_min, yield_ratio, plasticity, liquid_plasticity, damping, passive)",
        NULL);
    EXPECT_ERROR("duration: 1\nfluid:\n  spacing: -0.01\n",
                 "t.yaml:3:12: fluid.spacing: must be > 0", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  springs: {}\n  history: {q: 1.0}\n",
                 "t.yaml:9:16: effects.history.q: must be in (0,1)", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  springs: {}\n  history: {q: 0}\n",
                 "t.yaml:9:16: effects.history.q: must be in (0,1)", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  springs: {}\n  history: {d: 0}\n",
                 "t.yaml:9:16: effects.history.d: must be >= 1", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  springs: {}\n  history: {d: 150.5}\n",
                 "t.yaml:9:16: effects.history.d: expected an integer", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  springs: {}\n  history: {d: 10, memory: 0.1}\n",
                 "t.yaml:9:20: effects.history.memory:", NULL);
    /* memory is d = round(memory / dt) steps: below half a step it was silently 1 step */
    EXPECT_ERROR(MIN_HEAD "effects:\n  springs: {}\n  history: {memory: 0.0001}\n",
                 "t.yaml:9:21: effects.history.memory: must be in [0.5 dt", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  springs: {}\n  history: {memory: 1e6}\n",
                 "t.yaml:9:21: effects.history.memory: must be in [0.5 dt", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  history: {}\n",
                 "t.yaml:8:3: effects.history: needs effects.springs", NULL);
    /* the pressure's two modes: each one's keys are refused with the other, ranges named */
    EXPECT_ERROR(MIN_HEAD "effects:\n  pressure: {mode: projection, k: 100}\n",
                 "t.yaml:8:32: effects.pressure.k: a key of mode relax", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  pressure: {k: 100, eta: 0.01}\n",
                 "t.yaml:8:22: effects.pressure.eta: a key of mode: projection", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  pressure: {mode: projection, eta: 2}\n",
                 "t.yaml:8:37: effects.pressure.eta: must be in (0,1)", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  pressure: {mode: projection, solver: lu}\n",
                 "effects.pressure.solver: expected one of: jacobi, cg", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  pressure: {mode: projection, min_iterations: 5, "
                 "max_iterations: 4}\n", "effects.pressure.max_iterations: must be in "
                 "[min_iterations, 10000]", NULL);
    /* the relaxation's rest packing: a choice, exclusive with rest_density and tension */
    EXPECT_ERROR(MIN_HEAD "effects:\n  pressure: {rest: random}\n",
                 "effects.pressure.rest: expected one of: lattice, liquid", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  pressure: {rest: liquid, rest_density: 2.5}\n",
                 "effects.pressure.rest: liquid sets the rest density", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  pressure: {rest: liquid, tension: true}\n",
                 "effects.pressure.rest: liquid is measured without tension", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  pressure: {mode: projection, rest: liquid}\n",
                 "effects.pressure.rest: a key of mode relax", NULL);
    /* the relaxation's walls: a choice of mode relax */
    EXPECT_ERROR(MIN_HEAD "effects:\n  pressure: {wall: image}\n",
                 "effects.pressure.wall: expected one of: mirror, ghost", NULL);
    EXPECT_ERROR(MIN_HEAD "effects:\n  pressure: {mode: projection, wall: ghost}\n",
                 "effects.pressure.wall: a key of mode relax", NULL);
    {
        char e2[256];
        stf_scene *sc = NULL;
        CHECK(stf_scene_load_string("w.yaml", MIN_HEAD "effects:\n  pressure: {wall: ghost}\n",
                                    NULL, 0, &sc, e2, sizeof e2) == 0 && sc &&
                  sc->fluid.relax_wall == STF_RELAX_WALL_GHOST,
              "pressure.wall ghost: %d (%s)", sc ? sc->fluid.relax_wall : -1, e2);
        stf_scene_free(sc);
    }
    {   /* the projection's blocks start on the lattice unless fluid.jitter is given */
        char e2[256];
        stf_scene *sc = NULL;
        CHECK(stf_scene_load_string("p.yaml", MIN_HEAD "effects:\n  pressure: {mode: projection}\n",
                                    NULL, 0, &sc, e2, sizeof e2) == 0 && sc && sc->fluid.jitter == 0 &&
                  sc->fluid.pressure_mode == STF_PRESSURE_PROJECTION,
              "projection: jitter %g (%s)", sc ? sc->fluid.jitter : -1, e2);
        stf_scene_free(sc);
        sc = NULL;
        CHECK(stf_scene_load_string("p.yaml", "duration: 1\nfluid:\n  spacing: 0.01\n  jitter: 0.1\n"
                                    "  blocks: [{min: [0, 0, 0], max: [0.1, 0.1, 0.1]}]\n"
                                    "effects:\n  pressure: {mode: projection}\n",
                                    NULL, 0, &sc, e2, sizeof e2) == 0 && sc && sc->fluid.jitter == 0.1,
              "projection with jitter 0.1: %g (%s)", sc ? sc->fluid.jitter : -1, e2);
        stf_scene_free(sc);
    }
    EXPECT_ERROR(MIN_HEAD "effects:\n  pressure: {mode: implicit}\n",
                 "t.yaml:8:20: effects.pressure.mode: expected one of: relax, projection", NULL);
    EXPECT_ERROR(MIN_HEAD "effects: {}\ngravity: [0, 0, 1]\n", "t.yaml:8:1: gravity: unknown key",
                 NULL);
    EXPECT_ERROR(MIN_HEAD "effects: {gravity: {g: [0, 1]}}\n",
                 "t.yaml:7:25: effects.gravity.g: expected a list of 3 numbers", NULL);
    EXPECT_ERROR(MIN_HEAD "      velocity: 1\n" MIN_EFFECTS,
                 "t.yaml:7:17: fluid.blocks.0.velocity: expected a list of 3 numbers", NULL);
    EXPECT_ERROR(
        "duration: 1\nfluid:\n  spacing: 0.01\n  blocks:\n    - {min: [0, 0, 0], max: [1, 0, 1]}\n",
        "t.yaml:5:30: fluid.blocks.0.max: must be > min", NULL);
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS "container: {size: [0.05, 0.05, 0.05]}\n",
                 "t.yaml:5:7: fluid.blocks.0: lies outside the container", NULL);
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS
                 "bodies:\n  - name: ball\n    shape: sphere\n    radius: 0.1\n",
                 "t.yaml:11:5: bodies.0.mass: required key is missing", NULL);
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS
                 "bodies:\n  - name: ball\n    shape: sphere\n    radius: 0.1\n"
                 "    size: [1, 1, 1]\n    mass: 1\n",
                 "t.yaml:14:5: bodies.0.size: not a key of shape sphere (allowed: radius)", NULL);
    EXPECT_ERROR(
        MIN_HEAD MIN_EFFECTS "bodies:\n  - name: ball\n    shape: cube\n",
        "t.yaml:12:12: bodies.0.shape: expected one of: sphere, box, capsule, cylinder, convex",
        NULL);
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS "bodies:\n  - {name: a, shape: sphere, radius: 1, mass: 1}\n"
                                      "  - {name: a, shape: sphere, radius: 1, mass: 1}\n",
                 "t.yaml:12:12: bodies.1.name: duplicate body name", NULL);
    {   /* the metrics hold 16 bodies: a 17th would be missing from the report and expect */
        static char many[4096];
        int len = snprintf(many, sizeof many, "%s", MIN_HEAD MIN_EFFECTS "bodies:\n");
        for (int i = 0; i < 17; i++)
            len += snprintf(many + len, sizeof many - (size_t)len,
                            "  - {name: b%d, shape: sphere, radius: 0.01, mass: 1, position: [%d, 0, 1]}\n",
                            i, i);
        EXPECT_ERROR(many, "t.yaml:27:", "bodies.16: at most 16 bodies");
    }
    /* frames are written at most once per step: 2000 frames/s at dt = 1 ms would silently
     * be 1000 */
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS "frame_rate: 2000\n",
                 "t.yaml:10:13: frame_rate: must be <= 1/dt", NULL);
    /* a static body given a velocity moved with it (1 cm in 10 ms at 1 m/s) */
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS "bodies:\n  - {name: a, shape: sphere, radius: 1, motion: static, "
                                      "velocity: [1, 0, 0]}\n",
                 "t.yaml:11:", "bodies.0.velocity: not with motion: static");
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS "bodies:\n  - {name: a, shape: sphere, radius: 1, motion: static, "
                                      "angular_velocity: [0, 0, 1]}\n",
                 "t.yaml:11:", "bodies.0.angular_velocity: not with motion: static");
    /* a body named fluid could not be named by an expectation (fluid.bounces is a fluid key) */
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS "bodies:\n  - {name: fluid, shape: sphere, radius: 1, mass: 1}\n",
                 "t.yaml:11:12: bodies.0.name: 'fluid' is reserved", NULL);
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS
                 "bodies:\n  - {name: a, shape: sphere, radius: 1, mass: 1, density: 2}\n",
                 "bodies.0.density: give either mass or density", NULL);
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS
                 "bodies:\n  - {name: a, shape: sphere, radius: 1, density: 2, motion: static}\n",
                 "bodies.0.density: only for motion: dynamic", NULL);
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS "bodies:\n  - {name: a, shape: sphere, radius: 1, mass: 1, "
                                      "vibration: {}}\n",
                 "bodies.0.vibration: only allowed with motion: kinematic", NULL);
    /* libfyaml marks a quoted scalar just after its opening quote. */
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS "expect:\n  time_end: \"=< 3\"\n",
                 "t.yaml:11:14: expect.time_end: expected \"OP NUMBER\"", NULL);
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS "expect:\n  bounces: 1\n",
                 "t.yaml:11:3: expect.bounces: a body metric needs at least one body", NULL);
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS "expect:\n  ghost.bounces: 1\n",
                 "expect.ghost.bounces:", NULL);
    EXPECT_ERROR("duration: 1\nfluid: [1, 2\neffects: {}\n", "t.yaml:", "YAML syntax error");
    EXPECT_ERROR("duration: 1\nduration: 2\n", "t.yaml:2:1: YAML syntax error: duplicate key",
                 NULL);
    EXPECT_ERROR(MIN_HEAD MIN_EFFECTS "dt: 0.5\n", "t.yaml:10:5: dt: must be > 0 and <= 0.1", NULL);
    EXPECT_ERROR(MIN_HEAD "  h: 0.001\n" MIN_EFFECTS, "t.yaml:7:6: fluid.h: must be 0", NULL);
    EXPECT_ERROR(MIN_HEAD "  model: sph\n" MIN_EFFECTS, "fluid.model: expected one of: clavet_stf",
                 NULL);
}

static void test_overrides(void)
{
    char err[512] = "";
    stf_scene *s = NULL;
    stf_override set_q[] = {{"effects.history.q", "0.3"}};
    int rc = stf_scene_load_string("m.yaml", min_scene, set_q, 1, &s, err, sizeof err);
    CHECK(rc == 0 && s && s->fluid.q == 0.3, "--set q: %s", err);
    stf_scene_free(s);

    /* Creates history: under effects, and viscosity with a param. */
    stf_override create[] = {{"effects.history.q", "0.3"}, {"effects.viscosity.sigma", "0.5"}};
    rc = stf_scene_load_string("m.yaml", MIN_HEAD "effects:\n  springs:\n", create, 2, &s, err,
                               sizeof err);
    CHECK(rc == 0 && s, "--set creating mappings: %s", err);
    if (s) {
        CHECK(s->fluid.effects & STF_EFFECT_HISTORY, "history on");
        CHECK(s->fluid.effects & STF_EFFECT_VISCOSITY, "viscosity on");
        CHECK(s->fluid.q == 0.3 && s->fluid.sigma == 0.5, "created values");
        CHECK(strstr(s->text, "history:") != NULL, "text has the override: %s", s->text);
    }
    stf_scene_free(s);

    stf_override full_ov[] = {{"bodies.0.mass", "5"},
                              {"effects.viscosity", NULL},
                              {"container.vibration.axis", "[1, 0, 0]"}};
    rc = stf_scene_load_string("full.yaml", full_scene, full_ov, 3, &s, err, sizeof err);
    CHECK(rc == 0 && s, "full with overrides: %s", err);
    if (s) {
        CHECK(s->bodies[0].mass == 5, "bodies.0.mass %g", s->bodies[0].mass);
        CHECK(!(s->fluid.effects & STF_EFFECT_VISCOSITY), "viscosity off");
        CHECK(s->container.vibration.axis[0] == 1, "list value");
        stf_scene *again = NULL;
        rc = stf_scene_load_string("again.yaml", s->text, NULL, 0, &again, err, sizeof err);
        CHECK(rc == 0 && again, "override text round trip: %s", err);
        if (again) {
            CHECK(again->bodies[0].mass == 5 && !(again->fluid.effects & STF_EFFECT_VISCOSITY) &&
                      again->container.vibration.axis[0] == 1 && again->fluid.q == 0.6,
                  "round trip values");
        }
        stf_scene_free(again);
    }
    stf_scene_free(s);

    /* an expect key holds dots itself (fluid.escaped, BODY.sink_time): everything after
     * "expect." is the one key, so a prefixed expectation can be set and unset */
    stf_override set_expect[] = {{"expect.fluid.escaped", "0"}, {"expect.time_end", "\"> 0\""}};
    rc = stf_scene_load_string("m.yaml", min_scene, set_expect, 2, &s, err, sizeof err);
    CHECK(rc == 0 && s && s->nexpect == 2 && !strcmp(s->expect[0].key, "fluid.escaped"),
          "--set expect.fluid.escaped: %s", err);
    stf_scene_free(s);
    s = NULL;
    stf_override unset_expect[] = {{"expect.fluid.escaped", NULL}};
    rc = stf_scene_load_string("m.yaml", MIN_HEAD MIN_EFFECTS "expect:\n  fluid.escaped: 0\n  time_end: 1\n",
                               unset_expect, 1, &s, err, sizeof err);
    CHECK(rc == 0 && s && s->nexpect == 1 && !strcmp(s->expect[0].key, "time_end"),
          "--unset expect.fluid.escaped: %s", err);
    stf_scene_free(s);
    s = NULL;
    stf_override bad_spacing[] = {{"fluid.spacing", "-1"}};
    rc = stf_scene_load_string("m.yaml", min_scene, bad_spacing, 1, &s, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "--set fluid.spacing=-1: fluid.spacing: must be > 0") == err,
          "bad --set: %s", err);
    stf_override bad_list[] = {{"fluid.blocks.0.max", "[1, 1]"}};
    rc = stf_scene_load_string("m.yaml", min_scene, bad_list, 1, &s, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "--set fluid.blocks.0.max=[1, 1]: fluid.blocks.0.max:") == err,
          "bad --set list: %s", err);
    stf_override unset_missing[] = {{"effects.nothing", NULL}};
    rc = stf_scene_load_string("m.yaml", min_scene, unset_missing, 1, &s, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "--unset effects.nothing: effects.nothing:") == err,
          "unset missing: %s", err);
    stf_override unset_deep[] = {{"bodies.3.mass", NULL}};
    rc = stf_scene_load_string("m.yaml", min_scene, unset_deep, 1, &s, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "--unset bodies.3.mass:") == err, "unset missing deep: %s", err);
    stf_override unset_required[] = {{"duration", NULL}};
    rc = stf_scene_load_string("m.yaml", min_scene, unset_required, 1, &s, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "--unset duration: duration: required key is missing") == err,
          "unset required: %s", err);
    stf_override bad_yaml[] = {{"fluid.spacing", "[1, 2"}};
    rc = stf_scene_load_string("m.yaml", min_scene, bad_yaml, 1, &s, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "--set fluid.spacing=[1, 2: fluid.spacing:") == err,
          "bad value: %s", err);
    stf_override history_only[] = {{"effects.springs", NULL}};
    rc = stf_scene_load_string("m.yaml", min_scene, history_only, 1, &s, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "m.yaml:9:3: effects.history: needs"),
          "history without springs after unset: %s", err);
}

static void test_files(void)
{
    char path[] = "/tmp/stf_test_sceneXXXXXX", err[512] = "";
    int fd = mkstemp(path);
    CHECK(fd >= 0, "mkstemp");
    if (fd < 0) return;
    FILE *fp = fdopen(fd, "w");
    fputs(min_scene, fp);
    fclose(fp);
    stf_scene *s = NULL;
    int rc = stf_scene_load(path, NULL, 0, &s, err, sizeof err);
    CHECK(rc == 0 && s, "file: %s", err);
    if (s) {
        CHECK(!strcmp(s->path, path), "path %s", s->path);
        CHECK(!strcmp(s->name, strrchr(path, '/') + 1), "name from stem: %s", s->name);
    }
    stf_scene_free(s);
    unlink(path);
    rc = stf_scene_load(path, NULL, 0, &s, err, sizeof err);
    CHECK(rc == 2 && strstr(err, ": cannot read: ") && strstr(err, path) == err, "unreadable: %s",
          err);

    /* Every shipped scene loads (none yet is fine). */
    const char *dir = getenv("STF_SCENES");
    DIR *d = dir ? opendir(dir) : NULL;
    struct dirent *e;
    while (d && (e = readdir(d))) {
        size_t n = strlen(e->d_name);
        if (n < 6 || strcmp(e->d_name + n - 5, ".yaml")) continue;
        char file[1024];
        snprintf(file, sizeof file, "%s/%s", dir, e->d_name);
        rc = stf_scene_load(file, NULL, 0, &s, err, sizeof err);
        CHECK(rc == 0, "%s", err);
        stf_scene_free(s);
    }
    if (d) closedir(d);
}

/* A ball block: centre and radius land in the block with its bounding box; the fluid gets
 * the lattice sites inside the ball (about its volume / spacing^3); a ball with a box corner,
 * or a centre without a radius, is an error naming the key. */
static void test_ball_block(void)
{
    const char *text = "duration: 1\nfluid:\n  spacing: 0.01\n  blocks:\n"
                       "    - center: [0.1, 0, 0.2]\n      radius: 0.05\n"
                       "      velocity: [0, 0, -1]\neffects: {}\n";
    char err[512] = "";
    stf_scene *s = NULL;
    int rc = stf_scene_load_string("t.yaml", text, NULL, 0, &s, err, sizeof err);
    CHECK(rc == 0 && s, "ball scene: %s", err);
    if (s) {
        const stf_block *b = &s->blocks[0];
        CHECK_NEAR(b->radius, 0.05, 0, "radius");
        CHECK_NEAR(b->center[0], 0.1, 0, "center");
        CHECK_NEAR(b->lo[0], 0.05, 1e-15, "bounding box lo");
        CHECK_NEAR(b->hi[2], 0.25, 1e-15, "bounding box hi");
        stf_fluid *f = NULL;
        if (stf_fluid_create(&s->fluid, &f, err, sizeof err) == 0) {
            int n = stf_fluid_add_ball(f, b->center, b->radius, b->velocity);
            double want = 4.0 / 3.0 * 3.14159265358979 * 125.0; /* (r / spacing)^3 = 125 */
            CHECK(n > 0 && fabs(n - want) < 0.05 * want, "ball of %d particles, volume says %.0f", n, want);
            double *x = malloc((size_t)n * 3 * sizeof *x);
            stf_fluid_get_positions(f, x);
            double c[3] = {0, 0, 0}, rmax = 0;
            for (int i = 0; i < n; i++)
                for (int a = 0; a < 3; a++) c[a] += x[3 * i + a] / n;
            for (int i = 0; i < n; i++) {
                double d2 = 0;
                for (int a = 0; a < 3; a++) d2 += (x[3 * i + a] - b->center[a]) * (x[3 * i + a] - b->center[a]);
                rmax = fmax(rmax, sqrt(d2));
            }
            /* symmetric about the centre (jitter averages out); no site beyond the radius + jitter */
            CHECK_NEAR(c[0], 0.1, 2e-4, "ball centre x");
            CHECK_NEAR(c[2], 0.2, 2e-4, "ball centre z");
            CHECK(rmax < 0.05 + 0.2 * 0.01 * sqrt(3.0), "site at %g from the centre", rmax);
            free(x);
            stf_fluid_destroy(f);
        }
    }
    stf_scene_free(s);
    EXPECT_ERROR("duration: 1\nfluid:\n  spacing: 0.01\n  blocks:\n"
                 "    - center: [0, 0, 0]\n      radius: 0.05\n      min: [0, 0, 0]\neffects: {}\n",
                 "t.yaml:7:7: fluid.blocks.0.min: not allowed with radius", NULL);
    EXPECT_ERROR("duration: 1\nfluid:\n  spacing: 0.01\n  blocks:\n"
                 "    - center: [0, 0, 0]\n      min: [0, 0, 0]\n      max: [1, 1, 1]\neffects: {}\n",
                 "t.yaml:5:7: fluid.blocks.0.center: only allowed with radius", NULL);
    EXPECT_ERROR("duration: 1\nfluid:\n  spacing: 0.01\n  blocks:\n"
                 "    - radius: 0.05\neffects: {}\n",
                 "fluid.blocks.0.center: required key is missing", NULL);
    EXPECT_ERROR("duration: 1\nfluid:\n  spacing: 0.01\n  blocks:\n"
                 "    - center: [0, 0, 0]\n      radius: -1\neffects: {}\n",
                 "fluid.blocks.0.radius: must be > 0", NULL);
}

/* container.periodic: the container's inner box along each listed axis is the period. */
static void test_periodic(void)
{
    const char *text = "duration: 1\nfluid:\n  model: carreau_yasuda\n  spacing: 0.01\n  blocks:\n"
                       "    - min: [0.96, 1.97, 0]\n      max: [1.04, 2.03, 0.1]\neffects: {}\n"
                       "container:\n  size: [0.08, 0.06, 0.2]\n  position: [1, 2, 0]\n"
                       "  periodic: [y]\n";
    char err[512] = "";
    stf_scene *s = NULL;
    int rc = stf_scene_load_string("t.yaml", text, NULL, 0, &s, err, sizeof err);
    CHECK(rc == 0 && s, "periodic scene: %s", err);
    if (s) {
        CHECK(s->fluid.periodic[0] == 0 && s->fluid.periodic[2] == 0, "only y is periodic");
        CHECK_NEAR(s->fluid.periodic[1], 0.06, 0, "period along y = container size.y");
        CHECK_NEAR(s->fluid.periodic_origin[1], 1.97, 1e-15, "origin = position.y - size.y / 2");
    }
    stf_scene_free(s);
}

/* effects.carreau_yasuda: cfl is 0 (off) or in (0,1) as documented; dt_max only with cfl,
 * refused at its value in the file (the fluid's check refuses it; the loader names the place). */
static void test_cy_ranges(void)
{
#define CY_HEAD "duration: 1\nfluid:\n  model: carreau_yasuda\n  spacing: 0.01\n  blocks:\n" \
                "    - {min: [0, 0, 0], max: [0.1, 0.1, 0.1]}\neffects:\n  carreau_yasuda:\n"
    char err[512] = "";
    stf_scene *s = NULL;
    int rc = stf_scene_load_string("t.yaml", CY_HEAD "    cfl: 0\n", NULL, 0, &s, err, sizeof err);
    CHECK(rc == 0 && s && s->fluid.cy.cfl == 0, "cfl: 0 (off): %s", err);
    stf_scene_free(s);
    EXPECT_ERROR(CY_HEAD "    dt_max: 0.001\n",
                 "t.yaml:9:13: effects.carreau_yasuda.dt_max: only with cfl", NULL);
#undef CY_HEAD
}

/* The fluid def's ranges are stf_fluid_check_def's: the loader reports the field it refuses
 * at the place it came from (FILE:LINE:COL of its value, or the --set), with its scene key.
 * One key per line; a case replaces lines of def_scene (gravity has no range but
 * finiteness, which the loader's number check holds). */
static const char *const def_scene[] = {
    "duration: 1",                                        /* 1 */
    "fluid:",                                             /* 2 */
    "  spacing: 0.01",                                    /* 3 */
    "  jitter: 0.2",                                      /* 4 */
    "  blocks: [{min: [0, 0, 0], max: [0.1, 0.1, 0.1]}]", /* 5 */
    "effects:",                                           /* 6 */
    "  gravity: {}",                                      /* 7 */
    "  viscosity:",                                       /* 8 */
    "    sigma: 2",                                       /* 9 */
    "  pressure:",                                        /* 10 */
    "    k: 1000",                                        /* 11 */
    "  springs:",                                         /* 12 */
    "    k_min: 100",                                     /* 13 */
    "  history:",                                         /* 14 */
    "    k_onset: 0",                                     /* 15 */
    "  boundary_stick:",                                  /* 16 */
    "    stick: 200",                                     /* 17 */
    NULL};

/* def_scene with line l1 (and l2, if > 0) replaced by t1 (t2). */
static const char *def_text(int l1, const char *t1, int l2, const char *t2)
{
    static char text[2048];
    size_t n = 0;
    for (int i = 0; def_scene[i]; i++) {
        const char *line = i + 1 == l1 ? t1 : i + 1 == l2 ? t2 : def_scene[i];
        n += (size_t)snprintf(text + n, sizeof text - n, "%s\n", line);
    }
    return text;
}

static void test_def_check_places(void)
{
    char err[512] = "";
    stf_scene *s = NULL;
    int rc =
        stf_scene_load_string("t.yaml", def_text(0, NULL, 0, NULL), NULL, 0, &s, err, sizeof err);
    CHECK(rc == 0 && s, "the def scene: %s", err);
    stf_scene_free(s);
    /* the fluid section, each effect, and fields refused together with another */
    EXPECT_ERROR(def_text(3, "  spacing: 2", 0, NULL),
                 "t.yaml:3:12: fluid.spacing: must be > 0 and <= 1 m (got 2)", NULL);
    EXPECT_ERROR(def_text(4, "  jitter: 0.5", 0, NULL),
                 "t.yaml:4:11: fluid.jitter: must be in [0, 0.45] (got 0.5)", NULL);
    EXPECT_ERROR(def_text(4, "  h: 0.06", 0, NULL),
                 "t.yaml:4:6: fluid.h: must be 0 or in [spacing, 5*spacing] (got 0.06)", NULL);
    EXPECT_ERROR(def_text(4, "  iterations: 65", 0, NULL),
                 "t.yaml:4:15: fluid.iterations: must be in [1, 64] (got 65)", NULL);
    EXPECT_ERROR(def_text(9, "    sigma: -1", 0, NULL),
                 "t.yaml:9:12: effects.viscosity.sigma: must be >= 0 (got -1)", NULL);
    EXPECT_ERROR(def_text(11, "    k: 0", 0, NULL),
                 "t.yaml:11:8: effects.pressure.k: must be > 0 (got 0)", NULL);
    EXPECT_ERROR(def_text(13, "    yield_ratio: 2", 0, NULL),
                 "t.yaml:13:18: effects.springs.yield_ratio: must be in [0,1] (got 2)", NULL);
    EXPECT_ERROR(def_text(13, "    damping: 0.1", 0, NULL), /* stf_fluid_create refused it */
                 "t.yaml:13:14: effects.springs.damping: needs relaxation gauss_seidel", NULL);
    EXPECT_ERROR(def_text(15, "    k_onset: -1", 0, NULL),
                 "t.yaml:15:14: effects.history.k_onset: must be >= 0 (got -1)", NULL);
    EXPECT_ERROR(def_text(15, "    d: 100001", 0, NULL),
                 "t.yaml:15:8: effects.history.d: must be >= 1 and <= 100000 (got 100001)", NULL);
    EXPECT_ERROR(def_text(4, "  reference_spacing: 0.02", 15, "    reference_spacing: 0.01"),
                 "t.yaml:15:24: effects.history.reference_spacing: give the material's (fluid) "
                 "or the history's, not both",
                 NULL);
    EXPECT_ERROR(def_text(4, "  reference_spacing: 0.02", 3, "  spacing: 0.01\n  h: 0.03"),
                 "t.yaml:4:6: fluid.h: must be 0 (2 spacings) with a reference_spacing", NULL);
    EXPECT_ERROR(def_text(17, "    stick: -1", 0, NULL),
                 "t.yaml:17:12: effects.boundary_stick.stick: must be >= 0 (got -1)", NULL);
    /* type errors stay the loader's */
    EXPECT_ERROR(def_text(15, "    k_onset: lots", 0, NULL),
                 "t.yaml:15:14: effects.history.k_onset: expected a number", NULL);
    EXPECT_ERROR(def_text(15, "    k_onset: .inf", 0, NULL),
                 "t.yaml:15:14: effects.history.k_onset: must be a finite number", NULL);
    /* the Carreau-Yasuda parameters (cy_check_def) */
#define CY_DEF                                                                                     \
    "duration: 1\nfluid:\n  model: carreau_yasuda\n  spacing: 0.01\n  blocks:\n"                   \
    "    - {min: [0, 0, 0], max: [0.1, 0.1, 0.1]}\neffects:\n  carreau_yasuda:\n"
    EXPECT_ERROR(CY_DEF "    mu0: -1\n",
                 "t.yaml:9:10: effects.carreau_yasuda.mu0: must be >= 0 (got -1)", NULL);
    EXPECT_ERROR(CY_DEF "    relaxation: 2\n",
                 "t.yaml:9:17: effects.carreau_yasuda.relaxation: must be in (0,1]", NULL);
    /* max_pressure_iterations (its default, 100) is refused where min was given */
    EXPECT_ERROR(CY_DEF "    min_pressure_iterations: 500\n",
                 "t.yaml:9:30: effects.carreau_yasuda.max_pressure_iterations: must be >= "
                 "min_pressure_iterations (got 100)",
                 NULL);
#undef CY_DEF
    /* --set: the override is named, as for every value it gives */
    stf_override set_onset[] = {{"effects.history.k_onset", "-5"}};
    rc = stf_scene_load_string("t.yaml", def_text(0, NULL, 0, NULL), set_onset, 1, &s, err,
                               sizeof err);
    CHECK(rc == 2 && strstr(err, "--set effects.history.k_onset=-5: effects.history.k_onset: "
                                 "must be >= 0 (got -5)") == err,
          "--set k_onset: %s", err);
    stf_override set_near[] = {{"effects.pressure.k_near", "-1"}}; /* a key the file lacks */
    rc = stf_scene_load_string("t.yaml", def_text(0, NULL, 0, NULL), set_near, 1, &s, err,
                               sizeof err);
    CHECK(rc == 2 && strstr(err, "--set effects.pressure.k_near=-1: effects.pressure.k_near: "
                                 "must be >= 0 (got -1)") == err,
          "--set k_near: %s", err);
    stf_override set_jitter[] = {{"fluid.jitter", "1"}};
    rc = stf_scene_load_string("t.yaml", def_text(0, NULL, 0, NULL), set_jitter, 1, &s, err,
                               sizeof err);
    CHECK(rc == 2 && strstr(err, "--set fluid.jitter=1: fluid.jitter: must be in [0, 0.45]") == err,
          "--set jitter: %s", err);
    /* the fluid section is checked before its blocks: a bad spacing comes first */
    EXPECT_ERROR("duration: 1\nfluid:\n  spacing: 5\n  blocks: 3\n",
                 "t.yaml:3:12: fluid.spacing: must be > 0 and <= 1 m", NULL);
}

int main(void)
{
    test_periodic();
    test_cy_ranges();
    test_def_check_places();
    test_ball_block();
    test_full();
    test_defaults();
    test_errors();
    test_overrides();
    test_files();
    return test_result("test_scene");
}
