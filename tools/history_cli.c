/* history_cli.c - `stf history`: the single-particle analysis of paper section 3.2.
 *
 * Figure 2: the weights a_{p,n} of Eq. 3 (stf_history_weight) at a fixed n for several q.
 * Figures 3 and 4: one history spring between a particle i that follows a velocity profile
 * (along x) and a particle j at rest. Both are pushed into the simulation's own ring
 * (stf_history_init / stf_history_push / stf_history_derivative of src/history.h) every step, and the
 * history stiffness of Eq. 5/6 is k_hist * stf_history_scale(q, dt) * |D_i - D_j| for each q and
 * each window d (plus the full history). Writes CSV + PNG per figure into one directory. */
#define _POSIX_C_SOURCE 200809L
#include "history_cli.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "canvas.h"
#include "history.h"
#include "stf.h"

static const cli_usage USAGE = {
    "history",
    "usage: stf history [--fig 2|3|4|all] [-o DIR] [--q 0.2,0.5,0.8] [--d 50,150,500]\n"
    "                   [--dt S] [--k-hist K] [--steps N] [--n N] [--profile FILE.csv]\n",
    "The single-particle analysis of the history springs (paper section 3.2, Figures 2-4),\n"
    "with the simulation's own weights: CSV and PNG files in DIR.\n"
    "options:\n"
    "  --fig      which figure(s) of paper section 3.2 (default all)\n"
    "  -o         output directory (default history_analysis)\n"
    "  --q        fractional orders, each in (0,1) (default 0.2,0.5,0.8)\n"
    "  --d        history windows in steps, 1 to 1000000 ('full' or 0: full history; the full\n"
    "             history is always added) (default 50,150,500)\n"
    "  --dt       time step in s, > 0 and <= 1000 (default 1/30)\n"
    "  --k-hist   history stiffness constant k_hist, >= 0 (default 1)\n"
    "  --steps    steps of the built-in profiles, 2 to 1000000 (default 300)\n"
    "  --n        current step n of the weights of figure 2, 1 to 100000 (default 50)\n"
    "  --profile  velocity profile instead of the built-in ones: one 'v' or 't,v' per line\n"
    "             (m/s, s; evenly spaced t sets dt), '#' comments, optional name header;\n"
    "             written as fig3_impact / fig4_constant with --fig 3 / 4, else as\n"
    "             profile_stiffness.csv/.png (next to figure 2)\n"
    "exit codes: 0 written, 2 bad input (bad option or profile) or a write error\n"};

#define MAXQ 8
#define MAXD 8
#define TS 2 /* text scale */

static const float BLACK[3] = {0.10f, 0.10f, 0.12f};
static const float WHITE[3] = {1, 1, 1};
static const float GREY[3] = {0.42f, 0.42f, 0.46f};
static const float FRAMEC[3] = {0.70f, 0.70f, 0.72f};
static const float VELC[3] = {0.80f, 0.15f, 0.15f};
static const float PALETTE[MAXD][3] = {
    {0.12f, 0.40f, 0.80f}, {0.92f, 0.50f, 0.08f}, {0.18f, 0.60f, 0.28f}, {0.60f, 0.25f, 0.70f},
    {0.55f, 0.35f, 0.20f}, {0.85f, 0.30f, 0.55f}, {0.10f, 0.65f, 0.70f}, {0.50f, 0.50f, 0.10f},
};

/* ---------------------------------------------------------------- plotting helpers */

typedef canvas_axes frame;


/* [0, hi] (or [lo, hi] when lo < 0) rounded out to whole ticks with a little headroom. */
static void y_range(double lo, double hi, double *b0, double *b1)
{
    if (!isfinite(lo) || !isfinite(hi)) lo = 0, hi = 1;
    if (lo > 0) lo = 0;
    if (!(hi > lo)) hi = lo + 1;
    double step = canvas_nice_step((hi - lo) * 1.06, 5);
    *b0 = lo < 0 ? floor(lo * 1.06 / step) * step : 0;
    *b1 = ceil(hi * 1.06 / step) * step;
    if (!(*b1 > *b0)) *b1 = *b0 + step;
}

/* Text where "^x" draws the run x (up to a space or ')') as a raised superscript. */
static int rich_width(const char *s, int scale)
{
    int w = 0, sup = 0;
    for (; *s; s++) {
        if (*s == '^') {
            sup = 1;
            continue;
        }
        if (sup && (*s == ' ' || *s == ')')) sup = 0;
        w += 6 * (sup && scale > 1 ? scale - 1 : scale);
    }
    return w > 0 ? w - 1 : 0;
}

