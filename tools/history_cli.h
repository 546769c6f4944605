/* history_cli.h - `stf history`: the single-particle analysis of the history-based springs
 * (paper section 3.2, Figures 2-4), computed with the simulation's own ring buffer and
 * weights (src/history.h). argv holds the arguments after the subcommand name. Returns the
 * exit code: 0 ok, 2 bad input (message on stderr). */
#ifndef STF_HISTORY_CLI_H
#define STF_HISTORY_CLI_H

int cli_history(int argc, char **argv);

#endif
