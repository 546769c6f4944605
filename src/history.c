/* history.c - ring of past velocities and the weights of Eq. 3. */
#include "history.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fluid.h"
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

/* Window mode, time blocks of HIST_TBLOCK samples (see derivative_blocked). */
enum { HIST_TBLOCK = 16, HIST_CHUNK = 64 };

int history_init(stf_history *h, double q, int window, int n)
{
    memset(h, 0, sizeof *h);
    h->old_n0 = -1;
    h->q = q;
    h->window = window;
    h->cap = window > 0 ? window + 1 : 64;
    /* a window's weights are followed by HIST_TBLOCK zeros (old_chunk reads past lag d) */
    h->w = calloc((size_t)h->cap + (window > 0 ? HIST_TBLOCK : 0), sizeof *h->w);
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
    free(h->old);
    memset(h, 0, sizeof *h);
    h->old_n0 = -1;
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
    h->old_n0 = -1;
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

/* Window mode in steady state (every sum has all d + 1 lags with the interior weights), in
 * blocks of HIST_TBLOCK samples aligned on the sample index: the sum for sample t = n0 + j
 * of its block is
 *     D_t = old_j + sum_{k=0..j} w_k v_{t-k},   old_j = sum_{k=j+1..d} w_k v_{t-k},
 * where old_j only uses samples older than n0. All old_j of a block are taken in one pass
 * over the ring (each sample read once per block instead of once per step: the direct sum
 * reads the whole 12 n (d+1) byte ring every step and is bound by memory bandwidth). Each
 * old_j adds its terms in the order of the samples, oldest first, and a pass started in
 * the middle of a block (after a re-sort, a resize, a resume) adds the same terms in the same
 * order: the sums do not depend on when old was taken, nor on the threads. */
/* old_j (j >= j0) for the elements [lo, lo + cnt) of the block, into old (stride apart):
 * the HIST_TBLOCK x cnt sums stay in L1 while the samples stream past, each converted once.
 * wx holds the weights padded with zeros past lag d (h->w, see history_init): a term past
 * the window adds +0 to a sum that is never -0, which leaves its bits as they were. */
static STF_VECTOR_CLONES void old_chunk(const stf_history *h, const double *wx, int j0, int lo,
                                        int cnt, double *old, size_t stride)
{
    int d = h->cap - 1;
    size_t row = (size_t)h->n_alloc * 3;
    double a[HIST_TBLOCK][HIST_CHUNK], v[HIST_CHUNK];
    for (int j = 0; j < HIST_TBLOCK; j++)
        for (int e = 0; e < HIST_CHUNK; e++) a[j][e] = 0.0;
    for (int e = cnt; e < HIST_CHUNK; e++) v[e] = 0.0;
    /* samples n0 - L, L = d - j0 .. 1, oldest first; lag from sample n0 + j: j + L */
    for (int L = d - j0; L >= 1; L--) {
        int s = h->head - j0 - L;
        if (s < 0) s += h->cap;
        const float *r = h->ring + (size_t)s * row + lo;
        for (int e = 0; e < cnt; e++) v[e] = r[e];
        const double *wl = wx + L;
        for (int j = 0; j < HIST_TBLOCK; j++) {
            double wk = wl[j];
            for (int e = 0; e < HIST_CHUNK; e++) a[j][e] += wk * v[e];
        }
    }
    for (int j = j0; j < HIST_TBLOCK; j++)
        memcpy(old + (size_t)j * stride + lo, a[j], (size_t)cnt * sizeof(double));
}

/* old_j for j in [j0, HIST_TBLOCK) of the block starting at sample n0 (= newest - j0). */
static int fill_old(stf_history *h, long n0, int j0, int n)
{
    int len = 3 * n;
    if (h->n_old < n) {
        free(h->old);
        h->old = malloc((size_t)HIST_TBLOCK * (size_t)h->n_alloc * 3 * sizeof *h->old);
        h->n_old = h->old ? h->n_alloc : 0;
        if (!h->old) return -1;
    }
    size_t stride = (size_t)h->n_old * 3;
    int nchunks = (len + HIST_CHUNK - 1) / HIST_CHUNK;
#pragma omp parallel for schedule(static)
    for (int c = 0; c < nchunks; c++) {
        int lo = c * HIST_CHUNK, cnt = len - lo < HIST_CHUNK ? len - lo : HIST_CHUNK;
        old_chunk(h, h->w, j0, lo, cnt, h->old, stride);
    }
    h->old_n0 = n0;
    return 0;
}

static int derivative_blocked(stf_history *h, int n)
{
    long t = h->pushed - 1, n0 = t - t % HIST_TBLOCK;
    int j = (int)(t - n0);
    if (h->old_n0 != n0 || h->n_old < n) {
        if (fill_old(h, n0, j, n) != 0) return -1;
    }
    size_t stride = (size_t)h->n_old * 3, row = (size_t)h->n_alloc * 3;
    int len = 3 * n;
    const double *w = h->w, *old = h->old + (size_t)j * stride;
    int nchunks = (len + HIST_CHUNK - 1) / HIST_CHUNK;
#pragma omp parallel for schedule(static)
    for (int c = 0; c < nchunks; c++) {
        int lo = c * HIST_CHUNK, cnt = len - lo < HIST_CHUNK ? len - lo : HIST_CHUNK;
        double acc[HIST_CHUNK];
        for (int e = 0; e < cnt; e++) acc[e] = old[lo + e];
        for (int k = j; k >= 0; k--) { /* the block's samples, oldest first */
            int s = h->head - k;
            if (s < 0) s += h->cap;
            const float *r = h->ring + (size_t)s * row + lo;
            double wk = w[k];
            for (int e = 0; e < cnt; e++) acc[e] += wk * r[e];
        }
        memcpy(h->D + lo, acc, (size_t)cnt * sizeof *acc);
    }
    return 0;
}

void history_derivative(stf_history *h, int n)
{
    if (h->terms) return; /* the soe push computed D */
    /* a window longer than a block, in steady state: the blocked sum (falls back to the
       direct one below when out of memory) */
    if (h->window > HIST_TBLOCK && h->pushed - 1 >= h->cap && derivative_blocked(h, n) == 0)
        return;
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

/* Reorders the n rows of 3 elements of each of `rows` arrays of T, `stride` elements apart,
 * in place (each row is copied to a scratch row, then gathered back), and zeroes each row past
 * the n rows: particles added later have a zero past. One scratch row per thread, not a
 * second copy of everything (the ring is 12 n d bytes: a new one every re-sort cost more in
 * page faults than the permutation itself). 0 / -1. */
#define PERMUTE_ROWS(T, name)                                                                 \
    static int name(T *a, size_t stride, int rows, const int *perm, int n)                    \
    {                                                                                         \
        int failed = 0;                                                                       \
        _Pragma("omp parallel reduction(| : failed)")                                          \
        {                                                                                     \
            T *tmp = malloc((size_t)n * 3 * sizeof *tmp);                                     \
            if (!tmp) failed = 1;                                                             \
            _Pragma("omp for schedule(static)")                                               \
            for (int s = 0; s < rows; s++) {                                                  \
                if (!tmp) continue;                                                           \
                T *row = a + (size_t)s * stride;                                              \
                memcpy(tmp, row, (size_t)n * 3 * sizeof *tmp);                                \
                for (int i = 0; i < n; i++)                                                   \
                    for (int c = 0; c < 3; c++) row[3 * i + c] = tmp[3 * (size_t)perm[i] + c]; \
                memset(row + (size_t)n * 3, 0, (stride - (size_t)n * 3) * sizeof *row);       \
            }                                                                                 \
            free(tmp);                                                                        \
        }                                                                                     \
        return failed ? -1 : 0;                                                               \
    }
PERMUTE_ROWS(float, permute_rows_f)
PERMUTE_ROWS(double, permute_rows_d)

int history_permute(stf_history *h, const int *perm, int n)
{
    if (h->terms) return history_soe_permute(h, perm, n);
    if (permute_rows_f(h->ring, (size_t)h->n_alloc * 3, h->cap, perm, n) != 0) return -1;
    /* old is per element: reordered, it equals a recomputed one */
    if (h->old_n0 >= 0 && permute_rows_d(h->old, (size_t)h->n_old * 3, HIST_TBLOCK, perm, n) != 0)
        h->old_n0 = -1; /* recomputed at the next step */
    return 0;
}

size_t history_bytes(const stf_history *h)
{
    if (h->terms) return history_soe_bytes(h);
    return (size_t)h->n_alloc * ((size_t)h->cap * 3 * sizeof(float) + 3 * sizeof(double)) +
           (size_t)h->cap * sizeof(double) +
           (size_t)h->n_old * 3 * HIST_TBLOCK * sizeof(double);
}

int history_set_slots(stf_history *h, int cap)
{
    while (h->window == 0 && h->cap < cap)
        if (grow_slots(h) != 0) return -1;
    return h->cap == cap ? 0 : -1;
}
