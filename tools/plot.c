/* plot.c - `stf plot OUT.h5`: a PNG with two stacked panels, a body's centre height z(t)
 * and its velocity (vertical vz(t) and horizontal speed), with the fluid's surface height S,
 * the centre height S - R under which the body's top is under S (the sink metric), first
 * contact, bounce peaks and the sink time marked. Without bodies the fluid's centre
 * of mass is plotted instead. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "canvas.h"
#include "h5io.h"
#include "metrics.h"
#include "pictures.h"

static const cli_usage USAGE = {
    "plot", "usage: stf plot OUT.h5 [-o FILE.png] [--body NAME] [--width W] [--height H]\n",
    "Draws a PNG of two panels: a body's centre height z(t) and its velocity (vz and the\n"
    "horizontal speed), with the fluid's surface height S, the centre height S - R under\n"
    "which the body's top is under S (the sink metric), the first contact, the bounce peaks\n"
    "and the sink time marked; without bodies, the fluid's centre of mass.\n"
    "options:\n"
    "  -o FILE.png   the picture (default: OUT_plot.png, OUT without .h5)\n"
    "  --body NAME   which body (default: the scene's first)\n"
    "  --width W     width in pixels, 320 to 8192 (default 1000)\n"
    "  --height H    height in pixels, 320 to 8192 (default 760)\n"
    "exit codes: 0 written, 2 bad input (bad option, unreadable file, no such body) or a write\n"
    "error\n"};

static const float BLACK[3] = {0.10f, 0.10f, 0.12f};
static const float WHITE[3] = {1, 1, 1};
static const float BLUE[3] = {0.12f, 0.35f, 0.75f};
static const float ORANGE[3] = {0.90f, 0.50f, 0.10f};
static const float GREEN[3] = {0.15f, 0.55f, 0.25f};
static const float RED[3] = {0.80f, 0.12f, 0.12f};
static const float GREY[3] = {0.45f, 0.45f, 0.48f};

#define TS 2 /* text scale */

typedef struct series {
    int n;
    double *t, *z, *vz, *vh;
} series;

static void series_free(series *s)
{
    free(s->t);
    free(s->z);
    free(s->vz);
    free(s->vh);
}

static int series_alloc(series *s, int n)
{
    s->n = n;
    s->t = malloc((size_t)(n > 0 ? n : 1) * sizeof(double));
    s->z = malloc((size_t)(n > 0 ? n : 1) * sizeof(double));
    s->vz = malloc((size_t)(n > 0 ? n : 1) * sizeof(double));
    s->vh = malloc((size_t)(n > 0 ? n : 1) * sizeof(double));
    return s->t && s->z && s->vz && s->vh ? 0 : -1;
}

/* ---------------------------------------------------------------- axes */

typedef canvas_axes panel;

static void draw_axes(canvas *c, const panel *p, const char *ylabel, int xlabels)
{
    canvas_axes_draw(c, p, 8, 5, xlabels, TS);
    canvas_text(c, p->x0, p->y0 - 24, ylabel, BLACK, TS);
}

static void draw_curve(canvas *c, const panel *p, const double *t, const double *v, int n,
                       const float rgb[3])
{
    for (int i = 1; i < n; i++)
        if (isfinite(v[i - 1]) && isfinite(v[i]))
            canvas_line(c, canvas_axes_x(p, t[i - 1]), canvas_axes_y(p, v[i - 1]), canvas_axes_x(p, t[i]), canvas_axes_y(p, v[i]), rgb, 2.2);
    if (n == 1 && isfinite(v[0])) canvas_circle(c, canvas_axes_x(p, t[0]), canvas_axes_y(p, v[0]), 3, rgb);
}

static void vmark(canvas *c, const panel *top, const panel *bot, double t, const char *label,
                  const float rgb[3], int label_row)
{
    if (!isfinite(t) || t < top->u0 || t > top->u1) return;
    double x = canvas_axes_x(top, t);
    canvas_line(c, x, top->y0, x, top->y1, rgb, 1.5);
    canvas_line(c, x, bot->y0, x, bot->y1, rgb, 1.5);
    int w = canvas_text_width(label, TS);
    int lx = (int)lround(x) + 6;
    if (lx + w > top->x1 - 4) lx = (int)lround(x) - 6 - w;
    canvas_text_halo(c, lx, top->y0 + 8 + label_row * 20, label, rgb, WHITE, TS);
}

static void minmax(const double *v, int n, double *lo, double *hi)
{
    for (int i = 0; i < n; i++)
        if (isfinite(v[i])) {
            if (v[i] < *lo) *lo = v[i];
            if (v[i] > *hi) *hi = v[i];
        }
}