static void rich_text(canvas *c, int x, int y, const char *s, const float rgb[3], int scale)
{
    int sup = 0;
    char one[2] = {0, 0};
    for (; *s; s++) {
        if (*s == '^') {
            sup = 1;
            continue;
        }
        if (sup && (*s == ' ' || *s == ')')) sup = 0;
        int sc = sup && scale > 1 ? scale - 1 : scale;
        one[0] = *s;
        canvas_text(c, x, sup ? y - 2 * scale : y, one, rgb, sc);
        x += 6 * sc;
    }
}

static void bold_text(canvas *c, int x, int y, const char *s, const float rgb[3], int scale)
{
    canvas_text(c, x, y, s, rgb, scale);
    canvas_text(c, x + 1, y, s, rgb, scale);
}

static void draw_frame(canvas *c, const frame *f, const char *title, const char *xlabel,
                       const char *ylabel)
{
    canvas_rect(c, f->x0, f->y0, f->x1, f->y1, WHITE);
    canvas_axes_draw(c, f, 8, 5, 1, TS);
    if (f->v0 < 0 && f->v1 > 0) canvas_line(c, f->x0, canvas_axes_y(f, 0), f->x1, canvas_axes_y(f, 0), GREY, 1.2);
    if (title) bold_text(c, (f->x0 + f->x1) / 2 - canvas_text_width(title, TS) / 2, f->y0 - 52, title, BLACK, TS);
    if (ylabel) rich_text(c, f->x0 - 60 > 4 ? f->x0 - 60 : 4, f->y0 - 30, ylabel, GREY, TS);
    if (xlabel) rich_text(c, (f->x0 + f->x1) / 2 - rich_width(xlabel, TS) / 2, f->y1 + 34, xlabel, GREY, TS);
}

/* Polyline (optionally dashed with a pattern continuing across the segments), clipped to
 * the frame's y range by clamping (the ranges are chosen to hold the data). */
static void draw_curve(canvas *c, const frame *f, const double *x, const double *y, int n,
                       const float rgb[3], double width, int dashed)
{
    const double dash = 12, gap = 7;
    double phase = 0; /* distance into the current dash+gap period */
    for (int i = 1; i < n; i++) {
        if (!isfinite(y[i - 1]) || !isfinite(y[i])) continue;
        double X0 = canvas_axes_x(f, x[i - 1]), Y0 = canvas_axes_y(f, y[i - 1]), X1 = canvas_axes_x(f, x[i]), Y1 = canvas_axes_y(f, y[i]);
        if (!dashed) {
            canvas_line(c, X0, Y0, X1, Y1, rgb, width);
            continue;
        }
        double len = hypot(X1 - X0, Y1 - Y0), s = 0;
        while (s < len) {
            int in_dash = phase < dash;
            double left = in_dash ? dash - phase : dash + gap - phase;
            if (left < 1e-6) { /* rounding at a dash boundary */
                phase = in_dash ? dash : 0;
                continue;
            }
            double e = s + left < len ? s + left : len;
            if (in_dash && len > 0)
                canvas_line(c, X0 + (X1 - X0) * s / len, Y0 + (Y1 - Y0) * s / len,
                            X0 + (X1 - X0) * e / len, Y0 + (Y1 - Y0) * e / len, rgb, width);
            phase += e - s;
            if (phase >= dash + gap) phase -= dash + gap;
            s = e;
        }
    }
}

typedef struct legend_item {
    char label[48];
    const float *rgb;
    int dashed, marker;
} legend_item;

/* A row of legend entries centred at (cx, y) inside a light frame. */
static void draw_legend_row(canvas *c, int cx, int y, const legend_item *it, int n)
{
    int total = 0;
    for (int i = 0; i < n; i++) total += 44 + canvas_text_width(it[i].label, TS) + (i + 1 < n ? 30 : 0);
    int x = cx - total / 2;
    canvas_rect(c, x - 13, y - 11, x + total + 13, y + 25, FRAMEC);
    canvas_rect(c, x - 12, y - 10, x + total + 12, y + 24, WHITE);
    for (int i = 0; i < n; i++) {
        double ly = y + 7;
        if (it[i].dashed) {
            canvas_line(c, x, ly, x + 12, ly, it[i].rgb, 3);
            canvas_line(c, x + 20, ly, x + 34, ly, it[i].rgb, 3);
        } else {
            canvas_line(c, x, ly, x + 34, ly, it[i].rgb, 3);
        }
        if (it[i].marker) canvas_circle(c, x + 17, ly, 4.5, it[i].rgb);
        canvas_text(c, x + 44, y, it[i].label, BLACK, TS);
        x += 44 + canvas_text_width(it[i].label, TS) + 30;
    }
}

