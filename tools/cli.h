/* cli.h - the subcommands of the stf tool. Each returns the process exit code. */
#ifndef STF_CLI_H
#define STF_CLI_H

#include "stf.h"

int cli_run(int argc, char **argv, int check);
int cli_report(int argc, char **argv);
int cli_bench(int argc, char **argv); /* bench.c */

#endif
