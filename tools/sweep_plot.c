/* sweep_plot.c - the chart of `stf sweep`: one metric against one varied key, one line per
 * value of a second key. A point whose runs all have a null metric (the event never
 * happened in the run, e.g. a ball that never sank has no float_duration) is an open marker
 * in a "never" band above the axis, so "never" is not mistaken for a value. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "canvas.h"
#include "sweep.h"

static const float BLACK[3] = {0.10f, 0.10f, 0.12f};
static const float WHITE[3] = {1, 1, 1};
static const float PALETTE[8][3] = {{0.12f, 0.35f, 0.75f}, {0.90f, 0.50f, 0.10f}, {0.15f, 0.55f, 0.25f},
                                    {0.80f, 0.12f, 0.12f}, {0.50f, 0.30f, 0.65f}, {0.55f, 0.35f, 0.20f},
                                    {0.85f, 0.40f, 0.70f}, {0.45f, 0.45f, 0.48f}};
#define TS 2 /* text scale */

typedef canvas_axes box;

static int find_key(const sweep_plan *p, const char *name)
{
    for (int k = 0; k < p->nkeys; k++)
        if (!strcmp(p->keys[k].key, name)) return k;
    return -1;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* A run's value of key k as a number; NAN if unset or not a number. */
static double num(const sweep_run *r, int k)
{
    if (k < 0 || !r->val[k]) return NAN;
    char *end;
    double v = strtod(r->val[k], &end);
    return *end || end == r->val[k] ? NAN : v;
}

/* A summary column's value: an expectation key, or BODY.final_x/_y/_z. */
static int metric_value(const stf_metrics *m, const char *key, double *v)
{
    if (stf_metrics_get(m, key, v) == 0) return 0;
    const char *dot = strrchr(key, '.');
    const char *f = dot ? dot + 1 : key;
    if (strcmp(f, "final_x") && strcmp(f, "final_y") && strcmp(f, "final_z")) return -1;
    for (int b = 0; b < m->nbodies; b++)
        if (!dot ? b == 0 : strlen(m->bodies[b].name) == (size_t)(dot - key) &&
                                !strncmp(m->bodies[b].name, key, (size_t)(dot - key))) {
            *v = m->bodies[b].final_position[f[6] - 'x'];
            return 0;
        }
    return -1;
}

static void axes(canvas *c, const box *b, const char *xlabel, const char *ylabel)
{
    canvas_axes_draw(c, b, 5, 6, 1, TS);
    canvas_text(c, (b->x0 + b->x1 - canvas_text_width(xlabel, TS)) / 2, b->y1 + 40, xlabel, BLACK, TS);
    canvas_text(c, b->x0, 46, ylabel, BLACK, TS); /* under the title, above any "never" band */
}

static void marker(canvas *c, double x, double y, const float rgb[3], int open)
{
    canvas_circle(c, x, y, 5, rgb);
    if (open) canvas_circle(c, x, y, 3, WHITE);
}

int sweep_plot_check(const sweep_plan *p, const stf_metrics *m0, const char *metric,
                     const char *xname, const char *sname, char *err, size_t errlen)
{
    if (p->nkeys == 0) return snprintf(err, errlen, "no varied keys"), -1;
    double probe;
    if (metric && metric_value(m0, metric, &probe) != 0)
        return snprintf(err, errlen, "--plot %s: no such metric (see the columns of summary.csv)", metric), -1;
    if (xname && find_key(p, xname) < 0) return snprintf(err, errlen, "--x %s: not a varied key", xname), -1;
    if (sname && find_key(p, sname) < 0)
        return snprintf(err, errlen, "--series %s: not a varied key", sname), -1;
    return 0;
}

int sweep_plot(const char *png, const sweep_plan *p, const char *metric, const char *xname,
               const char *sname, char *err, size_t errlen)
{
    const stf_metrics *m0 = NULL;
    for (int i = 0; i < p->nruns && !m0; i++)
        if (p->runs[i].have_metrics) m0 = &p->runs[i].m;
    if (!m0) return snprintf(err, errlen, p->nkeys ? "no finished run" : "no varied keys"), -1;
    char defmetric[96];
    if (!metric) {
        if (m0->nbodies > 0) snprintf(defmetric, sizeof defmetric, "%s.float_duration", m0->bodies[0].name);
        else snprintf(defmetric, sizeof defmetric, "fluid.max_speed");
        metric = defmetric;
    }
    if (sweep_plot_check(p, m0, metric, xname, sname, err, errlen) != 0) return -1;
    int kx = xname ? find_key(p, xname) : 0;
    int ks = sname ? find_key(p, sname) : (p->nkeys > 1 ? (kx == 0 ? 1 : 0) : -1);
    if (ks == kx) ks = -1;

    /* distinct x values (numeric, sorted) and series values (numeric sorted, else as met) */
    int n = p->nruns, nx = 0, ns = 0;
    double *xs = malloc((size_t)n * sizeof *xs), *sv = malloc((size_t)n * sizeof *sv);
    const char **sl = malloc((size_t)n * sizeof *sl);
    if (!xs || !sv || !sl) abort();
    for (int i = 0; i < n; i++) {
        double x = num(&p->runs[i], kx);
        if (isnan(x)) {
            free(xs), free(sv), free(sl);
            return snprintf(err, errlen, "key %s has a value that is not a number", p->keys[kx].key), -1;
        }
        int seen = 0;
        for (int j = 0; j < nx; j++) seen |= xs[j] == x;
        if (!seen) xs[nx++] = x;
        const char *s = ks >= 0 && p->runs[i].val[ks] ? p->runs[i].val[ks] : "";
        seen = 0;
        for (int j = 0; j < ns; j++) seen |= !strcmp(sl[j], s);
        if (!seen) sl[ns] = s, sv[ns++] = num(&p->runs[i], ks);
    }
    qsort(xs, (size_t)nx, sizeof *xs, cmp_double);
    int numeric = 1;
    for (int j = 0; j < ns; j++) numeric &= !isnan(sv[j]);
    for (int a = 1; numeric && a < ns; a++) /* insertion sort of the series by value */
        for (int b = a; b > 0 && sv[b] < sv[b - 1]; b--) {
            double t = sv[b];
            sv[b] = sv[b - 1], sv[b - 1] = t;
            const char *ts = sl[b];
            sl[b] = sl[b - 1], sl[b - 1] = ts;
        }

    /* mean of the finite values per (series, x); has[] counts runs, nfin[] finite ones */
    double *mean = calloc((size_t)(nx * ns), sizeof *mean);
    int *has = calloc((size_t)(nx * ns), sizeof *has), *nfin = calloc((size_t)(nx * ns), sizeof *nfin);
    if (!mean || !has || !nfin) abort();
    double lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i < n; i++) {
        const sweep_run *r = &p->runs[i];
        if (!r->have_metrics) continue;
        double x = num(r, kx), v;
        const char *s = ks >= 0 && r->val[ks] ? r->val[ks] : "";
        int ix = 0, is = 0;
        while (xs[ix] != x) ix++;
        while (strcmp(sl[is], s)) is++;
        has[is * nx + ix]++;
        if (metric_value(&r->m, metric, &v) == 0 && isfinite(v)) {
            mean[is * nx + ix] += v;
            nfin[is * nx + ix]++;
        }
    }
    int nnull = 0;
    for (int j = 0; j < nx * ns; j++) {
        if (nfin[j]) {
            mean[j] /= nfin[j];
            lo = fmin(lo, mean[j]), hi = fmax(hi, mean[j]);
        } else nnull += has[j] > 0;
    }
    if (!(lo <= hi)) lo = 0, hi = 1;
    if (lo > 0 && lo <= hi / 2) lo = 0; /* positive quantities from zero, unless bunched up */
    if (lo > 0 && lo == hi) lo = 0;

    canvas *c = canvas_new(1000, 600);
    if (!c) abort();
    canvas_fill(c, WHITE);
    /* nulls get a band of their own above the axis: "never" is not a value */
    int band = nnull ? 44 : 0;
    box b = {110, 70 + band, 730, 510, xs[0], xs[nx - 1], lo, hi};
    if (!(b.u1 > b.u0)) b.u0 -= 1, b.u1 += 1;
    double pad = (b.u1 - b.u0) * 0.04;
    b.u0 -= pad, b.u1 += pad;
    canvas_nice_range(&b.v0, &b.v1, 1);
    char title[256];
    snprintf(title, sizeof title, "%s vs %s", metric, p->keys[kx].key);
    canvas_text(c, b.x0, 14, title, BLACK, TS + 1);
    axes(c, &b, p->keys[kx].key, metric);
    if (band) {
        canvas_dashed_line(c, b.x0, b.y0 - band, b.x1, b.y0 - band, BLACK, 1, 6, 4);
        canvas_line(c, b.x0, b.y0 - band, b.x0, b.y0, BLACK, 1.5);
        canvas_line(c, b.x1, b.y0 - band, b.x1, b.y0, BLACK, 1.5);
        canvas_text(c, b.x0 - 12 - canvas_text_width("never", TS), b.y0 - band / 2 - 7, "never", BLACK, TS);
    }
    int ly = b.y0 - band;
    if (ks >= 0) {
        canvas_text(c, b.x1 + 20, ly, p->keys[ks].key, BLACK, TS);
        ly += 26;
    }
    for (int is = 0; is < ns; is++) {
        const float *col = PALETTE[is % 8];
        double px = NAN, py = NAN;
        for (int ix = 0; ix < nx; ix++) {
            int j = is * nx + ix;
            if (!has[j]) continue;
            double x = canvas_axes_x(&b, xs[ix]);
            if (nfin[j]) {
                double y = canvas_axes_y(&b, mean[j]);
                if (!isnan(px)) canvas_line(c, px, py, x, y, col, 2.2);
                px = x, py = y;
            } else px = py = NAN; /* a null breaks the line */
        }
        for (int ix = 0; ix < nx; ix++) {
            int j = is * nx + ix;
            if (!has[j]) continue;
            double x = canvas_axes_x(&b, xs[ix]);
            if (nfin[j]) marker(c, x, canvas_axes_y(&b, mean[j]), col, 0);
            else marker(c, x + 4.0 * (is - (ns - 1) / 2.0), b.y0 - band / 2, col, 1);
        }
        if (ks >= 0) {
            canvas_line(c, b.x1 + 20, ly + 7, b.x1 + 50, ly + 7, col, 2.2);
            marker(c, b.x1 + 35, ly + 7, col, 0);
            canvas_text(c, b.x1 + 60, ly, sl[is], BLACK, TS);
            ly += 24;
        }
    }
    if (nnull) {
        ly += 10;
        marker(c, b.x1 + 35, ly + 7, BLACK, 1);
        canvas_text(c, b.x1 + 50, ly, "null: never", BLACK, TS);
        canvas_text(c, b.x1 + 50, ly + 20, "in the run", BLACK, TS);
    }
    int rc = canvas_write_png(c, png, err, errlen);
    canvas_free(c);
    free(xs), free(sv), free(sl), free(mean), free(has), free(nfin);
    return rc;
}
