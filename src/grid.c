/* grid.c - spatial hashing and neighbour lists. */
#include "grid.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static uint32_t cell_hash(int64_t ix, int64_t iy, int64_t iz)
{
    /* Teschner et al. 2003 primes; unsigned arithmetic wraps by definition. */
    return ((uint32_t)ix * 73856093u) ^ ((uint32_t)iy * 19349663u) ^ ((uint32_t)iz * 83492791u);
}

static int64_t cell_of(double x, double inv) { return (int64_t)floor(x * inv); }

static int periodic(const stf_grid *g) { return g->period[0] > 0 || g->period[1] > 0 || g->period[2] > 0; }

/* Cell index along axis a; a periodic axis wraps into [0, ncell). */
static int64_t cell_axis(const stf_grid *g, double x, int a)
{
    if (!(g->period[a] > 0)) return cell_of(x, 1.0 / g->cell);
    int64_t c = (int64_t)floor((x - g->origin[a]) / g->period[a] * g->ncell[a]);
    int64_t m = g->ncell[a];
    return ((c % m) + m) % m;
}

static int64_t wrap_cell(const stf_grid *g, int64_t c, int a)
{
    if (!(g->period[a] > 0)) return c;
    int64_t m = g->ncell[a];
    return ((c % m) + m) % m;
}

/* Nearest-image difference along axis a. */
static double wrap_delta(const stf_grid *g, double d, int a)
{
    if (g->period[a] > 0) d -= g->period[a] * floor(d / g->period[a] + 0.5);
    return d;
}

static int ensure_particles(stf_grid *g, int n)
{
    if (n <= g->n_alloc) return 0;
    int cap = n + n / 4 + 16;
    uint32_t *key = realloc(g->key, (size_t)cap * sizeof *key);
    if (!key) return -1;
    g->key = key;
    int32_t *order = realloc(g->order, (size_t)cap * sizeof *order);
    if (!order) return -1;
    g->order = order;
    int32_t *count = realloc(g->count, (size_t)cap * sizeof *count);
    if (!count) return -1;
    g->count = count;
    if (g->stride == 0) g->stride = 48;
    int32_t *nbr = realloc(g->nbr, (size_t)cap * (size_t)g->stride * sizeof *nbr);
    if (!nbr) return -1;
    g->nbr = nbr;
    g->n_alloc = cap;
    return 0;
}

static int sort_by_bucket(stf_grid *g, const double *x, int n)
{
    uint32_t nb = 1;
    while (nb < 2u * (uint32_t)n + 64u) nb <<= 1;
    if (nb > g->nbuckets_alloc) {
        int32_t *start = realloc(g->start, ((size_t)nb + 1) * sizeof *start);
        if (!start) return -1;
        g->start = start;
        g->nbuckets_alloc = nb;
    }
    g->mask = nb - 1;
    double inv = 1.0 / g->cell;
    if (periodic(g)) {
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++)
            g->key[i] = cell_hash(cell_axis(g, x[3 * i], 0), cell_axis(g, x[3 * i + 1], 1),
                                  cell_axis(g, x[3 * i + 2], 2)) & g->mask;
    } else {
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++)
            g->key[i] = cell_hash(cell_of(x[3 * i], inv), cell_of(x[3 * i + 1], inv),
                                  cell_of(x[3 * i + 2], inv)) & g->mask;
    }
    /* Counting sort: serial, stable, and cheap next to the neighbour pass. */
    memset(g->start, 0, ((size_t)nb + 1) * sizeof *g->start);
    for (int i = 0; i < n; i++) g->start[g->key[i] + 1]++;
    for (uint32_t b = 0; b < nb; b++) g->start[b + 1] += g->start[b];
    for (int i = 0; i < n; i++) g->order[g->start[g->key[i]]++] = i;
    for (uint32_t b = nb; b > 0; b--) g->start[b] = g->start[b - 1];
    g->start[0] = 0;
    return 0;
}

