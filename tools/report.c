/* report.c - `stf report OUT.h5 [--json]`: the metrics of a finished or interrupted run. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "h5io.h"
#include "metrics.h"

/* The unit of a metric (metrics.h), a body's (without "NAME.") or the fluid's (without
 * "fluid."): "count" for the integers (bounces, particles, escaped). */
const char *cli_metric_unit(const char *key)
{
    if (!strcmp(key, "bounces") || !strcmp(key, "particles") || !strcmp(key, "escaped"))
        return "count";
    if (!strcmp(key, "rolling_ratio")) return "(omega R / v)";
    if (!strcmp(key, "max_speed")) return "m/s";
    if (!strncmp(key, "density_error", 13)) return "1";
    if (strstr(key, "time") || strstr(key, "duration") || !strcmp(key, "rest_on_surface")) return "s";
    return "m";
}

static void line(const char *name, double v, const char *unit)
{
    if (isnan(v)) printf("  %-22s never\n", name);
    else printf("  %-22s %.4g %s\n", name, v, unit);
}

static const cli_usage USAGE = {
    "report", "usage: stf report OUT.h5 [--json]\n",
    "The metrics of a finished or interrupted run, computed from its file: the end time, the\n"
    "surface height, each body's and the fluid's metrics (the keys of a scene's expect block),\n"
    "with their units; \"never\" for an event that did not happen.\n"
    "options:\n"
    "  --json   the metrics as one JSON object instead (null: never happened), the JSON that\n"
    "           stf run writes into the file's /metrics\n"
    "exit codes: 0 printed, 2 bad input (bad option, unreadable or not a run's file)\n"};

/* A run that did not finish says so first: its metrics cover only the part it ran. The
 * file's exit_status (0 done, 3 numerical failure, 130 interrupted; absent while a run
 * writes it or after a kill) and the time it reached against the scene's duration. */
static void run_status(const char *path)
{
    stf_h5r *r = NULL;
    char err[256];
    if (stf_h5r_open(path, &r, err, sizeof err) != 0) return;
    double status = -1, duration = 0, removed = 0;
    int has_status = stf_h5r_attr_double(r, "exit_status", &status) == 0;
    stf_h5r_attr_double(r, "duration", &duration);
    if (stf_h5r_attr_double(r, "removed_at_setup", &removed) == 0 && removed > 0)
        printf("  %-22s %.0f (overlapped a body at set-up)\n", "removed_particles", removed);
    stf_h5r_close(r);
    const char *what = !has_status ? "unfinished (no exit status: still running, or killed)"
                       : status == 0 ? NULL
                       : status == 3 ? "stopped by a numerical failure (exit 3)"
                       : status == 130 ? "interrupted (exit 130)"
                       : "ended with an error";
    if (what) printf("  %-22s %s; the metrics cover the run up to time_end, of %g s\n", "status",
                     what, duration);
}

int cli_report(int argc, char **argv)
{
    if (cli_help_asked(argc, argv)) return cli_help(&USAGE);
    const char *path = NULL;
    int json = 0;
    for (int i = 0; i < argc; i++) {
        if (!strcmp(argv[i], "--json")) json = 1;
        else if (argv[i][0] == '-') return cli_usage_error(&USAGE, "unknown option '%s'", argv[i]);
        else if (path) return cli_usage_error(&USAGE, "unexpected argument '%s'", argv[i]);
        else path = argv[i];
    }
    if (!path) return cli_usage_error(&USAGE, "no output file given");
    stf_metrics m;
    char err[1024];
    if (stf_metrics_compute(path, &m, err, sizeof err) != 0) {
        fprintf(stderr, "stf report: %s\n", err);
        return 2;
    }
    if (json) {
        char *s = stf_metrics_json(&m);
        fputs(s ? s : "{}\n", stdout);
        free(s);
        return 0;
    }
    printf("%s\n", path);
    run_status(path);
    line("time_end", m.time_end, "s");
    line("surface_height", m.surface_height, "m");
    for (int k = 0; k < m.nbodies; k++) {
        const stf_body_metrics *b = &m.bodies[k];
        printf(" body %s\n", b->name);
        for (int f = 0; stf_body_metric_names[f]; f++) {
            const char *key = stf_body_metric_names[f];
            double v;
            char full[160];
            snprintf(full, sizeof full, "%s.%s", b->name, key);
            stf_metrics_get(&m, full, &v);
            if (!strcmp(key, "bounces")) printf("  %-22s %d\n", key, b->bounces);
            else line(key, v, cli_metric_unit(key));
        }
        printf("  %-22s %.4g %.4g %.4g m\n", "final_position", b->final_position[0],
               b->final_position[1], b->final_position[2]);
    }
    printf(" fluid\n  %-22s %ld\n  %-22s %ld\n", "particles", m.particles, "escaped", m.escaped);
    line("max_speed", m.max_speed, "m/s");
    printf("  %-22s %s\n", "nan", m.nan ? "yes" : "no");
    line("com_rebound_height", m.com_rebound_height, "m");
    line("finger_height", m.finger_height, "m");
    line("surface_roughness", m.surface_roughness, "m");
    line("final_com_height", m.final_com_height, "m");
    line("impact_time", m.impact_time, "s");
    line("solid_duration", m.solid_duration, "s");
    line("splash_height", m.splash_height, "m");
    return 0;
}