/* Local maxima after contact that rise >= rise above the preceding minimum. */
static int bounce_peaks(const series *s, double t_contact, double rise, int *peaks, int max)
{
    int np = 0, i0 = 0;
    if (!isfinite(t_contact)) return 0;
    while (i0 < s->n && s->t[i0] < t_contact) i0++;
    if (i0 >= s->n) return 0;
    double lo = s->z[i0];
    int rising = 0, pk = i0;
    for (int i = i0; i < s->n; i++) {
        double z = s->z[i];
        if (!isfinite(z)) continue;
        if (!rising) {
            if (z < lo) lo = z;
            if (z - lo >= rise) rising = 1, pk = i;
        } else if (z >= s->z[pk]) {
            pk = i;
        } else if (s->z[pk] - z >= rise) {
            if (np < max) peaks[np++] = pk;
            rising = 0;
            lo = z;
        }
    }
    if (rising && pk < s->n - 1 && s->z[s->n - 1] < s->z[pk] && np < max) peaks[np++] = pk;
    return np;
}

/* ---------------------------------------------------------------- data */

static int body_data(const stf_h5r *r, const char *name, series *s, char *err, size_t errlen)
{
    double *t = NULL, *pos = NULL, *vel = NULL;
    int n = stf_h5r_body_series(r, name, &t, &pos, NULL, &vel, NULL, NULL);
    if (n < 0) {
        snprintf(err, errlen, "cannot read the series of body '%s'", name);
        return -1;
    }
    if (series_alloc(s, n) != 0) {
        free(t), free(pos), free(vel);
        snprintf(err, errlen, "out of memory");
        return -1;
    }
    for (int i = 0; i < n; i++) {
        s->t[i] = t[i];
        s->z[i] = pos[3 * i + 2];
        s->vz[i] = vel[3 * i + 2];
        s->vh[i] = hypot(vel[3 * i], vel[3 * i + 1]);
    }
    free(t), free(pos), free(vel);
    return 0;
}

static int fluid_data(const stf_h5r *r, series *s, char *err, size_t errlen)
{
    int nf = stf_h5r_frames(r);
    if (series_alloc(s, nf) != 0) {
        snprintf(err, errlen, "out of memory");
        return -1;
    }
    for (int f = 0; f < nf; f++) {
        int n = stf_h5r_frame_count(r, f);
        s->t[f] = stf_h5r_frame_time(r, f);
        s->z[f] = s->vz[f] = s->vh[f] = NAN;
        if (n <= 0) continue;
        double *x = malloc(3 * (size_t)n * sizeof *x), *v = malloc(3 * (size_t)n * sizeof *v);
        if (!x || !v || stf_h5r_read_frame(r, f, x, v) != 0) {
            free(x), free(v);
            snprintf(err, errlen, "cannot read frame %d", f);
            return -1;
        }
        double sz = 0, sv[3] = {0, 0, 0};
        int cnt = 0;
        for (int i = 0; i < n; i++) {
            if (!isfinite(x[3 * i + 2]) || !isfinite(v[3 * i]) || !isfinite(v[3 * i + 1]) ||
                !isfinite(v[3 * i + 2]))
                continue;
            sz += x[3 * i + 2];
            for (int k = 0; k < 3; k++) sv[k] += v[3 * i + k];
            cnt++;
        }
        if (cnt) {
            s->z[f] = sz / cnt;
            s->vz[f] = sv[2] / cnt;
            s->vh[f] = hypot(sv[0], sv[1]) / cnt;
        }
        free(x), free(v);
    }
    return 0;
}

/* ---------------------------------------------------------------- the command */

