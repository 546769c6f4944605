/* stf.c - the command-line tool: run scenes, check expectations, report metrics.
 * Exit codes: 0 ok, 1 expectation failed, 2 bad input, 3 numerical failure,
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
#include "history_cli.h"
#include "pictures.h"

static const char usage_text[] =
    "usage:\n"
    "  stf run SCENE [-o OUT.h5] [--set KEY=VALUE]... [--unset KEY]... [--duration S]\n"
    "              [--threads N] [--quiet] [--checkpoint S|off | --checkpoint-frames N]\n"
    "              (--checkpoint: wall-clock seconds between checkpoints, default 60;\n"
    "              0: every frame; --checkpoint-frames: at every N-th frame of the file\n"
    "              instead; also taken on SIGINT/SIGTERM)\n"
    "  stf run --resume OUT.h5 | stf run SCENE [-o OUT.h5] --resume   (continue a stopped\n"
    "              run from its checkpoint, bit-identical; scene from the file or checked)\n"
    "  stf check SCENE [-o OUT.h5] [--set ...] [--unset ...] [--duration S] [--threads N]\n"
    "  stf report OUT.h5 [--json]\n"
    "  stf render OUT.h5 [-o DIR] [--frames all|N|A:B|a,b,c] [--every K] [--color speed|khist|none]\n"
    "             [--width W] [--height H] [--max V] [--camera x,y,z] [--look x,y,z]\n"
    "             [--montage FILE.png]\n"
    "  stf plot OUT.h5 [-o FILE.png] [--body NAME] [--width W] [--height H]\n"
    "  stf history [--fig 2|3|4|all] [-o DIR] [--q 0.2,0.5,0.8] [--d 50,150,500] [--dt S]\n"
    "              [--k-hist K] [--profile FILE.csv]   (paper Fig. 2-4)\n"
    "  stf bench table1 [BOWLING.yaml] | effects SCENE | scaling SCENE | grid SCENE | accuracy SCENE [-o DIR] | dam SCENE\n"
    "            | convergence SCENE [-o DIR] [--tolerance FRAC] [--jobs N]   (every metric at dt, dt/2,\n"
    "            dt/4 and 1.5x the spacing; exit 1 if one is not within FRAC of dt/4's, default 0.2;\n"
    "            stf bench convergence --help)\n"
    "            [--error M] [--knobs dt,spacing,history,solver] [--steps N] [--warmup N] [--duration S]\n"
    "            [--full] [--threads N] [--repeat R] (R interleaved rounds, each row's fastest)\n"
    "            [--grow spacing|domain]   (scaling: 10x the particles by a finer spacing or a wider pool)\n"
    "            [--set KEY=VALUE]... [--unset KEY]...   (cost of accuracy, paper Table 1)\n"
    "  stf sweep SCENE (--vary KEY=V1,V2,...|--vary KEY=START:STOP:COUNT)... | --list FILE\n"
    "            -o DIR [--repeat N] [--jobs N] [--threads N] [--duration S] [--set ...]\n"
    "            [--plot METRIC] [--x KEY] [--series KEY] [--png FILE]   (DIR/summary.csv, .png;\n"
    "            under mpirun the runs are spread over the ranks)\n"
    "exit codes: 0 ok, 1 expectation failed, 2 bad input, 3 numerical failure, "
    "130 interrupted\n";

static void usage(FILE *to) { fputs(usage_text, to); }

/* `stf CMD --help`: the usage lines of CMD (those from "  stf CMD " up to the next command's),
 * and the exit codes. */
static int command_help(const char *cmd)
{
    char head[32];
    snprintf(head, sizeof head, "  stf %s ", cmd);
    int on = 0;
    for (const char *l = usage_text; *l;) {
        const char *e = strchr(l, '\n');
        size_t len = e ? (size_t)(e - l + 1) : strlen(l);
        if (!strncmp(l, "  stf ", 6)) on = !strncmp(l, head, strlen(head));
        if (on || !strncmp(l, "exit codes", 10) || !strncmp(l, "usage:", 6))
            fwrite(l, 1, len, stdout);
        l += len;
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc < 2 || !strcmp(argv[1], "-h") || !strcmp(argv[1], "--help")) {
        usage(argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    const char *cmd = argv[1];
    static const char *const own_help[] = {"run", "check", "report", "plot", "bench"};
    for (size_t k = 0; k < sizeof own_help / sizeof *own_help; k++)
        if (!strcmp(cmd, own_help[k]) && argc > 2 &&
            (!strcmp(argv[2], "-h") || !strcmp(argv[2], "--help")))
            return command_help(cmd);
    if (!strcmp(cmd, "run")) return cli_run(argc - 2, argv + 2, 0);
    if (!strcmp(cmd, "check")) return cli_run(argc - 2, argv + 2, 1);
    if (!strcmp(cmd, "report")) return cli_report(argc - 2, argv + 2);
    if (!strcmp(cmd, "render")) return cli_render(argc - 2, argv + 2);
    if (!strcmp(cmd, "plot")) return cli_plot(argc - 2, argv + 2);
    if (!strcmp(cmd, "history")) return cli_history(argc - 2, argv + 2);
    if (!strcmp(cmd, "bench")) return cli_bench(argc - 2, argv + 2);
    if (!strcmp(cmd, "sweep")) return cli_sweep(argc - 2, argv + 2);
    if (!strcmp(cmd, "--version")) {
        printf("stf %s\n", STF_VERSION);
        return 0;
    }
    fprintf(stderr, "stf: unknown command '%s' (allowed: run, check, report, render, plot, history, bench, sweep)\n", cmd);
    usage(stderr);
    return 2;
}

int cli_missing_value(const char *cmd, const char *opt, const char *const *valued, const char *usage)
{
    int known = 0;
    for (; *valued; valued++) known |= !strcmp(opt, *valued);
    if (known) fprintf(stderr, "stf %s: option %s needs a value\n%s\n", cmd, opt, usage);
    else fprintf(stderr, "stf %s: unknown option '%s'\n%s\n", cmd, opt, usage);
    return 2;
}
