/* metrics.c - metrics of a run, computed from its output file (definitions in metrics.h). */
#include "metrics.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "h5io.h"

typedef struct run_geometry {
    double spacing, min_rise;
    int has_container;
    double lo[3], hi[3]; /* container inner box */
    double pool_lo[2], pool_hi[2]; /* the fluid's horizontal extent at t = 0 (x, y), m */
} run_geometry;

static double attr_or(const stf_h5r *r, const char *name, double dflt)
{
    double v;
    return stf_h5r_attr_double(r, name, &v) == 0 ? v : dflt;
}

/* A body's shape from its "body.NAME.shape" attribute ("sphere R", "box HX HY HZ",
 * "capsule R HL", "cylinder R HL": radius, half extents, half length along local z). */
typedef struct body_shape {
    char kind[16];
    double a[3];
} body_shape;

/* How far the body reaches below and above its centre at orientation q (w, x, y, z): the
 * support of the shape along world z (the shapes are symmetric: the same both ways). */
static double shape_reach(const body_shape *s, const double *q)
{
    double w = q[0], x = q[1], y = q[2], z = q[3];
    double n = w * w + x * x + y * y + z * z;
    if (!(n > 0)) w = 1, x = y = z = 0, n = 1;
    /* the world z row of the rotation matrix: world z of the body's axes */
    double r0 = 2 * (x * z - w * y) / n, r1 = 2 * (y * z + w * x) / n, r2 = 1 - 2 * (x * x + y * y) / n;
    double h = 0;
    if (!strcmp(s->kind, "box")) h = fabs(r0) * s->a[0] + fabs(r1) * s->a[1] + fabs(r2) * s->a[2];
    else if (!strcmp(s->kind, "capsule")) h = s->a[0] + fabs(r2) * s->a[1];
    else if (!strcmp(s->kind, "cylinder"))
        h = fabs(r2) * s->a[1] + s->a[0] * sqrt(fmax(0, 1 - fmin(1, r2 * r2)));
    else h = s->a[0]; /* sphere */
    return h;
}

/* A rise from a local minimum being followed (body_metrics). */
typedef struct rise {
    int up;             /* 1 while rising clearly above zmin */
    double zmin, zmax;  /* m: the minimum, and the peak since */
    double peak_depth;  /* m: depth at the peak */
} rise;

/* Ends the rise being followed: a bounce if the body was on the surface at its peak. */
static void close_rise(rise *r, double R, stf_body_metrics *b)
{
    if (r->up && r->peak_depth <= 0.5 * R) {
        b->bounces++;
        if (r->zmax - r->zmin > b->max_rebound_height) b->max_rebound_height = r->zmax - r->zmin;
    }
    r->up = 0;
}

