/* test_checkpoint.c - a simulation saved after K steps (through an HDF5 checkpoint read
 * back), loaded into a fresh simulation of the same scene and stepped to N, is bit-identical
 * to one stepped to N without stopping: particles in memory order, bodies, counters. For the
 * window, full and sum-of-exponentials histories with springs, a ball, a box and a vibrating
 * container (random frequency jumps), adaptive substeps, and the Carreau-Yasuda model with
 * its warm start. A checkpoint does not load into another scene. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "h5io.h"
#include "state.h"
#include "stf_sim.h"
#include "test_util.h"

static const char *const clavet_scene =
    "name: ckpt\n"
    "duration: 1\n"
    "dt: 0.004\n" /* dt^2 k/h = 0.32 > 0.25: the adaptive control splits steps */
    "fluid:\n"
    "  spacing: 0.01\n"
    "  blocks:\n"
    "    - {min: [-0.03, -0.03, 0.0], max: [0.03, 0.03, 0.04]}\n"
    "effects:\n"
    "  gravity: {}\n"
    "  viscosity: {sigma: 2}\n"
    "  pressure: {k: 400, k_near: 1000}\n"
    "  springs: {k_min: 1000, yield_ratio: 0.1, plasticity: 2}\n"
    "  history: {q: 0.5, d: 20, k_hist: 10000}\n"
    "  boundary_stick: {stick: 1}\n"
    "container:\n"
    "  size: [0.08, 0.08, 0.1]\n"
    "  wall: 0.02\n"
    "  motion: kinematic\n"
    "  vibration: {axis: [0, 0, 1], amplitude: 0.003, frequency: 20, jitter: 0.3, "
    "jitter_period: 0.05, seed: 3}\n"
    "bodies:\n"
    "  - {name: ball, shape: sphere, radius: 0.012, mass: 0.02, position: [0.005, 0, 0.07], "
    "velocity: [0, 0, -1]}\n"
    "  - {name: box, shape: box, size: [0.02, 0.02, 0.01], mass: 0.02, position: [0, 0, 0.1], "
    "angular_velocity: [3, 1, 0]}\n";

static const char *const cy_scene =
    "name: ckpt_cy\n"
    "duration: 1\n"
    "dt: 0.002\n"
    "fluid:\n"
    "  model: carreau_yasuda\n"
    "  spacing: 0.02\n"
    "  density: 1000\n"
    "  blocks:\n"
    "    - {min: [-0.1, -0.06, 0.0], max: [0.1, 0.06, 0.06]}\n"
    "    - {min: [-0.04, -0.04, 0.12], max: [0.04, 0.04, 0.2]}\n"
    "effects:\n"
    "  gravity: {}\n"
    "  carreau_yasuda: {mu0: 0.01, mu_inf: 0.001, K: 1.0, alpha: 2, n: 1.5, eta: 0.01, "
    "warm_start: 0.5}\n"
    "container:\n"
    "  size: [0.2, 0.12, 0.3]\n"
    "  wall: 0.04\n"
    "  friction: 0.0\n"
    "  stick: false\n";

/* periodic in x and y (a film down an incline), with the warm start and relaxation */
static const char *const cy_periodic_scene =
    "name: ckpt_cy_periodic\n"
    "duration: 1\n"
    "dt: 0.002\n"
    "fluid:\n"
    "  model: carreau_yasuda\n"
    "  spacing: 0.01\n"
    "  density: 1000\n"
    "  blocks:\n"
    "    - {min: [-0.04, -0.03, 0.0], max: [0.04, 0.03, 0.06]}\n"
    "effects:\n"
    "  gravity: {g: [3, 0.5, -9.3]}\n"
    "  carreau_yasuda: {mu0: 0.01, mu_inf: 0.001, K: 1.0, alpha: 2, n: 1.5, eta: 0.01, "
    "warm_start: 0.5, relaxation: 0.7}\n"
    "container:\n"
    "  size: [0.08, 0.06, 0.2]\n"
    "  periodic: [x, y]\n"
    "  wall: 0.02\n"
    "  friction: 0.0\n"
    "  stick: false\n";

typedef struct snapshot {
    int n;
    double *x, *v;
    double body[4][16];
    long steps, substeps;
    double time, dt_min, dt_max;
} snapshot;