/* Fills particle i's neighbour list; returns how many it has (may exceed the stride). */
static int find_neighbours(const stf_grid *g, const double *x, int i, double h2)
{
    double inv = 1.0 / g->cell;
    int64_t cx = cell_of(x[3 * i], inv), cy = cell_of(x[3 * i + 1], inv),
            cz = cell_of(x[3 * i + 2], inv);
    uint32_t seen[27];
    int nseen = 0, cnt = 0;
    int32_t *out = g->nbr + (size_t)i * (size_t)g->stride;
    for (int dz = -1; dz <= 1; dz++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                uint32_t b = cell_hash(cx + dx, cy + dy, cz + dz) & g->mask;
                int dup = 0; /* two cells may share a bucket: visit it once */
                for (int s = 0; s < nseen; s++) dup |= seen[s] == b;
                if (dup) continue;
                seen[nseen++] = b;
                for (int k = g->start[b]; k < g->start[b + 1]; k++) {
                    int j = g->order[k];
                    if (j == i) continue;
                    double rx = x[3 * j] - x[3 * i], ry = x[3 * j + 1] - x[3 * i + 1],
                           rz = x[3 * j + 2] - x[3 * i + 2];
                    if (rx * rx + ry * ry + rz * rz >= h2) continue;
                    if (cnt < g->stride) out[cnt] = j;
                    cnt++;
                }
            }
    return cnt;
}

/* find_neighbours across periodic seams: cells wrap and distances use the nearest image. */
static int find_neighbours_periodic(const stf_grid *g, const double *x, int i, double h2)
{
    int64_t c0[3];
    for (int a = 0; a < 3; a++) c0[a] = cell_axis(g, x[3 * i + a], a);
    uint32_t seen[27];
    int nseen = 0, cnt = 0;
    int32_t *out = g->nbr + (size_t)i * (size_t)g->stride;
    for (int dz = -1; dz <= 1; dz++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                uint32_t b = cell_hash(wrap_cell(g, c0[0] + dx, 0), wrap_cell(g, c0[1] + dy, 1),
                                       wrap_cell(g, c0[2] + dz, 2)) & g->mask;
                int dup = 0;
                for (int s = 0; s < nseen; s++) dup |= seen[s] == b;
                if (dup) continue;
                seen[nseen++] = b;
                for (int k = g->start[b]; k < g->start[b + 1]; k++) {
                    int j = g->order[k];
                    if (j == i) continue;
                    double rx = wrap_delta(g, x[3 * j] - x[3 * i], 0),
                           ry = wrap_delta(g, x[3 * j + 1] - x[3 * i + 1], 1),
                           rz = wrap_delta(g, x[3 * j + 2] - x[3 * i + 2], 2);
                    if (rx * rx + ry * ry + rz * rz >= h2) continue;
                    if (cnt < g->stride) out[cnt] = j;
                    cnt++;
                }
            }
    return cnt;
}

int grid_build(stf_grid *g, const double *x, int n, double h)
{
    g->cell = h;
    for (int a = 0; a < 3; a++) /* cells of at least h that tile the period */
        g->ncell[a] = g->period[a] > 0 ? (int)floor(g->period[a] / h) : 0;
    if (ensure_particles(g, n) != 0 || sort_by_bucket(g, x, n) != 0) return -1;
    int per = periodic(g);
    for (;;) {
        int most = 0;
#pragma omp parallel for schedule(static) reduction(max : most)
        for (int i = 0; i < n; i++) {
            g->count[i] = per ? find_neighbours_periodic(g, x, i, h * h)
                              : find_neighbours(g, x, i, h * h);
            if (g->count[i] > most) most = g->count[i];
        }
        if (most <= g->stride) return 0;
        /* Compressed regions: widen every list and redo (rare, deterministic). */
        int stride = most + most / 2;
        int32_t *nbr = realloc(g->nbr, (size_t)g->n_alloc * (size_t)stride * sizeof *nbr);
        if (!nbr) return -1;
        g->nbr = nbr;
        g->stride = stride;
    }
}

void grid_free(stf_grid *g)
{
    free(g->key);
    free(g->order);
    free(g->start);
    free(g->nbr);
    free(g->count);
    memset(g, 0, sizeof *g);
}

size_t grid_bytes(const stf_grid *g)
{
    return (size_t)g->n_alloc * (sizeof(uint32_t) + 2 * sizeof(int32_t) +
                                 (size_t)g->stride * sizeof(int32_t)) +
           ((size_t)g->nbuckets_alloc + 1) * sizeof(int32_t);
}