static void body_metrics(const stf_h5r *r, const char *name, double surface,
                         const run_geometry *g, stf_body_metrics *b)
{
    memset(b, 0, sizeof *b);
    snprintf(b->name, sizeof b->name, "%s", name);
    b->first_contact_time = b->sink_time = b->float_duration = NAN;
    b->rest_time = b->rolling_ratio = b->penetration_depth = NAN;
    char key[128];
    snprintf(key, sizeof key, "body.%s.half_height", name);
    double R = attr_or(r, key, 0.0);
    b->radius = R;
    snprintf(key, sizeof key, "body.%s.shape", name); /* the reach follows the orientation */
    char *shape_text = stf_h5r_attr_string(r, key);
    body_shape shape = {{0}, {0, 0, 0}};
    int oriented = shape_text && sscanf(shape_text, "%15s %lf %lf %lf", shape.kind, &shape.a[0],
                                        &shape.a[1], &shape.a[2]) >= 2;
    free(shape_text);
    double *t = NULL, *p = NULL, *v = NULL, *qs = NULL, *w = NULL;
    int n = stf_h5r_body_series(r, name, &t, &p, &qs, &v, &w, NULL);
    double *depth = n > 0 ? malloc((size_t)n * sizeof *depth) : NULL;
    if (n <= 0 || !depth) goto done;
    int contact = -1;
    for (int i = 0; i < n; i++) {
        double reach = oriented ? shape_reach(&shape, qs + 4 * i) : R;
        depth[i] = surface - (p[3 * i + 2] - reach); /* NaN without fluid: never in contact */
        /* beside the fluid (the centre outside its extent at t = 0): not in it, not on it */
        for (int a = 0; a < 2; a++)
            if (!(p[3 * i + a] >= g->pool_lo[a] && p[3 * i + a] <= g->pool_hi[a])) depth[i] = NAN;
        if (contact < 0 && depth[i] > 0) contact = i;
    }
    if (contact < 0) goto done;
    double tc = t[contact];
    b->first_contact_time = tc;
    b->penetration_depth = 0;
    /* penetration, bounces, roll */
    rise up = {0, p[3 * contact + 2], p[3 * contact + 2], depth[contact]};
    double ratio_sum = 0, ratio_path = 0;
    for (int i = contact; i < n; i++) {
        double z = p[3 * i + 2];
        if (t[i] <= tc + STF_PENETRATION_WINDOW && depth[i] > b->penetration_depth)
            b->penetration_depth = depth[i];
        if (!up.up) {
            if (z < up.zmin) up.zmin = z;
            if (z >= up.zmin + g->min_rise) up.up = 1, up.zmax = z, up.peak_depth = depth[i];
        } else if (z > up.zmax) {
            up.zmax = z, up.peak_depth = depth[i];
        } else if (z <= up.zmax - g->min_rise) { /* coming down again: the rise is over */
            close_rise(&up, R, b);
            up.zmin = z;
        }
        if (i > contact && depth[i] <= 0.5 * R && depth[i - 1] <= 0.5 * R) {
            double dx = p[3 * i] - p[3 * i - 3], dy = p[3 * i + 1] - p[3 * i - 2];
            double ds = sqrt(dx * dx + dy * dy);
            b->roll_distance += ds;
            const double *vi = v + 3 * i, *wi = w + 3 * i;
            double vh = sqrt(vi[0] * vi[0] + vi[1] * vi[1]);
            if (vh > STF_REST_SPEED) {
                ratio_sum += ds * sqrt(wi[0] * wi[0] + wi[1] * wi[1]) * R / vh;
                ratio_path += ds;
            }
        }
    }
    close_rise(&up, R, b); /* a rise still going at the end counts too */
    if (ratio_path > 0) b->rolling_ratio = ratio_sum / ratio_path;
    /* rest on the surface: the longest span of slow samples at depth <= R */
    int best = -1, start = -1;
    for (int i = contact; i <= n; i++) {
        int slow = 0;
        if (i < n) {
            const double *vi = v + 3 * i;
            slow = sqrt(vi[0] * vi[0] + vi[1] * vi[1] + vi[2] * vi[2]) < STF_REST_SPEED &&
                   depth[i] <= R;
        }
        if (slow && start < 0) start = i;
        if (!slow && start >= 0) {
            double span = t[i < n ? i : n - 1] - t[start];
            if (span > b->rest_on_surface || best < 0) b->rest_on_surface = span, best = start;
            start = -1;
        }
    }
    if (best >= 0) b->rest_time = t[best];
    for (int i = best >= 0 ? best : contact; i < n; i++) {
        double above = oriented ? shape_reach(&shape, qs + 4 * i) : R;
        if (!isnan(depth[i]) && p[3 * i + 2] + above < surface) {
            b->sink_time = t[i];
            b->float_duration = t[i] - tc;
            break;
        }
    }
done:
    if (n > 0)
        for (int a = 0; a < 3; a++) b->final_position[a] = p[3 * (n - 1) + a];
    free(depth);
    free(t);
    free(p);
    free(v);
    free(w);
    free(qs);
}

