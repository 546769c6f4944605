/* history.c - ring of past velocities and the weights of Eq. 3. */
#include "history.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "stf.h"

/* Eq. 3 (Soon et al.'s second-order scheme; the product-trapezoidal rule for the Riemann-
 * Liouville integral of order 1-q of v, so exact for piecewise-linear v). */
double stf_history_weight(double q, long p, long n)
{
    double e = 2.0 - q;
    if (p == n) return 1.0;
    if (p == 0) return pow((double)(n - 1), e) - pow((double)n, 1.0 - q) * ((double)n + q - 2.0);
    double k = (double)(n - p);
    return pow(k - 1.0, e) - 2.0 * pow(k, e) + pow(k + 1.0, e);
}

double history_scale(double q, double dt) { return pow(dt, 1.0 - q) / tgamma(3.0 - q); }

static void fill_weights(stf_history *h, int from)
{
    /* Interior weights depend on the lag k = n - p only: a window of d steps is Eq. 3 with
     * the start index moved from 0 to n - d (paper section 3.2). */
    h->w[0] = 1.0;
    for (int k = from > 1 ? from : 1; k < h->cap; k++)
        h->w[k] = stf_history_weight(h->q, 1, (long)k + 1);
}

int history_init(stf_history *h, double q, int window, int n)
{
    memset(h, 0, sizeof *h);
    h->q = q;
    h->window = window;
    h->cap = window > 0 ? window + 1 : 64;
    h->w = malloc((size_t)h->cap * sizeof *h->w);
    if (!h->w) return -1;
    fill_weights(h, 1);
    h->head = -1;
    return history_resize(h, n);
}

void history_free(stf_history *h)
{
    free(h->soe_r);
    free(h->soe_c);
    free(h->soe_T);
    free(h->soe_v0);
    free(h->ring);
    free(h->w);
    free(h->D);
    memset(h, 0, sizeof *h);
}

void *history_grow_zeroed(void *p, size_t old_n, size_t new_n, size_t size)
{
    char *q = realloc(p, new_n * size);
    if (q) memset(q + old_n * size, 0, (new_n - old_n) * size);
    return q;
}

/* A new slot-major ring of `slots` slots of 3 n_new floats, taking slot s of the old ring
 * from old slot from(s) for s < keep (3 n_old floats each), the rest zero. NULL when out of
 * memory. */
static float *reshape_ring(const stf_history *h, int slots, int n_new, int keep, int first)
{
    size_t row = (size_t)n_new * 3, orow = (size_t)h->n_alloc * 3;
    float *ring = calloc((size_t)slots * row, sizeof *ring);
    if (!ring) return NULL;
    for (int s = 0; s < keep; s++)
        memcpy(ring + (size_t)s * row, h->ring + (size_t)((first + s) % h->cap) * orow,
               orow * sizeof *ring);
    return ring;
}

int history_resize(stf_history *h, int n)
{
    if (h->terms) return history_soe_resize(h, n);
    if (n <= h->n_alloc) return 0;
    int cap = n + n / 4 + 16;
    float *ring = reshape_ring(h, h->cap, cap, h->ring ? h->cap : 0, 0); /* slots stay put */
    if (!ring) return -1;
    double *D = history_grow_zeroed(h->D, (size_t)h->n_alloc * 3, (size_t)cap * 3, sizeof *D);
    if (!D) {
        free(ring);
        return -1;
    }
    free(h->ring);
    h->ring = ring;
    h->D = D;
    h->n_alloc = cap;
    return 0;
}

/* Full history: doubles the slots, unrolling the ring so the oldest sample is slot 0. */
static int grow_slots(stf_history *h)
{
    int old = h->cap, cap = 2 * old;
    double *w = realloc(h->w, (size_t)cap * sizeof *w);
    if (!w) return -1;
    h->w = w;
    float *ring = reshape_ring(h, cap, h->n_alloc, old, h->head + 1); /* oldest first */
    if (!ring) return -1;
    free(h->ring);
    h->ring = ring;
    h->head = old - 1;
    h->cap = cap;
    fill_weights(h, old);
    return 0;
}

int history_push(stf_history *h, const double *v, int n)
{
    if (h->terms) {
        history_soe_push(h, v, n);
        return 0;
    }
    if (h->window == 0 && h->pushed >= h->cap && grow_slots(h) != 0) return -1;
    h->head = (h->head + 1) % h->cap;
    h->pushed++;
    float *slot = h->ring + (size_t)h->head * (size_t)h->n_alloc * 3;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < 3 * n; i++) slot[i] = (float)v[i];
    return 0;
}

void history_derivative(stf_history *h, int n)
{
    if (h->terms) return; /* the soe push computed D */
    /* m = the oldest lag present. While fewer than cap samples exist, the oldest one is p = 0
     * of Eq. 3 and takes the end-point weight a_{0,n}. */
    long last = h->pushed - 1;
    int m = last < h->cap ? (int)last : h->cap - 1;
    double w_end = last < h->cap ? stf_history_weight(h->q, 0, last) : h->w[m];
    if (last == 0) w_end = 1.0;
    size_t row = (size_t)h->n_alloc * 3;
    int head = h->head, cap = h->cap, len = 3 * n;
    const double *w = h->w;
    /* Blocks of particles: each block's sums stay in L1 while every slot streams past. The
       sum of each component runs over the lags in the same order whatever the blocks (or
       threads), from lag 0 to the end point. */
    enum { BLOCK = 1536 };
    int nblocks = (len + BLOCK - 1) / BLOCK;
#pragma omp parallel for schedule(static)
    for (int b = 0; b < nblocks; b++) {
        int lo = b * BLOCK, cnt = len - lo < BLOCK ? len - lo : BLOCK;
        double acc[BLOCK];
        for (int e = 0; e < cnt; e++) acc[e] = 0.0;
        for (int k = 0; k <= m; k++) {
            int s = head - k;
            if (s < 0) s += cap;
            const float *r = h->ring + (size_t)s * row + lo;
            double wk = k < m ? w[k] : w_end;
            for (int e = 0; e < cnt; e++) acc[e] += wk * r[e];
        }
        memcpy(h->D + lo, acc, (size_t)cnt * sizeof *acc);
    }
}

int history_permute(stf_history *h, const int *perm, int n)
{
    if (h->terms) return history_soe_permute(h, perm, n);
    size_t row = (size_t)h->n_alloc * 3;
    float *ring = malloc((size_t)h->cap * row * sizeof *ring);
    if (!ring) return -1;
#pragma omp parallel for schedule(static)
    for (int s = 0; s < h->cap; s++) {
        const float *src = h->ring + (size_t)s * row;
        float *dst = ring + (size_t)s * row;
        for (int i = 0; i < n; i++)
            for (int c = 0; c < 3; c++) dst[3 * i + c] = src[3 * (size_t)perm[i] + c];
        memset(dst + (size_t)n * 3, 0, (row - (size_t)n * 3) * sizeof *ring);
    }
    free(h->ring);
    h->ring = ring;
    return 0;
}

size_t history_bytes(const stf_history *h)
{
    if (h->terms) return history_soe_bytes(h);
    return (size_t)h->n_alloc * ((size_t)h->cap * 3 * sizeof(float) + 3 * sizeof(double)) +
           (size_t)h->cap * sizeof(double);
}

int history_set_slots(stf_history *h, int cap)
{
    while (h->window == 0 && h->cap < cap)
        if (grow_slots(h) != 0) return -1;
    return h->cap == cap ? 0 : -1;
}
