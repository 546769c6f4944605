/* bench.c - `stf bench`: what accuracy costs in time, and the solvers' speed.
 *
 *   stf bench table1 [BOWLING.yaml]   the paper's Table 1 (time per step without history, time
 *                                      of the history terms, history memory, d = 0/50/150/500)
 *                                      on the bowling ball and a vibrated layer, ~20K particles
 *   stf bench effects SCENE           cost of each effect, turning them off one at a time
 *   stf bench accuracy SCENE          error vs wall time for dt, spacing, the history mode and
 *                                      (Carreau-Yasuda scenes) the solvers' tolerances
 *   stf bench scaling SCENE           the step at the scene's particles and at 10x as many:
 *                                      a finer spacing (--grow spacing, the default) or a
 *                                      wider pool at the same spacing (--grow domain)
 *   stf bench grid SCENE              the neighbour search alone: a candidate rebuild and a
 *                                      filter, at the scene's particles and at 10x as many
 *   stf bench dam SCENE               Carreau-Yasuda solver speed (against SPlisHSPlasH):
 *                                      wall and steps per simulated second, pressure
 *                                      iterations, density error, peak memory, for 1 and 2
 *                                      threads (--duration, 0.2 s)
 *   stf bench convergence SCENE       every metric at the scene's dt, dt/2, dt/4 and at 1.5x its
 *                                      spacing, side by side, each within --tolerance of the
 *                                      finest (dt/4) run or not (exit 1, as `stf check`)
 *
 * Timings run the simulation in this process (no output file); the accuracy and convergence
 * runs are ordinary `stf run` child processes of this executable, whose output files are read
 * back for the metrics and the body / fluid centre-of-mass paths. Short by default: --full
 * runs the long versions. */
#define _DEFAULT_SOURCE /* getloadavg, readlink */
#include <errno.h>
#include <math.h>
#include <omp.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "canvas.h"
#include "cli.h"
#include "fluid.h" /* the per-stage timers (internal; the tool is part of the project) */
#include "h5io.h"
#include "metrics.h"
#include "stf_sim.h"

extern char **environ;

#define MAX_OV 64

typedef struct bench_args {
    const char *what;  /* table1, effects, accuracy */
    const char *scene; /* scene file (table1: the bowling scene) */
    const char *out;   /* accuracy: output directory */
    stf_override ov[MAX_OV];
    int nov;
    int threads;       /* 0: OpenMP default */
    int steps;         /* timed steps (table1, effects) */
    int warmup;        /* steps run before timing (table1, effects) */
    int full, warmup_set;
    int repeat;        /* table1, effects, scaling: rounds over the rows (interleaved); each
                          row's fastest run counts */
    double duration;   /* accuracy: simulated seconds, 0 = default */
    const char *duration_arg; /* its text */
    double error;      /* accuracy: error budget, m */
    const char *knobs; /* accuracy: comma list of dt, spacing, history, solver */
    int grow_domain;   /* scaling: 10x the particles by a wider pool (1) or a finer spacing */
    double tolerance;  /* convergence: relative difference from the finest run allowed */
    int jobs;          /* convergence: child runs at a time (1: one after the other) */
} bench_args;

/* ------------------------------------------------------------------------- usage */

#define BENCH_OV                                                                              \
    "  --set KEY=VALUE, --unset KEY   scene overrides, as for stf run (at most 64 in all)\n"
#define BENCH_THREADS "  --threads N    OpenMP threads, 1 to 1024 (default: OpenMP's, OMP_NUM_THREADS)\n"
#define BENCH_TIMING                                                                          \
    "  --steps N      timed steps, 1 to 1000000 (default 32, --full 224); with a history\n"      \
    "                 window, up to whole history time blocks (the count is printed)\n"         \
    "  --warmup N     steps run before the timing, 0 to 1000000 (default 50: the bowling ball\n"\
    "                 reaches the pool, so that the impact is timed)\n"                          \
    "  --repeat R     rounds over all the rows, 1 to 100 (default 1), interleaved; each row\n"  \
    "                 shows its fastest run\n"                                                   \
    "  --full         the long version: 224 timed steps\n"
#define BENCH_EXIT(one)                                                                       \
    "exit codes: 0 done" one ", 2 bad input, 3 numerical failure\n"

static const cli_usage bench_usage = {
    "bench",
    "usage: stf bench table1 [BOWLING.yaml] [OPTIONS]\n"
    "       stf bench effects|accuracy|scaling|grid|dam|convergence SCENE [OPTIONS]\n",
    "What accuracy costs in time. Timings run in this process (no output file); accuracy and\n"
    "convergence run stf run child processes and read their files back.\n"
    "  table1 [BOWLING.yaml]  the paper's Table 1: time per step, time and memory of the history\n"
    "                         terms at d = 0, 50, 150, 500 (and soe), bowling ball and a layer\n"
    "  effects SCENE          the cost of each effect, turning them off one at a time\n"
    "  accuracy SCENE         error against wall time for dt, spacing, history mode, solvers\n"
    "  scaling SCENE          the step at the scene's particles and at 10x as many\n"
    "  grid SCENE             the neighbour search alone, at the scene's particles and 10x\n"
    "  dam SCENE              Carreau-Yasuda solver speed at 1 and 2 threads\n"
    "  convergence SCENE      every metric at dt, dt/2, dt/4 and 1.5x the spacing, each within\n"
    "                         --tolerance of dt/4's or not\n"
    "stf bench NAME --help: NAME's options, their units and defaults.\n"
    "exit codes: 0 done, 1 effects: an effect that is off costs time or memory; convergence: a\n"
    "metric not within the tolerance, 2 bad input, 3 numerical failure\n"};

static const cli_usage bench_usages[] = {
    {"bench table1", "usage: stf bench table1 [BOWLING.yaml] [--steps N] [--warmup N] [--repeat R] [--full]\n"
                     "                        [--threads N] [--set KEY=VALUE]... [--unset KEY]...\n",
     "The paper's Table 1 on the bowling ball (BOWLING.yaml, default scenes/bowling_ball.yaml\n"
     "from the current directory) and a built-in vibrated layer of about 20K particles: the\n"
     "time per step without the history terms (ms), the time of the history terms (ms) and\n"
     "the history memory (MB, 12 n d) at d = 0, 50, 150, 500 and in soe mode (16 terms), next\n"
     "to the paper's figures. The overrides apply to both scenes.\n"
     "options:\n" BENCH_TIMING BENCH_THREADS BENCH_OV BENCH_EXIT("")},
    {"bench effects", "usage: stf bench effects SCENE [--steps N] [--warmup N] [--repeat R] [--full]\n"
                      "                         [--threads N] [--set KEY=VALUE]... [--unset KEY]...\n",
     "The cost of each effect of SCENE: the scene as it is, then without each of its effects in\n"
     "turn (without springs also without history): wall and cpu ms per step, ms per stage and\n"
     "each effect's storage (bytes). An effect that is off must cost nothing: checked.\n"
     "options:\n" BENCH_TIMING BENCH_THREADS BENCH_OV
     BENCH_EXIT(", 1 an effect that is off cost time or memory")},
    {"bench accuracy",
     "usage: stf bench accuracy SCENE [-o DIR] [--duration S] [--error M] [--knobs LIST] [--full]\n"
     "                          [--threads N] [--set KEY=VALUE]... [--unset KEY]...\n",
     "Error against cost: SCENE run (stf run child processes) at dt x 0.25, 0.5, 1, 2; at\n"
     "spacing x 0.6, 0.8, 1, 1.4; with the history full, in windows of d = 500, 150, 50, 10 and\n"
     "soe of 16, 8, 4 terms (scenes with effects.history); with the Carreau-Yasuda solvers'\n"
     "tolerances x 0.1, 0.3, 1, 3 (carreau_yasuda scenes). A run's error is the RMS distance\n"
     "(m) of the first body's path (the fluid's centre of mass without bodies) from the\n"
     "knob's finest run. Writes DIR/runNN.h5, DIR/accuracy.csv and DIR/accuracy.png and names\n"
     "each knob's cheapest setting within --error.\n"
     "options:\n"
     "  -o DIR         the runs, the table and the plot (default bench_accuracy)\n"
     "  --duration S   simulated seconds of each run (default: the scene's, at most 0.6 s;\n"
     "                 --full: the scene's); at most 1e9 steps of the finest dt\n"
     "  --error M      the error budget, m, > 0 (default 0.01)\n"
     "  --knobs LIST   a comma list of dt, spacing, history, solver (default: all four)\n"
     "  --full         the scene's spacing and duration (default: a spacing of at least\n"
     "                 0.025 m and at most 0.6 s)\n"
     BENCH_THREADS BENCH_OV "exit codes: 0 done (a failed run is shown as failed), 2 bad input\n"},
    {"bench scaling",
     "usage: stf bench scaling SCENE [--grow spacing|domain] [--steps N] [--warmup N] [--repeat R]\n"
     "                         [--full] [--threads N] [--set KEY=VALUE]... [--unset KEY]...\n",
     "The step at SCENE's particles and at about 10x as many: wall and cpu ms per step,\n"
     "particles per second, substeps, neighbour rebuilds, neighbours and springs per particle,\n"
     "ms per stage.\n"
     "options:\n"
     "  --grow spacing|domain   10x the particles by spacing / 10^(1/3) (spacing, the default)\n"
     "                 or by a pool sqrt(10) times wider in x and y at the same spacing (domain:\n"
     "                 needs a container and box blocks)\n"
     BENCH_TIMING BENCH_THREADS BENCH_OV BENCH_EXIT("")},
    {"bench grid", "usage: stf bench grid SCENE [--steps N] [--full] [--threads N] [--set KEY=VALUE]...\n"
                   "                      [--unset KEY]...\n",
     "The neighbour search alone on SCENE's initial particles: N candidate rebuilds (each with\n"
     "its filter) and N filters, at the scene's spacing and at spacing / 10^(1/3) (10x the\n"
     "particles); cpu ms per call, candidates and neighbours per particle.\n"
     "options:\n"
     "  --steps N      N, 1 to 1000000 (default 32, --full 224)\n"
     "  --full         N = 224\n" BENCH_THREADS BENCH_OV BENCH_EXIT("")},
    {"bench dam", "usage: stf bench dam SCENE [--duration S] [--threads N] [--set KEY=VALUE]... [--unset KEY]...\n",
     "Carreau-Yasuda solver speed on SCENE (fluid.model: carreau_yasuda) from rest,\n"
     "in this process: wall and cpu seconds per simulated second, substeps per simulated\n"
     "second, ms per substep, pressure iterations, density error, dt range, CFL number, peak\n"
     "memory and neighbour rebuilds; one row at 1 thread and one at 2.\n"
     "options:\n"
     "  --duration S   simulated seconds, round(S / dt) steps, 1 to 1e9 (default 0.2)\n"
     "  --threads N    one row at N threads, 1 to 1024, instead of the two\n" BENCH_OV
     BENCH_EXIT("")},
    {"bench convergence",
    "usage: stf bench convergence SCENE [--set KEY=VALUE]... [--unset KEY]... [--duration S]\n"
    "                             [--threads N] [--jobs N] [-o DIR] [--tolerance FRAC]\n",
    "Runs SCENE four times, as `stf run` child processes: at its dt and spacing (column \"dt\"),\n"
    "at dt/2, at dt/4 (the finest run) and at its dt with 1.5x its spacing (\"1.5x_spacing\"),\n"
    "by --set dt=... and --set fluid.spacing=... after your own --set's. It prints every metric\n"
    "of the runs (those of `stf report`: each body's, then the fluid's) side by side, one row a\n"
    "metric and one column a run, then:\n"
    "  range   max - min over the runs, in the metric's unit\n"
    "  spread  range / |the dt/4 run's value|, in %; \"n/a\" when the metric is null in every\n"
    "          run, \"DIFFERS\" when it is null in some runs only (a ball that sinks at one\n"
    "          resolution and not at another); \"-\" when the dt/4 value is 0\n"
    "  ok      \"yes\" when every run is within the tolerance of the dt/4 run:\n"
    "            |v - v_dt/4| <= FRAC |v_dt/4|; when v_dt/4 is 0: |v| <= FRAC S, S a scale of\n"
    "            the unit: the body's radius (a body's lengths), the scene's spacing (the\n"
    "            fluid's lengths), the simulated duration (times), 1 m/s, 1 (rolling_ratio);\n"
    "            counts (bounces, escaped): equal, or all >= 1 (it bounces in every run);\n"
    "            null in every run is ok, null in some runs only (DIFFERS) is not;\n"
    "          \"no\" otherwise; \"-\" not judged (fluid.particles: the spacing sets it)\n"
    "and each run's dt, spacing, wall and cpu seconds, steps, substeps and particles. The same\n"
    "table goes to DIR/convergence.csv (null: an empty field).\n"
    "options:\n"
    "  --duration S      simulated seconds of each run (default: the scene's duration);\n"
    "                    round(S / (dt / 4)) steps at most 1e9\n"
    "  --tolerance FRAC  the relative tolerance, a fraction >= 0 (default 0.2: 20%)\n"
    "  --jobs N          child runs at a time, 1 to 4 (default 1: one after the other, so that\n"
    "                    each run's wall seconds are its own)\n"
    "  --threads N       OpenMP threads of each run, 1 to 1024 (default: OpenMP's)\n"
    "  --set KEY=VALUE, --unset KEY   scene overrides of every run, as for stf run (at most\n"
    "                    64 in all)\n"
    "  -o DIR            the runs (run0.h5 .. run3.h5, columns in order) and convergence.csv\n"
    "                    (default: convergence-NAME, NAME the scene's name); an existing\n"
    "                    directory is used and its files of those names overwritten, as\n"
    "                    `stf bench accuracy -o` does\n"
    "A history memory given in steps (effects.history.d) halves in seconds with dt: a warning\n"
    "says so and the runs go on; give effects.history.memory (s) to keep it. The scene's\n"
    "dt_control and substep settings stay as they are.\n"
    "exit codes: 0 every metric ok, 1 some metric not within the tolerance, 2 bad input (or a\n"
    "run refused its settings), 3 a run failed numerically\n"},
};

