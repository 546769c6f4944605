/* stf.c - the command-line tool: run scenes, check expectations, report metrics.
 * Exit codes (DESIGN.md): 0 ok, 1 expectation failed, 2 bad input, 3 numerical failure,
 * 130 interrupted. */
#include <errno.h>
#include <math.h>
#include <omp.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"

static void usage(FILE *to)
{
    fputs("usage:\n"
          "  stf run SCENE [-o OUT.h5] [--set KEY=VALUE]... [--unset KEY]... [--duration S]\n"
          "              [--threads N] [--quiet]\n"
          "  stf check SCENE [-o OUT.h5] [--set ...] [--unset ...] [--duration S] [--threads N]\n"
          "  stf report OUT.h5 [--json]\n"
          "exit codes: 0 ok, 1 expectation failed, 2 bad input, 3 numerical failure, "
          "130 interrupted\n",
          to);
}

int main(int argc, char **argv)
{
    if (argc < 2 || !strcmp(argv[1], "-h") || !strcmp(argv[1], "--help")) {
        usage(argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    const char *cmd = argv[1];
    if (!strcmp(cmd, "run")) return cli_run(argc - 2, argv + 2, 0);
    if (!strcmp(cmd, "check")) return cli_run(argc - 2, argv + 2, 1);
    if (!strcmp(cmd, "report")) return cli_report(argc - 2, argv + 2);
    if (!strcmp(cmd, "--version")) {
        printf("stf %s\n", STF_VERSION);
        return 0;
    }
    fprintf(stderr, "stf: unknown command '%s' (allowed: run, check, report)\n", cmd);
    usage(stderr);
    return 2;
}
