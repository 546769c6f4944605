/* sweep.h - the plan and results of `stf sweep` (tools/sweep.c), shared with its plot
 * (tools/sweep_plot.c). */
#ifndef STF_SWEEP_H
#define STF_SWEEP_H

#include <stddef.h>

#include "metrics.h"

#define SWEEP_MAX_KEYS 16

typedef struct sweep_key {
    char *key;  /* dotted scene path, as for --set */
    int nval;   /* values of a --vary grid key (0 for --list keys) */
    char **val;
} sweep_key;

typedef struct sweep_run {
    char *val[SWEEP_MAX_KEYS]; /* this run's value of each key, NULL if it leaves it alone */
    int combo, repeat;         /* which combination of values, which repetition of it */
    int line;                  /* --list: the run's line in the list file; 0 for --vary */
    int status;                /* exit_status in its file (0 ok, 3 numerical failure), -1 none */
    int have_metrics;
    stf_metrics m;
    int nexpect, failed;       /* the scene's expectations, how many failed (-1 unknown) */
    double wall;               /* s, the run's wall_seconds attribute */
} sweep_run;

typedef struct sweep_plan {
    int nkeys;
    sweep_key keys[SWEEP_MAX_KEYS];
    int nruns;
    sweep_run *runs;
} sweep_plan;

/* Draws the PNG file png: metric (a summary column: an expectation key or BODY.final_z, default: the scene's first body's
 * float_duration if it has bodies, else fluid.max_speed) against the numeric values of key x
 * (default: the first key), one line per value of key series (default: the second key, if
 * any); runs that agree on both are averaged (repeats, other keys). Returns 0, or -1 with a
 * reason in err. */
int sweep_plot(const char *png, const sweep_plan *p, const char *metric, const char *x,
               const char *series, char *err, size_t errlen);

/* The checks of sweep_plot's options that need no run, made before the runs: metric (if not
 * NULL) names a column for runs with m's bodies (only their names are read), x and series
 * (if not NULL) are varied keys. Returns 0, or -1 with a reason in err. */
int sweep_plot_check(const sweep_plan *p, const stf_metrics *m, const char *metric, const char *x,
                     const char *series, char *err, size_t errlen);

#endif