/* The accuracy benchmark's knobs, in the order they run and are drawn. */
enum { NKNOBS = 4 };
static const char *const KNOBS[NKNOBS] = {"dt", "spacing", "history", "solver"};

static int knob_index(const char *name)
{
    for (int k = 0; k < NKNOBS; k++)
        if (!strcmp(name, KNOBS[k])) return k;
    return -1;
}

/* The usage of benchmark what, or bench's own (NULL: no benchmark, or
 * an unknown one). */
static const cli_usage *usage_for(const char *what)
{
    for (size_t k = 0; what && k < sizeof bench_usages / sizeof *bench_usages; k++)
        if (!strcmp(what, bench_usages[k].cmd + 6)) return &bench_usages[k];
    return &bench_usage;
}

/* A usage error of benchmark what (NULL: of stf bench). Returns 2. */
static int bad_of(const char *what, const char *msg, const char *arg)
{
    return cli_usage_error(usage_for(what), "%s '%s'", msg, arg);
}

/* The benchmarks that read each of these options; the others refuse it rather than ignore it.
 * (--set, --unset and --threads apply to all.) */
static const struct {
    const char *opt, *users;
} option_users[] = {{"-o", "accuracy convergence"}, {"--out", "accuracy convergence"},
                    {"--steps", "table1 effects scaling grid"},
                    {"--warmup", "table1 effects scaling"},
                    {"--repeat", "table1 effects scaling"},
                    {"--full", "table1 effects scaling grid accuracy"},
                    {"--duration", "accuracy dam convergence"}, {"--error", "accuracy"},
                    {"--knobs", "accuracy"},       {"--grow", "scaling"},
                    {"--tolerance", "convergence"}, {"--jobs", "convergence"}};

/* 1 if option s is one that benchmark what does not read (message printed). */
static int not_for(const char *what, const char *s)
{
    for (size_t k = 0; k < sizeof option_users / sizeof *option_users; k++) {
        if (strcmp(s, option_users[k].opt)) continue;
        char word[32], list[96];
        snprintf(word, sizeof word, " %s ", what);
        snprintf(list, sizeof list, " %s ", option_users[k].users);
        if (strstr(list, word)) return 0;
        cli_usage_error(usage_for(what), "%s does not apply to it (only to: %s)", s,
                        option_users[k].users);
        return 1;
    }
    return 0;
}

static int parse(int argc, char **argv, bench_args *a)
{
    memset(a, 0, sizeof *a);
    a->error = 0.01;
    a->tolerance = 0.2;
    a->jobs = 1;
    if (argc < 1)
        return cli_usage_error(&bench_usage, "no benchmark given (one of table1, effects, accuracy, "
                                             "scaling, grid, dam, convergence)");
    a->what = argv[0];
    if (strcmp(a->what, "table1") && strcmp(a->what, "effects") && strcmp(a->what, "accuracy") &&
        strcmp(a->what, "scaling") && strcmp(a->what, "grid") && strcmp(a->what, "dam") &&
        strcmp(a->what, "convergence"))
        return bad_of(NULL, "unknown benchmark (allowed: table1, effects, accuracy, scaling, grid, dam, "
                   "convergence):", a->what);
    for (int i = 1; i < argc; i++) {
        const char *s = argv[i];
        int more = i + 1 < argc;
        char *end;
        if (not_for(a->what, s)) return 2;
        if ((!strcmp(s, "-o") || !strcmp(s, "--out")) && more) a->out = argv[++i];
        else if (!strcmp(s, "--set") && more) {
            char *eq = strchr(argv[++i], '=');
            if (!eq) return bad_of(a->what, "--set needs KEY=VALUE, got", argv[i]);
            if (a->nov == MAX_OV) return bad_of(a->what, "too many overrides at", argv[i]);
            *eq = 0;
            a->ov[a->nov].key = argv[i];
            a->ov[a->nov++].value = eq + 1;
        } else if (!strcmp(s, "--unset") && more) {
            if (a->nov == MAX_OV) return bad_of(a->what, "too many overrides at", argv[i + 1]);
            a->ov[a->nov].key = argv[++i];
            a->ov[a->nov++].value = NULL;
        } else if (!strcmp(s, "--threads") && more) {
            long t = strtol(argv[++i], &end, 10);
            if (*end || t < 1 || t > 1024) return bad_of(a->what, "--threads must be an integer in [1,1024], got", argv[i]);
            a->threads = (int)t;
        } else if (!strcmp(s, "--steps") && more) {
            long t = strtol(argv[++i], &end, 10);
            if (*end || t < 1 || t > 1000000) return bad_of(a->what, "--steps must be an integer >= 1, got", argv[i]);
            a->steps = (int)t;
        } else if (!strcmp(s, "--warmup") && more) {
            long t = strtol(argv[++i], &end, 10);
            if (*end || t < 0 || t > 1000000) return bad_of(a->what, "--warmup must be an integer >= 0, got", argv[i]);
            a->warmup = (int)t;
            a->warmup_set = 1;
        } else if (!strcmp(s, "--repeat") && more) {
            long t = strtol(argv[++i], &end, 10);
            if (*end || t < 1 || t > 100) return bad_of(a->what, "--repeat must be an integer in [1,100], got", argv[i]);
            a->repeat = (int)t;
        } else if (!strcmp(s, "--duration") && more) {
            a->duration = strtod(a->duration_arg = argv[++i], &end);
            if (*end || !(a->duration > 0) || !isfinite(a->duration))
                return bad_of(a->what, "--duration must be a number of seconds > 0, got", argv[i]);
        } else if (!strcmp(s, "--error") && more) {
            a->error = strtod(argv[++i], &end);
            if (*end || !(a->error > 0) || !isfinite(a->error))
                return bad_of(a->what, "--error must be a distance in m > 0, got", argv[i]);
        } else if (!strcmp(s, "--knobs") && more) {
            a->knobs = argv[++i];
            /* a comma list of known knobs, each once at most */
            char buf[256];
            if (strlen(a->knobs) >= sizeof buf) return bad_of(a->what, "--knobs: too long:", a->knobs);
            strcpy(buf, a->knobs);
            char *save = NULL;
            for (char *k = strtok_r(buf, ",", &save); k; k = strtok_r(NULL, ",", &save))
                if (knob_index(k) < 0)
                    return bad_of(a->what, "--knobs: a comma list of dt, spacing, history, solver; unknown", k);
            if (!a->knobs[0]) return bad_of(a->what, "--knobs: empty list", a->knobs);
        } else if (!strcmp(s, "--grow") && more) {
            const char *g = argv[++i];
            if (strcmp(g, "spacing") && strcmp(g, "domain"))
                return bad_of(a->what, "--grow must be spacing or domain, got", g);
            a->grow_domain = !strcmp(g, "domain");
        } else if (!strcmp(s, "--tolerance") && more) {
            a->tolerance = strtod(argv[++i], &end);
            if (*end || end == argv[i] || !(a->tolerance >= 0) || !isfinite(a->tolerance))
                return bad_of(a->what, "--tolerance must be a fraction >= 0 (0.2: 20%), got", argv[i]);
        } else if (!strcmp(s, "--jobs") && more) {
            long t = strtol(argv[++i], &end, 10);
            if (*end || t < 1 || t > 4) return bad_of(a->what, "--jobs must be an integer in [1,4], got", argv[i]);
            a->jobs = (int)t;
        } else if (!strcmp(s, "--full")) a->full = 1;
        else if (s[0] == '-') return bad_of(a->what, "unknown or incomplete option", s);
        else if (!a->scene) a->scene = s;
        else return bad_of(a->what, "unexpected argument", s);
    }
    if (!a->scene && strcmp(a->what, "table1")) return bad_of(a->what, "needs a scene file after", a->what);
    if (!a->steps) a->steps = a->full ? 224 : 32; /* whole history time blocks (16 or 32 steps) */
    /* 50 steps: the bowling ball reaches the pool (t = 0.05 s), so the timed steps include
       the impact rather than a pool at rest */
    if (!a->warmup_set) a->warmup = 50;
    if (!a->repeat) a->repeat = 1;
    return 0;
}

/* Refuses a run duration whose step count round(duration / dt) is not one a run can take
 * (stf_run_steps); whence names where the duration came from when not from --duration.
 * Returns 0, or 2 with a message. */
static int check_duration(const bench_args *a, double duration, double dt, const char *whence)
{
    char why[512];
    if (stf_run_steps(duration, dt, why, sizeof why) >= 0) return 0;
    if (a->duration > 0)
        fprintf(stderr, "stf bench %s: --duration %s: %s\n", a->what, a->duration_arg, why);
    else fprintf(stderr, "stf bench %s: %s: %s: %s\n", a->what, a->scene, whence, why);
    return 2;
}