static void take(const stf_sim *s, snapshot *o)
{
    o->n = stf_fluid_count(s->fluid);
    o->x = malloc((size_t)o->n * 3 * sizeof *o->x);
    o->v = malloc((size_t)o->n * 3 * sizeof *o->v);
    stf_fluid_get_positions(s->fluid, o->x);
    stf_fluid_get_velocities(s->fluid, o->v);
    memset(o->body, 0, sizeof o->body);
    for (int k = 0; k < s->scene->nbodies && k < 4; k++) {
        double *b = o->body[k];
        stf_sim_body_state(s, k, b, b + 3, b + 7, b + 10, b + 13);
    }
    o->steps = s->steps, o->substeps = s->substeps;
    o->time = s->time, o->dt_min = s->dt_min, o->dt_max = s->dt_max;
}

static int same(const snapshot *a, const snapshot *b)
{
    return a->n == b->n && !memcmp(a->x, b->x, (size_t)a->n * 3 * sizeof *a->x) &&
           !memcmp(a->v, b->v, (size_t)a->n * 3 * sizeof *a->v) &&
           !memcmp(a->body, b->body, sizeof a->body) && a->steps == b->steps &&
           a->substeps == b->substeps && !memcmp(&a->time, &b->time, sizeof a->time) &&
           a->dt_min == b->dt_min && a->dt_max == b->dt_max;
}

static void drop(snapshot *s)
{
    free(s->x);
    free(s->v);
}

static stf_sim *build(const char *text, const stf_override *ov, int nov, stf_scene **sc)
{
    char err[1024];
    stf_sim *s = NULL;
    CHECK(stf_scene_load_string("ckpt.yaml", text, ov, nov, sc, err, sizeof err) == 0, "%s", err);
    if (*sc) CHECK(stf_sim_create(*sc, &s, err, sizeof err) == 0, "%s", err);
    return s;
}

static int run(stf_sim *s, long steps)
{
    for (long k = 0; k < steps; k++)
        if (stf_sim_step(s) != 0) return -1;
    return 0;
}

/* Saves s into path's /checkpoint and reads it back into st. */
static void through_file(const stf_sim *s, const char *path, stf_state *st)
{
    char err[512];
    stf_state out = {0};
    stf_h5 *h;
    CHECK(stf_sim_save_state(s, &out) == 0, "save failed");
    CHECK(stf_h5_create(path, &h, err, sizeof err) == 0, "%s", err);
    CHECK(stf_h5_write_checkpoint(h, &out) == 0, "%s", stf_h5_last_error(h));
    stf_h5_abort(h);
    stf_state_free(&out);
    CHECK(stf_h5_read_checkpoint(path, st, err, sizeof err) == 0, "%s", err);
}

/* Steps N straight, and K + load + (N - K); the two must agree bit for bit. */
static const char *only; /* argv[1]: run only this case */
static void resume_case(const char *name, const char *text, const stf_override *ov, int nov,
                        long K, long N)
{
    if (only && strcmp(only, name) != 0) return;
    stf_scene *sa = NULL, *sb = NULL, *sc = NULL;
    stf_set_threads(2); /* saved with 2 threads, resumed with 1: results must not care */
    stf_sim *a = build(text, ov, nov, &sa), *b = build(text, ov, nov, &sb);
    if (!a || !b) goto done;
    CHECK(run(a, N) == 0, "%s: straight run failed: %s", name, stf_fluid_failure(a->fluid));
    CHECK(run(b, K) == 0, "%s: first part failed: %s", name, stf_fluid_failure(b->fluid));
    char path[64];
    snprintf(path, sizeof path, "ckpt_%s.h5", name);
    stf_state st = {0};
    through_file(b, path, &st);
    stf_set_threads(1);
    stf_sim *c = build(text, ov, nov, &sc);
    char err[512] = "";
    if (c) {
        CHECK(stf_sim_load_state(c, &st, err, sizeof err) == 0, "%s: load: %s", name, err);
        CHECK(c->steps == K, "%s: loaded at step %ld, want %ld", name, c->steps, K);
        CHECK(run(c, N - K) == 0, "%s: resumed part failed: %s", name, stf_fluid_failure(c->fluid));
        snapshot sa_, sc_;
        take(a, &sa_);
        take(c, &sc_);
        CHECK(same(&sa_, &sc_), "%s: resumed run differs from the straight one", name);
        if (getenv("VERBOSE")) printf("%s: %ld substeps\n", name, sa_.substeps);
        CHECK(sa_.substeps > N || strcmp(name, "window") != 0,
              "%s: the adaptive control never split a step (%ld substeps)", name, sa_.substeps);
        /* and the test can tell: the simulation saved at K is not at N */
        snapshot sb_;
        take(b, &sb_);
        CHECK(!same(&sa_, &sb_), "%s: the state did not change from step %ld to %ld", name, K, N);
        drop(&sa_), drop(&sb_), drop(&sc_);
        stf_sim_destroy(c);
    }
    stf_state_free(&st);
    unlink(path);
done:
    stf_sim_destroy(a), stf_sim_destroy(b);
    stf_scene_free(sa), stf_scene_free(sb), stf_scene_free(sc);
}