/* ---------------------------------------------------------------- options */

typedef struct opts {
    int fig;                /* 0 all, else 2, 3, 4 */
    const char *dir;
    int nq;
    double q[MAXQ];
    int nd;
    int d[MAXD + 1];        /* ascending windows, the full history (0) last */
    double dt, k_hist;
    int steps, n_weights;
    const char *profile;
} opts;

static int parse_double(const char *s, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    while (*end == ' ' || *end == '\t' || *end == '\r') end++;
    if (end == s || *end || errno == ERANGE || !isfinite(v)) return -1;
    *out = v;
    return 0;
}

static int parse_int(const char *s, long lo, long hi, int *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (end == s || *end || errno == ERANGE || v < lo || v > hi) return -1;
    *out = (int)v;
    return 0;
}

static int cmp_int(const void *a, const void *b) { return (*(const int *)a > *(const int *)b) - (*(const int *)a < *(const int *)b); }

static int parse_q_list(const char *val, opts *o)
{
    char buf[256];
    if (strlen(val) >= sizeof buf) {
        fprintf(stderr, "stf history: --q value too long (at most %zu characters)\n", sizeof buf - 1);
        return -1;
    }
    strcpy(buf, val);
    o->nq = 0;
    for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        double q;
        if (o->nq >= MAXQ || parse_double(tok, &q) != 0 || !(q > 0 && q < 1)) {
            fprintf(stderr, "stf history: bad --q value '%s' (each in (0,1), at most %d)\n", tok, MAXQ);
            return -1;
        }
        o->q[o->nq++] = q;
    }
    if (o->nq == 0) {
        fprintf(stderr, "stf history: --q needs at least one value\n");
        return -1;
    }
    return 0;
}

static int parse_d_list(const char *val, opts *o)
{
    char buf[256];
    if (strlen(val) >= sizeof buf) {
        fprintf(stderr, "stf history: --d value too long (at most %zu characters)\n", sizeof buf - 1);
        return -1;
    }
    strcpy(buf, val);
    int n = 0, d[MAXD + 8];
    for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        int v;
        if (!strcmp(tok, "full")) v = 0;
        else if (parse_int(tok, 0, 1000000, &v) != 0) {
            fprintf(stderr, "stf history: bad --d value '%s' (steps >= 1, or 'full')\n", tok);
            return -1;
        }
        if (v == 0) continue; /* the full history is always there */
        int dup = 0;
        for (int k = 0; k < n; k++) dup |= d[k] == v;
        if (dup) continue;
        if (n >= MAXD - 1) {
            fprintf(stderr, "stf history: too many --d values (at most %d)\n", MAXD - 1);
            return -1;
        }
        d[n++] = v;
    }
    qsort(d, (size_t)n, sizeof *d, cmp_int);
    for (int k = 0; k < n; k++) o->d[k] = d[k];
    o->d[n] = 0;
    o->nd = n + 1;
    return 0;
}

/* ---------------------------------------------------------------- profiles */

typedef struct profile {
    int n;
    double *t, *v;
    char desc[512];
} profile;

static void profile_free(profile *p)
{
    free(p->t);
    free(p->v);
    p->t = p->v = NULL;
}

static int profile_alloc(profile *p, int n)
{
    p->n = n;
    p->t = malloc((size_t)n * sizeof *p->t);
    p->v = malloc((size_t)n * sizeof *p->v);
    return p->t && p->v ? 0 : -1;
}

/* Figure 3: an impact. */
static int builtin_impact(profile *p, int steps, double dt)
{
    const int s0 = 10, rise = 5, hold = 10, decay = 30;
    if (profile_alloc(p, steps + 1) != 0) return -1;
    for (int i = 0; i <= steps; i++) {
        double v = 0;
        if (i >= s0 && i < s0 + rise) v = (double)(i - s0) / rise;
        else if (i >= s0 + rise && i <= s0 + rise + hold) v = 1;
        else if (i > s0 + rise + hold && i < s0 + rise + hold + decay) v = 1 - (double)(i - s0 - rise - hold) / decay;
        p->t[i] = i * dt;
        p->v[i] = v;
    }
    snprintf(p->desc, sizeof p->desc,
             "built-in impact: v = 0 m/s until step %d, rises linearly to 1 m/s at step %d, stays "
             "1 m/s until step %d, decays linearly to 0 at step %d, then 0 (steps 0..%d)",
             s0, s0 + rise, s0 + rise + hold, s0 + rise + hold + decay, steps);
    return 0;
}

