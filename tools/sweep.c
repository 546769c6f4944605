/* sweep.c - `stf sweep SCENE --vary KEY=V1,V2,... -o DIR`: many runs of one scene.
 *
 * The runs are the grid of the --vary values (last key fastest) or the rows of a --list file,
 * each repeated --repeat times. Every run is a plain `stf run` of the scene with the run's
 * --set's into DIR/run_NNNN.h5 (log in DIR/run_NNNN.log): locally as child processes of this
 * same program, --jobs at a time; under mpirun (built with MPI) in-process on the ranks,
 * run i on rank i mod size. The results are read back from the files, so a summary does not
 * depend on who ran what: DIR/summary.csv has one row per run (the varied values, exit
 * status, the scene's expectations held or not, wall time, every metric) and DIR/summary.png
 * plots one metric against one or two varied keys.
 *
 * Resume: DIR/plan.txt records the runs' arguments; a sweep started again on the same DIR
 * with the same plan skips every run whose file says it ended (root attribute exit_status 0
 * or 3, written by `stf run` when it closes the file), continues those with a checkpoint
 * (`stf run --resume`) and reruns the others. */
#define _XOPEN_SOURCE 700 /* realpath */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <omp.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#ifdef STF_HAVE_MPI
#include <mpi.h>
#endif

#include "canvas.h"
#include "cli.h"
#include "h5io.h"
#include "metrics.h"
#include "state.h"
#include "sweep.h"

extern char **environ;

#define MAX_KEYS SWEEP_MAX_KEYS
#define MAX_FIXED 64
#define MAX_RUNS 100000 /* runs of a sweep, repeats included */

static const cli_usage USAGE = {
    "sweep",
    "usage: stf sweep SCENE (--vary KEY=V1,V2,...|--vary KEY=START:STOP:COUNT)... | --list FILE\n"
    "                 -o DIR [--repeat N] [--jobs N] [--threads N] [--duration S]\n"
    "                 [--set KEY=VALUE]... [--unset KEY]... [--plot METRIC] [--x KEY]\n"
    "                 [--series KEY] [--png FILE.png] [--quiet]\n",
    "Runs SCENE many times, each a stf run with its own --set's into DIR/run_NNNN.h5 (log:\n"
    "DIR/run_NNNN.log): every combination of the --vary values (the last key fastest) or each\n"
    "line of a --list file, --repeat times. Then DIR/summary.csv, one row a run (its values,\n"
    "exit status, expectations, wall seconds, every metric), and a plot, DIR/summary.png.\n"
    "Started again on the same DIR (DIR/plan.txt: the same sweep), it skips the runs that\n"
    "ended and continues the stopped ones from their checkpoints. Under mpirun (an stf built\n"
    "with MPI) the runs are spread over the ranks.\n"
    "options:\n"
    "  --vary KEY=V1,V2,...         a scene key (as for --set) and its values, YAML (commas\n"
    "                               inside [...] belong to the value); up to 16 keys\n"
    "  --vary KEY=START:STOP:COUNT  COUNT values (1 to 100000) evenly spaced, both ends in\n"
    "  --list FILE                  one run a line, KEY=VALUE words; '#' starts a comment\n"
    "  -o, --out DIR                the runs and the summary: a new or empty directory, or the\n"
    "                               same sweep's (required)\n"
    "  --repeat N                   runs of each combination or line, 1 to 1000 (default 1);\n"
    "                               at most 100000 runs in all\n"
    "  --jobs N                     runs at a time, 1 to 1024 (default: the cores)\n"
    "  --threads N                  OpenMP threads of each run, 1 to 1024 (default: the cores\n"
    "                               / the jobs)\n"
    "  --duration S                 simulated seconds of each run (default: the scene's);\n"
    "                               round(S / dt) steps, 1 to 1e9\n"
    "  --set KEY=VALUE, --unset KEY for every run, before its varied keys (at most 64)\n"
    "  --plot METRIC                the plotted column of summary.csv, a metric key such as\n"
    "                               ball.sink_time (default: the first body's float_duration;\n"
    "                               without bodies fluid.max_speed)\n"
    "  --x KEY                      the x axis, a varied key (default: the first)\n"
    "  --series KEY                 one line per value of this varied key (default: the\n"
    "                               second, if any)\n"
    "  --png FILE.png               the plot (default DIR/summary.png)\n"
    "  -q, --quiet                  no progress on stderr\n"
    "exit codes: 0 every run done and its expectations held, 1 a run's expectations failed,\n"
    "2 bad input (no run started) or a run that did not end (its log says why), 130\n"
    "interrupted (run the same sweep again to continue it)\n"};

typedef struct sweep_args {
    const char *scene, *dir, *list, *plot_metric, *plot_x, *plot_series, *png;
    char *vary[MAX_KEYS];
    int nvary;
    const char *fixed[2 * MAX_FIXED]; /* "--set", "K=V" / "--unset", "K" pairs */
    int nfixed;
    const char *duration;
    int repeat, jobs, threads, quiet;
} sweep_args;

static volatile sig_atomic_t stop_sweep;
static void on_signal(int sig) { stop_sweep = sig; }