/* Column heights of a frame on a 2-spacing grid; returns the number of columns filled. */
static int column_heights(const double *x, int n, double cell, double *out, int maxcols)
{
    if (n == 0) return 0;
    double x0 = x[0], y0 = x[1], x1 = x[0], y1 = x[1];
    for (int i = 1; i < n; i++) {
        x0 = fmin(x0, x[3 * i]), x1 = fmax(x1, x[3 * i]);
        y0 = fmin(y0, x[3 * i + 1]), y1 = fmax(y1, x[3 * i + 1]);
    }
    double fx = floor((x1 - x0) / cell) + 1, fy = floor((y1 - y0) / cell) + 1;
    if (!(fx * fy <= maxcols)) return 0; /* also a particle flown far, or no finite one */
    int nx = (int)fx, ny = (int)fy;
    for (int c = 0; c < nx * ny; c++) out[c] = -INFINITY;
    for (int i = 0; i < n; i++) {
        if (!isfinite(x[3 * i]) || !isfinite(x[3 * i + 1]) || !isfinite(x[3 * i + 2])) continue;
        int cx = (int)((x[3 * i] - x0) / cell), cy = (int)((x[3 * i + 1] - y0) / cell);
        double *h = &out[cy * nx + cx];
        if (x[3 * i + 2] > *h) *h = x[3 * i + 2];
    }
    int m = 0;
    for (int c = 0; c < nx * ny; c++)
        if (out[c] > -INFINITY) out[m++] = out[c];
    return m;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The q-quantile of the m > 0 sorted values h, interpolated linearly between ranks. */
static double quantile_sorted(const double *h, int m, double q)
{
    double at = q * (m - 1);
    int lo = (int)floor(at), hi = lo + 1 < m ? lo + 1 : lo;
    return h[lo] + (at - lo) * (h[hi] - h[lo]);
}

/* 95th percentile of the column heights above their median; the roughness (standard
 * deviation) in *rough. */
static double finger_of(const double *x, int n, double spacing, double *rough)
{
    enum { MAXCOLS = 1 << 20 };
    double *h = malloc(MAXCOLS * sizeof *h);
    if (!h) return 0;
    int m = column_heights(x, n, 2 * spacing, h, MAXCOLS);
    double finger = 0, mean = 0, var = 0;
    if (m > 0) {
        qsort(h, (size_t)m, sizeof *h, cmp_double);
        double median = m % 2 ? h[m / 2] : 0.5 * (h[m / 2 - 1] + h[m / 2]);
        finger = quantile_sorted(h, m, 0.95) - median;
        for (int c = 0; c < m; c++) mean += h[c] / m;
        for (int c = 0; c < m; c++) var += (h[c] - mean) * (h[c] - mean) / m;
    }
    *rough = sqrt(var);
    free(h);
    return finger;
}

/* 1 when p is inside the container's inner box grown by one spacing. */
static int in_container(const run_geometry *g, const double *p)
{
    int in = 1;
    for (int a = 0; a < 3; a++) in &= p[a] >= g->lo[a] - g->spacing && p[a] <= g->hi[a] + g->spacing;
    return in;
}

/* Swaps particle i of x with particle m. */
static void swap_particles(double *x, int i, int m)
{
    for (int a = 0; a < 3; a++) {
        double t = x[3 * m + a];
        x[3 * m + a] = x[3 * i + a];
        x[3 * i + a] = t;
    }
}

/* Moves the particles inside the container (grown by one spacing; all particles without a
 * container) to the front of x; returns how many. The surface is the contained fluid's:
 * spilled particles lying outside are not columns of it. */
static int inside_first(double *x, int n, const run_geometry *g)
{
    if (!g->has_container) return n;
    int m = 0;
    for (int i = 0; i < n; i++)
        if (in_container(g, x + 3 * i)) swap_particles(x, i, m++);
    return m;
}

/* 99th percentile of the particle heights of a frame (x: 3n positions; tmp: n doubles). */
static double top_percentile(const double *x, int n, double *tmp)
{
    if (n <= 0) return NAN;
    for (int i = 0; i < n; i++) tmp[i] = x[3 * i + 2];
    qsort(tmp, (size_t)n, sizeof *tmp, cmp_double);
    return quantile_sorted(tmp, n, 0.99);
}

/* Union-find root with path halving. */
static int uf_root(int *parent, int i)
{
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
}

typedef struct cell_key {
    long long key; /* packed cell coordinates */
    int i;         /* particle */
} cell_key;

static int cmp_cell_key(const void *a, const void *b)
{
    long long x = ((const cell_key *)a)->key, y = ((const cell_key *)b)->key;
    return (x > y) - (x < y);
}

static long long pack_cell(long long cx, long long cy, long long cz)
{
    return ((cx + (1 << 20)) << 42) | ((cy + (1 << 20)) << 21) | (cz + (1 << 20));
}

/* Moves the particles of the fluid body to the front of x and returns how many: the
 * particles joined by chains of neighbours closer than STF_LINK_SPACINGS spacings (the
 * connected components), keeping each component that holds at least a tenth of the
 * particles (a hole may split the layer) and always the largest one. Drops and spray thrown
 * off the surface, separated from it by a visible gap, are not part of the surface.
 * Returns n (everything kept) when out of memory or a position is not finite or more than
 * a million links from the origin. */
static int bulk_first(double *x, int n, double spacing)
{
    const double link = STF_LINK_SPACINGS * spacing;
    if (n <= 1 || !(link > 0)) return n;
    int *parent = malloc((size_t)n * sizeof *parent), *size = calloc((size_t)n, sizeof *size);
    cell_key *k = malloc((size_t)n * sizeof *k);
    if (!parent || !size || !k) {
        free(parent), free(size), free(k);
        return n;
    }
    for (int i = 0; i < n; i++) {
        double c[3];
        for (int d = 0; d < 3; d++) {
            c[d] = floor(x[3 * i + d] / link);
            if (!(fabs(c[d]) < (1 << 20) - 2)) { /* NaN, or beyond the packed range */
                free(parent), free(size), free(k);
                return n;
            }
        }
        parent[i] = i;
        k[i].i = i;
        k[i].key = pack_cell((long long)c[0], (long long)c[1], (long long)c[2]);
    }
    qsort(k, (size_t)n, sizeof *k, cmp_cell_key);
    const double link2 = link * link;
    for (int a0 = 0, a1; a0 < n; a0 = a1) { /* the run k[a0, a1) is one cell */
        for (a1 = a0 + 1; a1 < n && k[a1].key == k[a0].key; a1++) continue;
        long long c[3];
        for (int d = 0; d < 3; d++) c[d] = (long long)floor(x[3 * k[a0].i + d] / link);
        for (int dx = -1; dx <= 1; dx++)
            for (int dy = -1; dy <= 1; dy++)
                for (int dz = -1; dz <= 1; dz++) {
                    long long want = pack_cell(c[0] + dx, c[1] + dy, c[2] + dz);
                    if (want < k[a0].key) continue; /* that pair of cells is met from the other */
                    int lo = a0, hi = n;            /* first entry with key >= want */
                    while (lo < hi) {
                        int mid = lo + (hi - lo) / 2;
                        if (k[mid].key < want) lo = mid + 1;
                        else hi = mid;
                    }
                    for (int ia = a0; ia < a1; ia++)
                        for (int b = want == k[a0].key ? ia + 1 : lo; b < n && k[b].key == want; b++) {
                            int i = k[ia].i, j = k[b].i;
                            double r2 = 0;
                            for (int d = 0; d < 3; d++) r2 += (x[3 * i + d] - x[3 * j + d]) * (x[3 * i + d] - x[3 * j + d]);
                            if (r2 < link2) {
                                int ri = uf_root(parent, i), rj = uf_root(parent, j);
                                if (ri != rj) parent[ri] = rj;
                            }
                        }
                }
    }
    int largest = 0;
    for (int i = 0; i < n; i++) {
        int r = uf_root(parent, i);
        if (++size[r] > size[largest]) largest = r;
    }
    int m = 0;
    for (int i = 0; i < n; i++) {
        int r = uf_root(parent, i);
        if (r == largest || 10 * size[r] >= n) swap_particles(x, i, m++);
    }
    free(parent), free(size), free(k);
    return m;
}

/* The bodies' centres and radii at time t (the nearest sample of each series), for the
 * density sample's exclusion zones. */
typedef struct body_track {
    int n;
    double *t, *p, R;
} body_track;

/* The density of the bulk of a frame (metrics.h, density_error_max): particles in the
 * container shrunk by Rc = 3 spacings, at least Rc under the median surface column and Rc
 * clear of every body; for each, the particles within Rc (itself included). Returns the
 * number of samples; their counts in cnt (n). */
static int bulk_counts(const double *x, int n, const run_geometry *g, const body_track *bt,
                       int nb, double t, double *cnt)
{
    double s = g->spacing, rc = 3 * s, rc2 = rc * rc;
    enum { MAXCOLS = 1 << 20 };
    double *col = malloc(MAXCOLS * sizeof *col);
    if (!col || n <= 0 || !g->has_container) {
        free(col);
        return 0;
    }
    int mcol = column_heights(x, n, 2 * s, col, MAXCOLS);
    double median = 0;
    if (mcol > 0) {
        qsort(col, (size_t)mcol, sizeof *col, cmp_double);
        median = mcol % 2 ? col[mcol / 2] : 0.5 * (col[mcol / 2 - 1] + col[mcol / 2]);
    }
    free(col);
    double c[STF_METRICS_MAX_BODIES][3];
    for (int b = 0; b < nb; b++) {
        int k = 0;
        while (k + 1 < bt[b].n && bt[b].t[k + 1] <= t) k++;
        for (int a = 0; a < 3; a++) c[b][a] = bt[b].n > 0 ? bt[b].p[3 * k + a] : NAN;
    }
    /* cells of Rc over the container box: the neighbours within Rc are in the 27 about */
    double lo[3], span[3];
    long dim[3];
    for (int a = 0; a < 3; a++) {
        lo[a] = g->lo[a] - s;
        span[a] = (a < 2 ? g->hi[a] + s : fmax(g->hi[a], median) + s) - lo[a];
        dim[a] = (long)(span[a] / rc) + 1;
    }
    long ncell = dim[0] * dim[1] * dim[2];
    int *head = malloc((size_t)ncell * sizeof *head), *next = malloc((size_t)n * sizeof *next);
    int m = 0;
    if (!head || !next) goto out;
    for (long k = 0; k < ncell; k++) head[k] = -1;
    for (int i = 0; i < n; i++) {
        long ci[3];
        int in = 1;
        for (int a = 0; a < 3; a++) {
            double u = floor((x[3 * i + a] - lo[a]) / rc);
            in &= u >= 0 && u < dim[a];
            ci[a] = in ? (long)u : 0;
        }
        next[i] = -1;
        if (!in) continue;
        long k = (ci[2] * dim[1] + ci[1]) * dim[0] + ci[0];
        next[i] = head[k];
        head[k] = i;
    }
    for (int i = 0; i < n; i++) {
        const double *p = x + 3 * i;
        int ok = p[2] >= g->lo[2] + rc && p[2] <= median - rc;
        for (int a = 0; a < 2; a++) ok &= p[a] >= g->lo[a] + rc && p[a] <= g->hi[a] - rc;
        for (int b = 0; b < nb && ok; b++) {
            double d2 = 0;
            for (int a = 0; a < 3; a++) d2 += (p[a] - c[b][a]) * (p[a] - c[b][a]);
            ok = !(d2 < (bt[b].R + rc) * (bt[b].R + rc)); /* NaN centre: no exclusion */
        }
        if (!ok) continue;
        long ci[3];
        for (int a = 0; a < 3; a++) ci[a] = (long)floor((p[a] - lo[a]) / rc);
        double count = 0; /* smooth weights: a lattice and a liquid read alike */
        for (long dz = -1; dz <= 1; dz++)
            for (long dy = -1; dy <= 1; dy++)
                for (long dx = -1; dx <= 1; dx++) {
                    long X = ci[0] + dx, Y = ci[1] + dy, Z = ci[2] + dz;
                    if (X < 0 || Y < 0 || Z < 0 || X >= dim[0] || Y >= dim[1] || Z >= dim[2]) continue;
                    for (int j = head[(Z * dim[1] + Y) * dim[0] + X]; j >= 0; j = next[j]) {
                        double d2 = 0;
                        for (int a = 0; a < 3; a++) d2 += (x[3 * j + a] - p[a]) * (x[3 * j + a] - p[a]);
                        double u = 1 - d2 / rc2;
                        count += d2 < rc2 ? u * u : 0.0;
                    }
                }
        cnt[m++] = count * s * s * s / (32.0 * 3.14159265358979323846 / 105.0 * rc * rc * rc); /* / its integral */
    }
out:
    free(head);
    free(next);
    return m;
}

/* density_error_max / density_error_local over the frames (metrics.h). */
static void density_errors(const stf_h5r *r, const run_geometry *g, stf_metrics *m)
{
    int nb = stf_h5r_body_count(r);
    if (nb > STF_METRICS_MAX_BODIES) nb = STF_METRICS_MAX_BODIES;
    body_track bt[STF_METRICS_MAX_BODIES];
    for (int b = 0; b < nb; b++) {
        char key[128];
        const char *name = stf_h5r_body_name(r, b);
        bt[b].t = bt[b].p = NULL;
        bt[b].n = stf_h5r_body_series(r, name, &bt[b].t, &bt[b].p, NULL, NULL, NULL, NULL);
        snprintf(key, sizeof key, "body.%s.half_height", name);
        bt[b].R = attr_or(r, key, 0.0);
    }
    int nf = stf_h5r_frames(r);
    m->density_error_max = m->density_error_local = m->density_error_first = NAN;
    for (int f = 0; f < nf; f++) {
        int n = stf_h5r_frame_count(r, f);
        double *x = malloc((size_t)(n > 0 ? n : 1) * 3 * sizeof *x);
        double *cnt = malloc((size_t)(n > 0 ? n : 1) * sizeof *cnt);
        int k = x && cnt && stf_h5r_read_frame(r, f, x, NULL) == 0
                    ? bulk_counts(x, n, g, bt, nb, stf_h5r_frame_time(r, f), cnt)
                    : 0;
        if (k > 0) {
            double mean = 0;
            for (int i = 0; i < k; i++) mean += cnt[i] / k;
            if (f == 0) m->density_error_first = mean - 1;
            else {
                double e = mean - 1;
                if (!(fabs(e) <= m->density_error_max)) m->density_error_max = fabs(e);
                double *err = malloc((size_t)k * sizeof *err);
                if (err) {
                    for (int i = 0; i < k; i++) err[i] = fabs(cnt[i] - 1);
                    qsort(err, (size_t)k, sizeof *err, cmp_double);
                    double p95 = quantile_sorted(err, k, 0.95);
                    if (!(p95 <= m->density_error_local)) m->density_error_local = p95;
                    free(err);
                }
            }
        }
        free(x);
        free(cnt);
    }
    for (int b = 0; b < nb; b++) free(bt[b].t), free(bt[b].p);
}

static int fluid_metrics(const stf_h5r *r, const run_geometry *g, stf_metrics *m)
{
    int nf = stf_h5r_frames(r);
    double com_lowest = INFINITY, top_lowest = INFINITY, speed_prev = NAN, rg0 = NAN;
    int second_half = nf / 2, counted = 0;
    m->impact_time = m->solid_duration = NAN;
    for (int f = 0; f < nf; f++) {
        int n = stf_h5r_frame_count(r, f);
        double *x = malloc((size_t)(n > 0 ? n : 1) * 3 * sizeof *x);
        double *v = malloc((size_t)(n > 0 ? n : 1) * 3 * sizeof *v);
        if (!x || !v || stf_h5r_read_frame(r, f, x, v) != 0) {
            free(x);
            free(v);
            return -1;
        }
        double c[3] = {0, 0, 0}, vc[3] = {0, 0, 0}; /* centre of mass and its velocity */
        for (int i = 0; i < n; i++)
            for (int a = 0; a < 3; a++) c[a] += x[3 * i + a] / n, vc[a] += v[3 * i + a] / n;
        double rg = 0;
        for (int i = 0; i < n; i++)
            for (int a = 0; a < 3; a++) rg += (x[3 * i + a] - c[a]) * (x[3 * i + a] - c[a]) / n;
        rg = sqrt(rg);
        double speed = sqrt(vc[0] * vc[0] + vc[1] * vc[1] + vc[2] * vc[2]);
        double t = stf_h5r_frame_time(r, f);
        if (f == 0) rg0 = rg;
        if (isnan(m->impact_time) && speed < speed_prev) m->impact_time = t;
        if (!isnan(m->impact_time) && isnan(m->solid_duration) && rg > 1.5 * rg0)
            m->solid_duration = t - m->impact_time;
        speed_prev = speed;
        for (int i = 0; i < n; i++) {
            double s = sqrt(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
            if (!isfinite(s) || !isfinite(x[3 * i]) || !isfinite(x[3 * i + 1]) || !isfinite(x[3 * i + 2]))
                m->nan = 1;
            else if (s > m->max_speed) m->max_speed = s;
        }
        if (n > 0) {
            if (c[2] < com_lowest) com_lowest = c[2];
            if (c[2] - com_lowest > m->com_rebound_height) m->com_rebound_height = c[2] - com_lowest;
            double *z = malloc((size_t)n * sizeof *z), top = z ? top_percentile(x, n, z) : NAN;
            free(z);
            if (top < top_lowest) top_lowest = top;
            if (top - top_lowest > m->splash_height) m->splash_height = top - top_lowest;
        }
        if (f >= second_half) {
            double rough = 0;
            m->finger_height += finger_of(x, bulk_first(x, inside_first(x, n, g), g->spacing), g->spacing, &rough);
            counted++;
            if (f == nf - 1) m->surface_roughness = rough;
        }
        if (f == nf - 1) {
            m->particles = n;
            m->final_com_height = c[2];
            for (int i = 0; g->has_container && i < n; i++) m->escaped += !in_container(g, x + 3 * i);
        }
        free(x);
        free(v);
    }
    if (counted) m->finger_height /= counted;
    if (!isnan(m->impact_time) && isnan(m->solid_duration))
        m->solid_duration = m->time_end - m->impact_time; /* never spread: a lower bound */
    return 0;
}

/* The fluid's top at t = 0 (S), and its horizontal extent into g (both half a spacing past the
 * outermost centres; NaN, and an empty extent, without particles). */
static double surface_of_first_frame(const stf_h5r *r, run_geometry *g)
{
    double s = g->spacing;
    g->pool_lo[0] = g->pool_lo[1] = INFINITY;
    g->pool_hi[0] = g->pool_hi[1] = -INFINITY;
    int n = stf_h5r_frames(r) > 0 ? stf_h5r_frame_count(r, 0) : 0;
    if (n <= 0) return NAN;
    double *x = malloc((size_t)n * 3 * sizeof *x);
    double top = -INFINITY;
    if (x && stf_h5r_read_frame(r, 0, x, NULL) == 0)
        for (int i = 0; i < n; i++) {
            top = fmax(top, x[3 * i + 2]);
            for (int a = 0; a < 2; a++) {
                g->pool_lo[a] = fmin(g->pool_lo[a], x[3 * i + a] - 0.5 * s);
                g->pool_hi[a] = fmax(g->pool_hi[a], x[3 * i + a] + 0.5 * s);
            }
        }
    free(x);
    return top + 0.5 * s;
}

int stf_metrics_compute(const char *path, stf_metrics *m, char *err, size_t errlen)
{
    memset(m, 0, sizeof *m);
    stf_h5r *r;
    if (stf_h5r_open(path, &r, err, errlen) != 0) return 2;
    run_geometry g = {0};
    if (stf_h5r_attr_double(r, "spacing", &g.spacing) != 0 || !(g.spacing > 0)) {
        snprintf(err, errlen, "%s: not an stf output file (no 'spacing' attribute)", path);
        stf_h5r_close(r);
        return 2;
    }
    g.min_rise = attr_or(r, "bounce_min_rise", 0.0);
    if (!(g.min_rise > 0)) g.min_rise = 0.25 * g.spacing;
    const char *names[6] = {"container_x0", "container_y0", "container_z0",
                            "container_x1", "container_y1", "container_z1"};
    g.has_container = 1;
    for (int a = 0; a < 6; a++) {
        double *dst = a < 3 ? &g.lo[a] : &g.hi[a - 3];
        if (stf_h5r_attr_double(r, names[a], dst) != 0) g.has_container = 0;
    }
    int nf = stf_h5r_frames(r);
    m->time_end = nf > 0 ? stf_h5r_frame_time(r, nf - 1) : 0;
    m->surface_height = surface_of_first_frame(r, &g);
    int nb = stf_h5r_body_count(r);
    for (int k = 0; k < nb && k < STF_METRICS_MAX_BODIES; k++)
        body_metrics(r, stf_h5r_body_name(r, k), m->surface_height, &g, &m->bodies[m->nbodies++]);
    char *first = stf_h5r_attr_string(r, "first_body"); /* the scene's first body leads */
    for (int k = 1; first && k < m->nbodies; k++)
        if (!strcmp(m->bodies[k].name, first)) {
            stf_body_metrics t = m->bodies[0];
            m->bodies[0] = m->bodies[k];
            m->bodies[k] = t;
        }
    free(first);
    int rc = fluid_metrics(r, &g, m); /* after time_end: solid_duration may need it */
    density_errors(r, &g, m);
    stf_h5r_close(r);
    if (rc != 0) {
        snprintf(err, errlen, "%s: cannot read the particle frames", path);
        return 2;
    }
    return 0;
}

/* ------------------------------------------------------------------------ output */

typedef struct sbuf {
    char *s;
    size_t len, cap;
} sbuf;

static void put(sbuf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
#include <stdarg.h>
static void put(sbuf *b, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int need = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (need < 0) return;
    if (b->len + (size_t)need + 1 > b->cap) {
        size_t cap = 2 * (b->len + (size_t)need + 1);
        char *s = realloc(b->s, cap);
        if (!s) return;
        b->s = s, b->cap = cap;
    }
    va_start(ap, fmt);
    vsnprintf(b->s + b->len, b->cap - b->len, fmt, ap);
    va_end(ap);
    b->len += (size_t)need;
}

static void put_num(sbuf *b, double v)
{
    if (isfinite(v)) put(b, "%.9g", v);
    else put(b, "null");
}

/* ", \"key\": " and the value. */
static void put_field(sbuf *b, const char *key, double v)
{
    put(b, ", \"%s\": ", key);
    put_num(b, v);
}

char *stf_metrics_json(const stf_metrics *m)
{
    sbuf b = {0};
    put(&b, "{\"time_end\": ");
    put_num(&b, m->time_end);
    put_field(&b, "surface_height", m->surface_height);
    put(&b, ",\n \"bodies\": {");
    for (int k = 0; k < m->nbodies; k++) {
        const stf_body_metrics *o = &m->bodies[k];
        put(&b, "%s\n  \"%s\": {\"radius\": ", k ? "," : "", o->name);
        put_num(&b, o->radius);
        put_field(&b, "first_contact_time", o->first_contact_time);
        put_field(&b, "penetration_depth", o->penetration_depth);
        put(&b, ", \"bounces\": %d", o->bounces);
        put_field(&b, "max_rebound_height", o->max_rebound_height);
        put_field(&b, "roll_distance", o->roll_distance);
        put_field(&b, "rolling_ratio", o->rolling_ratio);
        put_field(&b, "rest_on_surface", o->rest_on_surface);
        put_field(&b, "rest_time", o->rest_time);
        put_field(&b, "sink_time", o->sink_time);
        put_field(&b, "float_duration", o->float_duration);
        put(&b, ", \"final_position\": [");
        for (int a = 0; a < 3; a++) {
            if (a) put(&b, ", ");
            put_num(&b, o->final_position[a]); /* null, not the invalid nan */
        }
        put(&b, "]}");
    }
    put(&b, "},\n \"fluid\": {\"particles\": %ld, \"escaped\": %ld, \"max_speed\": ", m->particles,
        m->escaped);
    put_num(&b, m->max_speed);
    put(&b, ", \"nan\": %s, \"com_rebound_height\": ", m->nan ? "true" : "false");
    put_num(&b, m->com_rebound_height);
    put_field(&b, "finger_height", m->finger_height);
    put_field(&b, "surface_roughness", m->surface_roughness);
    put_field(&b, "final_com_height", m->final_com_height);
    put_field(&b, "impact_time", m->impact_time);
    put_field(&b, "solid_duration", m->solid_duration);
    put_field(&b, "splash_height", m->splash_height);
    put_field(&b, "density_error_max", m->density_error_max);
    put_field(&b, "density_error_local", m->density_error_local);
    put_field(&b, "density_error_first", m->density_error_first);
    put(&b, "}}\n");
    return b.s;
}

const char *const stf_body_metric_names[] = {
    "radius",          "first_contact_time", "penetration_depth", "bounces",
    "max_rebound_height", "roll_distance",   "rolling_ratio",     "rest_on_surface",
    "rest_time",       "sink_time",          "float_duration",    NULL};

static int body_field(const stf_body_metrics *b, const char *f, double *v)
{
    if (!strcmp(f, "radius")) *v = b->radius;
    else if (!strcmp(f, "first_contact_time")) *v = b->first_contact_time;
    else if (!strcmp(f, "penetration_depth")) *v = b->penetration_depth;
    else if (!strcmp(f, "bounces")) *v = b->bounces;
    else if (!strcmp(f, "max_rebound_height")) *v = b->max_rebound_height;
    else if (!strcmp(f, "roll_distance")) *v = b->roll_distance;
    else if (!strcmp(f, "rolling_ratio")) *v = b->rolling_ratio;
    else if (!strcmp(f, "rest_on_surface")) *v = b->rest_on_surface;
    else if (!strcmp(f, "rest_time")) *v = b->rest_time;
    else if (!strcmp(f, "sink_time")) *v = b->sink_time;
    else if (!strcmp(f, "float_duration")) *v = b->float_duration;
    else return -1;
    return 0;
}

const char *const stf_fluid_metric_names[] = {
    "particles",     "escaped",           "max_speed",        "com_rebound_height",
    "finger_height", "surface_roughness", "final_com_height", "impact_time",
    "solid_duration", "splash_height",    "density_error_max", "density_error_local",
    "density_error_first", NULL};

int stf_metrics_get(const stf_metrics *m, const char *key, double *v)
{
    if (!strcmp(key, "time_end")) return *v = m->time_end, 0;
    if (!strcmp(key, "surface_height")) return *v = m->surface_height, 0;
    if (!strncmp(key, "fluid.", 6)) {
        const char *f = key + 6;
        if (!strcmp(f, "particles")) *v = (double)m->particles;
        else if (!strcmp(f, "escaped")) *v = (double)m->escaped;
        else if (!strcmp(f, "max_speed")) *v = m->max_speed;
        else if (!strcmp(f, "com_rebound_height")) *v = m->com_rebound_height;
        else if (!strcmp(f, "finger_height")) *v = m->finger_height;
        else if (!strcmp(f, "surface_roughness")) *v = m->surface_roughness;
        else if (!strcmp(f, "final_com_height")) *v = m->final_com_height;
        else if (!strcmp(f, "impact_time")) *v = m->impact_time;
        else if (!strcmp(f, "solid_duration")) *v = m->solid_duration;
        else if (!strcmp(f, "splash_height")) *v = m->splash_height;
        else if (!strcmp(f, "density_error_max")) *v = m->density_error_max;
        else if (!strcmp(f, "density_error_local")) *v = m->density_error_local;
        else if (!strcmp(f, "density_error_first")) *v = m->density_error_first;
        else return -1;
        return 0;
    }
    const char *dot = strchr(key, '.');
    if (!dot) return m->nbodies > 0 ? body_field(&m->bodies[0], key, v) : -1;
    for (int k = 0; k < m->nbodies; k++)
        if (strlen(m->bodies[k].name) == (size_t)(dot - key) &&
            !strncmp(m->bodies[k].name, key, (size_t)(dot - key)))
            return body_field(&m->bodies[k], dot + 1, v);
    return -1;
}