/* Figure 4: constant velocity from the first sample (the motion starts with the history, so
 * Eq. 3 - the trapezoidal rule of a piecewise-linear velocity - is exact for it). */
static int builtin_constant(profile *p, int steps, double dt)
{
    int stop = steps / 2;
    if (profile_alloc(p, steps + 1) != 0) return -1;
    for (int i = 0; i <= steps; i++) {
        p->t[i] = i * dt;
        p->v[i] = i <= stop ? 1.0 : 0.0;
    }
    snprintf(p->desc, sizeof p->desc,
             "built-in constant: v = 1 m/s from step 0 (t = 0, the start of the motion) to step %d "
             "(t = %g s), then 0 (steps 0..%d)", stop, stop * dt, steps);
    return 0;
}

/* One 'v' or 't,v' per line. On error prints FILE:LINE and returns -1. dt_given: --dt set. */
static int read_profile(const char *path, profile *p, double *dt, int dt_given)
{
    FILE *fp = fopen(path, "r");
    if (!fp) {
        fprintf(stderr, "stf history: %s: %s\n", path, strerror(errno));
        return -1;
    }
    char line[1024];
    int lineno = 0, cap = 0, ncols = 0, header_ok = 1, rc = -1;
    memset(p, 0, sizeof *p);
    while (fgets(line, sizeof line, fp)) {
        lineno++;
        size_t len = strlen(line);
        if (len == sizeof line - 1 && line[len - 1] != '\n') {
            fprintf(stderr, "stf history: %s:%d: line too long\n", path, lineno);
            goto out;
        }
        char *s = line;
        while (*s == ' ' || *s == '\t') s++;
        s[strcspn(s, "\r\n")] = 0;
        if (!*s || *s == '#') continue;
        char *num_end;
        strtod(s, &num_end);
        if (header_ok && num_end == s && ((*s >= 'a' && *s <= 'z') || (*s >= 'A' && *s <= 'Z'))) {
            header_ok = 0; /* a column-name header ('nan' or 'inf' is a value, refused below) */
            continue;
        }
        header_ok = 0;
        char *fields[3];
        int nf = 0;
        for (char *q = s;;) {
            if (nf < 3) fields[nf] = q;
            nf++;
            q += strcspn(q, ",;\t");
            if (!*q) break;
            *q++ = 0;
        }
        if (nf > 2) {
            fprintf(stderr, "stf history: %s:%d: expected 'v' or 't,v', got %d columns\n", path, lineno, nf);
            goto out;
        }
        if (ncols == 0) ncols = nf;
        else if (nf != ncols) {
            fprintf(stderr, "stf history: %s:%d: %d columns, the earlier lines have %d\n", path, lineno, nf, ncols);
            goto out;
        }
        double t = 0, v;
        int bad_field = nf == 2 && parse_double(fields[0], &t) != 0 ? 0
                        : parse_double(fields[nf - 1], &v) != 0 ? nf - 1 : -1;
        if (bad_field >= 0) {
            fprintf(stderr, "stf history: %s:%d: not a finite number: '%s'\n", path, lineno, fields[bad_field]);
            goto out;
        }
        if (p->n >= cap) {
            cap = cap ? 2 * cap : 256;
            if (cap > 10000000) {
                fprintf(stderr, "stf history: %s:%d: too many samples\n", path, lineno);
                goto out;
            }
            double *nt = realloc(p->t, (size_t)cap * sizeof *nt);
            if (nt) p->t = nt;
            double *nv = realloc(p->v, (size_t)cap * sizeof *nv);
            if (nv) p->v = nv;
            if (!nt || !nv) {
                fprintf(stderr, "stf history: out of memory\n");
                goto out;
            }
        }
        if (nf == 2 && p->n >= 1) {
            double h = t - p->t[p->n - 1];
            if (!(h > 0)) {
                fprintf(stderr, "stf history: %s:%d: time %g does not increase\n", path, lineno, t);
                goto out;
            }
            if (p->n == 1) {
                if (dt_given && fabs(h - *dt) > 1e-6 * *dt) {
                    fprintf(stderr, "stf history: %s:%d: time step %g differs from --dt %g\n", path, lineno, h, *dt);
                    goto out;
                }
                *dt = h;
            } else if (fabs(h - *dt) > 1e-6 * *dt + 1e-9 * fabs(t)) {
                fprintf(stderr, "stf history: %s:%d: time step %g, the earlier steps are %g (the "
                        "samples must be evenly spaced)\n", path, lineno, h, *dt);
                goto out;
            }
        }
        p->t[p->n] = t;
        p->v[p->n] = v;
        p->n++;
    }
    if (ferror(fp)) {
        fprintf(stderr, "stf history: %s: read error\n", path);
        goto out;
    }
    if (p->n < 2) {
        fprintf(stderr, "stf history: %s:%d: need at least 2 velocity samples, found %d\n", path, lineno, p->n);
        goto out;
    }
    if (ncols == 1)
        for (int i = 0; i < p->n; i++) p->t[i] = i * *dt;
    snprintf(p->desc, sizeof p->desc, "from %s: %d samples (%s), dt = %g s", path, p->n,
             ncols == 2 ? "t,v" : "v", *dt);
    rc = 0;
out:
    fclose(fp);
    if (rc != 0) profile_free(p);
    return rc;
}