static int bad(const char *msg, const char *arg)
{
    return cli_usage_error(&USAGE, "%s '%s'", msg, arg);
}

static int parse_int(const char *s, int lo, int hi, int *out)
{
    char *end;
    long v = strtol(s, &end, 10);
    if (*end || end == s || v < lo || v > hi) return -1;
    *out = (int)v;
    return 0;
}

static int parse_args(int argc, char **argv, sweep_args *a)
{
    memset(a, 0, sizeof *a);
    a->repeat = 1;
    for (int i = 0; i < argc; i++) {
        const char *s = argv[i];
        int more = i + 1 < argc;
        if ((!strcmp(s, "-o") || !strcmp(s, "--out")) && more) a->dir = argv[++i];
        else if (!strcmp(s, "--vary") && more) {
            if (a->nvary == MAX_KEYS) return bad("too many --vary keys at", argv[i + 1]);
            a->vary[a->nvary++] = argv[++i];
        } else if (!strcmp(s, "--list") && more) a->list = argv[++i];
        else if ((!strcmp(s, "--set") || !strcmp(s, "--unset")) && more) {
            if (a->nfixed == MAX_FIXED) return bad("too many --set/--unset at", argv[i + 1]);
            if (!strcmp(s, "--set") && !strchr(argv[i + 1], '='))
                return bad("--set needs KEY=VALUE, got", argv[i + 1]);
            a->fixed[2 * a->nfixed] = s;
            a->fixed[2 * a->nfixed++ + 1] = argv[++i];
        } else if (!strcmp(s, "--repeat") && more) {
            if (parse_int(argv[++i], 1, 1000, &a->repeat)) return bad("--repeat must be in [1,1000], got", argv[i]);
        } else if (!strcmp(s, "--jobs") && more) {
            if (parse_int(argv[++i], 1, 1024, &a->jobs)) return bad("--jobs must be in [1,1024], got", argv[i]);
        } else if (!strcmp(s, "--threads") && more) {
            if (parse_int(argv[++i], 1, 1024, &a->threads)) return bad("--threads must be in [1,1024], got", argv[i]);
        } else if (!strcmp(s, "--duration") && more) {
            char *end;
            double d = strtod(argv[++i], &end);
            if (*end || !(d > 0) || !isfinite(d)) return bad("--duration must be a number of seconds > 0, got", argv[i]);
            a->duration = argv[i];
        } else if (!strcmp(s, "--plot") && more) a->plot_metric = argv[++i];
        else if (!strcmp(s, "--x") && more) a->plot_x = argv[++i];
        else if (!strcmp(s, "--png") && more) a->png = argv[++i];
        else if (!strcmp(s, "--series") && more) a->plot_series = argv[++i];
        else if (!strcmp(s, "--quiet") || !strcmp(s, "-q")) a->quiet = 1;
        else if (s[0] == '-') return bad("unknown or incomplete option", s);
        else if (!a->scene) a->scene = s;
        else return bad("unexpected argument", s);
    }
    if (!a->scene) return cli_usage_error(&USAGE, "no scene file given");
    if (!a->dir) return cli_usage_error(&USAGE, "no output directory given (-o DIR)");
    if (!a->nvary && !a->list)
        return cli_usage_error(&USAGE, "nothing to vary: give --vary KEY=... or --list FILE");
    if (a->nvary && a->list) return bad("--vary and --list exclude each other; got --list", a->list);
    return 0;
}

/* ---------------------------------------------------------------- the plan */

static char *dup_n(const char *s, size_t n)
{
    char *p = malloc(n + 1);
    if (!p) abort();
    memcpy(p, s, n);
    p[n] = 0;
    return p;
}

static void add_value(sweep_key *k, char *v)
{
    char **nv = realloc(k->val, (size_t)(k->nval + 1) * sizeof *nv);
    if (!nv) abort();
    k->val = nv;
    k->val[k->nval++] = v;
}

/* KEY=V1,V2,... (commas inside [...] belong to a flow sequence) or KEY=START:STOP:COUNT. */
static int parse_vary(const char *spec, sweep_key *k)
{
    const char *eq = strchr(spec, '=');
    if (!eq || eq == spec || !eq[1]) return bad("--vary needs KEY=V1,V2,... or KEY=START:STOP:COUNT, got", spec);
    k->key = dup_n(spec, (size_t)(eq - spec));
    const char *v = eq + 1;
    double a, b;
    int used = 0;
    char *end = NULL;
    long n = 0;
    /* START:STOP:COUNT when COUNT is an integer (strtol: a COUNT too large for sscanf's %d
       was undefined, and could pass as a small one) */
    if (v[0] != '[' && sscanf(v, "%lf:%lf:%n", &a, &b, &used) == 2 && used > 0 &&
        v[used] >= '0' && v[used] <= '9' && (errno = 0, n = strtol(v + used, &end, 10), !*end)) {
        if (errno == ERANGE || n < 1 || n > 100000 || !isfinite(a) || !isfinite(b))
            return bad("--vary START:STOP:COUNT needs finite ends and COUNT in [1,100000], got",
                       spec);
        for (int i = 0; i < n; i++) {
            char buf[32];
            /* the ends exactly; %.10g so that 0:1:11 gives 0.1, not 0.10000000000000001 */
            snprintf(buf, sizeof buf, "%.10g",
                     n == 1 ? a : i == n - 1 ? b : a + (b - a) * i / (double)(n - 1));
            add_value(k, dup_n(buf, strlen(buf)));
        }
        return 0;
    }
    int depth = 0;
    const char *start = v;
    for (const char *p = v;; p++) {
        if (*p == '[') depth++;
        else if (*p == ']') depth--;
        if (*p == 0 || (*p == ',' && depth == 0)) {
            if (p == start) return bad("--vary has an empty value in", spec);
            add_value(k, dup_n(start, (size_t)(p - start)));
            if (!*p) break;
            start = p + 1;
        }
    }
    return 0;
}

