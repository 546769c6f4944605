/* run.c - `stf run` and `stf check`: simulate a scene into an HDF5 file. */
#include <math.h>
#include <omp.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "h5io.h"
#include "metrics.h"
#include "stf_sim.h"

typedef struct run_args {
    const char *scene, *out;
    stf_override ov[256];
    int nov;
    double duration; /* s, 0: the scene's */
    int threads, quiet;
} run_args;

static volatile sig_atomic_t interrupted;
static void on_signal(int sig) { interrupted = sig; }

static int bad_flag(const char *msg, const char *arg)
{
    fprintf(stderr, "stf: %s '%s'\n", msg, arg);
    return 2;
}

static int parse_args(int argc, char **argv, run_args *a)
{
    memset(a, 0, sizeof *a);
    for (int i = 0; i < argc; i++) {
        const char *s = argv[i];
        int more = i + 1 < argc;
        if ((!strcmp(s, "-o") || !strcmp(s, "--out")) && more) a->out = argv[++i];
        else if (!strcmp(s, "--set") && more) {
            char *eq = strchr(argv[++i], '=');
            if (!eq) return bad_flag("--set needs KEY=VALUE, got", argv[i]);
            if (a->nov == 256) return bad_flag("too many overrides at", argv[i]);
            *eq = 0;
            a->ov[a->nov].key = argv[i];
            a->ov[a->nov++].value = eq + 1;
        } else if (!strcmp(s, "--unset") && more) {
            if (a->nov == 256) return bad_flag("too many overrides at", argv[i + 1]);
            a->ov[a->nov].key = argv[++i];
            a->ov[a->nov++].value = NULL;
        } else if (!strcmp(s, "--duration") && more) {
            char *end;
            a->duration = strtod(argv[++i], &end);
            if (*end || !(a->duration > 0) || !isfinite(a->duration))
                return bad_flag("--duration must be a number of seconds > 0, got", argv[i]);
        } else if (!strcmp(s, "--threads") && more) {
            char *end;
            long t = strtol(argv[++i], &end, 10);
            if (*end || t < 1 || t > 1024)
                return bad_flag("--threads must be an integer in [1,1024], got", argv[i]);
            a->threads = (int)t;
        } else if (!strcmp(s, "--quiet") || !strcmp(s, "-q")) a->quiet = 1;
        else if (s[0] == '-') return bad_flag("unknown or incomplete option", s);
        else if (!a->scene) a->scene = s;
        else return bad_flag("unexpected argument", s);
    }
    if (!a->scene) {
        fprintf(stderr, "stf: no scene file given\n");
        return 2;
    }
    return 0;
}

/* Refuses an output path that would destroy something that is not a previous output: the
 * scene file itself, or an existing non-empty file without the HDF5 signature (a typo in
 * -o must not eat a scene or a note). Returns 0 or 2 with a message. */