/* ---------------------------------------------------------------- computation */

/* k[i] = k_hist * stf_history_scale(q, dt) * |D_0 - D_1| after pushing sample i: particle 0 moves
 * with v[i] along x, particle 1 is at rest. window 0: full history. */
static int stiffness_series(double q, int window, const profile *p, double dt, double k_hist, double *k)
{
    stf_history h;
    if (stf_history_init(&h, q, window, 2) != 0) return -1;
    double scale = stf_history_scale(q, dt);
    for (int i = 0; i < p->n; i++) {
        double v[6] = {p->v[i], 0, 0, 0, 0, 0};
        if (stf_history_push(&h, v, 2) != 0) {
            stf_history_free(&h);
            return -1;
        }
        stf_history_derivative(&h, 2);
        double dx = h.D[0] - h.D[3], dy = h.D[1] - h.D[4], dz = h.D[2] - h.D[5];
        k[i] = k_hist * scale * sqrt(dx * dx + dy * dy + dz * dz);
    }
    stf_history_free(&h);
    return 0;
}

static int mkdir_p(const char *dir)
{
    char buf[4096];
    if (strlen(dir) >= sizeof buf) return -1;
    strcpy(buf, dir);
    for (char *s = buf + 1; *s; s++)
        if (*s == '/') {
            *s = 0;
            if (mkdir(buf, 0777) != 0 && errno != EEXIST) return -1;
            *s = '/';
        }
    if (mkdir(buf, 0777) != 0 && errno != EEXIST) return -1;
    struct stat st;
    return stat(buf, &st) == 0 && S_ISDIR(st.st_mode) ? 0 : -1;
}

static void join(char *out, size_t n, const char *dir, const char *name) { snprintf(out, n, "%s/%s", dir, name); }

static int write_png(canvas *c, const char *path)
{
    char err[1024];
    if (canvas_write_png(c, path, err, sizeof err) != 0) {
        fprintf(stderr, "stf history: %s\n", err);
        return -1;
    }
    printf("stf history: wrote %s\n", path);
    return 0;
}

static void d_label(char *buf, size_t n, int d)
{
    if (d == 0) snprintf(buf, n, "full history");
    else snprintf(buf, n, "d = %d", d);
}

/* ---------------------------------------------------------------- figure 2 */