static int key_index(sweep_plan *p, const char *key)
{
    for (int i = 0; i < p->nkeys; i++)
        if (!strcmp(p->keys[i].key, key)) return i;
    if (p->nkeys == MAX_KEYS) return -1;
    memset(&p->keys[p->nkeys], 0, sizeof p->keys[0]);
    p->keys[p->nkeys].key = dup_n(key, strlen(key));
    return p->nkeys++;
}

static void add_run(sweep_plan *p, char **vals, int combo, int rep)
{
    sweep_run *nr = realloc(p->runs, (size_t)(p->nruns + 1) * sizeof *nr);
    if (!nr) abort();
    p->runs = nr;
    sweep_run *r = &p->runs[p->nruns++];
    memset(r, 0, sizeof *r);
    r->combo = combo;
    r->repeat = rep;
    r->status = -1;
    for (int i = 0; i < MAX_KEYS; i++) r->val[i] = vals[i];
}

/* A list file: one run a line, whitespace-separated KEY=VALUE; '#' starts a comment. */
static int read_list(const char *path, sweep_plan *p, int repeat)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "stf sweep: %s: %s\n", path, strerror(errno));
        return 2;
    }
    char line[4096];
    int ln = 0, combo = 0;
    while (fgets(line, sizeof line, f)) {
        ln++;
        char *hash = strchr(line, '#');
        if (hash) *hash = 0;
        char *vals[MAX_KEYS] = {0};
        int any = 0;
        for (char *save, *tok = strtok_r(line, " \t\r\n", &save); tok; tok = strtok_r(NULL, " \t\r\n", &save)) {
            char *eq = strchr(tok, '=');
            int col = (int)(tok - line) + 1;
            if (!eq || eq == tok || !eq[1]) {
                fprintf(stderr, "%s:%d:%d: %s: expected KEY=VALUE\n", path, ln, col, tok);
                fclose(f);
                return 2;
            }
            *eq = 0;
            int k = key_index(p, tok);
            if (k < 0) {
                fprintf(stderr, "%s:%d:%d: %s: more than %d keys\n", path, ln, col, tok, MAX_KEYS);
                fclose(f);
                return 2;
            }
            if (vals[k]) {
                fprintf(stderr, "%s:%d:%d: %s: set twice on one line\n", path, ln, col, tok);
                fclose(f);
                return 2;
            }
            vals[k] = dup_n(eq + 1, strlen(eq + 1));
            any = 1;
        }
        if (!any) continue;
        if ((long)p->nruns + repeat > MAX_RUNS) {
            fprintf(stderr, "%s:%d: more than %d runs (the lines times --repeat)\n", path, ln,
                    MAX_RUNS);
            for (int k = 0; k < MAX_KEYS; k++) free(vals[k]);
            fclose(f);
            return 2;
        }
        for (int r = 0; r < repeat; r++) {
            add_run(p, vals, combo, r);
            p->runs[p->nruns - 1].line = ln;
        }
        combo++;
    }
    fclose(f);
    if (p->nruns == 0) {
        fprintf(stderr, "stf sweep: %s: no runs in the list\n", path);
        return 2;
    }
    return 0;
}

static int build_plan(const sweep_args *a, sweep_plan *p)
{
    memset(p, 0, sizeof *p);
    if (a->list) return read_list(a->list, p, a->repeat);
    long total = 1;
    for (int i = 0; i < a->nvary; i++) {
        int rc = parse_vary(a->vary[i], &p->keys[i]);
        p->nkeys = i + 1;
        if (rc) return rc;
        for (int j = 0; j < i; j++)
            if (!strcmp(p->keys[j].key, p->keys[i].key)) return bad("a key is varied twice:", p->keys[i].key);
        total *= p->keys[i].nval;
        if (total * a->repeat > MAX_RUNS)
            return bad("more than 100000 runs (the values' combinations times --repeat) at",
                       a->vary[i]);
    }
    for (long c = 0; c < total; c++) {
        char *vals[MAX_KEYS] = {0};
        long rest = c;
        for (int i = p->nkeys - 1; i >= 0; i--) {
            vals[i] = p->keys[i].val[rest % p->keys[i].nval];
            rest /= p->keys[i].nval;
        }
        for (int r = 0; r < a->repeat; r++) add_run(p, vals, (int)c, r);
    }
    return 0;
}

/* The `stf run` arguments of run i (after "run"), in static buffers that cli_run may
 * write into (it splits --set KEY=VALUE in place); valid until the next call. */