/* A checkpoint of one scene does not load into another (other particle count). */
static void refuses_other_scene(void)
{
    stf_scene *sa = NULL, *sb = NULL;
    stf_override ov = {"fluid.spacing", "0.012"};
    stf_sim *a = build(clavet_scene, NULL, 0, &sa), *b = build(clavet_scene, &ov, 1, &sb);
    if (a && b) {
        CHECK(run(a, 10) == 0, "steps failed");
        stf_state st = {0};
        CHECK(stf_sim_save_state(a, &st) == 0, "save failed");
        char err[512] = "";
        CHECK(stf_sim_load_state(b, &st, err, sizeof err) != 0, "loaded into another scene");
        CHECK(strstr(err, "particles") != NULL, "message: %s", err);
        stf_state_free(&st);
    }
    stf_sim_destroy(a), stf_sim_destroy(b);
    stf_scene_free(sa), stf_scene_free(sb);
}

/* A damaged checkpoint (a non-finite position, velocity or warm-start pressure, a warm-start
 * count that is not the particles') is refused by the load, naming the entry: resumed, it
 * would only fail as a numerical failure (exit 3), which ends the run for good. */
static void refuses_damaged(void)
{
    static const struct {
        const char *entry;
        int type; /* 0: poison a double with NaN, 1: set an i64 to 7 */
    } cases[] = {{"fluid.x", 0}, {"fluid.v", 0}, {"fluid.xprev", 0}, {"cy.ktot", 0}, {"cy.rho", 0},
                 {"cy.warm_n", 1}};
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        stf_scene *sa = NULL, *sb = NULL;
        stf_sim *a = build(cy_scene, NULL, 0, &sa), *b = build(cy_scene, NULL, 0, &sb);
        if (a && b) {
            CHECK(run(a, 5) == 0, "steps failed");
            stf_state st = {0};
            through_file(a, "ckpt_damaged.h5", &st);
            unlink("ckpt_damaged.h5");
            const stf_state_entry *e = NULL;
            for (int i = 0; i < st.n; i++)
                if (!strcmp(st.e[i].name, cases[k].entry)) e = &st.e[i];
            CHECK(e && e->owned, "%s: not in the checkpoint", cases[k].entry);
            if (e && e->owned) {
                if (cases[k].type == 0) ((double *)e->owned)[e->count / 2] = NAN;
                else *(int64_t *)e->owned = 7;
                char err[512] = "";
                CHECK(stf_sim_load_state(b, &st, err, sizeof err) != 0, "%s damaged: loaded",
                      cases[k].entry);
                CHECK(strstr(err, cases[k].entry) != NULL, "%s damaged: message '%s'",
                      cases[k].entry, err);
            }
            stf_state_free(&st);
        }
        stf_sim_destroy(a), stf_sim_destroy(b);
        stf_scene_free(sa), stf_scene_free(sb);
    }
}

int main(int argc, char **argv)
{
    only = argc > 1 ? argv[1] : NULL;
    resume_case("window", clavet_scene, NULL, 0, 97, 200);
    stf_override full[] = {{"effects.history.mode", "full"}};
    resume_case("full", clavet_scene, full, 1, 131, 200); /* after the ring grew to 128+ */
    /* a window of d >= 256: the ring's row map (re-sorts rename rows) and blocks of 32,
       saved in the middle of one */
    stf_override longw[] = {{"effects.history.d", "300"}};
    resume_case("window_map", clavet_scene, longw, 1, 113, 200);
    stf_override soe[] = {{"effects.history.mode", "soe"}, {"effects.history.terms", "8"}};
    resume_case("soe", clavet_scene, soe, 2, 97, 200);
    resume_case("cy", cy_scene, NULL, 0, 60, 120);
    /* CFL substeps (with dt_max), the warm start across them, and the explicit viscosity */
    stf_override cfl[] = {{"effects.carreau_yasuda.cfl", "0.3"},
                          {"effects.carreau_yasuda.dt_max", "0.001"},
                          {"effects.carreau_yasuda.relaxation", "0.6"}};
    resume_case("cy_cfl", cy_scene, cfl, 3, 37, 90);
    stf_override expl[] = {{"effects.carreau_yasuda.viscosity_solver", "explicit"}};
    resume_case("cy_explicit", cy_scene, expl, 1, 41, 80);
    resume_case("cy_periodic", cy_periodic_scene, NULL, 0, 53, 120);
    refuses_other_scene();
    if (!only) refuses_damaged();
    return test_result("test_checkpoint");
}