static int figure2(const opts *o)
{
    int n = o->n_weights;
    char path[4200];
    join(path, sizeof path, o->dir, "fig2_weights.csv");
    FILE *fp = fopen(path, "w");
    if (!fp) {
        fprintf(stderr, "stf history: %s: %s\n", path, strerror(errno));
        return -1;
    }
    fprintf(fp, "# stf history: figure 2, weights a_{p,n} of Eq. 3 (stf_history_weight) at n = %d\n", n);
    fprintf(fp, "# lag = n - p (steps back from the newest sample); p = 0 is the start point of the sum\n");
    fprintf(fp, "lag");
    for (int j = 0; j < o->nq; j++) fprintf(fp, ",q%g", o->q[j]);
    fprintf(fp, "\n");
    double *x = malloc((size_t)(n + 1) * sizeof *x), *w = malloc((size_t)(n + 1) * MAXQ * sizeof *w);
    if (!x || !w) {
        fclose(fp);
        free(x), free(w);
        fprintf(stderr, "stf history: out of memory\n");
        return -1;
    }
    double hi = 0;
    for (int lag = 0; lag <= n; lag++) {
        fprintf(fp, "%d", lag);
        x[n - lag] = n - lag; /* plotted against p */
        for (int j = 0; j < o->nq; j++) {
            double a = stf_history_weight(o->q[j], n - lag, n);
            w[(size_t)j * (size_t)(n + 1) + (size_t)(n - lag)] = a;
            if (a > hi) hi = a;
            fprintf(fp, ",%.12g", a);
        }
        fprintf(fp, "\n");
    }
    if (fclose(fp) != 0) {
        fprintf(stderr, "stf history: %s: write error\n", path);
        free(x), free(w);
        return -1;
    }
    printf("stf history: wrote %s\n", path);

    int W = 1200, H = 780;
    canvas *c = canvas_new(W, H);
    if (!c) {
        free(x), free(w);
        return -1;
    }
    canvas_fill(c, WHITE);
    char title[128];
    snprintf(title, sizeof title, "Weights a(p, n) of the fractional derivative (Eq. 3), n = %d", n);
    bold_text(c, W / 2 - canvas_text_width(title, 3) / 2, 18, title, BLACK, 3);
    const char *sub = "a(n, n) = 1 weights the newest velocity, smaller q remembers the past more";
    canvas_text(c, W / 2 - canvas_text_width(sub, TS) / 2, 52, sub, GREY, TS);
    legend_item it[MAXQ];
    for (int j = 0; j < o->nq; j++) {
        snprintf(it[j].label, sizeof it[j].label, "q = %g", o->q[j]);
        it[j].rgb = PALETTE[j % MAXD];
        it[j].dashed = 0;
        it[j].marker = 1;
    }
    draw_legend_row(c, W / 2, 92, it, o->nq);
    frame f = {110, 180, W - 40, H - 80, 0, n, 0, 1};
    y_range(0, hi, &f.v0, &f.v1);
    draw_frame(c, &f, NULL, "past time step p", "weight a(p, n)");
    for (int j = 0; j < o->nq; j++) {
        const double *wj = w + (size_t)j * (size_t)(n + 1);
        draw_curve(c, &f, x, wj, n + 1, PALETTE[j % MAXD], 2, 0);
        if (n <= 120)
            for (int p = 0; p <= n; p++) canvas_circle(c, canvas_axes_x(&f, x[p]), canvas_axes_y(&f, wj[p]), 3.6, PALETTE[j % MAXD]);
    }
    join(path, sizeof path, o->dir, "fig2_weights.png");
    int rc = write_png(c, path);
    canvas_free(c);
    free(x), free(w);
    return rc;
}

/* ---------------------------------------------------------------- figures 3 and 4 */