static int run_argv(const sweep_args *a, const sweep_plan *p, int i, int threads, char *outbuf,
                    size_t outlen, char **argv)
{
    static char buf[MAX_FIXED + MAX_KEYS + 2][4096];
    int n = 0, b = 0;
    argv[n++] = (char *)a->scene;
    snprintf(outbuf, outlen, "%s/run_%04d.h5", a->dir, i);
    argv[n++] = "-o";
    argv[n++] = outbuf;
    for (int f = 0; f < a->nfixed; f++) {
        argv[n++] = (char *)a->fixed[2 * f];
        snprintf(buf[b], sizeof buf[b], "%s", a->fixed[2 * f + 1]);
        argv[n++] = buf[b++];
    }
    for (int k = 0; k < p->nkeys; k++) {
        if (!p->runs[i].val[k]) continue;
        snprintf(buf[b], sizeof buf[b], "%s=%s", p->keys[k].key, p->runs[i].val[k]);
        argv[n++] = "--set";
        argv[n++] = buf[b++];
    }
    if (a->duration) {
        argv[n++] = "--duration";
        argv[n++] = (char *)a->duration;
    }
    snprintf(buf[b], sizeof buf[b], "%d", threads);
    argv[n++] = "--threads";
    argv[n++] = buf[b];
    argv[n++] = "--quiet";
    argv[n] = NULL;
    return n;
}

/* Loads the scene with run i's overrides: a bad key or value is reported before any run. */
static int check_run(const sweep_args *a, const sweep_plan *p, int i, stf_scene **out)
{
    stf_override ov[MAX_FIXED + MAX_KEYS];
    char kv[MAX_FIXED + MAX_KEYS][4096];
    int n = 0;
    for (int f = 0; f < a->nfixed; f++, n++) {
        snprintf(kv[n], sizeof kv[n], "%s", a->fixed[2 * f + 1]);
        char *eq = strchr(kv[n], '=');
        if (eq) *eq = 0;
        ov[n].key = kv[n];
        ov[n].value = !strcmp(a->fixed[2 * f], "--set") && eq ? eq + 1 : NULL;
    }
    for (int k = 0; k < p->nkeys; k++) {
        if (!p->runs[i].val[k]) continue;
        snprintf(kv[n], sizeof kv[n], "%s", p->runs[i].val[k]);
        ov[n].key = p->keys[k].key;
        ov[n].value = kv[n];
        n++;
    }
    char err[2048];
    if (stf_scene_load(a->scene, ov, n, out, err, sizeof err) != 0) {
        if (p->runs[i].line) fprintf(stderr, "%s:%d: %s\n", a->list, p->runs[i].line, err);
        else fprintf(stderr, "%s\n", err);
        return 2;
    }
    return 0;
}

/* 1 if directory dir has no entries (or cannot be listed: mkdir or plan.txt will say why). */
static int dir_is_empty(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return 1;
    const struct dirent *e;
    int empty = 1;
    while (empty && (e = readdir(d)))
        empty = !strcmp(e->d_name, ".") || !strcmp(e->d_name, "..");
    closedir(d);
    return empty;
}

/* 1 if the directory part of path (".", if none) is a directory. */
static int dir_exists_for(const char *path)
{
    char dir[4096];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (!slash) return 1;
    slash[slash == dir] = 0; /* "/x.png": the root */
    struct stat st;
    return stat(dir, &st) == 0 && S_ISDIR(st.st_mode);
}

/* Writes DIR/plan.txt, or checks that the one there is the same sweep. A DIR with files but
 * no plan.txt is not a sweep's: its run_NNNN.h5 would be taken for this sweep's runs. */
static int write_plan(const sweep_args *a, const sweep_plan *p)
{
    size_t cap = 1 << 16, len = 0;
    char *text = malloc(cap);
    if (!text) abort();
    char *scene = realpath(a->scene, NULL); /* the same scene by any path */
    len += (size_t)snprintf(text, cap, "stf sweep plan: %s\n", scene ? scene : a->scene);
    free(scene);
    for (int i = 0; i < p->nruns; i++) {
        char out[4096], *argv[2 * (MAX_FIXED + MAX_KEYS) + 16];
        int n = run_argv(a, p, i, 1, out, sizeof out, argv);
        argv[2] = out + strlen(a->dir) + 1; /* run_NNNN.h5: the same DIR by any path */
        for (int j = 1; j < n - 3; j++) { /* no scene, no --threads/--quiet */
            size_t need = strlen(argv[j]) + 2;
            if (len + need + 2 > cap) {
                cap = 2 * cap + need;
                char *nt = realloc(text, cap);
                if (!nt) abort();
                text = nt;
            }
            len += (size_t)snprintf(text + len, cap - len, "%s%s", argv[j], j == n - 4 ? "\n" : " ");
        }
    }
    char path[4096];
    snprintf(path, sizeof path, "%s/plan.txt", a->dir);
    FILE *f = fopen(path, "r");
    if (f) {
        char *old = malloc(len + 2);
        if (!old) abort();
        size_t got = fread(old, 1, len + 1, f);
        fclose(f);
        int same = got == len && !memcmp(old, text, len);
        free(old);
        free(text);
        if (!same) {
            fprintf(stderr, "stf sweep: %s holds a different sweep (other scene, keys, values or "
                            "--set's); nothing was changed: choose another -o DIR or delete it\n", path);
            return 2;
        }
        return 0;
    }
    if (!dir_is_empty(a->dir)) {
        fprintf(stderr, "stf sweep: %s holds files but no sweep (no plan.txt); nothing was changed: "
                        "choose a new or empty -o DIR\n", a->dir);
        free(text);
        return 2;
    }
    f = fopen(path, "w");
    int ok = f && fwrite(text, 1, len, f) == len;
    if (f && fclose(f) != 0) ok = 0;
    free(text);
    if (!ok) {
        fprintf(stderr, "stf sweep: cannot write %s: %s\n", path, strerror(errno));
        return 2;
    }
    return 0;
}