/* ------------------------------------------------------------------ in-process timing */

typedef struct timing {
    int particles;
    long springs;
    double step_ms;                /* wall per coupled step (fluid + ODE), ms */
    double cpu_ms;                 /* process cpu time per step (all threads), ms */
    double stage_ms[STAGE_COUNT];  /* per fluid stage, ms per step */
    size_t bytes[6];               /* per effect, bytes (index = bit of enum stf_effect) */
    int history_steps;
    int steps;                     /* steps timed (whole history time blocks, see time_scene) */
    long rebuilds;                 /* neighbour candidate rebuilds in the timed steps */
    double neighbours;             /* neighbours within h per particle at the end */
    double substeps;               /* fluid substeps per step in the timed steps (adaptive dt) */
} timing;

static const char *const effect_names[6] = {"gravity", "viscosity", "pressure", "springs",
                                            "history", "boundary_stick"};
static const char *const stage_names[STAGE_COUNT] = {"grid",     "gravity",  "viscosity",
                                                     "springs",  "history",  "pressure",
                                                     "collide",  "boundary"};

static double cpu_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Loads a scene (from path, or text when path is NULL), runs `warm` steps, then times
 * `steps` steps. Returns 0, 2 bad scene, 3 numerical failure. */
static int time_scene(const char *path, const char *text, const stf_override *ov, int nov,
                      int warm, int steps, timing *t)
{
    char err[2048];
    stf_scene *sc;
    int rc = path ? stf_scene_load(path, ov, nov, &sc, err, sizeof err)
                  : stf_scene_load_string("vibration_layer", text, ov, nov, &sc, err, sizeof err);
    if (rc != 0) {
        fprintf(stderr, "%s\n", err);
        return 2;
    }
    stf_sim *sim;
    if (stf_sim_create(sc, &sim, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        stf_scene_free(sc);
        return 2;
    }
    memset(t, 0, sizeof *t);
    rc = 0;
    for (int s = 0; s < warm && rc == 0; s++) rc = stf_sim_step(sim);
    /* Time a full window, as after d steps: the ring's unwritten slots are zero velocities
       (the pool at rest before t = 0), so the weighted sums run over all d lags. The count
       is rounded up to a whole time block, so the first timed step starts a block: a count
       in the middle of one would make that step redo the block's pass (the timed steps
       would hold one pass too many). */
    stf_history *hh = &sim->fluid->hist;
    long block = hh->w && !hh->terms && hh->window > 0 && hh->tblock > 0 ? hh->tblock : 0;
    if (block && hh->pushed > 0 && hh->pushed < hh->cap)
        hh->pushed = (hh->cap + block - 1) / block * block;
    /* Whole time blocks: a block's pass (the ring read once) serves tblock samples, and a
       step pushes one sample per substep (adaptive dt). So the timed steps start and end on
       a block's edge: with the history window they run until `steps` samples or more were
       pushed and the count is whole blocks (at most 4 max(steps, tblock) steps), otherwise
       `steps` steps. 32 steps of 1.09 substeps each (the bowling ball's impact) would hold
       two passes for 35 samples, 1.8x the passes of a long run. The figures are per step
       timed. */
    for (int s = 0; block && s < steps && hh->pushed % block && rc == 0; s++)
        rc = stf_sim_step(sim); /* to the edge of a block (the forced window starts on one) */
    double before[STAGE_COUNT];
    memcpy(before, sim->fluid->stage_seconds, sizeof before);
    long rebuilds0 = sim->fluid->grid.rebuilds, substeps0 = sim->substeps, pushed0 = hh->pushed;
    double t0 = omp_get_wtime(), c0 = cpu_seconds();
    int timed = 0;
    int most = 4 * (steps > block ? steps : (int)block);
    while (rc == 0 && (block ? (hh->pushed - pushed0 < steps || hh->pushed % block) && timed < most
                             : timed < steps)) {
        rc = stf_sim_step(sim);
        timed++;
    }
    steps = timed;
    double wall = omp_get_wtime() - t0, cpu = cpu_seconds() - c0;
    if (rc != 0) {
        fprintf(stderr, "stf bench: numerical failure: %s\n", stf_fluid_failure(sim->fluid));
        rc = 3;
    } else {
        t->particles = stf_fluid_count(sim->fluid);
        t->springs = stf_fluid_spring_count(sim->fluid);
        t->step_ms = 1e3 * wall / steps;
        t->cpu_ms = 1e3 * cpu / steps;
        for (int k = 0; k < STAGE_COUNT; k++)
            t->stage_ms[k] = 1e3 * (sim->fluid->stage_seconds[k] - before[k]) / steps;
        for (int e = 0; e < 6; e++) t->bytes[e] = stf_fluid_effect_bytes(sim->fluid, 1u << e);
        t->history_steps = stf_fluid_history_steps(sim->fluid);
        t->steps = timed;
        t->rebuilds = sim->fluid->grid.rebuilds - rebuilds0;
        t->substeps = (double)(sim->substeps - substeps0) / steps;
        long nb = 0;
        for (int i = 0; i < t->particles; i++) nb += sim->fluid->grid.count[i];
        t->neighbours = t->particles > 0 ? (double)nb / t->particles : 0;
    }
    stf_sim_destroy(sim);
    stf_scene_free(sc);
    return rc;
}

static void print_load(void)
{
    double l[3];
    if (getloadavg(l, 3) == 3) printf("# load average %.2f %.2f %.2f, ", l[0], l[1], l[2]);
    else printf("# ");
    printf("%d OpenMP threads, %ld cores online\n", omp_get_max_threads(),
           sysconf(_SC_NPROCESSORS_ONLN));
}

/* ------------------------------------------------------------------------- table 1 */

/* A vibrated layer of about 20K particles (paper Fig. 5): the container shakes up and down. */
static const char vibration_layer[] =
    "name: vibration_layer\n"
    "duration: 2.0\n"
    "dt: 0.001\n"
    "frame_rate: 30\n"
    "fluid:\n"
    "  model: clavet_stf\n"
    "  spacing: 0.015\n"
    "  density: 1270\n"
    "  blocks:\n"
    "    - min: [-0.3, -0.3, 0.0]\n"
    "      max: [0.3, 0.3, 0.18]\n"
    "effects:\n"
    "  gravity: {g: [0, 0, -9.81]}\n"
    "  viscosity: {sigma: 10.0}\n"
    "  pressure: {k: 1000, k_near: 200}\n"
    "  springs: {k_min: 100, yield_ratio: 0.0, plasticity: 2.0}\n"
    "  history: {q: 0.5, d: 50, k_hist: 200000, reference_spacing: 0.02}\n"
    "  boundary_stick: {stick: 200}\n"
    "container:\n"
    "  size: [0.6, 0.6, 0.3]\n"
    "  wall: 0.03\n"
    "  motion: kinematic\n"
    "  vibration: {axis: [0, 0, 1], amplitude: 0.004, frequency: 40}\n";

/* Paper Table 1: t_simstep (s), t_history (ms), m_history (MB) for d = 0, 50, 150, 500. */
static const double paper_step[2][4] = {{1.226, 1.335, 1.494, 1.627}, {1.192, 1.245, 1.388, 1.539}};
static const double paper_hist[2][4] = {{0, 4, 12, 40}, {0, 4, 12, 40}};

static int bench_table1(const bench_args *a)
{
    static const int ds[5] = {0, 50, 150, 500, -16}; /* -K: soe with K terms (full history) */
    const char *bowling = a->scene ? a->scene : "scenes/bowling_ball.yaml";
    printf("# stf bench table1: %d timed steps after %d warm-up steps (--full: 224), fastest of "
           "%d run(s) a row, the rounds interleaved\n", a->steps, a->warmup, a->repeat);
    print_load();
    printf("%-12s %4s %6s | %10s %10s %8s %8s %9s | %10s %10s %8s | %8s %8s\n", "experiment",
           "d", "n", "step ms", "hist ms", "hist %", "mem MB", "cpu ms", "paper s", "paper ms",
           "paper MB", "x step", "x hist");
    /* --repeat rounds over all ten rows (a slow spell of a shared machine then hits one run of
       several rows, not every run of one row); each row keeps its fastest run */
    timing best[2][5];
    for (int r = 0; r < a->repeat; r++)
        for (int e = 0; e < 2; e++)
            for (int k = 0; k < 5; k++) {
                stf_override ov[MAX_OV + 4];
                int nov = 0;
                for (int i = 0; i < a->nov; i++) ov[nov++] = a->ov[i];
                char dv[32];
                snprintf(dv, sizeof dv, "%d", ds[k] > 0 ? ds[k] : -ds[k]);
                if (ds[k] == 0) ov[nov++] = (stf_override){"effects.history", NULL};
                else if (ds[k] > 0) ov[nov++] = (stf_override){"effects.history.d", dv};
                else {
                    ov[nov++] = (stf_override){"effects.history.mode", "soe"};
                    ov[nov++] = (stf_override){"effects.history.terms", dv};
                }
                timing t;
                int rc = e == 0 ? time_scene(bowling, NULL, ov, nov, a->warmup, a->steps, &t)
                                : time_scene(NULL, vibration_layer, ov, nov, a->warmup, a->steps,
                                             &t);
                if (rc) return rc;
                if (r == 0 || t.step_ms < best[e][k].step_ms) best[e][k] = t;
            }
    for (int e = 0; e < 2; e++)
        for (int k = 0; k < 5; k++) {
            const timing *t = &best[e][k];
            char dv[32];
            double hist = t->stage_ms[STAGE_HISTORY];
            double simstep = t->step_ms - hist; /* the step without the history terms */
            if (ds[k] < 0) { /* no paper row: the soe history's own cost */
                double soe_mem = (double)t->bytes[4] / 1e6;
                printf("%-12s %4s %6d | %10.2f %10.3f %7.1f%% %8.1f %9.2f | %10s %10s %8s | %8s %8s\n",
                       e == 0 ? "bowling" : "vibration", "soe", t->particles, simstep, hist,
                       100.0 * hist / t->step_ms, soe_mem, t->cpu_ms, "-", "-", "-", "-", "-");
                continue;
            }
            double mem = 12.0 * t->particles * ds[k] / 1e6; /* the paper's 12 n d */
            double pm = 12.0 * 20000 * ds[k] / 1e6;
            printf("%-12s %4d %6d | %10.2f %10.3f %7.1f%% %8.1f %9.2f | %10.3f %10.0f %8.0f | %8.0f %8s\n",
                   e == 0 ? "bowling" : "vibration", ds[k], t->particles, simstep, hist,
                   100.0 * hist / t->step_ms, mem, t->cpu_ms, paper_step[e][k], paper_hist[e][k],
                   pm, 1e3 * paper_step[e][k] / simstep,
                   ds[k] ? (snprintf(dv, sizeof dv, "%.0f", paper_hist[e][k] / hist), dv) : "-");
            if (ds[k] && t->bytes[4] < (size_t)(mem * 1e6))
                printf("# warning: history storage %zu B below 12 n d\n", t->bytes[4]);
        }
    printf("# steps timed (to whole history time blocks):");
    for (int e = 0; e < 2; e++)
        for (int k = 0; k < 5; k++) printf(" %d", best[e][k].steps);
    printf("\n");
    printf("# step ms: wall per step minus the history stage; hist ms: the history stage (ring\n"
           "# push + weighted sums); mem: 12 n d (allocated: d+1 float32 vectors per particle);\n"
           "# cpu ms: process cpu time per whole step, all threads (steadier than wall on a busy machine).\n"
           "# x step, x hist: paper time / our time (paper: one i7-2600K core, 2011).\n"
           "# soe: history mode soe, 16 exponentials, full history (mem: all its storage).\n"
           "# The window is timed full (d lags summed; the past before t = 0 is rest).\n");
    return 0;
}

/* ------------------------------------------------------------------------- effects */

static int bench_effects(const bench_args *a)
{
    char err[2048];
    stf_scene *sc;
    if (stf_scene_load(a->scene, a->ov, a->nov, &sc, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        return 2;
    }
    unsigned have = sc->fluid.effects;
    stf_scene_free(sc);
    printf("# stf bench effects %s: %d timed steps after %d warm-up steps, fastest of %d "
           "run(s) a row, the rounds interleaved\n", a->scene, a->steps, a->warmup, a->repeat);
    print_load();
    printf("%-22s %9s %9s %9s |", "run", "step ms", "cpu ms", "saved ms");
    for (int k = 0; k < STAGE_COUNT; k++) printf(" %9s", stage_names[k]);
    printf(" | %s\n", "effect storage (B)");
    /* --repeat rounds over all the rows, interleaved (see bench_table1); each row keeps its
       fastest run */
    timing best[7];
    memset(best, 0, sizeof best);
    int status[7] = {0}; /* per row: 0 timed, 3 a numerical failure without the effect */
    for (int r = 0; r < a->repeat; r++)
        for (int e = -1; e < 6; e++) {
            if (e >= 0 && !(have & (1u << e))) continue;
            stf_override ov[MAX_OV + 2];
            int nov = 0;
            for (int i = 0; i < a->nov; i++) ov[nov++] = a->ov[i];
            char key[64];
            if (e >= 0) {
                snprintf(key, sizeof key, "effects.%s", effect_names[e]);
                ov[nov++] = (stf_override){key, NULL};
                /* history lives on the springs: without springs there is no history either */
                if (e == 3 && (have & STF_EFFECT_HISTORY))
                    ov[nov++] = (stf_override){"effects.history", NULL};
            }
            timing t;
            int rc = time_scene(a->scene, NULL, ov, nov, a->warmup, a->steps, &t);
            if (rc == 3) status[e + 1] = 3;
            else if (rc) return rc;
            else if (r == 0 || t.step_ms < best[e + 1].step_ms) best[e + 1] = t;
        }
    const timing *base = &best[0];
    for (int e = -1; e < 6; e++) {
        if (e >= 0 && !(have & (1u << e))) continue;
        char label[64];
        if (e >= 0)
            snprintf(label, sizeof label, "no %s%s", effect_names[e],
                     e == 3 && (have & STF_EFFECT_HISTORY) ? "+history" : "");
        else snprintf(label, sizeof label, "all (scene)");
        if (status[e + 1] == 3) {
            printf("%-22s   fails without this effect (numerical failure)\n", label);
            continue;
        }
        const timing *t = &best[e + 1];
        printf("%-22s %9.2f %9.2f %9.2f |", label, t->step_ms, t->cpu_ms,
               e < 0 ? 0.0 : base->step_ms - t->step_ms);
        for (int k = 0; k < STAGE_COUNT; k++) printf(" %9.3f", t->stage_ms[k]);
        printf(" |");
        for (int k = 0; k < 6; k++)
            if (t->bytes[k]) printf(" %s=%zu", effect_names[k], t->bytes[k]);
        printf("\n");
        /* An effect that is off must cost nothing: no stage time, no storage. */
        if (e >= 0) {
            int stage = e == 0 ? STAGE_GRAVITY : e == 1 ? STAGE_VISCOSITY : e == 2 ? STAGE_PRESSURE
                      : e == 3 ? STAGE_SPRINGS : e == 4 ? STAGE_HISTORY : STAGE_BOUNDARY;
            if (t->stage_ms[stage] != 0 || t->bytes[e] != 0) {
                fprintf(stderr, "stf bench: effect %s is off but cost %.3g ms and %zu B\n",
                        effect_names[e], t->stage_ms[stage], t->bytes[e]);
                return 1;
            }
        }
    }
    printf("# not in the scene (0 ms, 0 B, checked):");
    for (int e = 0; e < 6; e++)
        if (!(have & (1u << e))) printf(" %s", effect_names[e]);
    printf("\n# %d particles, %ld springs in the full run; neighbour candidates rebuilt in %ld of "
           "the %d timed steps\n", base->particles, base->springs, base->rebuilds, a->steps);
    return 0;
}

/* ------------------------------------------------------------------------- scaling */

/* The two particle counts of scaling and grid: the scene's spacing and spacing / 10^(1/3)
 * (10x the particles), into sp[2]. 0, or 2 (message printed) when the scene is bad. */
static int two_spacings(const bench_args *a, double sp[2])
{
    char err[2048];
    stf_scene *sc;
    if (stf_scene_load(a->scene, a->ov, a->nov, &sc, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        return 2;
    }
    sp[0] = sc->fluid.spacing;
    sp[1] = sp[0] / cbrt(10.0);
    stf_scene_free(sc);
    return 0;
}

/* The command's overrides and fluid.spacing = spacing (its text in buf) into ov; their count. */
static int with_spacing(const bench_args *a, double spacing, stf_override *ov, char buf[64])
{
    int nov = 0;
    for (int i = 0; i < a->nov; i++) ov[nov++] = a->ov[i];
    snprintf(buf, 64, "%.9g", spacing);
    ov[nov++] = (stf_override){"fluid.spacing", buf};
    return nov;
}

/* --grow domain: the scene with its pool widened sqrt(10) times in x and y about the
 * container's centre (every fluid box's corners and the container's inner size), at the same
 * spacing, so about 10x the particles with the same physics per particle (the same dt limit,
 * the same neighbours); the bodies stay where they are. Box blocks only (a ball block is not
 * a pool). Returns the overrides' count, -1 (message printed) when the scene has no
 * container or a ball block. */
enum { WIDE_OV = 2 * 16 + 1 };
static int widened(const bench_args *a, stf_override *ov, char keys[WIDE_OV][48],
                   char vals[WIDE_OV][96])
{
    char err[2048];
    stf_scene *sc;
    if (stf_scene_load(a->scene, a->ov, a->nov, &sc, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        return -1;
    }
    int nov = 0, rc = 0;
    for (int i = 0; i < a->nov; i++) ov[nov++] = a->ov[i];
    const double f = sqrt(10.0), *c = sc->container.position;
    if (!sc->container.present || sc->nblocks < 1 || 2 * sc->nblocks + 1 > WIDE_OV) {
        fprintf(stderr, "stf bench scaling --grow domain: %s needs a container and 1 to %d fluid "
                "blocks\n", a->scene, (WIDE_OV - 1) / 2);
        rc = -1;
    }
    for (int b = 0; b < sc->nblocks && rc == 0; b++) {
        const stf_block *bl = &sc->blocks[b];
        if (bl->radius > 0) {
            fprintf(stderr, "stf bench scaling --grow domain: %s:%d: fluid block %d is a ball, "
                    "not a pool\n", a->scene, bl->line, b);
            rc = -1;
            break;
        }
        for (int e = 0; e < 2; e++) {
            const double *p = e ? bl->hi : bl->lo;
            int k = 2 * b + e;
            snprintf(keys[k], sizeof keys[k], "fluid.blocks.%d.%s", b, e ? "max" : "min");
            snprintf(vals[k], sizeof vals[k], "[%.17g, %.17g, %.17g]", c[0] + f * (p[0] - c[0]),
                     c[1] + f * (p[1] - c[1]), p[2]);
            ov[nov++] = (stf_override){keys[k], vals[k]};
        }
    }
    if (rc == 0) {
        int k = 2 * sc->nblocks;
        const double *z = sc->container.size;
        snprintf(keys[k], sizeof keys[k], "container.size");
        const double g = f * (1.0 + 1e-12); /* a hair wider than the corners' rounding */
        snprintf(vals[k], sizeof vals[k], "[%.17g, %.17g, %.17g]", g * z[0], g * z[1], z[2]);
        ov[nov++] = (stf_override){keys[k], vals[k]};
    }
    stf_scene_free(sc);
    return rc == 0 ? nov : -1;
}

/* The scene at its spacing and at 10x the particles (spacing / 10^(1/3), or the pool
 * widened): cost per step. */
static int bench_scaling(const bench_args *a)
{
    double spk[2];
    if (two_spacings(a, spk) != 0) return 2;
    if (a->grow_domain) spk[1] = spk[0];
    printf("# stf bench scaling %s: %d timed steps after %d warm-up steps, %d run(s) of each; "
           "10x the particles by %s\n", a->scene, a->steps, a->warmup, a->repeat,
           a->grow_domain ? "a wider pool (--grow domain)" : "a finer spacing");
    print_load();
    printf("%12s %9s %10s %10s %14s %8s %9s %9s %9s %6s %7s |", "spacing m", "n", "step ms",
           "cpu ms", "particles/s", "x time", "substeps", "x substep", "rebuilds", "nbrs",
           "springs");
    for (int k = 0; k < STAGE_COUNT; k++) printf(" %9s", stage_names[k]);
    printf("\n");
    /* each size --repeat times, interleaved (a slow spell of the machine hits both); the
       fastest run of each counts, and the spread of the runs is printed */
    timing best[2];
    double slowest[2] = {0, 0};
    for (int r = 0; r < a->repeat; r++)
        for (int k = 0; k < 2; k++) {
            stf_override ov[MAX_OV + WIDE_OV];
            char v[64], keys[WIDE_OV][48], vals[WIDE_OV][96];
            int nov = k == 1 && a->grow_domain ? widened(a, ov, keys, vals)
                                               : with_spacing(a, spk[k], ov, v);
            if (nov < 0) return 2;
            timing t;
            int rc = time_scene(a->scene, NULL, ov, nov, a->warmup, a->steps, &t);
            if (rc) return rc;
            if (r == 0 || t.step_ms < best[k].step_ms) best[k] = t;
            if (t.step_ms > slowest[k]) slowest[k] = t.step_ms;
        }
    for (int k = 0; k < 2; k++) {
        const timing *t = &best[k];
        printf("%12.5g %9d %10.2f %10.2f %14.3g %8.2f %9.2f %9.2f %9ld %6.1f %7.1f |", spk[k],
               t->particles, t->step_ms, t->cpu_ms, 1e3 * t->particles / t->step_ms,
               t->step_ms / best[0].step_ms, t->substeps,
               t->step_ms / t->substeps / (best[0].step_ms / best[0].substeps), t->rebuilds,
               t->neighbours, 2.0 * (double)t->springs / t->particles);
        for (int st = 0; st < STAGE_COUNT; st++) printf(" %9.2f", t->stage_ms[st]);
        printf("\n");
    }
    if (a->repeat > 1)
        printf("# %d runs of each, the fastest shown; slowest step: %.2f and %.2f ms\n", a->repeat,
               slowest[0], slowest[1]);
    printf("# x time: step time / the first row's (linear cost: the particle ratio); substeps:\n"
           "# fluid substeps per step (adaptive dt: the finer spacing's CFL limit splits more\n"
           "# steps); x substep: the same ratio per substep; rebuilds: neighbour candidate\n"
           "# rebuilds in the timed steps; nbrs, springs: per particle at the end (the work of\n"
           "# each neighbour and spring pass); then wall ms per step by stage\n");
    return 0;
}

/* ---------------------------------------------------------------------------- grid */

/* The neighbour search on the scene's initial particles (sorted as the fluid sorts them):
 * --steps candidate rebuilds (each followed by its filter) and --steps filters alone, at the
 * scene's spacing and at 10x the particles. */
static int bench_grid(const bench_args *a)
{
    printf("# stf bench grid %s: %d rebuilds and %d filters at the initial positions\n", a->scene,
           a->steps, a->steps);
    print_load();
    printf("%12s %9s %8s %8s %12s %12s %10s\n", "spacing m", "n", "cand", "nbrs", "rebuild ms",
           "filter ms", "cpu ratio");
    double spk[2], first = 0;
    if (two_spacings(a, spk) != 0) return 2;
    for (int k = 0; k < 2; k++) {
        char err[2048], v[64];
        stf_override ov[MAX_OV + 1];
        int nov = with_spacing(a, spk[k], ov, v);
        stf_scene *sc;
        stf_sim *sim;
        if (stf_scene_load(a->scene, ov, nov, &sc, err, sizeof err) != 0 ||
            stf_sim_create(sc, &sim, err, sizeof err) != 0) {
            fprintf(stderr, "%s\n", err);
            return 2;
        }
        stf_fluid *f = sim->fluid;
        int n = f->n;
        stf_grid g = {0};
        double *x = malloc((size_t)n * 3 * sizeof *x);
        int rc = x && stf_grid_sort(&g, f->x, n, f->h) == 0 ? 0 : 3;
        for (int i = 0; i < n && rc == 0; i++) memcpy(x + 3 * i, f->x + 3 * g.order[i], 3 * sizeof *x);
        double c0 = cpu_seconds();
        for (int r = 0; r < a->steps && rc == 0; r++) {
            grid_invalidate(&g);
            if (stf_grid_build(&g, x, n, f->h) != 0) rc = 3;
        }
        double c1 = cpu_seconds();
        for (int r = 0; r < a->steps && rc == 0; r++)
            if (stf_grid_build(&g, x, n, f->h) != 0) rc = 3;
        double c2 = cpu_seconds();
        if (rc == 0) {
            long nc = 0, nn = 0;
            for (int i = 0; i < n; i++) nc += g.ccount[i], nn += g.count[i];
            double filter = 1e3 * (c2 - c1) / a->steps, rebuild = 1e3 * (c1 - c0) / a->steps - filter;
            if (k == 0) first = rebuild + filter;
            printf("%12.5g %9d %8.1f %8.1f %12.2f %12.2f %10.2f\n", spk[k], n, (double)nc / n,
                   (double)nn / n, rebuild, filter, (rebuild + filter) / first);
        } else {
            fprintf(stderr, "stf bench grid: out of memory\n");
        }
        free(x);
        stf_grid_free(&g);
        stf_sim_destroy(sim);
        stf_scene_free(sc);
        if (rc) return rc;
    }
    printf("# cpu ms per call, all threads (process CPU time); cand, nbrs: candidates (r < 1.25 h)\n"
           "# and neighbours (r < h) per particle; cpu ratio: (rebuild + filter) / the first row's\n");
    return 0;
}

/* ------------------------------------------------------------------------ accuracy */

typedef struct acc_run {
    char knob[16], setting[48];
    double value;     /* the knob's value (dt s, spacing m, solver: tolerance factor) */
    double wall;      /* s, the run's own wall clock of its steps */
    double cpu;       /* s, user + system time of the whole child process */
    int ok;
    stf_metrics m;
    int nb;           /* body samples */
    double *bt, *bp;  /* body time, position (first body) */
    int nf;           /* frames */
    double *ft, *fc;  /* frame time, fluid centre of mass */
    double err_body, err_com, err_metric; /* m */
    long steps, substeps; /* coupled steps and fluid substeps of the run (-1: not in the file) */
} acc_run;

/* Starts `SELF run SCENE -o OUT --quiet --duration D` with the bench's --threads and
 * overrides, then the extra arguments (later --set win). Returns 0 and the child's pid, or
 * -1 when it cannot be started. */
static int spawn_start(const char *self, const char *scene, const char *out, const bench_args *a,
                       const char *const *extra, int nextra, double duration, pid_t *child)
{
    const char *argv[2 * MAX_OV + 32];
    int n = 0;
    char dur[32], thr[16];
    argv[n++] = self;
    argv[n++] = "run";
    argv[n++] = scene;
    argv[n++] = "-o";
    argv[n++] = out;
    argv[n++] = "--quiet";
    snprintf(dur, sizeof dur, "%.9g", duration);
    argv[n++] = "--duration";
    argv[n++] = dur;
    if (a->threads) {
        snprintf(thr, sizeof thr, "%d", a->threads);
        argv[n++] = "--threads";
        argv[n++] = thr;
    }
    static char ovbuf[MAX_OV][512];
    for (int i = 0; i < a->nov; i++) {
        if (a->ov[i].value) {
            snprintf(ovbuf[i], sizeof ovbuf[i], "%s=%s", a->ov[i].key, a->ov[i].value);
            argv[n++] = "--set";
            argv[n++] = ovbuf[i];
        } else {
            argv[n++] = "--unset";
            argv[n++] = a->ov[i].key;
        }
    }
    for (int i = 0; i < nextra; i++) argv[n++] = extra[i];
    argv[n] = NULL;
    /* posix_spawn returns once the child has exec'ed: argv (and ovbuf) may change after */
    return posix_spawn(child, self, NULL, NULL, (char *const *)argv, environ) != 0 ? -1 : 0;
}

/* Waits for child *pid (any child when *pid is -1; *pid is then the one that ended).
 * Returns its exit code (-1 killed by a signal or not waited for) and its cpu seconds (user
 * + system) in *cpu. */
static int spawn_wait(pid_t *pid, double *cpu)
{
    int st;
    struct rusage ru;
    pid_t got;
    while ((got = wait4(*pid, &st, 0, &ru)) < 0 && errno == EINTR) {}
    if (got < 0) return -1;
    *pid = got;
    *cpu = (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec +
           (double)ru.ru_stime.tv_sec + 1e-6 * (double)ru.ru_stime.tv_usec;
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* One child run to its end: spawn_start then spawn_wait. Returns its exit code (-1: it did
 * not start or was killed) and its cpu seconds in *cpu. */
static int spawn_run(const char *self, const char *scene, const char *out, const bench_args *a,
                     const char *const *extra, int nextra, double duration, double *cpu)
{
    pid_t pid;
    if (spawn_start(self, scene, out, a, extra, nextra, duration, &pid) != 0) return -1;
    return spawn_wait(&pid, cpu);
}

static int read_run(const char *path, acc_run *r)
{
    char err[1024];
    if (stf_metrics_compute(path, &r->m, err, sizeof err) != 0) return -1;
    stf_h5r *h;
    if (stf_h5r_open(path, &h, err, sizeof err) != 0) return -1;
    if (stf_h5r_attr_double(h, "wall_seconds", &r->wall) != 0) r->wall = NAN;
    double v;
    r->steps = stf_h5r_attr_double(h, "steps", &v) == 0 ? lround(v) : -1;
    r->substeps = stf_h5r_attr_double(h, "substeps", &v) == 0 ? lround(v) : -1;
    r->nb = 0;
    if (stf_h5r_body_count(h) > 0) {
        int nb = stf_h5r_body_series(h, stf_h5r_body_name(h, 0), &r->bt, &r->bp, NULL, NULL, NULL, NULL);
        r->nb = nb > 0 ? nb : 0;
    }
    r->nf = stf_h5r_frames(h);
    r->ft = malloc(((size_t)r->nf + 1) * sizeof *r->ft);
    r->fc = malloc(((size_t)r->nf + 1) * 3 * sizeof *r->fc);
    int rc = r->ft && r->fc ? 0 : -1;
    for (int k = 0; k < r->nf && rc == 0; k++) {
        int n = stf_h5r_frame_count(h, k);
        double *x = malloc(((size_t)n + 1) * 3 * sizeof *x);
        if (!x || stf_h5r_read_frame(h, k, x, NULL) != 0) rc = -1;
        double c[3] = {0, 0, 0};
        for (int i = 0; rc == 0 && i < n; i++)
            for (int q = 0; q < 3; q++) c[q] += x[3 * i + q] / n;
        r->ft[k] = stf_h5r_frame_time(h, k);
        memcpy(r->fc + 3 * k, c, sizeof c);
        free(x);
    }
    stf_h5r_close(h);
    return rc;
}

/* RMS over the reference's samples of |p(t) - p_ref(t)|, p linearly interpolated in time. */
static double path_error(const double *t, const double *p, int n, const double *tr,
                         const double *pr, int nr)
{
    if (n < 2 || nr < 1) return NAN;
    double s = 0;
    int cnt = 0, j = 0;
    for (int k = 0; k < nr; k++) {
        if (tr[k] < t[0] || tr[k] > t[n - 1]) continue;
        while (j + 2 < n && t[j + 1] < tr[k]) j++;
        double u = t[j + 1] > t[j] ? (tr[k] - t[j]) / (t[j + 1] - t[j]) : 0;
        if (u < 0) u = 0;
        if (u > 1) u = 1;
        double d2 = 0;
        for (int q = 0; q < 3; q++) {
            double v = (1 - u) * p[3 * j + q] + u * p[3 * (j + 1) + q] - pr[3 * k + q];
            d2 += v * v;
        }
        s += d2;
        cnt++;
    }
    return cnt ? sqrt(s / cnt) : NAN;
}

/* The largest difference of the length metrics (bounce height, roll distance), in m, and
 * of the time metrics (contact, sink, float) times 1 m/s (so 10 ms counts as 1 cm), and a
 * bounce more or less as 1 cm. NaN on one side only counts as the other's value. Without
 * bodies: the fluid's rebound and finger height. */
static double metric_error(const stf_metrics *m, const stf_metrics *r)
{
    if (m->nbodies < 1 || r->nbodies < 1) /* drop and vibration scenes */
        return fmax(fabs(m->com_rebound_height - r->com_rebound_height),
                    fabs(m->finger_height - r->finger_height));
    const stf_body_metrics *a = &m->bodies[0], *b = &r->bodies[0];
    double v[6][2] = {{a->max_rebound_height, b->max_rebound_height},
                      {a->roll_distance, b->roll_distance},
                      {a->first_contact_time, b->first_contact_time},
                      {a->sink_time, b->sink_time},
                      {a->float_duration, b->float_duration},
                      {(double)a->bounces * 0.01, (double)b->bounces * 0.01}};
    double worst = 0;
    for (int k = 0; k < 6; k++) {
        double x = v[k][0], y = v[k][1], d;
        if (isnan(x) && isnan(y)) continue;
        d = isnan(x) ? fabs(y) : isnan(y) ? fabs(x) : fabs(x - y);
        if (d > worst) worst = d;
    }
    return worst;
}

static void free_run(acc_run *r)
{
    free(r->bt), free(r->bp), free(r->ft), free(r->fc);
    r->bt = r->bp = r->ft = r->fc = NULL;
}

static void plot_pareto(const char *path, acc_run *runs, int nruns, double budget)
{
    static const float BLACK[3] = {0, 0, 0}, GRID[3] = {0.85f, 0.85f, 0.85f},
                       WHITE[3] = {1, 1, 1}, RED[3] = {0.8f, 0.1f, 0.1f};
    static const float col[NKNOBS][3] = {{0.12f, 0.35f, 0.75f}, {0.9f, 0.5f, 0.05f}, {0.1f, 0.6f, 0.2f},
                                    {0.6f, 0.2f, 0.7f}};
    int W = 1000, H = 700, x0 = 110, x1 = 960, y0 = 80, y1 = 610;
    canvas *c = canvas_new(W, H);
    if (!c) return;
    canvas_fill(c, WHITE);
    double tmin = INFINITY, tmax = -INFINITY, emin = INFINITY, emax = -INFINITY;
    for (int i = 0; i < nruns; i++) {
        if (!runs[i].ok) continue;
        tmin = fmin(tmin, runs[i].cpu), tmax = fmax(tmax, runs[i].cpu);
        double e = fmax(runs[i].err_body, 1e-5);
        emin = fmin(emin, e), emax = fmax(emax, e);
    }
    if (!(tmax > 0)) {
        canvas_free(c);
        return;
    }
    emin = fmin(emin, budget), emax = fmax(emax, budget);
    double lt0 = floor(log10(tmin)), lt1 = ceil(log10(tmax)), le0 = floor(log10(emin)),
           le1 = ceil(log10(emax));
    if (lt1 <= lt0) lt1 = lt0 + 1;
    if (le1 <= le0) le1 = le0 + 1;
#define PX(t) (x0 + (x1 - x0) * (log10(t) - lt0) / (lt1 - lt0))
#define PY(e) (y1 - (y1 - y0) * (log10(e) - le0) / (le1 - le0))
    char buf[64];
    for (double d = lt0; d <= lt1 + 1e-9; d++) {
        double x = PX(pow(10, d));
        canvas_line(c, x, y0, x, y1, GRID, 1);
        snprintf(buf, sizeof buf, "%g", pow(10, d));
        canvas_text(c, (int)x - canvas_text_width(buf, 2) / 2, y1 + 10, buf, BLACK, 2);
    }
    for (double d = le0; d <= le1 + 1e-9; d++) {
        double y = PY(pow(10, d));
        canvas_line(c, x0, y, x1, y, GRID, 1);
        snprintf(buf, sizeof buf, "%g", pow(10, d));
        canvas_text(c, x0 - 10 - canvas_text_width(buf, 2), (int)y - 7, buf, BLACK, 2);
    }
    canvas_line(c, x0, y0, x1, y0, BLACK, 1.5), canvas_line(c, x0, y1, x1, y1, BLACK, 1.5);
    canvas_line(c, x0, y0, x0, y1, BLACK, 1.5), canvas_line(c, x1, y0, x1, y1, BLACK, 1.5);
    canvas_dashed_line(c, x0, PY(budget), x1, PY(budget), RED, 1.5, 8, 6);
    snprintf(buf, sizeof buf, "budget %g m", budget);
    canvas_text_halo(c, x1 - 10 - canvas_text_width(buf, 2), (int)PY(budget) - 20, buf, RED, WHITE, 2);
    canvas_text(c, x0, 20, "error vs cost (each knob against its finest setting)", BLACK, 2);
    canvas_text(c, x0, 44, "y: rms body path error, m (reference: 1e-5)   x: cpu time, s", BLACK, 2);
    for (int k = 0; k < NKNOBS; k++) {
        double px = 0, py = 0;
        char series[16] = "";
        for (int i = 0; i < nruns; i++) {
            if (!runs[i].ok || strcmp(runs[i].knob, KNOBS[k])) continue;
            /* one line per mode: window d, soe K (full and its 0 error stand alone) */
            char mode[16]; /* the setting's first word, at most 15 characters */
            size_t len = strcspn(runs[i].setting, " =");
            if (len >= sizeof mode) len = sizeof mode - 1;
            memcpy(mode, runs[i].setting, len);
            mode[len] = 0;
            double x = PX(runs[i].cpu), y = PY(fmax(runs[i].err_body, 1e-5));
            if (!strcmp(series, mode)) canvas_line(c, px, py, x, y, col[k], 2);
            canvas_circle(c, x, y, 5, col[k]);
            canvas_text_halo(c, (int)x + 8, (int)y - 7 - 10 * (i % 2), runs[i].setting, col[k], WHITE, 1);
            px = x, py = y;
            snprintf(series, sizeof series, "%s", mode);
        }
        canvas_circle(c, x0 + 35 + 220 * k, y1 + 57, 5, col[k]);
        canvas_text(c, x0 + 48 + 220 * k, y1 + 50, KNOBS[k], BLACK, 2);
    }
#undef PX
#undef PY
    char err[512];
    if (canvas_write_png(c, path, err, sizeof err) != 0) fprintf(stderr, "stf bench: %s\n", err);
    canvas_free(c);
}

static int bench_accuracy(const bench_args *a, const char *self)
{
    char err[2048];
    stf_scene *sc;
    if (stf_scene_load(a->scene, a->ov, a->nov, &sc, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        return 2;
    }
    double dt = sc->dt, sp = sc->fluid.spacing;
    int hist = (sc->fluid.effects & STF_EFFECT_HISTORY) != 0;
    int cy = sc->fluid.model == STF_MODEL_CARREAU_YASUDA;
    double eta = sc->fluid.cy.eta, cg_tol = sc->fluid.cy.cg_tolerance;
    double duration = a->duration > 0 ? a->duration : a->full ? sc->duration : fmin(sc->duration, 0.6);
    stf_scene_free(sc);
    /* the finest dt run (dt / 4) takes the most steps */
    const char *knobs_in = a->knobs ? a->knobs : "dt";
    if (check_duration(a, duration, strstr(knobs_in, "dt") ? dt / 4 : dt, "its duration") != 0)
        return 2;
    /* Short by default: the spacing the cli_bowling test uses and 0.6 s (the impact). */
    double base_sp = a->full ? sp : fmax(sp, 0.025);
    const char *dir = a->out ? a->out : "bench_accuracy";
    const char *knobs = a->knobs ? a->knobs : "dt,spacing,history,solver";
    acc_run runs[64];
    int nruns = 0;
    memset(runs, 0, sizeof runs);
    /* Settings, finest first: the first of each knob is its reference. */
    for (int k = 0; k < NKNOBS; k++) {
        if (!strstr(knobs, KNOBS[k]) || (k == 2 && !hist) || (k == 3 && !cy)) continue;
        int first = nruns;
        if (k == 0) {
            static const double f[] = {0.25, 0.5, 1.0, 2.0};
            for (int i = 0; i < 4; i++) {
                acc_run *r = &runs[nruns++];
                strcpy(r->knob, "dt");
                r->value = dt * f[i];
                snprintf(r->setting, sizeof r->setting, "dt=%g", r->value);
            }
        } else if (k == 1) {
            static const double f[] = {0.6, 0.8, 1.0, 1.4};
            for (int i = 0; i < 4; i++) {
                acc_run *r = &runs[nruns++];
                strcpy(r->knob, "spacing");
                r->value = base_sp * f[i];
                snprintf(r->setting, sizeof r->setting, "spacing=%.4g", r->value);
            }
        } else if (k == 3) {
            /* the Carreau-Yasuda solvers' tolerances (pressure projection eta, implicit
               viscosity cg_tolerance) times f, finest first: their iterations are the cost */
            static const double f[] = {0.1, 0.3, 1.0, 3.0};
            for (int i = 0; i < 4; i++) {
                if (!(eta * f[i] < 1 && cg_tol * f[i] < 1)) continue; /* both must be < 1 */
                acc_run *r = &runs[nruns++];
                strcpy(r->knob, "solver");
                r->value = f[i];
                snprintf(r->setting, sizeof r->setting, "tolerances x%g", f[i]);
            }
        } else {
            static const char *const s[] = {"full", "window d=500", "window d=150", "window d=50",
                                            "window d=10", "soe K=16", "soe K=8", "soe K=4"};
            for (int i = 0; i < 8; i++) {
                acc_run *r = &runs[nruns++];
                strcpy(r->knob, "history");
                snprintf(r->setting, sizeof r->setting, "%s", s[i]);
            }
        }
        (void)first;
    }
    if (nruns == 0) {
        fprintf(stderr, "stf bench accuracy: no knob of '%s' applies to %s (history needs "
                "effects.history; solver needs the carreau_yasuda model)\n", knobs, a->scene);
        return 2;
    }
    if (mkdir(dir, 0777) != 0 && errno != EEXIST) {
        fprintf(stderr, "stf bench: cannot create %s: %s\n", dir, strerror(errno));
        return 2;
    }
    printf("# stf bench accuracy %s: %.3g s simulated, base spacing %g m, base dt %g s\n", a->scene,
           duration, base_sp, dt);
    print_load();
    for (int i = 0; i < nruns; i++) {
        acc_run *r = &runs[i];
        char path[1024], v1[64], v2[64], v3[64], v4[64];
        snprintf(path, sizeof path, "%s/run%02d.h5", dir, i);
        const char *extra[12];
        int ne = 0;
        snprintf(v1, sizeof v1, "fluid.spacing=%.9g", !strcmp(r->knob, "spacing") ? r->value : base_sp);
        extra[ne++] = "--set", extra[ne++] = v1;
        if (!strcmp(r->knob, "dt")) {
            snprintf(v2, sizeof v2, "dt=%.9g", r->value);
            extra[ne++] = "--set", extra[ne++] = v2;
        }
        if (!strcmp(r->knob, "solver")) {
            snprintf(v2, sizeof v2, "effects.carreau_yasuda.eta=%.9g", eta * r->value);
            snprintf(v4, sizeof v4, "effects.carreau_yasuda.cg_tolerance=%.9g", cg_tol * r->value);
            extra[ne++] = "--set", extra[ne++] = v2;
            extra[ne++] = "--set", extra[ne++] = v4;
        }
        if (!strcmp(r->knob, "history")) {
            if (!strncmp(r->setting, "full", 4)) {
                extra[ne++] = "--set", extra[ne++] = "effects.history.mode=full";
            } else if (!strncmp(r->setting, "window", 6)) {
                snprintf(v2, sizeof v2, "effects.history.d=%s", r->setting + 9);
                extra[ne++] = "--set", extra[ne++] = "effects.history.mode=window";
                extra[ne++] = "--set", extra[ne++] = v2;
            } else {
                snprintf(v3, sizeof v3, "effects.history.terms=%s", r->setting + 6);
                extra[ne++] = "--set", extra[ne++] = "effects.history.mode=soe";
                extra[ne++] = "--set", extra[ne++] = v3;
            }
        }
        int rc = spawn_run(self, a->scene, path, a, extra, ne, duration, &r->cpu);
        r->ok = (rc == 0 || rc == 3) && read_run(path, r) == 0;
        if (rc == 3) r->ok = 0;
        fprintf(stderr, "  %-8s %-18s %s, %.1f s wall, %.1f s cpu\n", r->knob, r->setting,
                r->ok ? "ok" : rc == 3 ? "numerical failure" : "failed", r->wall, r->cpu);
    }
    /* Errors against the first (finest) run of the same knob. */
    char csv[1024];
    snprintf(csv, sizeof csv, "%s/accuracy.csv", dir);
    FILE *fc = fopen(csv, "w");
    if (!fc) {
        fprintf(stderr, "stf bench: cannot write %s\n", csv);
        return 2;
    }
    fprintf(fc, "knob,setting,wall_s,cpu_s,err_body_path_m,err_fluid_com_m,err_metrics,bounces,"
                "max_rebound_height_m,first_contact_s,sink_time_s,float_duration_s,roll_distance_m,"
                "com_rebound_height_m\n");
    printf("%-8s %-18s %9s %9s %12s %12s %12s %7s %9s %9s\n", "knob", "setting", "wall s", "cpu s",
           "body path m", "fluid com m", "metrics", "bounces", "rebound", "sink s");
    for (int i = 0; i < nruns; i++) {
        acc_run *r = &runs[i];
        int ref = i;
        while (ref > 0 && !strcmp(runs[ref - 1].knob, r->knob)) ref--;
        const acc_run *R = &runs[ref];
        if (!r->ok || !R->ok) {
            fprintf(fc, "%s,%s,,,,,,,,,,,,\n", r->knob, r->setting);
            printf("%-8s %-18s   (failed)\n", r->knob, r->setting);
            continue;
        }
        r->err_body = r->nb ? path_error(r->bt, r->bp, r->nb, R->bt, R->bp, R->nb)
                            : path_error(r->ft, r->fc, r->nf, R->ft, R->fc, R->nf);
        r->err_com = path_error(r->ft, r->fc, r->nf, R->ft, R->fc, R->nf);
        r->err_metric = metric_error(&r->m, &R->m);
        const stf_body_metrics *b = r->m.nbodies ? &r->m.bodies[0] : NULL;
        fprintf(fc, "%s,%s,%.4f,%.4f,%.6g,%.6g,%.6g,%d,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", r->knob,
                r->setting, r->wall, r->cpu, r->err_body, r->err_com, r->err_metric, b ? b->bounces : 0,
                b ? b->max_rebound_height : NAN, b ? b->first_contact_time : NAN,
                b ? b->sink_time : NAN, b ? b->float_duration : NAN, b ? b->roll_distance : NAN,
                r->m.com_rebound_height);
        printf("%-8s %-18s %9.2f %9.2f %12.5f %12.5f %12.5f %7d %9.4f %9.4f\n", r->knob, r->setting,
               r->wall, r->cpu, r->err_body, r->err_com, r->err_metric, b ? b->bounces : 0,
               b ? b->max_rebound_height : NAN, b ? b->sink_time : NAN);
    }
    fclose(fc);
    /* The cheapest setting within the budget, per knob (its reference excluded). */
    for (int i = 0; i < nruns;) {
        int j = i, best = -1;
        while (j < nruns && !strcmp(runs[j].knob, runs[i].knob)) {
            if (j > i && runs[j].ok && runs[j].err_body <= a->error &&
                (best < 0 || runs[j].cpu < runs[best].cpu))
                best = j;
            j++;
        }
        if (best >= 0)
            printf("cheapest %-8s within %g m: %s (%.2f s cpu, error %.4f m; reference %s %.2f s cpu)\n",
                   runs[i].knob, a->error, runs[best].setting, runs[best].cpu, runs[best].err_body,
                   runs[i].setting, runs[i].cpu);
        else
            printf("cheapest %-8s within %g m: none but the reference %s\n", runs[i].knob, a->error,
                   runs[i].setting);
        i = j;
    }
    char png[1024];
    snprintf(png, sizeof png, "%s/accuracy.png", dir);
    plot_pareto(png, runs, nruns, a->error);
    printf("# wrote %s and %s\n", csv, png);
    for (int i = 0; i < nruns; i++) free_run(&runs[i]);
    return 0;
}

/* --------------------------------------------------------------------- convergence */

/* The runs of `stf bench convergence`: the scene's dt and spacing times these factors. The
 * dt/4 run is the finest, the one each metric is held against. */
enum { NCONV = 4, CONV_FINEST = 2 };
static const char *const conv_names[NCONV] = {"dt", "dt/2", "dt/4", "1.5x_spacing"};
static const double conv_dt[NCONV] = {1, 0.5, 0.25, 1}, conv_sp[NCONV] = {1, 1, 1, 1.5};


/* One metric row: its key for stf_metrics_get, its name in the lists of metrics.h, and its
 * body (index into the metrics' bodies, -1 for the fluid). */
typedef struct conv_row {
    char key[96];
    const char *field;
    int body;
} conv_row;

/* The verdict on one metric over the runs that ended (ran[i]), values v (NAN for null):
 * 1 ok, 0 not within the tolerance, -1 not judged (the finest run failed, or the metric is
 * set by the resolution). The spread column's text goes to spread, the spread in % to *pct and
 * max - min to *range (NAN when undefined). scale: the absolute scale when the finest value
 * is 0 (see the usage). */
static int conv_judge(const conv_row *row, const double *v, const int *ran, double tol,
                      double scale, char *spread, size_t len, double *range, double *pct)
{
    int nran = 0, ndef = 0;
    double lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i < NCONV; i++) {
        if (!ran[i]) continue;
        nran++;
        if (isnan(v[i])) continue;
        ndef++;
        lo = fmin(lo, v[i]), hi = fmax(hi, v[i]);
    }
    *range = ndef ? hi - lo : NAN;
    *pct = NAN;
    snprintf(spread, len, "-");
    if (!ran[CONV_FINEST]) return -1;
    if (ndef == 0) {
        snprintf(spread, len, "n/a");
        return 1;
    }
    if (ndef < nran) {
        snprintf(spread, len, "DIFFERS");
        return 0;
    }
    double f = v[CONV_FINEST];
    if (f != 0 || hi == lo) {
        *pct = f != 0 ? 100 * (hi - lo) / fabs(f) : 0;
        snprintf(spread, len, "%.3g%%", *pct);
    }
    int count = !strcmp(cli_metric_unit(row->field), "count");
    if (row->body < 0 && !strcmp(row->field, "particles")) return -1;
    for (int i = 0; i < NCONV; i++) {
        if (!ran[i]) continue;
        int ok = count ? v[i] == f || (v[i] >= 1 && f >= 1)
                 : f != 0 ? fabs(v[i] - f) <= tol * fabs(f)
                          : fabs(v[i]) <= tol * scale;
        if (!ok) return 0;
    }
    return 1;
}

/* A value as the table shows it: counts whole, null as "null". */
static void conv_value(char *buf, size_t len, double v, int count)
{
    if (isnan(v)) snprintf(buf, len, "null");
    else if (count) snprintf(buf, len, "%.0f", v);
    else snprintf(buf, len, "%.5g", v);
}

static int bench_convergence(const bench_args *a, const char *self)
{
    char err[2048];
    stf_scene *sc;
    if (stf_scene_load(a->scene, a->ov, a->nov, &sc, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        return 2;
    }
    double dt = sc->dt, sp = sc->fluid.spacing;
    double duration = a->duration > 0 ? a->duration : sc->duration;
    int steps_memory = (sc->fluid.effects & STF_EFFECT_HISTORY) &&
                       sc->fluid.history_mode == STF_HISTORY_WINDOW && !(sc->fluid.memory > 0);
    int d = sc->fluid.d;
    char dirbuf[128];
    snprintf(dirbuf, sizeof dirbuf, "convergence-%s", sc->name);
    stf_scene_free(sc);
    if (check_duration(a, duration, dt * conv_dt[CONV_FINEST], "its duration") != 0) return 2;
    if (steps_memory)
        fprintf(stderr, "memory given in steps (d = %d): dt/2 and dt/4 change the memory in "
                "seconds; give effects.history.memory\n", d);
    const char *dir = a->out ? a->out : dirbuf;
    if (mkdir(dir, 0777) != 0 && errno != EEXIST) {
        fprintf(stderr, "stf bench: cannot create %s: %s\n", dir, strerror(errno));
        return 2;
    }
    printf("# stf bench convergence %s: %.4g s simulated, dt %g s, spacing %g m, tolerance %g%% "
           "of the dt/4 run\n", a->scene, duration, dt, sp, 100 * a->tolerance);
    print_load();
    fflush(stdout);

    /* The runs, at most --jobs at a time. */
    acc_run runs[NCONV];
    memset(runs, 0, sizeof runs);
    char path[NCONV][1024], vdt[NCONV][64], vsp[NCONV][64];
    int code[NCONV], ran[NCONV] = {0};
    pid_t pid[NCONV];
    int started = 0, running = 0, ended = 0;
    for (int i = 0; i < NCONV; i++) {
        runs[i].value = dt * conv_dt[i];
        snprintf(path[i], sizeof path[i], "%s/run%d.h5", dir, i);
        snprintf(vdt[i], sizeof vdt[i], "dt=%.17g", dt * conv_dt[i]);
        snprintf(vsp[i], sizeof vsp[i], "fluid.spacing=%.17g", sp * conv_sp[i]);
        code[i] = -1;
        pid[i] = -1;
    }
    while (ended < NCONV) {
        while (running < a->jobs && started < NCONV) {
            int i = started++;
            const char *extra[4] = {"--set", vdt[i], "--set", vsp[i]};
            if (spawn_start(self, a->scene, path[i], a, extra, 4, duration, &pid[i]) == 0) {
                running++;
                continue;
            }
            fprintf(stderr, "  %-12s cannot start %s\n", conv_names[i], self);
            ended++;
        }
        if (!running) continue;
        pid_t got = -1;
        double cpu = 0;
        int rc = spawn_wait(&got, &cpu);
        int i = 0;
        while (i < NCONV && (got < 0 || pid[i] != got)) i++;
        if (i == NCONV) { /* no child left to wait for: the others count as failed */
            fprintf(stderr, "stf bench convergence: lost track of the runs: %s\n", strerror(errno));
            break;
        }
        running--, ended++;
        pid[i] = -1;
        code[i] = rc;
        runs[i].cpu = cpu;
        ran[i] = rc == 0 && read_run(path[i], &runs[i]) == 0;
        if (ran[i])
            fprintf(stderr, "  %-12s dt %g s, spacing %g m: ok, %.1f s wall, %.1f s cpu\n",
                    conv_names[i], dt * conv_dt[i], sp * conv_sp[i], runs[i].wall, cpu);
        else
            fprintf(stderr, "  %-12s dt %g s, spacing %g m: %s (exit %d), %.1f s cpu\n",
                    conv_names[i], dt * conv_dt[i], sp * conv_sp[i],
                    rc == 3 ? "numerical failure" : "failed", rc, cpu);
    }

    /* The metric rows: each body's (the scene's bodies, the same in every run), the fluid's. */
    const stf_metrics *mref = NULL;
    for (int i = NCONV - 1; i >= 0; i--)
        if (ran[i]) mref = &runs[i].m;
    if (ran[CONV_FINEST]) mref = &runs[CONV_FINEST].m;
    int nbody = 0, nfluid = 0;
    while (stf_body_metric_names[nbody]) nbody++;
    while (stf_fluid_metric_names[nfluid]) nfluid++;
    int nb = mref ? mref->nbodies : 0, nrows = 0;
    conv_row *rows = malloc(((size_t)nb * (size_t)nbody + (size_t)nfluid) * sizeof *rows);
    if (!rows) {
        fprintf(stderr, "stf bench convergence: out of memory\n");
        return 2;
    }
    for (int b = 0; b < nb; b++)
        for (int k = 0; k < nbody; k++, nrows++) {
            snprintf(rows[nrows].key, sizeof rows[nrows].key, "%s.%s", mref->bodies[b].name,
                     stf_body_metric_names[k]);
            rows[nrows].field = stf_body_metric_names[k];
            rows[nrows].body = b;
        }
    for (int k = 0; k < nfluid; k++, nrows++) {
        snprintf(rows[nrows].key, sizeof rows[nrows].key, "fluid.%s", stf_fluid_metric_names[k]);
        rows[nrows].field = stf_fluid_metric_names[k];
        rows[nrows].body = -1;
    }

    char csv[1100];
    snprintf(csv, sizeof csv, "%s/convergence.csv", dir);
    FILE *fc = fopen(csv, "w");
    if (!fc) {
        fprintf(stderr, "stf bench: cannot write %s\n", csv);
        free(rows);
        for (int i = 0; i < NCONV; i++) free_run(&runs[i]);
        return 2;
    }
    fprintf(fc, "metric,unit");
    printf("%-28s %-13s", "metric", "unit");
    for (int i = 0; i < NCONV; i++) fprintf(fc, ",%s", conv_names[i]), printf(" %12s", conv_names[i]);
    fprintf(fc, ",range,spread_percent,ok\n");
    printf(" %11s %9s %4s\n", "range", "spread", "ok");
    int failed = 0, judged = 0;
    for (int r = 0; r < nrows; r++) {
        const conv_row *row = &rows[r];
        const char *unit = cli_metric_unit(row->field);
        int count = !strcmp(unit, "count");
        double v[NCONV];
        for (int i = 0; i < NCONV; i++)
            if (!ran[i] || stf_metrics_get(&runs[i].m, row->key, &v[i]) != 0) v[i] = NAN;
        double scale = !strcmp(unit, "s") ? duration
                       : strcmp(unit, "m") ? 1.0
                       : row->body >= 0 ? mref->bodies[row->body].radius
                                        : sp;
        char spread[32], buf[32];
        double range, pct;
        int ok = conv_judge(row, v, ran, a->tolerance, scale, spread, sizeof spread, &range, &pct);
        judged += ok >= 0;
        if (ok == 0) failed++;
        printf("%-28s %-13s", row->key, unit);
        fprintf(fc, "%s,%s", row->key, unit);
        for (int i = 0; i < NCONV; i++) {
            conv_value(buf, sizeof buf, v[i], count);
            printf(" %12s", ran[i] ? buf : "failed");
            if (!ran[i]) fprintf(fc, ",failed");
            else if (isnan(v[i])) fprintf(fc, ",");
            else fprintf(fc, ",%.9g", v[i]);
        }
        conv_value(buf, sizeof buf, range, count);
        const char *verdict = ok > 0 ? "yes" : ok == 0 ? "no" : "-";
        printf(" %11s %9s %4s\n", isnan(range) ? "-" : buf, spread, verdict);
        if (isnan(range)) fprintf(fc, ",");
        else fprintf(fc, ",%.9g", range);
        if (!isnan(pct)) fprintf(fc, ",%.9g", pct);
        else if (spread[0] == '-') fprintf(fc, ",");
        else fprintf(fc, ",%s", spread);
        fprintf(fc, ",%s\n", verdict);
    }
    /* Each run's settings and cost. */
    static const char *const run_rows[7] = {"run.dt", "run.spacing", "run.wall", "run.cpu",
                                            "run.steps", "run.substeps", "run.particles"};
    static const char *const run_units[7] = {"s", "m", "s", "s", "count", "count", "count"};
    for (int k = 0; k < 7; k++) {
        printf("%-28s %-13s", run_rows[k], run_units[k]);
        fprintf(fc, "%s,%s", run_rows[k], run_units[k]);
        for (int i = 0; i < NCONV; i++) {
            const acc_run *R = &runs[i];
            double x = k == 0 ? dt * conv_dt[i] : k == 1 ? sp * conv_sp[i] : !ran[i] ? NAN
                       : k == 2 ? R->wall : k == 3 ? R->cpu : k == 4 ? (double)R->steps
                       : k == 5 ? (double)R->substeps : (double)R->m.particles;
            if (k == 3 && code[i] >= 0) x = R->cpu; /* a failed run's cpu is still its own */
            if (k >= 4 && x < 0) x = NAN;       /* not in the file */
            char buf[32];
            if (k == 2 || k == 3) snprintf(buf, sizeof buf, isnan(x) ? "-" : "%.2f", x);
            else conv_value(buf, sizeof buf, x, k >= 4);
            printf(" %12s", buf);
            if (isnan(x)) fprintf(fc, ",");
            else fprintf(fc, ",%.9g", x);
        }
        printf(" %11s %9s %4s\n", "", "", "-");
        fprintf(fc, ",,,-\n");
    }
    fclose(fc);

    int rc = failed ? 1 : 0;
    for (int i = 0; i < NCONV; i++) {
        if (ran[i]) continue;
        fprintf(stderr, "stf bench convergence: run %s (dt %g s, spacing %g m, %s) %s\n",
                conv_names[i], dt * conv_dt[i], sp * conv_sp[i], path[i],
                code[i] == 3 ? "failed numerically" : code[i] == 2 ? "refused its settings"
                : code[i] == 0 ? "wrote a file that cannot be read"
                               : "failed (killed, or could not start)");
        int c = code[i] == 2 ? 2 : 3;
        if (c > rc) rc = c;
    }
    printf("# %d of %d metrics judged within %g%% of the dt/4 run%s; wall, cpu: s of each run "
           "(cpu: user + system of the child process)\n", judged - failed, judged, 100 * a->tolerance,
           rc >= 2 ? " (a run failed)" : "");
    printf("# wrote %s\n", csv);
    free(rows);
    for (int i = 0; i < NCONV; i++) free_run(&runs[i]);
    return rc;
}

/* ------------------------------------------------------------------------------ dam */

/* The Carreau-Yasuda solver on a scene for `duration` simulated seconds with `threads`
 * threads: one row of the table against SPlisHSPlasH (tools/README.md). Returns 0, 2 bad
 * scene, 3 numerical failure. */
static int dam_row(const bench_args *a, double duration, int threads)
{
    char err[2048];
    stf_scene *sc;
    if (stf_scene_load(a->scene, a->ov, a->nov, &sc, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        return 2;
    }
    if (sc->fluid.model != STF_MODEL_CARREAU_YASUDA) {
        fprintf(stderr, "stf bench dam: %s: needs fluid.model: carreau_yasuda\n", a->scene);
        stf_scene_free(sc);
        return 2;
    }
    stf_set_threads(threads);
    stf_sim *sim;
    if (stf_sim_create(sc, &sim, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        stf_scene_free(sc);
        return 2;
    }
    long steps = lround(duration / sc->dt), substeps = 0, iters = 0;
    double err_sum = 0, err_max = 0, dt_min = sc->dt, dt_max = 0, cfl = 0;
    int rc = 0;
    long rebuilds0 = sim->fluid->grid.rebuilds;
    double t0 = omp_get_wtime(), c0 = cpu_seconds();
    for (long s = 0; s < steps && rc == 0; s++) {
        rc = stf_sim_step(sim);
        stf_solver_stats st = sim->step_stats; /* all the fluid steps of the step */
        substeps += st.substeps;
        iters += st.pressure_iterations_total;
        err_sum += st.density_error_sum;
        err_max = st.density_error_max > err_max ? st.density_error_max : err_max;
        dt_min = st.dt_min < dt_min ? st.dt_min : dt_min;
        dt_max = st.dt_max > dt_max ? st.dt_max : dt_max;
        cfl = st.cfl_number > cfl ? st.cfl_number : cfl;
    }
    double wall = omp_get_wtime() - t0, cpu = cpu_seconds() - c0, T = (double)steps * sc->dt;
    if (rc != 0) {
        fprintf(stderr, "stf bench dam: numerical failure: %s\n", stf_fluid_failure(sim->fluid));
        rc = 3;
    } else {
        struct rusage ru;
        getrusage(RUSAGE_SELF, &ru);
        printf("%7d %8d %10.2f %10.2f %9.1f %8.2f %8.2f %9.3f %9.3f %9.2e %9.2e %7.3f %8.1f %8.2f\n",
               threads, stf_fluid_count(sim->fluid), wall / T, cpu / T, (double)substeps / T,
               1e3 * wall / (double)substeps, (double)iters / (double)substeps,
               100 * err_sum / (double)substeps, 100 * err_max, dt_min, dt_max, cfl,
               (double)ru.ru_maxrss / 1024.0,
               (double)(sim->fluid->grid.rebuilds - rebuilds0) / (double)substeps);
        fflush(stdout);
    }
    stf_sim_destroy(sim);
    stf_scene_free(sc);
    return rc;
}

static int bench_dam(const bench_args *a)
{
    double duration = a->duration > 0 ? a->duration : 0.2;
    char err[2048];
    stf_scene *sc;
    if (stf_scene_load(a->scene, a->ov, a->nov, &sc, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        return 2;
    }
    int bad_steps = check_duration(a, duration, sc->dt, "the default duration, 0.2 s,");
    stf_scene_free(sc);
    if (bad_steps) return 2;
    printf("# stf bench dam %s: %.3g simulated s from rest (--duration)\n", a->scene, duration);
    print_load();
    printf("%7s %8s %10s %10s %9s %8s %8s %9s %9s %9s %9s %7s %8s %8s\n", "threads", "n",
           "wall s/s", "cpu s/s", "steps/s", "ms/step", "p.iter", "err mean%", "err max%",
           "dt min s", "dt max s", "cfl", "maxrss MB", "rebuilds");
    int counts[2] = {1, 2}, nc = 2;
    if (a->threads) counts[0] = a->threads, nc = 1;
    for (int k = 0; k < nc; k++) {
        int rc = dam_row(a, duration, counts[k]);
        if (rc) return rc;
    }
    print_load();
    printf("# wall s/s: wall seconds per simulated second; steps/s: solver substeps per simulated "
           "second; p.iter: pressure iterations per substep; err: mean compression after the "
           "projection (mean over substeps, and the largest); cfl: largest v_max dt / h; maxrss: "
           "peak resident memory of this process so far (getrusage); rebuilds: neighbour "
           "candidate rebuilds per substep\n");
    return 0;
}

int cli_bench(int argc, char **argv)
{
    /* stf bench --help, stf bench NAME ... --help */
    if (cli_help_asked(argc, argv)) return cli_help(usage_for(argc >= 1 ? argv[0] : NULL));
    bench_args a;
    if (parse(argc, argv, &a) != 0) return 2;
    if (a.threads) stf_set_threads(a.threads);
    if (!strcmp(a.what, "table1")) return bench_table1(&a);
    if (!strcmp(a.what, "effects")) return bench_effects(&a);
    if (!strcmp(a.what, "scaling")) return bench_scaling(&a);
    if (!strcmp(a.what, "grid")) return bench_grid(&a);
    if (!strcmp(a.what, "dam")) return bench_dam(&a);
    char self[4096];
    ssize_t len = readlink("/proc/self/exe", self, sizeof self - 1);
    if (len <= 0) {
        fprintf(stderr, "stf bench: cannot find this executable (/proc/self/exe)\n");
        return 2;
    }
    self[len] = 0;
    if (!strcmp(a.what, "convergence")) return bench_convergence(&a, self);
    return bench_accuracy(&a, self);
}