static int figure_stiffness(const opts *o, int which, const profile *p, double dt)
{
    /* which: 3 or 4, or 0 for a profile file with --fig all */
    const char *stem = which == 3 ? "fig3_impact" : which == 4 ? "fig4_constant" : "profile_stiffness";
    const char *kind = which == 3 ? "impact" : which == 4 ? "constant velocity" : "profile file";
    int n = p->n, nk = o->nq * o->nd;
    double *k = malloc((size_t)n * (size_t)nk * sizeof *k);
    if (!k) {
        fprintf(stderr, "stf history: out of memory\n");
        return -1;
    }
    for (int j = 0; j < o->nq; j++)
        for (int e = 0; e < o->nd; e++)
            if (stiffness_series(o->q[j], o->d[e], p, dt, o->k_hist,
                                 k + (size_t)(j * o->nd + e) * (size_t)n) != 0) {
                fprintf(stderr, "stf history: out of memory\n");
                free(k);
                return -1;
            }

    char path[4200], lab[64];
    snprintf(path, sizeof path, "%s/%s.csv", o->dir, stem);
    FILE *fp = fopen(path, "w");
    if (!fp) {
        fprintf(stderr, "stf history: %s: %s\n", path, strerror(errno));
        free(k);
        return -1;
    }
    if (which) fprintf(fp, "# stf history: figure %d (%s), history stiffness of one spring (Eq. 6)\n", which, kind);
    else fprintf(fp, "# stf history: history stiffness of one spring (Eq. 6) for a velocity profile file\n");
    fprintf(fp, "# velocity profile: %s\n", p->desc);
    fprintf(fp, "# particle i moves with v along x, particle j is at rest; both pushed into the "
                "simulation's history ring (src/history.c) every step\n");
    fprintf(fp, "# stiffness = k_hist * dt^(1-q)/Gamma(3-q) * |D_i - D_j| (1/s^2), k_hist = %g, dt = %.10g s\n",
            o->k_hist, dt);
    fprintf(fp, "# column qQ_dD: order q = Q, window d = D steps; qQ_full: full history\n");
    fprintf(fp, "step,t,v");
    for (int j = 0; j < o->nq; j++)
        for (int e = 0; e < o->nd; e++) {
            if (o->d[e]) fprintf(fp, ",q%g_d%d", o->q[j], o->d[e]);
            else fprintf(fp, ",q%g_full", o->q[j]);
        }
    fprintf(fp, "\n");
    for (int i = 0; i < n; i++) {
        fprintf(fp, "%d,%.10g,%.10g", i, p->t[i], p->v[i]);
        for (int s = 0; s < nk; s++) fprintf(fp, ",%.12g", k[(size_t)s * (size_t)n + (size_t)i]);
        fprintf(fp, "\n");
    }
    if (fclose(fp) != 0) {
        fprintf(stderr, "stf history: %s: write error\n", path);
        free(k);
        return -1;
    }
    printf("stf history: wrote %s\n", path);

    /* PNG: velocity top-left, then one panel per q (left-right, top-down) */
    int panels = 1 + o->nq, cols = 2, rows = (panels + cols - 1) / cols;
    int pw = 640, ph = 400, W = cols * pw + 40, H = 170 + rows * ph;
    canvas *c = canvas_new(W, H);
    if (!c) {
        free(k);
        return -1;
    }
    canvas_fill(c, WHITE);
    char title[160];
    const char *base = o->profile ? strrchr(o->profile, '/') : NULL;
    base = base ? base + 1 : o->profile;
    if (o->profile) snprintf(title, sizeof title, "History stiffness of one spring: velocity from %.60s", base);
    else snprintf(title, sizeof title, "History stiffness of one spring: %s",
                  which == 3 ? "impact (temporary velocity increase)" : "constant velocity for a period");
    bold_text(c, W / 2 - canvas_text_width(title, 3) / 2, 16, title, BLACK, 3);
    char sub[320];
    snprintf(sub, sizeof sub, "k_hist = %g, dt = %.4g s, %s", o->k_hist, dt,
             o->profile ? "velocity from the profile file" : "built-in velocity profile");
    int longest = 0;
    for (int e = 0; e < o->nd; e++)
        if (o->d[e] >= n - 1) longest = o->d[e];
    if (longest) {
        size_t l = strlen(sub);
        snprintf(sub + l, sizeof sub - l, "; d of %d steps or more = full history", n - 1);
    }
    canvas_text(c, W / 2 - canvas_text_width(sub, TS) / 2, 50, sub, GREY, TS);
    legend_item it[MAXD];
    for (int e = 0; e < o->nd; e++) {
        d_label(it[e].label, sizeof it[e].label, o->d[e]);
        it[e].rgb = o->d[e] ? PALETTE[e % MAXD] : BLACK;
        it[e].dashed = o->d[e] == 0;
        it[e].marker = 0;
    }
    draw_legend_row(c, W / 2, 88, it, o->nd);

    double t0 = p->t[0], t1 = p->t[n - 1];
    if (!(t1 > t0)) t1 = t0 + 1;
    for (int pi = 0; pi < panels; pi++) {
        int r = pi / cols, cc = pi % cols;
        int bx = 20 + cc * pw, by = 140 + r * ph;
        frame f = {bx + 90, by + 62, bx + pw - 24, by + ph - 62, t0, t1, 0, 1};
        if (pi == 0) {
            double lo = 0, hi = 0;
            for (int i = 0; i < n; i++) {
                if (p->v[i] < lo) lo = p->v[i];
                if (p->v[i] > hi) hi = p->v[i];
            }
            y_range(lo, hi, &f.v0, &f.v1);
            draw_frame(c, &f, "velocity of particle i", "t (s)", "v (m/s)");
            draw_curve(c, &f, p->t, p->v, n, VELC, 2.6, 0);
            continue;
        }
        int j = pi - 1;
        double hi = 0;
        for (int e = 0; e < o->nd; e++)
            for (int i = 0; i < n; i++) {
                double v = k[(size_t)(j * o->nd + e) * (size_t)n + (size_t)i];
                if (v > hi) hi = v;
            }
        y_range(0, hi, &f.v0, &f.v1);
        snprintf(lab, sizeof lab, "q = %g", o->q[j]);
        draw_frame(c, &f, lab, "t (s)", "stiffness (1/s^2)");
        /* windows from the longest down (solid), then the full history dashed on top */
        for (int e = o->nd - 1; e >= 0; e--) {
            int ee = e == 0 ? o->nd - 1 : e - 1;
            const double *ks = k + (size_t)(j * o->nd + ee) * (size_t)n;
            draw_curve(c, &f, p->t, ks, n, it[ee].rgb, it[ee].dashed ? 2.4 : 2.6, it[ee].dashed);
        }
    }
    snprintf(path, sizeof path, "%s/%s.png", o->dir, stem);
    int rc = write_png(c, path);
    canvas_free(c);
    free(k);
    return rc;
}

/* ---------------------------------------------------------------- the command */