/* ---------------------------------------------------------------- the runs */

/* exit_status of a finished run file, or -1 if the file is missing, unreadable or unfinished;
 * its wall_seconds in *wall (unless NULL; unchanged if absent). */
static int file_status(const char *path, double *wall)
{
    if (access(path, R_OK) != 0) return -1;
    char err[512];
    stf_h5r *r;
    if (stf_h5r_open(path, &r, err, sizeof err) != 0) return -1;
    double st;
    int rc = stf_h5r_attr_double(r, "exit_status", &st);
    if (wall) stf_h5r_attr_double(r, "wall_seconds", wall);
    stf_h5r_close(r);
    return rc == 0 ? (int)st : -1;
}

static int done(int status) { return status == 0 || status == 3; }

/* A run that was stopped after its first checkpoint (killed, interrupted) continues from it
 * when its file was written by this run (the same scene text and duration): argv (n
 * entries, from run_argv) loses --duration (the file keeps the run's) and gains --resume;
 * the result is bit-identical to the run never stopped. Other files are run again from the
 * start. Returns the new count. */
static int resume_if_stopped(const sweep_args *a, const sweep_plan *p, int i, const char *out,
                             char **argv, int n)
{
    if (access(out, R_OK) != 0 || done(file_status(out, NULL))) return n;
    stf_scene *sc = NULL;
    stf_h5r *r = NULL;
    char err[512], *text = NULL;
    double stored = 0;
    int same = check_run(a, p, i, &sc) == 0 && stf_h5r_open(out, &r, err, sizeof err) == 0 &&
               (text = stf_h5r_attr_string(r, "scene")) != NULL &&
               stf_h5r_attr_double(r, "duration", &stored) == 0 &&
               !strcmp(text, sc->text ? sc->text : "") &&
               stored == (a->duration ? strtod(a->duration, NULL) : sc->duration);
    free(text);
    if (r) stf_h5r_close(r);
    stf_scene_free(sc);
    stf_state st = {0};
    same = same && stf_h5_read_checkpoint(out, &st, err, sizeof err) == 0;
    stf_state_free(&st);
    if (!same) return n;
    if (!a->quiet) fprintf(stderr, "stf sweep: run %d continues %s from its checkpoint\n", i, out);
    for (int j = 0; j + 1 < n; j++)
        if (!strcmp(argv[j], "--duration")) {
            memmove(argv + j, argv + j + 2, (size_t)(n - j - 2) * sizeof *argv);
            n -= 2;
            break;
        }
    argv[n++] = "--resume";
    argv[n] = NULL;
    return n;
}

static int spawn_run(const sweep_args *a, const sweep_plan *p, int i, int threads, const char *self, pid_t *pid)
{
    char out[4096], logp[4096], *argv[2 * (MAX_FIXED + MAX_KEYS) + 18];
    argv[0] = (char *)self;
    argv[1] = "run";
    int n = run_argv(a, p, i, threads, out, sizeof out, argv + 2);
    resume_if_stopped(a, p, i, out, argv + 2, n);
    snprintf(logp, sizeof logp, "%s/run_%04d.log", a->dir, i);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, logp, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&fa, 1, 2);
    int rc = posix_spawn(pid, self, &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) fprintf(stderr, "stf sweep: cannot start %s: %s\n", self, strerror(rc));
    return rc ? 2 : 0;
}

static void say_run(const sweep_args *a, const sweep_plan *p, int i, int status, const char *who)
{
    if (a->quiet) return;
    fprintf(stderr, "stf sweep: run %d/%d", i + 1, p->nruns);
    for (int k = 0; k < p->nkeys; k++)
        if (p->runs[i].val[k]) fprintf(stderr, " %s=%s", p->keys[k].key, p->runs[i].val[k]);
    if (p->runs[i].repeat > 0 || a->repeat > 1) fprintf(stderr, " (repeat %d)", p->runs[i].repeat);
    fprintf(stderr, ": %s%s\n", status == 0 ? "done" : status == 3 ? "numerical failure" : status == 130 ? "interrupted" : "failed", who);
}