static int check_output(const char *out, const char *scene)
{
    struct stat so, ss;
    if (stat(out, &so) != 0) return 0; /* does not exist (or its directory does not: create fails later) */
    if (stat(scene, &ss) == 0 && so.st_dev == ss.st_dev && so.st_ino == ss.st_ino) {
        fprintf(stderr, "stf: %s: the output would overwrite the scene file\n", out);
        return 2;
    }
    if (!S_ISREG(so.st_mode) || so.st_size == 0) return 0; /* create reports directories */
    static const unsigned char sig[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
    unsigned char head[8] = {0};
    FILE *fp = fopen(out, "rb");
    size_t got = fp ? fread(head, 1, sizeof head, fp) : 0;
    if (fp) fclose(fp);
    if (got == sizeof head && !memcmp(head, sig, sizeof sig)) return 0;
    fprintf(stderr, "stf: %s: exists and is not an HDF5 file; not overwriting it (remove it or "
                    "choose another -o)\n", out);
    return 2;
}

static char *default_out(const stf_scene *sc)
{
    size_t len = strlen(sc->name) + 4;
    char *p = malloc(len);
    if (p) snprintf(p, len, "%s.h5", sc->name);
    return p;
}

/* Root attributes a reader needs to make sense of the file. */
static int write_header(stf_h5 *h, const stf_sim *sim)
{
    const stf_scene *sc = sim->scene;
    int rc = stf_h5_attr_string(h, "scene", sc->text ? sc->text : "");
    rc |= stf_h5_attr_string(h, "scene_path", sc->path);
    rc |= stf_h5_attr_string(h, "version", STF_VERSION);
    char params[4096];
    stf_fluid_describe(sim->fluid, params, sizeof params);
    rc |= stf_h5_attr_string(h, "parameters", params);
    rc |= stf_h5_attr_double(h, "spacing", sc->fluid.spacing);
    rc |= stf_h5_attr_double(h, "dt", sc->dt);
    rc |= stf_h5_attr_double(h, "particle_mass", stf_fluid_particle_mass(sim->fluid));
    rc |= stf_h5_attr_double(h, "bounce_min_rise", sc->bounce_min_rise);
    rc |= stf_h5_attr_long(h, "history_steps", stf_fluid_history_steps(sim->fluid));
    rc |= stf_h5_attr_long(h, "removed_at_setup", sim->removed);
    if (sc->container.present) {
        const stf_container_def *c = &sc->container;
        rc |= stf_h5_attr_double(h, "container_x0", c->position[0] - c->size[0] / 2);
        rc |= stf_h5_attr_double(h, "container_x1", c->position[0] + c->size[0] / 2);
        rc |= stf_h5_attr_double(h, "container_y0", c->position[1] - c->size[1] / 2);
        rc |= stf_h5_attr_double(h, "container_y1", c->position[1] + c->size[1] / 2);
        rc |= stf_h5_attr_double(h, "container_z0", c->position[2]);
        rc |= stf_h5_attr_double(h, "container_z1", c->position[2] + 2 * c->size[2]);
    }
    for (int k = 0; k < sc->nbodies; k++) {
        const stf_body_def *b = &sc->bodies[k];
        char key[128];
        double hh = b->shape.shape == STF_SHAPE_BOX ? b->shape.half[2]
                    : b->shape.shape == STF_SHAPE_SPHERE ? b->shape.radius
                                                         : b->shape.radius + b->shape.half_length;
        snprintf(key, sizeof key, "body.%s.half_height", b->name);
        rc |= stf_h5_attr_double(h, key, hh);
        if (k == 0) rc |= stf_h5_attr_string(h, "first_body", b->name);
    }
    return rc;
}

typedef struct frame_buf {
    double *x, *v;
    float *k;
    int32_t *id;
} frame_buf;

static int write_frame(stf_h5 *h, const stf_sim *sim, frame_buf *b)
{
    const stf_fluid *f = sim->fluid;
    int n = stf_fluid_count(f);
    stf_fluid_get_positions(f, b->x);
    stf_fluid_get_velocities(f, b->v);
    stf_fluid_get_history_stiffness(f, b->k);
    stf_fluid_get_ids(f, b->id);
    return stf_h5_write_frame(h, stf_fluid_time(f), n, b->x, b->v, b->k, b->id);
}

static int write_bodies(stf_h5 *h, const stf_sim *sim)
{
    for (int k = 0; k < sim->scene->nbodies; k++) {
        double p[3], q[4], v[3], w[3], F[3];
        stf_sim_body_state(sim, k, p, q, v, w, F);
        if (stf_h5_body_append(h, sim->scene->bodies[k].name, sim->time, p, q, v, w, F) != 0)
            return -1;
    }
    return 0;
}

static void progress(const run_args *a, const stf_sim *sim, double end, double wall)
{
    if (a->quiet || !isatty(2)) return;
    fprintf(stderr, "\r  t = %7.3f / %.3f s   %6.1f%%   %.1f s wall ", sim->time, end,
            100.0 * sim->time / end, wall);
}

int cli_expectation_holds(const stf_expectation *e, const stf_metrics *m, double *value)
{
    double v;
    if (stf_metrics_get(m, e->key, &v) != 0) return -1;
    *value = v;
    if (isnan(v)) return 0; /* a null metric (never happened) holds no comparison */
    if (!strcmp(e->op, "<")) return v < e->value;
    if (!strcmp(e->op, "<=")) return v <= e->value;
    if (!strcmp(e->op, ">")) return v > e->value;
    if (!strcmp(e->op, ">=")) return v >= e->value;
    return v == e->value;
}

/* Holds the scene's expect block against the metrics; prints one line each. */
static int hold_expectations(const stf_scene *sc, const stf_metrics *m)
{
    int failed = 0;
    for (int k = 0; k < sc->nexpect; k++) {
        const stf_expectation *e = &sc->expect[k];
        double v;
        int ok = cli_expectation_holds(e, m, &v);
        if (ok < 0) {
            printf("FAIL  %-28s  no such metric in this run\n", e->key);
            failed++;
            continue;
        }
        printf("%s  %-28s  measured %-12.6g expected %s %g\n", ok ? "pass" : "FAIL", e->key, v,
               e->op, e->value);
        failed += !ok;
    }
    return failed;
}

static int simulate(const run_args *a, stf_scene *sc, const char *out, stf_metrics *m)
{
    char err[1024];
    stf_sim *sim;
    if (stf_sim_create(sc, &sim, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        return 2;
    }
    stf_h5 *h;
    if (stf_h5_create(out, &h, err, sizeof err) != 0) {
        fprintf(stderr, "stf: cannot write the output: %s\n", err);
        stf_sim_destroy(sim);
        return 2;
    }
    int n = stf_fluid_count(sim->fluid);
    frame_buf b = {malloc((size_t)n * 3 * sizeof(double) + 1), malloc((size_t)n * 3 * sizeof(double) + 1),
                   malloc((size_t)n * sizeof(float) + 1), malloc((size_t)n * sizeof(int32_t) + 1)};
    int rc = (b.x && b.v && b.k && b.id) ? write_header(h, sim) : -1;
    double duration = a->duration > 0 ? a->duration : sc->duration;
    long steps = lround(duration / sc->dt);
    long per_frame = lround(1.0 / (sc->frame_rate * sc->dt));
    if (per_frame < 1) per_frame = 1;
    long body_every = lround(0.002 / sc->dt); /* bodies at 500 Hz or every step */
    if (body_every < 1) body_every = 1;
    if (rc == 0) rc = write_frame(h, sim, &b) | write_bodies(h, sim);
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    double t0 = omp_get_wtime();
    int status = rc ? 2 : 0;
    /* Carreau-Yasuda solver statistics, per frame (attributes of /Step#N: the steps since the
       frame before) and for the run (root attributes) */
    int cy = sc->fluid.model == STF_MODEL_CARREAU_YASUDA;
    double fr_it_max = 0, fr_it_sum = 0, fr_err_max = 0, fr_cg_max = 0, fr_cg_sum = 0, fr_n = 0;
    double run_it_max = 0, run_it_sum = 0, run_err_max = 0, run_cg_max = 0, run_cg_sum = 0;
    for (long s = 1; s <= steps && status == 0; s++) {
        int step_rc = stf_sim_step(sim);
        if (cy && step_rc == 0) {
            stf_solver_stats st;
            stf_fluid_solver_stats(sim->fluid, &st);
            fr_it_max = st.pressure_iterations > fr_it_max ? st.pressure_iterations : fr_it_max;
            fr_err_max = st.density_error > fr_err_max ? st.density_error : fr_err_max;
            fr_cg_max = st.viscosity_iterations > fr_cg_max ? st.viscosity_iterations : fr_cg_max;
            fr_it_sum += st.pressure_iterations, fr_cg_sum += st.viscosity_iterations, fr_n++;
            run_it_sum += st.pressure_iterations, run_cg_sum += st.viscosity_iterations;
        }
        if (step_rc != 0) {
            fprintf(stderr, "\nstf: numerical failure: %s; the last good frame is in %s\n",
                    stf_fluid_failure(sim->fluid), out);
            status = 3;
            break;
        }
        if (s % body_every == 0 && write_bodies(h, sim) != 0) status = 2;
        if (s % per_frame == 0 || s == steps) {
            if (write_frame(h, sim, &b) != 0) status = 2;
            if (cy && fr_n > 0) {
                stf_h5_frame_attr_double(h, "pressure_iterations_max", fr_it_max);
                stf_h5_frame_attr_double(h, "pressure_iterations_mean", fr_it_sum / fr_n);
                stf_h5_frame_attr_double(h, "density_error_max", fr_err_max);
                stf_h5_frame_attr_double(h, "viscosity_iterations_max", fr_cg_max);
                stf_h5_frame_attr_double(h, "viscosity_iterations_mean", fr_cg_sum / fr_n);
                run_it_max = fr_it_max > run_it_max ? fr_it_max : run_it_max;
                run_err_max = fr_err_max > run_err_max ? fr_err_max : run_err_max;
                run_cg_max = fr_cg_max > run_cg_max ? fr_cg_max : run_cg_max;
                fr_it_max = fr_it_sum = fr_err_max = fr_cg_max = fr_cg_sum = fr_n = 0;
            }
            progress(a, sim, duration, omp_get_wtime() - t0);
            if (interrupted) {
                fprintf(stderr, "\nstf: interrupted at t = %.4f s; %s holds the run so far\n",
                        sim->time, out);
                status = 130;
            }
        }
    }
    double wall = omp_get_wtime() - t0;
    if (!a->quiet && isatty(2)) fputc('\n', stderr);
    stf_h5_attr_long(h, "particles", stf_fluid_count(sim->fluid));
    stf_h5_attr_long(h, "steps", sim->steps);
    stf_h5_attr_long(h, "substeps", sim->substeps);
    stf_h5_attr_long(h, "spring_saturated_substeps", stf_fluid_saturated_steps(sim->fluid));
    stf_h5_attr_double(h, "wall_seconds", wall);
    stf_h5_attr_double(h, "dt_min", sim->dt_min > 0 ? sim->dt_min : sc->dt);
    stf_h5_attr_double(h, "dt_max", sim->dt_max > 0 ? sim->dt_max : sc->dt);
    stf_h5_attr_string(h, "dt_control", sc->dt_fixed ? "fixed" : "adaptive");
    if (cy && sim->steps > 0) {
        stf_h5_attr_double(h, "pressure_iterations_max", run_it_max);
        stf_h5_attr_double(h, "pressure_iterations_mean", run_it_sum / (double)sim->steps);
        stf_h5_attr_double(h, "density_error_max", run_err_max);
        stf_h5_attr_double(h, "viscosity_iterations_max", run_cg_max);
        stf_h5_attr_double(h, "viscosity_iterations_mean", run_cg_sum / (double)sim->steps);
        if (!a->quiet)
            fprintf(stderr, "stf: carreau_yasuda: pressure iterations mean %.2f max %.0f, mean "
                    "density error max %.3g%% (eta %g%%), viscosity CG iterations mean %.1f max %.0f\n",
                    run_it_sum / (double)sim->steps, run_it_max, 100 * run_err_max,
                    100 * sc->fluid.cy.eta, run_cg_sum / (double)sim->steps, run_cg_max);
    }
    if (status == 2) fprintf(stderr, "stf: writing %s failed: %s\n", out, stf_h5_last_error(h));
    stf_h5_flush_for_reading(h);
    if (stf_metrics_compute(out, m, err, sizeof err) == 0) {
        char *json = stf_metrics_json(m);
        if (json) stf_h5_write_metrics_json(h, json);
        free(json);
    }
    /* how the run ended (0 done, 3 numerical failure, 130 interrupted, 2 write error): a
       file without it was killed; `stf sweep` resumes every run not ended by 0 or 3 */
    stf_h5_attr_long(h, "exit_status", status);
    if (stf_h5_close(h, err, sizeof err) != 0) {
        fprintf(stderr, "stf: %s\n", err);
        if (status == 0) status = 2;
    }
    if (!a->quiet && sim->steps > 0)
        fprintf(stderr, "stf: %ld steps of %d particles in %.2f s: %.3f ms/step, %.3g particle-steps/s\n",
                sim->steps, stf_fluid_count(sim->fluid), wall, 1e3 * wall / (double)sim->steps,
                (double)sim->steps * stf_fluid_count(sim->fluid) / wall);
    free(b.x), free(b.v), free(b.k), free(b.id);
    stf_sim_destroy(sim);
    return status;
}

int cli_run(int argc, char **argv, int check)
{
    run_args a;
    if (parse_args(argc, argv, &a) != 0) return 2;
    if (a.threads) stf_set_threads(a.threads);
    char err[2048];
    stf_scene *sc;
    if (stf_scene_load(a.scene, a.ov, a.nov, &sc, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        return 2;
    }
    char *own = a.out ? NULL : default_out(sc);
    const char *out = a.out ? a.out : own;
    stf_metrics m;
    int status = check_output(out, a.scene);
    if (status == 0) status = simulate(&a, sc, out, &m);
    if (check && (status == 0 || status == 3)) {
        int failed = hold_expectations(sc, &m);
        if (status == 0) status = failed ? 1 : 0;
        printf("%s: %d of %d expectations held\n", sc->name, sc->nexpect - failed, sc->nexpect);
    }
    free(own);
    stf_scene_free(sc);
    return status;
}
