/* cli.h - the subcommands of the stf tool. Each returns the process exit code. */
#ifndef STF_CLI_H
#define STF_CLI_H

#include "stf_io.h"

int cli_run(int argc, char **argv, int check);
int cli_report(int argc, char **argv);
int cli_bench(int argc, char **argv); /* bench.c */
int cli_sweep(int argc, char **argv); /* sweep.c */

/* The unit of a metric named as in stf_body_metric_names or stf_fluid_metric_names
 * (report.c): "m", "s", "m/s", "(omega R / v)", or "count" for the integers. */
const char *cli_metric_unit(const char *key);

struct stf_metrics;
/* Whether expectation e holds for metrics m (run.c): 1 holds, 0 fails (a null metric fails),
 * -1 the key names no metric of this run. *value is the measured value (NAN for null). */
int cli_expectation_holds(const stf_expectation *e, const struct stf_metrics *m, double *value);

/* A command's usage, in its command's file: synopsis, its "usage: stf CMD ..." lines, and details,
 * what it does, its options with their units and defaults, and its exit codes. Both end in a
 * newline. */
typedef struct cli_usage {
    const char *cmd; /* "run", "bench table1" */
    const char *synopsis, *details;
} cli_usage;

/* 1 when one of the arguments is -h or --help: each command then prints its usage
 * (cli_help) and does nothing else, wherever the option is on its line. */
int cli_help_asked(int argc, char **argv);

/* `stf CMD --help`: the synopsis and the details on stdout. Returns 0, the exit code. */
int cli_help(const cli_usage *u);

/* A usage error: "stf CMD: MESSAGE", the synopsis and where the options are explained, on
 * stderr. Returns 2, the exit code. */
int cli_usage_error(const cli_usage *u, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* An option OPT last on CMD's command line, without its value: "option OPT needs a value"
 * when OPT is one of valued (NULL-terminated), "unknown option" otherwise, with the usage, on
 * stderr (cli_usage_error). Returns 2, the exit code. */
int cli_missing_value(const cli_usage *u, const char *opt, const char *const *valued);


#endif