/* Runs the pending runs locally, `jobs` child processes at a time. Returns 0, 130 or 2. */
static int run_local(const sweep_args *a, sweep_plan *p, const int *todo, int ntodo, int jobs, int threads)
{
    char self[4096];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0) {
        fprintf(stderr, "stf sweep: cannot find this program (/proc/self/exe): %s\n", strerror(errno));
        return 2;
    }
    self[n] = 0;
    pid_t *pids = calloc((size_t)jobs, sizeof *pids);
    int *slot_run = calloc((size_t)jobs, sizeof *slot_run);
    if (!pids || !slot_run) abort();
    int next = 0, running = 0, rc = 0, forwarded = 0;
    while (next < ntodo || running > 0) {
        while (running < jobs && next < ntodo && !stop_sweep && rc == 0) {
            int s = 0;
            while (pids[s]) s++;
            if (spawn_run(a, p, todo[next], threads, self, &pids[s]) != 0) {
                rc = 2;
                break;
            }
            slot_run[s] = todo[next++];
            running++;
        }
        if (running == 0) break;
        /* a signal to the sweep alone (kill PID): pass it on, the runs save what they have.
           Polled, not left to waitpid's EINTR: a signal that comes while a run is being
           started (outside waitpid) would otherwise wait for that run to end on its own */
        if (stop_sweep && !forwarded) {
            for (int s = 0; s < jobs; s++)
                if (pids[s]) kill(pids[s], SIGINT);
            forwarded = 1;
        }
        int ws;
        pid_t got = waitpid(-1, &ws, WNOHANG);
        if (got == 0 || (got < 0 && errno == EINTR)) {
            nanosleep(&(struct timespec){0, 20000000}, NULL); /* 20 ms */
            continue;
        }
        if (got < 0) break;
        for (int s = 0; s < jobs; s++)
            if (pids[s] == got) {
                int st = WIFEXITED(ws) ? WEXITSTATUS(ws) : 128 + (WIFSIGNALED(ws) ? WTERMSIG(ws) : 0);
                p->runs[slot_run[s]].status = st;
                say_run(a, p, slot_run[s], st, "");
                if (!done(st) && st != 130 && st < 128) {
                    fprintf(stderr, "stf sweep: run %d exited %d; see %s/run_%04d.log\n", slot_run[s], st, a->dir, slot_run[s]);
                    if (rc == 0) rc = 2;
                }
                pids[s] = 0;
                running--;
            }
    }
    free(pids);
    free(slot_run);
    if (stop_sweep && rc == 0) rc = 130;
    return rc;
}

/* ---------------------------------------------------------------- the summary */

static void csv_field(FILE *f, const char *s)
{
    if (!s) return;
    if (!strpbrk(s, ",\"\n")) {
        fputs(s, f);
        return;
    }
    fputc('"', f);
    for (; *s; s++) {
        if (*s == '"') fputc('"', f);
        fputc(*s, f);
    }
    fputc('"', f);
}

/* ",value" with every bit of the double; a null (never happened) is an empty field. */
static void csv_num(FILE *f, double v)
{
    fputc(',', f);
    if (!isnan(v)) fprintf(f, "%.17g", v);
}

/* Reads every run's file: status, metrics, expectations, wall time. */
static void collect(const sweep_args *a, sweep_plan *p)
{
    for (int i = 0; i < p->nruns; i++) {
        sweep_run *r = &p->runs[i];
        char path[4096], err[1024];
        snprintf(path, sizeof path, "%s/run_%04d.h5", a->dir, i);
        double wall = NAN;
        r->status = file_status(path, &wall);
        r->wall = NAN;
        if (!done(r->status)) continue; /* a partial run's metrics would mislead: rerun it */
        if (stf_metrics_compute(path, &r->m, err, sizeof err) != 0) {
            fprintf(stderr, "stf sweep: %s: %s\n", path, err);
            r->status = -1;
            continue;
        }
        r->have_metrics = 1;
        r->wall = wall;
        stf_scene *sc;
        r->failed = -1;
        if (check_run(a, p, i, &sc) == 0) {
            r->nexpect = sc->nexpect;
            r->failed = 0;
            for (int e = 0; e < sc->nexpect; e++) {
                double v;
                r->failed += cli_expectation_holds(&sc->expect[e], &r->m, &v) != 1;
            }
            stf_scene_free(sc);
        }
    }
}

#define BODY_FIELDS stf_body_metric_names
#define FLUID_FIELDS stf_fluid_metric_names

