/* stf.c - the command-line tool: run scenes, check expectations, report metrics.
 * Exit codes: 0 ok, 1 expectation failed, 2 bad input, 3 numerical failure,
 * 130 interrupted. Every command prints its usage on stdout for --help or -h (exit 0), and
 * on stderr after a usage error (exit 2). */
#include <errno.h>
#include <math.h>
#include <omp.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "history_cli.h"
#include "pictures.h"

static const char usage_text[] =
    "usage: stf COMMAND [ARGUMENTS]   (stf COMMAND --help: what it does, its options, units\n"
    "                                  and defaults)\n"
    "  stf run SCENE [-o OUT.h5] [--set KEY=VALUE]... [--unset KEY]... [--duration S]\n"
    "              [--threads N] [--quiet] [--checkpoint S|off | --checkpoint-frames N]\n"
    "  stf run --resume OUT.h5 | stf run SCENE [-o OUT.h5] --resume   (continue a stopped\n"
    "              run from its checkpoint, bit-identical)\n"
    "  stf check SCENE [the options of stf run]   (a run, then the scene's expectations)\n"
    "  stf report OUT.h5 [--json]\n"
    "  stf render OUT.h5 [-o DIR] [--frames all|N|A:B|a,b,c] [--every K] [--color speed|khist|none]\n"
    "             [--width W] [--height H] [--max V] [--camera x,y,z] [--look x,y,z]\n"
    "             [--montage FILE.png]\n"
    "  stf plot OUT.h5 [-o FILE.png] [--body NAME] [--width W] [--height H]\n"
    "  stf history [--fig 2|3|4|all] [-o DIR] [--q 0.2,0.5,0.8] [--d 50,150,500] [--dt S]\n"
    "              [--k-hist K] [--steps N] [--n N] [--profile FILE.csv]   (paper Fig. 2-4)\n"
    "  stf bench table1 [BOWLING.yaml] | effects SCENE | accuracy SCENE | scaling SCENE\n"
    "            | grid SCENE | dam SCENE | convergence SCENE   [OPTIONS]   (what accuracy costs\n"
    "            in time; stf bench NAME --help: NAME's options)\n"
    "  stf sweep SCENE (--vary KEY=V1,V2,...|--vary KEY=START:STOP:COUNT)... | --list FILE\n"
    "            -o DIR [--repeat N] [--jobs N] [--threads N] [--duration S] [--set ...]\n"
    "            [--plot METRIC] [--x KEY] [--series KEY] [--png FILE]   (DIR/summary.csv, .png;\n"
    "            under mpirun the runs are spread over the ranks)\n"
    "  stf --help | stf --version\n"
    "exit codes: 0 ok, 1 expectation failed, 2 bad input, 3 numerical failure, "
    "130 interrupted\n";

int cli_help_asked(int argc, char **argv)
{
    for (int i = 0; i < argc; i++)
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) return 1;
    return 0;
}

int cli_help(const cli_usage *u)
{
    fputs(u->synopsis, stdout);
    fputs(u->details, stdout);
    return 0;
}

int cli_usage_error(const cli_usage *u, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "stf %s: ", u->cmd);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, "\n%s(stf %s --help: what it does, its options, units and defaults)\n",
            u->synopsis, u->cmd);
    return 2;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fputs(usage_text, stderr);
        return 2;
    }
    const char *cmd = argv[1];
    if (!strcmp(cmd, "-h") || !strcmp(cmd, "--help")) {
        fputs(usage_text, stdout);
        return 0;
    }
    if (!strcmp(cmd, "--version")) {
        printf("stf %s\n", STF_PROJECT_VERSION);
        return 0;
    }
    if (!strcmp(cmd, "run")) return cli_run(argc - 2, argv + 2, 0);
    if (!strcmp(cmd, "check")) return cli_run(argc - 2, argv + 2, 1);
    if (!strcmp(cmd, "report")) return cli_report(argc - 2, argv + 2);
    if (!strcmp(cmd, "render")) return cli_render(argc - 2, argv + 2);
    if (!strcmp(cmd, "plot")) return cli_plot(argc - 2, argv + 2);
    if (!strcmp(cmd, "history")) return cli_history(argc - 2, argv + 2);
    if (!strcmp(cmd, "bench")) return cli_bench(argc - 2, argv + 2);
    if (!strcmp(cmd, "sweep")) return cli_sweep(argc - 2, argv + 2);
    fprintf(stderr, "stf: unknown %s '%s' (allowed: run, check, report, render, plot, history, "
            "bench, sweep, --help, --version)\n", cmd[0] == '-' ? "option" : "command", cmd);
    fputs(usage_text, stderr);
    return 2;
}

int cli_missing_value(const cli_usage *u, const char *opt, const char *const *valued)
{
    int known = 0;
    for (; *valued; valued++) known |= !strcmp(opt, *valued);
    if (known) return cli_usage_error(u, "option %s needs a value", opt);
    return cli_usage_error(u, "unknown option '%s'", opt);
}