int cli_plot(int argc, char **argv)
{
    if (cli_help_asked(argc, argv)) return cli_help(&USAGE);
    const char *in = NULL, *out_opt = NULL, *body = NULL;
    int width = 1000, height = 760;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        if (a[0] != '-') {
            if (in) return cli_usage_error(&USAGE, "unexpected argument '%s'", a);
            in = a;
            continue;
        }
        if (i + 1 >= argc) {
            static const char *const valued[] = {"-o", "--body", "--width", "--height", NULL};
            return cli_missing_value(&USAGE, a, valued);
        }
        const char *val = argv[++i];
        if (!strcmp(a, "-o")) out_opt = val;
        else if (!strcmp(a, "--body")) body = val;
        else if (!strcmp(a, "--width") || !strcmp(a, "--height")) {
            char *end;
            long v = strtol(val, &end, 10);
            if (end == val || *end || v < 320 || v > 8192)
                return cli_usage_error(&USAGE, "bad value '%s' for %s (320..8192)", val, a);
            *(a[2] == 'w' ? &width : &height) = (int)v;
        } else {
            return cli_usage_error(&USAGE, "unknown option '%s'", a);
        }
    }
    if (!in) return cli_usage_error(&USAGE, "no output file given");

    char err[1024];
    stf_h5r *r = NULL;
    if (stf_h5r_open(in, &r, err, sizeof err) != 0) {
        fprintf(stderr, "stf plot: %s\n", err);
        return 2;
    }
    int rc = 2;
    char *outp = NULL, *first = NULL, *scene_name = NULL;
    series s = {0};
    canvas *c = NULL;

    /* which body */
    int nb = stf_h5r_body_count(r);
    if (body) {
        int found = 0;
        for (int i = 0; i < nb; i++)
            if (!strcmp(stf_h5r_body_name(r, i), body)) found = 1;
        if (!found) {
            fprintf(stderr, "stf plot: %s: no body '%s' (bodies:", in, body);
            for (int i = 0; i < nb; i++) fprintf(stderr, " %s", stf_h5r_body_name(r, i));
            fprintf(stderr, "%s)\n", nb ? "" : " none");
            goto out;
        }
    } else if (nb > 0) {
        first = stf_h5r_attr_string(r, "first_body");
        body = stf_h5r_body_name(r, 0);
        for (int i = 0; first && i < nb; i++)
            if (!strcmp(stf_h5r_body_name(r, i), first)) body = stf_h5r_body_name(r, i);
    }
    if ((body ? body_data(r, body, &s, err, sizeof err) : fluid_data(r, &s, err, sizeof err)) != 0) {
        fprintf(stderr, "stf plot: %s: %s\n", in, err);
        goto out;
    }
    if (s.n < 1) {
        fprintf(stderr, "stf plot: %s: nothing to plot (no %s)\n", in, body ? "body samples" : "frames");
        goto out;
    }

    /* markers */
    stf_metrics m;
    int have_m = stf_metrics_compute(in, &m, err, sizeof err) == 0;
    if (!have_m) fprintf(stderr, "stf plot: no markers (%s)\n", err);
    double surface = have_m ? m.surface_height : NAN, t_contact = NAN, t_sink = NAN;
    double sunk = NAN; /* the centre height below which the body's top is under S (sink_time) */
    int bounces = -1;
    for (int i = 0; have_m && body && i < m.nbodies; i++)
        if (!strcmp(m.bodies[i].name, body)) {
            if (m.bodies[i].radius > 0) sunk = surface - m.bodies[i].radius;
            t_contact = m.bodies[i].first_contact_time;
            t_sink = m.bodies[i].sink_time;
            bounces = m.bodies[i].bounces;
        }
    double spacing = 0.01, rise = 0;
    stf_h5r_attr_double(r, "spacing", &spacing);
    stf_h5r_attr_double(r, "bounce_min_rise", &rise);
    if (!(rise > 0)) rise = spacing / 4;
    int peaks[256];
    int np = body ? bounce_peaks(&s, t_contact, rise, peaks, 256) : 0;

    /* layout */
    c = canvas_new(width, height);
    if (!c) {
        fprintf(stderr, "stf plot: out of memory\n");
        goto out;
    }
    canvas_fill(c, WHITE);
    int left = 110, right = width - 30, top = 104, bottom = height - 76, gap = 70;
    int mid = (top + bottom - gap) / 2;
    panel pz = {left, top, right, mid, s.t[0], s.t[s.n - 1], INFINITY, -INFINITY};
    panel pv = {left, mid + gap, right, bottom, s.t[0], s.t[s.n - 1], INFINITY, -INFINITY};
    if (!(pz.u1 > pz.u0)) pz.u1 = pv.u1 = pz.u0 + 1;
    minmax(s.z, s.n, &pz.v0, &pz.v1);
    if (isfinite(surface)) minmax(&surface, 1, &pz.v0, &pz.v1);
    if (isfinite(sunk)) minmax(&sunk, 1, &pz.v0, &pz.v1);
    minmax(s.vz, s.n, &pv.v0, &pv.v1);
    minmax(s.vh, s.n, &pv.v0, &pv.v1);
    if (!isfinite(pz.v0)) pz.v0 = 0, pz.v1 = 1;
    if (!isfinite(pv.v0)) pv.v0 = 0, pv.v1 = 1;
    canvas_nice_range(&pz.v0, &pz.v1, 0);
    canvas_nice_range(&pv.v0, &pv.v1, 0);

    /* title */
    scene_name = stf_h5r_attr_string(r, "scene_path");
    char title[256];
    if (body) snprintf(title, sizeof title, "body '%s': centre height and velocity", body);
    else snprintf(title, sizeof title, "fluid centre of mass: height and velocity");
    canvas_text(c, left, 16, title, BLACK, 3);
    char sub[320];
    const char *base = strrchr(in, '/');
    if (body && bounces >= 0)
        snprintf(sub, sizeof sub, "%s   bounces: %d", base ? base + 1 : in, bounces);
    else snprintf(sub, sizeof sub, "%s", base ? base + 1 : in);
    canvas_text(c, left, 46, sub, GREY, TS);

    draw_axes(c, &pz, body ? "z (m)" : "z of centre of mass (m)", 1);
    draw_axes(c, &pv, "v (m/s)", 1);
    const char *xl = "t (s)";
    canvas_text(c, (left + right) / 2 - canvas_text_width(xl, TS) / 2, bottom + 42, xl, BLACK, TS);

    if (isfinite(surface) && surface >= pz.v0 && surface <= pz.v1) {
        double y = canvas_axes_y(&pz, surface);
        canvas_dashed_line(c, pz.x0, y, pz.x1, y, GREEN, 1.8, 10, 6);
        const char *lab = "surface";
        canvas_text_halo(c, pz.x1 - 8 - canvas_text_width(lab, TS), (int)lround(y) - 20, lab, GREEN, WHITE, TS);
    }
    if (isfinite(sunk) && sunk >= pz.v0 && sunk <= pz.v1) { /* the sink metric's line */
        double y = canvas_axes_y(&pz, sunk);
        canvas_dashed_line(c, pz.x0, y, pz.x1, y, GREY, 1.4, 6, 6);
        const char *lab = "surface - R: top under the surface";
        canvas_text_halo(c, pz.x0 + 8, (int)lround(y) + 6, lab, GREY, WHITE, TS);
    }
    if (pv.v0 < 0 && pv.v1 > 0) canvas_line(c, pv.x0, canvas_axes_y(&pv, 0), pv.x1, canvas_axes_y(&pv, 0), GREY, 1.2);

    vmark(c, &pz, &pv, t_contact, "contact", RED, 0);
    vmark(c, &pz, &pv, t_sink, "sink", GREY, 1);

    draw_curve(c, &pz, s.t, s.z, s.n, BLUE);
    draw_curve(c, &pv, s.t, s.vh, s.n, ORANGE);
    draw_curve(c, &pv, s.t, s.vz, s.n, BLUE);
    for (int i = 0; i < np; i++) {
        canvas_circle(c, canvas_axes_x(&pz, s.t[peaks[i]]), canvas_axes_y(&pz, s.z[peaks[i]]), 6, BLACK);
        canvas_circle(c, canvas_axes_x(&pz, s.t[peaks[i]]), canvas_axes_y(&pz, s.z[peaks[i]]), 4, ORANGE);
    }

    /* legend of the velocity panel (top right inside) */
    {
        const char *l1 = "vertical vz", *l2 = "horizontal speed";
        int lw = canvas_text_width(l2, TS) + 44, lx = pv.x1 - lw - 10, ly = pv.y0 + 10;
        const float frame[3] = {0.7f, 0.7f, 0.72f};
        canvas_rect(c, lx - 9, ly - 9, lx + lw + 1, ly + 47, frame);
        canvas_rect(c, lx - 8, ly - 8, lx + lw, ly + 46, WHITE);
        canvas_line(c, lx, ly + 7, lx + 30, ly + 7, BLUE, 2.5);
        canvas_text(c, lx + 40, ly, l1, BLACK, TS);
        canvas_line(c, lx, ly + 31, lx + 30, ly + 31, ORANGE, 2.5);
        canvas_text(c, lx + 40, ly + 24, l2, BLACK, TS);
    }
    if (np > 0) {
        const char *l = "bounce peak";
        int lx = pz.x1 - canvas_text_width(l, TS) - 40, ly = pz.y1 - 26;
        canvas_circle(c, lx + 4, ly + 7, 6, BLACK);
        canvas_circle(c, lx + 4, ly + 7, 4, ORANGE);
        canvas_text_halo(c, lx + 20, ly, l, BLACK, WHITE, TS);
    }

    if (out_opt) outp = strdup(out_opt);
    else {
        size_t len = strlen(in);
        outp = malloc(len + 16);
        if (outp) {
            strcpy(outp, in);
            if (len > 3 && !strcmp(outp + len - 3, ".h5")) outp[len - 3] = 0;
            strcat(outp, "_plot.png");
        }
    }
    if (!outp || canvas_write_png(c, outp, err, sizeof err) != 0) {
        fprintf(stderr, "stf plot: %s\n", outp ? err : "out of memory");
        goto out;
    }
    printf("stf plot: wrote %s\n", outp);
    rc = 0;
out:
    canvas_free(c);
    series_free(&s);
    free(outp);
    free(first);
    free(scene_name);
    stf_h5r_close(r);
    return rc;
}