static int write_summary(const sweep_args *a, const sweep_plan *p)
{
    const stf_metrics *m0 = NULL;
    for (int i = 0; i < p->nruns && !m0; i++)
        if (p->runs[i].have_metrics) m0 = &p->runs[i].m;
    char path[4096];
    snprintf(path, sizeof path, "%s/summary.csv", a->dir);
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "stf sweep: cannot write %s: %s\n", path, strerror(errno));
        return 2;
    }
    fputs("run", f);
    for (int k = 0; k < p->nkeys; k++) fputc(',', f), csv_field(f, p->keys[k].key);
    fputs(",repeat,status,pass,expectations_failed,wall_seconds,time_end,surface_height", f);
    int nb = m0 ? m0->nbodies : 0;
    for (int b = 0; b < nb; b++) {
        for (int j = 0; BODY_FIELDS[j]; j++) fprintf(f, ",%s.%s", m0->bodies[b].name, BODY_FIELDS[j]);
        fprintf(f, ",%s.final_x,%s.final_y,%s.final_z", m0->bodies[b].name, m0->bodies[b].name, m0->bodies[b].name);
    }
    for (int j = 0; FLUID_FIELDS[j]; j++) fprintf(f, ",fluid.%s", FLUID_FIELDS[j]);
    fputs(",fluid.nan\n", f);
    for (int i = 0; i < p->nruns; i++) {
        const sweep_run *r = &p->runs[i];
        fprintf(f, "%d", i);
        for (int k = 0; k < p->nkeys; k++) fputc(',', f), csv_field(f, r->val[k]);
        char st[32];
        if (r->status == 0 || r->status == 3 || r->status == 130 || r->status < 0)
            snprintf(st, sizeof st, "%s", r->status == 0 ? "ok" : r->status == 3 ? "numerical_failure"
                                          : r->status == 130 ? "interrupted" : "missing");
        else snprintf(st, sizeof st, "exit_%d", r->status);
        fprintf(f, ",%d,%s,", r->repeat, st);
        if (r->have_metrics && r->failed >= 0) fprintf(f, "%s,%d", r->failed ? "fail" : "pass", r->failed);
        else fputc(',', f);
        if (!r->have_metrics) {
            fputc('\n', f);
            continue;
        }
        csv_num(f, r->wall);
        csv_num(f, r->m.time_end);
        csv_num(f, r->m.surface_height);
        for (int b = 0; b < nb; b++) {
            for (int j = 0; BODY_FIELDS[j]; j++) {
                char key[160];
                double v = NAN;
                snprintf(key, sizeof key, "%s.%s", m0->bodies[b].name, BODY_FIELDS[j]);
                if (stf_metrics_get(&r->m, key, &v) != 0) v = NAN;
                csv_num(f, v);
            }
            for (int d = 0; d < 3; d++) csv_num(f, b < r->m.nbodies ? r->m.bodies[b].final_position[d] : NAN);
        }
        for (int j = 0; FLUID_FIELDS[j]; j++) {
            char key[160];
            double v = NAN;
            snprintf(key, sizeof key, "fluid.%s", FLUID_FIELDS[j]);
            stf_metrics_get(&r->m, key, &v);
            csv_num(f, v);
        }
        fprintf(f, ",%d\n", r->m.nan);
    }
    if (fclose(f) != 0) {
        fprintf(stderr, "stf sweep: writing %s failed\n", path);
        return 2;
    }
    return 0;
}

static int finish(const sweep_args *a, sweep_plan *p, int rc)
{
    collect(a, p);
    int w = write_summary(a, p);
    int missing = 0, failed = 0;
    for (int i = 0; i < p->nruns; i++) {
        missing += !done(p->runs[i].status);
        failed += p->runs[i].have_metrics && p->runs[i].failed != 0;
    }
    char err[512];
    char png[4096];
    snprintf(png, sizeof png, "%s/summary.png", a->dir);
    int plotted = sweep_plot(a->png ? a->png : png, p, a->plot_metric, a->plot_x, a->plot_series, err, sizeof err);
    if (plotted != 0) fprintf(stderr, "stf sweep: no plot: %s\n", err);
    if (!a->quiet)
        fprintf(stderr, "stf sweep: %d runs, %d unfinished, %d failing expectations; %s/summary.csv%s%s\n",
                p->nruns, missing, failed, a->dir, plotted == 0 ? ", " : "", plotted == 0 ? (a->png ? a->png : png) : "");
    if (rc) return rc;
    if (w) return w;
    if (missing) return 2;
    return failed ? 1 : 0;
}

static void plan_free(sweep_plan *p, int from_list)
{
    for (int k = 0; k < p->nkeys; k++) {
        free(p->keys[k].key);
        for (int v = 0; v < p->keys[k].nval; v++) free(p->keys[k].val[v]);
        free(p->keys[k].val);
    }
    if (from_list) /* list values are owned by the runs (one copy per line, shared by repeats) */
        for (int i = 0; i < p->nruns; i++)
            if (p->runs[i].repeat == 0)
                for (int k = 0; k < MAX_KEYS; k++) free(p->runs[i].val[k]);
    free(p->runs);
}

/* Under mpirun: the launcher's environment says so (OpenMPI, MPICH/PMI, PMIx). */
static int under_mpi(void)
{
    return getenv("OMPI_COMM_WORLD_SIZE") || getenv("PMI_SIZE") || getenv("PMIX_RANK");
}