int cli_history(int argc, char **argv)
{
    if (cli_help_asked(argc, argv)) return cli_help(&USAGE);
    opts o = {0};
    o.dir = "history_analysis";
    o.nq = 3;
    o.q[0] = 0.2, o.q[1] = 0.5, o.q[2] = 0.8;
    o.nd = 4;
    o.d[0] = 50, o.d[1] = 150, o.d[2] = 500, o.d[3] = 0;
    o.dt = 1.0 / 30.0;
    o.k_hist = 1;
    o.steps = 300;
    o.n_weights = 50;
    int dt_given = 0, steps_given = 0;

    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        if (a[0] != '-') return cli_usage_error(&USAGE, "unexpected argument '%s'", a);
        if (i + 1 >= argc) {
            static const char *const valued[] = {"--fig", "-o", "--q", "--d", "--dt", "--k-hist",
                                                 "--steps", "--n", "--profile", NULL};
            return cli_missing_value(&USAGE, a, valued);
        }
        const char *val = argv[++i];
        if (!strcmp(a, "--fig")) {
            if (!strcmp(val, "all")) o.fig = 0;
            else if (!strcmp(val, "2") || !strcmp(val, "3") || !strcmp(val, "4")) o.fig = val[0] - '0';
            else {
                fprintf(stderr, "stf history: bad --fig value '%s' (2, 3, 4 or all)\n", val);
                return 2;
            }
        } else if (!strcmp(a, "-o")) {
            if (!*val) {
                fprintf(stderr, "stf history: empty -o directory\n");
                return 2;
            }
            o.dir = val;
        } else if (!strcmp(a, "--q")) {
            if (parse_q_list(val, &o) != 0) return 2;
        } else if (!strcmp(a, "--d")) {
            if (parse_d_list(val, &o) != 0) return 2;
        } else if (!strcmp(a, "--dt")) {
            if (parse_double(val, &o.dt) != 0 || !(o.dt > 0) || o.dt > 1e3) {
                fprintf(stderr, "stf history: bad --dt value '%s' (s, > 0)\n", val);
                return 2;
            }
            dt_given = 1;
        } else if (!strcmp(a, "--k-hist")) {
            if (parse_double(val, &o.k_hist) != 0 || o.k_hist < 0) {
                fprintf(stderr, "stf history: bad --k-hist value '%s' (>= 0)\n", val);
                return 2;
            }
        } else if (!strcmp(a, "--steps")) {
            if (parse_int(val, 2, 1000000, &o.steps) != 0) {
                fprintf(stderr, "stf history: bad --steps value '%s' (2..1000000)\n", val);
                return 2;
            }
            steps_given = 1;
        } else if (!strcmp(a, "--n")) {
            if (parse_int(val, 1, 100000, &o.n_weights) != 0) {
                fprintf(stderr, "stf history: bad --n value '%s' (1..100000)\n", val);
                return 2;
            }
        } else if (!strcmp(a, "--profile")) {
            o.profile = val;
        } else {
            return cli_usage_error(&USAGE, "unknown option '%s'", a);
        }
    }
    if (o.profile && o.fig == 2) {
        fprintf(stderr, "stf history: --profile applies to figures 3 and 4, not to --fig 2\n");
        return 2;
    }
    if (o.profile && steps_given) {
        fprintf(stderr, "stf history: --steps cannot be combined with --profile (the file sets the steps)\n");
        return 2;
    }

    profile user = {0};
    double dt = o.dt;
    if (o.profile && read_profile(o.profile, &user, &dt, dt_given) != 0) return 2;
    if (mkdir_p(o.dir) != 0) {
        fprintf(stderr, "stf history: cannot create the directory %s: %s\n", o.dir, strerror(errno));
        profile_free(&user);
        return 2;
    }

    int rc = 0;
    if (o.fig == 0 || o.fig == 2)
        if (figure2(&o) != 0) rc = 2;
    for (int which = 3; which <= 4 && rc == 0; which++) {
        if (o.fig != 0 && o.fig != which) continue;
        if (o.profile && o.fig == 0 && which == 4) continue; /* one figure for the file */
        profile b = {0};
        const profile *p = &user;
        if (!o.profile) {
            if ((which == 3 ? builtin_impact(&b, o.steps, dt) : builtin_constant(&b, o.steps, dt)) != 0) {
                fprintf(stderr, "stf history: out of memory\n");
                profile_free(&b);
                rc = 2;
                break;
            }
            p = &b;
        }
        if (figure_stiffness(&o, o.profile && o.fig == 0 ? 0 : which, p, dt) != 0) rc = 2;
        profile_free(&b);
    }
    profile_free(&user);
    return rc;
}
