/* canvas.h - a small RGB raster for the picture commands (stf render, stf plot).
 *
 * Colours are linear floats in [0,1] (written to PNG as 8-bit, clamped). Every pixel has a
 * depth (camera distance, smaller = nearer; +inf after canvas_clear_depth) used by the 3-D
 * primitives (sphere splats, depth-tested lines and triangles); the 2-D primitives ignore
 * it. Coordinates are pixels, x to the right, y down, pixel centres at integer + 0.5.
 */
#ifndef STF_CANVAS_H
#define STF_CANVAS_H

#include <stddef.h>

typedef struct canvas {
    int w, h;
    float *rgb;   /* 3*w*h, row-major from the top */
    float *depth; /* w*h */
} canvas;

/* A w x h canvas (both >= 1), black, cleared depth. NULL if out of memory. */
canvas *canvas_new(int w, int h);
void canvas_free(canvas *c);

void canvas_fill(canvas *c, const float rgb[3]);
/* Vertical gradient from top to bottom colour. */
void canvas_fill_gradient(canvas *c, const float top[3], const float bottom[3]);
void canvas_clear_depth(canvas *c);

/* Blends colour into pixel (x, y) with coverage a in [0,1]; out-of-range is ignored. */
void canvas_blend(canvas *c, int x, int y, const float rgb[3], float a);

/* Anti-aliased line of the given width (pixels). */
void canvas_line(canvas *c, double x0, double y0, double x1, double y1, const float rgb[3],
                 double width);
/* Dashed line: dash and gap lengths in pixels. */
void canvas_dashed_line(canvas *c, double x0, double y0, double x1, double y1,
                        const float rgb[3], double width, double dash, double gap);
/* Depth-tested line: endpoints at depths z0, z1 (interpolated linearly on the screen). A
 * pixel is drawn where the line is nearer than the stored depth (+ bias); depth unchanged. */
void canvas_line_depth(canvas *c, double x0, double y0, double z0, double x1, double y1,
                       double z1, const float rgb[3], double width, double bias);

/* Filled anti-aliased circle (2-D, no depth). */
void canvas_circle(canvas *c, double cx, double cy, double r, const float rgb[3]);
/* Filled axis-aligned rectangle [x0,x1) x [y0,y1) (2-D). */
void canvas_rect(canvas *c, int x0, int y0, int x1, int y1, const float rgb[3]);

/* Shaded sphere splat: screen centre (cx, cy), screen radius r (pixels), centre depth z
 * and world radius rz (the depth of a point on the visible half is z - rz*sqrt(1-d^2)).
 * Lit by a fixed light from the upper left front: rgb*(ambient + diffuse N.L) + specular.
 * Depth-tested and depth-writing. */
void canvas_sphere(canvas *c, double cx, double cy, double r, double z, double rz,
                   const float rgb[3]);

/* Flat triangle with depth interpolated over it; depth-tested and depth-writing. */
void canvas_triangle(canvas *c, const double p0[3], const double p1[3], const double p2[3],
                     const float rgb[3]);

/* Text in the built-in 5x7 font (digits, letters, . - + : / = , ( ) _ % ' space; others show
 * as '?'), each font pixel a scale x scale block; (x, y) is the top left. */
void canvas_text(canvas *c, int x, int y, const char *s, const float rgb[3], int scale);
/* Same with a 1-pixel-per-scale outline in the halo colour (legible on any background). */
void canvas_text_halo(canvas *c, int x, int y, const char *s, const float rgb[3],
                      const float halo[3], int scale);
int canvas_text_width(const char *s, int scale);
int canvas_text_height(int scale);

/* Box-filter downsampling by an integer factor (w, h divisible by f). NULL if no memory. */
canvas *canvas_downsample(const canvas *src, int f);
/* Copies src into dst with its top left at (x, y) (clipped). */
void canvas_blit(canvas *dst, const canvas *src, int x, int y);

/* Writes an 8-bit RGB PNG. An existing file is replaced only if it is empty or a PNG. Returns
 * 0, or -1 with "PATH: why" in err. */
int canvas_write_png(const canvas *c, const char *path, char *err, size_t errlen);
/* 1 if path is a file that canvas_write_png would not replace (not empty, not a PNG). */
int canvas_holds_other_data(const char *path);

/* Axis ticks for charts: a 1-2-5 step giving about `want` intervals over range, and the
 * number of decimals that step needs in a label (0..6). */
double canvas_nice_step(double range, int want);

/* A plot's axes: the pixel box of the plotting area and the data ranges it shows. */
typedef struct canvas_axes {
    int x0, y0, x1, y1; /* pixels */
    double u0, u1;      /* x range */
    double v0, v1;      /* y range */
} canvas_axes;

static inline double canvas_axes_x(const canvas_axes *a, double u)
{
    return a->x0 + (u - a->u0) / (a->u1 - a->u0) * (a->x1 - a->x0);
}
static inline double canvas_axes_y(const canvas_axes *a, double v)
{
    return a->y1 - (v - a->v0) / (a->v1 - a->v0) * (a->y1 - a->y0);
}
/* Grid lines at about xwant x and ywant y ticks, tick marks, the numbers (x numbers only if
 * xnumbers) at text scale ts, and the frame around the area. */
void canvas_axes_draw(canvas *c, const canvas_axes *a, int xwant, int ywant, int xnumbers, int ts);
/* Widens [lo, hi] by 5% (to a span if empty) and rounds it out to whole ticks of about 5; with
 * keep_zero, a range starting at 0 stays there. */
void canvas_nice_range(double *lo, double *hi, int keep_zero);
int canvas_tick_decimals(double step);

#endif