int cli_sweep(int argc, char **argv)
{
    if (cli_help_asked(argc, argv)) return cli_help(&USAGE);
    sweep_args a;
    if (parse_args(argc, argv, &a)) return 2;
    sweep_plan p;
    int rc = build_plan(&a, &p);
    if (rc) {
        plan_free(&p, a.list != NULL);
        return rc;
    }
    stf_metrics names = {0}; /* the first run's body names, for sweep_plot_check */
    for (int i = 0; i < p.nruns && rc == 0; i++) { /* every run's scene loads: bad input first */
        stf_scene *sc = NULL;
        if (p.runs[i].repeat > 0) continue;
        rc = check_run(&a, &p, i, &sc);
        for (int k = 0; rc == 0 && i == 0 && k < sc->nbodies && k < STF_METRICS_MAX_BODIES; k++)
            snprintf(names.bodies[names.nbodies++].name, sizeof names.bodies[0].name, "%s", sc->bodies[k].name);
        char why[512]; /* --duration at this run's dt (the scene's own duration passed its load) */
        if (rc == 0 && a.duration &&
            stf_run_steps(strtod(a.duration, NULL), sc->dt, why, sizeof why) < 0) {
            fprintf(stderr, "stf sweep: --duration %s (run %d", a.duration, i);
            if (p.runs[i].line) fprintf(stderr, ", %s:%d", a.list, p.runs[i].line);
            fprintf(stderr, "): %s\n", why);
            rc = 2;
        }
        if (sc) stf_scene_free(sc);
    }
    char perr[512];
    if (rc == 0 && sweep_plot_check(&p, &names, a.plot_metric, a.plot_x, a.plot_series, perr, sizeof perr) != 0) {
        fprintf(stderr, "stf sweep: %s\n", perr);
        rc = 2;
    }
    if (rc == 0 && a.png && !dir_exists_for(a.png)) {
        fprintf(stderr, "stf sweep: --png %s: its directory does not exist\n", a.png);
        rc = 2;
    }
    if (rc == 0 && a.png && canvas_holds_other_data(a.png)) {
        fprintf(stderr, "stf sweep: --png %s: exists and is not a PNG; not overwritten\n", a.png);
        rc = 2;
    }
    int rank = 0, size = 1, local = 1;
#ifdef STF_HAVE_MPI
    int mpi = under_mpi();
    if (mpi) {
        MPI_Init(NULL, NULL);
        MPI_Comm_rank(MPI_COMM_WORLD, &rank);
        MPI_Comm_size(MPI_COMM_WORLD, &size);
        MPI_Comm node;
        MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank, MPI_INFO_NULL, &node);
        MPI_Comm_size(node, &local);
        MPI_Comm_free(&node);
    }
#else
    if (under_mpi()) {
        fprintf(stderr, "stf sweep: started by mpirun, but this stf was built without MPI "
                        "(install libopenmpi-dev and rebuild): exiting\n");
        rc = 2;
    }
#endif
    if (rc == 0 && rank == 0) {
        if (mkdir(a.dir, 0755) != 0 && errno != EEXIST) {
            fprintf(stderr, "stf sweep: cannot make %s: %s\n", a.dir, strerror(errno));
            rc = 2;
        } else rc = write_plan(&a, &p);
    }
#ifdef STF_HAVE_MPI
    if (mpi) MPI_Bcast(&rc, 1, MPI_INT, 0, MPI_COMM_WORLD);
#endif
    if (rc) {
#ifdef STF_HAVE_MPI
        if (mpi) MPI_Finalize();
#endif
        plan_free(&p, a.list != NULL);
        return rc;
    }
    int procs = omp_get_num_procs();
    int *todo = malloc((size_t)p.nruns * sizeof *todo + 1), ntodo = 0;
    if (!todo) abort();
    for (int i = rank; i < p.nruns; i += size) {
        char path[4096];
        snprintf(path, sizeof path, "%s/run_%04d.h5", a.dir, i);
        if (done(file_status(path, NULL))) continue;
        todo[ntodo++] = i;
    }
    if (!a.quiet && size == 1)
        fprintf(stderr, "stf sweep: %d runs, %d to do (%d already done)\n", p.nruns, ntodo, p.nruns - ntodo);
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    if (size == 1) {
        int jobs = a.jobs ? a.jobs : procs;
        if (jobs > ntodo) jobs = ntodo > 0 ? ntodo : 1;
        int threads = a.threads ? a.threads : (procs / jobs > 1 ? procs / jobs : 1);
        rc = run_local(&a, &p, todo, ntodo, jobs, threads);
    } else {
        /* this rank's share of the node's cores; the runs in-process, one after the other */
        int threads = a.threads ? a.threads : (procs / local > 1 ? procs / local : 1);
        char who[32];
        snprintf(who, sizeof who, " (rank %d)", rank);
        for (int t = 0; t < ntodo && !stop_sweep; t++) {
            char out[4096], *rargv[2 * (MAX_FIXED + MAX_KEYS) + 16];
            int n = run_argv(&a, &p, todo[t], threads, out, sizeof out, rargv);
            n = resume_if_stopped(&a, &p, todo[t], out, rargv, n);
            int st = cli_run(n, rargv, 0);
            say_run(&a, &p, todo[t], st, who);
            if (st == 130) stop_sweep = SIGINT;
            else if (!done(st) && rc == 0) rc = 2;
        }
        if (stop_sweep && rc == 0) rc = 130;
    }
    free(todo);
#ifdef STF_HAVE_MPI
    if (mpi) {
        int all;
        MPI_Allreduce(&rc, &all, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
        rc = all;
    }
#endif
    if (rank == 0) rc = finish(&a, &p, rc);
#ifdef STF_HAVE_MPI
    if (mpi) {
        MPI_Bcast(&rc, 1, MPI_INT, 0, MPI_COMM_WORLD);
        MPI_Finalize();
    }
#endif
    plan_free(&p, a.list != NULL);
    return rc;
}
