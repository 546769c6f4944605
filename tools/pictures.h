/* pictures.h - the picture commands of the stf tool (tools/render.c, tools/plot.c).
 * Each takes the arguments after the subcommand name and returns the process exit code:
 * 0 ok, 2 bad input (bad option, unreadable or invalid file) with a message on stderr. */
#ifndef STF_PICTURES_H
#define STF_PICTURES_H

/* stf render OUT.h5 [-o DIR] [--frames all|N|A:B|a,b,c] [--every K] [--width W]
 *            [--height H] [--color speed|khist|none] [--max V] [--camera x,y,z]
 *            [--look x,y,z] [--montage FILE.png] */
int cli_render(int argc, char **argv);

/* stf plot OUT.h5 [-o FILE.png] [--body NAME] [--width W] [--height H] */
int cli_plot(int argc, char **argv);

#endif
