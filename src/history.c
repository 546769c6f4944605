/* history.c - ring of past velocities and the weights of Eq. 3. */
#include "history.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "stf.h"
#include "fluid.h" /* STF_VECTOR_CLONES */

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

double stf_history_scale(double q, double dt) { return pow(dt, 1.0 - q) / tgamma(3.0 - q); }

static void fill_weights(stf_history *h, int from)
{
    /* Interior weights depend on the lag k = n - p only: a window of d steps is Eq. 3 with
     * the start index moved from 0 to n - d (paper section 3.2). */
    h->w[0] = 1.0;
    for (int k = from > 1 ? from : 1; k < h->cap; k++)
        h->w[k] = stf_history_weight(h->q, 1, (long)k + 1);
}

/* Window mode, time blocks of h->tblock samples (see derivative_blocked), a multiple of
 * HIST_SUB up to HIST_TBLOCK; HIST_NEWER: the elements a thread sums at a time (also in the
 * direct sum, stf_history_derivative). */
enum { HIST_SUB = 16, HIST_TBLOCK = 32, HIST_CHUNK = 64, HIST_RUN = 16, HIST_NEWER = 1536 };
/* stf_history_permute: a re-sort renames the rows of a ring of more than HIST_MAP_SLOTS slots
 * (d = 500: moving the ring cost 20-25 ms a re-sort, about 1 ms a step; the pushes and sums
 * through a scrambled map about 0.1 ms a step more) and moves a shorter one (d = 50: the
 * map's gathers would cost 10% of the sums). */
enum { HIST_MAP_SLOTS = 256 };

/* The block length for a window of d steps: the ring is read once a block, the block's
 * older parts kept (8 bytes a sum, tblock of them per element): a long block for a long
 * window, where reading the ring (12 n d bytes) costs more than the arithmetic. */
static int block_len(int d) { return d >= 256 ? HIST_TBLOCK : HIST_SUB; }

/* Rows [rows, n) take the particles [rows, n) (new ones: the rows in use always hold the
 * particles 0 .. rows - 1 in some order, so these are free). */
static void add_rows(stf_history *h, int n)
{
    for (int r = h->rows; r < n; r++) h->part[r] = r;
    if (n > h->rows) h->rows = n;
}

/* The exact ring takes the time-blocked sum: a window longer than a sub-block. Before the
 * ring is full the sum runs over all d + 1 lags too, the slots not yet written being zeros
 * (the rest before t = 0), and the oldest sample's end-point weight is put right after it
 * (derivative_blocked): the first d steps cost what the later ones do, not a direct sum over
 * every sample each step. */
static int blocked_sum(const stf_history *h)
{
    return !h->terms && h->window > HIST_SUB && h->pushed >= 1;
}

int stf_history_init(stf_history *h, double q, int window, int n)
{
    memset(h, 0, sizeof *h);
    h->old_n0 = -1;
    h->q = q;
    h->window = window;
    h->cap = window > 0 ? window + 1 : 64;
    h->w = calloc((size_t)h->cap, sizeof *h->w);
    if (!h->w) return -1;
    fill_weights(h, 1);
    h->tblock = block_len(window);
    if (window > 0) { /* followed by HIST_TBLOCK zeros (old_chunk reads past lag d) */
        h->wf = calloc((size_t)h->cap + HIST_TBLOCK, sizeof *h->wf);
        if (!h->wf) return -1;
        for (int k = 0; k < h->cap; k++) h->wf[k] = (float)h->w[k];
    }
    h->head = -1;
    return stf_history_resize(h, n);
}

void stf_history_free(stf_history *h)
{
    free(h->soe_r);
    free(h->soe_c);
    free(h->soe_T);
    free(h->soe_v0);
    free(h->ring);
    free(h->part);
    free(h->w);
    free(h->wf);
    free(h->D);
    free(h->old);
    memset(h, 0, sizeof *h);
    h->old_n0 = -1;
}

void *stf_history_grow_zeroed(void *p, size_t old_n, size_t new_n, size_t size)
{
    char *q = realloc(p, new_n * size);
    if (q) memset(q + old_n * size, 0, (new_n - old_n) * size);
    return q;
}

/* A new slot-major ring of `slots` slots of 3 n_new floats, taking slot s from the ring's
 * slot (first + s) mod cap for s < keep (its 3 n_alloc floats), the rest zero. NULL when out
 * of memory. */
static float *reshape_ring(const stf_history *h, int slots, int n_new, int keep, int first)
{
    size_t row = (size_t)n_new * 3, orow = (size_t)h->n_alloc * 3;
    /* zeroed by hand: calloc's untouched pages would be mapped at the first read (one fault
       a page, inside a step) and, while never written, read as one shared zero page */
    float *ring = malloc((size_t)slots * row * sizeof *ring + 1);
    if (!ring) return NULL;
    memset(ring, 0, (size_t)slots * row * sizeof *ring);
    for (int s = 0; s < keep; s++)
        memcpy(ring + (size_t)s * row, h->ring + (size_t)((first + s) % h->cap) * orow,
               orow * sizeof *ring);
    return ring;
}

int stf_history_resize(stf_history *h, int n)
{
    if (h->terms) return stf_history_soe_resize(h, n);
    if (n <= h->n_alloc) return 0;
    int cap = n + n / 4 + 16;
    float *ring = reshape_ring(h, h->cap, cap, h->ring ? h->cap : 0, 0); /* slots stay put */
    if (!ring) return -1;
    double *D = stf_history_grow_zeroed(h->D, (size_t)h->n_alloc * 3, (size_t)cap * 3, sizeof *D);
    int *part = D ? realloc(h->part, (size_t)cap * sizeof *part) : NULL;
    if (D) h->D = D;
    if (!part) {
        free(ring);
        return -1;
    }
    for (int r = h->n_alloc; r < cap; r++) part[r] = -1;
    h->part = part;
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

int stf_history_push(stf_history *h, const double *v, int n)
{
    if (h->terms) {
        stf_history_soe_push(h, v, n);
        return 0;
    }
    if (h->window == 0 && h->pushed >= h->cap && grow_slots(h) != 0) return -1;
    if (n > h->n_alloc) return -1;
    add_rows(h, n);
    h->head = (h->head + 1) % h->cap;
    h->pushed++;
    float *slot = h->ring + (size_t)h->head * (size_t)h->n_alloc * 3;
    const int *part = h->part;
    if (!h->mapped && n == h->rows) { /* row i holds particle i */
#pragma omp parallel for schedule(static)
        for (int i = 0; i < 3 * n; i++) slot[i] = (float)v[i];
        return 0;
    }
#pragma omp parallel for schedule(static)
    for (int r = 0; r < h->rows; r++) { /* rows past n (none in use) keep zeros */
        int p = part[r];
        for (int k = 0; k < 3; k++)
            slot[3 * (size_t)r + (size_t)k] = p < n ? (float)v[3 * (size_t)p + (size_t)k] : 0.0f;
    }
    return 0;
}

/* Window mode in steady state (every sum has all d + 1 lags with the interior weights), in
 * blocks of T = tblock samples (16, or 32 for d >= 256) aligned on the sample index, each
 * made of sub-blocks of 16: the sum for sample t = n0 + j of its block is
 *     D_t = old_j + mid_j + sum_{k=0..j mod 16} w_k v_{t-k},
 *     old_j = sum_{k>j} w_k v_{t-k} over the samples older than n0,
 *     mid_j = the same over the block's earlier sub-blocks (none for j < 16).
 * All old_j of a block are taken in one pass over the ring at its start (each sample read
 * once per block instead of once per step: the direct sum reads the whole 12 n (d+1) byte
 * ring every step and is bound by memory bandwidth; a block of 32 halves what a block of 16
 * reads, and the sub-blocks keep the last sum short); each sub-block's terms are added to the
 * later old_j when it is complete (add_mid), from its 16 samples, still in cache.
 * old_j (j >= j0) for the elements [lo, lo + cnt): a product of a T x d Toeplitz matrix of
 * weights (w_{j+L}) by the d x cnt samples (v_{n0-L}), blocked as a matrix product: the T x
 * cnt sums of a chunk (rows of old) stay in L1/L2, and a micro-kernel (old_kernel) keeps up
 * to 16 x 16 of them in registers while it runs over a run of HIST_RUN samples.
 *
 * Precision. The samples are float32 (the ring), and so are the products and their sums
 * within a run: each run's float sum is then added, exactly converted, into the double old_j
 * (float arithmetic does twice the multiply-adds per instruction; the sum is bound by them).
 * Error of D_t against the same sum in exact arithmetic, with u = 2^-24 (float) and
 * S = sum |w_k v_k| over its terms: the weight rounded to float (<= u), the run's fused
 * multiply-adds (fmaf / vfmadd: one rounding each, the product exact inside; the first term
 * of a run is rounded once, the last added once: at most HIST_RUN roundings on any term), the
 * double sums (at most about d / 16 + 16 of them on any term, < cap + 1): at most
 * (HIST_RUN + 1) u S + (cap + 1) 2^-53 S (1 + O(u)), i.e. 1.0e-6 S for runs of 16; in
 * practice the roundings are of both signs and it stays near the float32 rounding the
 * samples already carry (u S). tests/test_history.c checks that bound against Eq. 3 in
 * double.
 *
 * Determinism. The runs are the samples in aligned groups of 16 (sample index 16 m .. 16 m +
 * 15): old's runs are anchored on the lag from n0 (run r holds L in (16 r, 16 r + 16], n0 a
 * multiple of 16) and each sub-block is one. Each sum adds its terms oldest first: in its run
 * (one fused multiply-add each, whatever the kernel), the runs into the double sum, then the
 * newest terms, whatever the chunks, the threads or the block length (a block of 32 gives
 * the bits of two of 16). A pass started in the middle of a block (j0 > 0: after a resize, a
 * resume) computes the rows of the sub-blocks from j0's on, from an older lag L = d - j0 < d:
 * the terms it leaves out have lags past d, weight 0 (wf holds HIST_TBLOCK zeros past lag d,
 * see stf_history_init), and they add +0 to a sum that is +0 so far (-0 + +0 is +0); then the
 * finished sub-blocks' runs, in order (derivative_blocked): every bit as in a pass from the
 * block's start. */
/* The kernel's sums: up to OLD_JB future samples x OLD_EB elements, in groups of j (of a
 * sub-block's 16) as many as the registers hold (AVX2: 16 registers, groups of 6, 6 and 4;
 * AVX-512: all 16, one 512-bit vector each; the plain C code: 8). */
enum { OLD_JB = 8, OLD_EB = 16 };
static const int old_group[3][4] = {{0, 8, 16, 16}, {0, 6, 12, 16}, {0, 16, 16, 16}}; /* by simd */

/* c[j][e] (j < jb, rows cs apart; e < OLD_EB) += the float sum over i < num of
 * wl[j - i] * ps[i][e]: the samples of a run, oldest first. The plain C version. */
static void old_kernel(const float *const *ps, int e0, int num, int jb, const float *wl,
                       double *c, size_t cs)
{
    float a[OLD_JB][OLD_EB] = {{0}};
    for (int i = 0; i < num; i++, wl--) {
        const float *p = ps[i] + e0;
        for (int j = 0; j < jb; j++)
            for (int e = 0; e < OLD_EB; e++) a[j][e] = fmaf(wl[j], p[e], a[j][e]);
    }
    for (int j = 0; j < jb; j++)
        for (int e = 0; e < OLD_EB; e++) c[(size_t)j * cs + (size_t)e] += (double)a[j][e];
}

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define HIST_X86 1
/* The same with 256-bit vectors (chosen at run time, stf_history_simd), jb a constant once
 * inlined: 2 jb float sums of 8 lanes in registers, the weights broadcast. Fused
 * multiply-add (_mm256_fmadd_ps, as fmaf), the run's sums then converted to double (exact)
 * and added: the same roundings as the plain version. */
__attribute__((target("avx2,fma"), always_inline)) static inline void
old_kernel_vec(const float *const *ps, int e0, int num, int jb, const float *wl, double *c,
               size_t cs)
{
    __m256 a[OLD_JB], b[OLD_JB];
    for (int j = 0; j < jb; j++) a[j] = b[j] = _mm256_setzero_ps();
    for (int i = 0; i < num; i++, wl--) {
        const float *p = ps[i] + e0;
        __m256 v = _mm256_loadu_ps(p), u = _mm256_loadu_ps(p + 8);
        for (int j = 0; j < jb; j++) {
            __m256 w = _mm256_broadcast_ss(wl + j);
            a[j] = _mm256_fmadd_ps(w, v, a[j]);
            b[j] = _mm256_fmadd_ps(w, u, b[j]);
        }
    }
    for (int j = 0; j < jb; j++) {
        double *cj = c + (size_t)j * cs;
        __m128 lo[2] = {_mm256_castps256_ps128(a[j]), _mm256_castps256_ps128(b[j])};
        __m128 hi[2] = {_mm256_extractf128_ps(a[j], 1), _mm256_extractf128_ps(b[j], 1)};
        for (int k = 0; k < 2; k++) {
            _mm256_storeu_pd(cj + 8 * k, _mm256_add_pd(_mm256_loadu_pd(cj + 8 * k),
                                                       _mm256_cvtps_pd(lo[k])));
            _mm256_storeu_pd(cj + 8 * k + 4, _mm256_add_pd(_mm256_loadu_pd(cj + 8 * k + 4),
                                                           _mm256_cvtps_pd(hi[k])));
        }
    }
}
__attribute__((target("avx2,fma"))) static void
old_kernel_avx2_6(const float *const *ps, int e0, int num, const float *wl, double *c, size_t cs)
{
    old_kernel_vec(ps, e0, num, 6, wl, c, cs);
}
__attribute__((target("avx2,fma"))) static void
old_kernel_avx2_4(const float *const *ps, int e0, int num, const float *wl, double *c, size_t cs)
{
    old_kernel_vec(ps, e0, num, 4, wl, c, cs);
}
/* AVX-512: one 512-bit vector of OLD_EB elements per future sample, all 16 of a sub-block
 * (16 sums in registers, one sample load and 16 weight broadcasts per lag). On the AMD Zen 4
 * this was measured on, a 512-bit multiply-add is split in two like two 256-bit ones, but
 * issues as one instruction: the history stage at d = 500 took 0.89x the time of the 256-bit
 * kernel's (whose loop the front end limits). */
__attribute__((target("avx2,fma,avx512f"))) static void
old_kernel_avx512_16(const float *const *ps, int e0, int num, const float *wl, double *c, size_t cs)
{
    __m512 a[HIST_SUB];
    for (int j = 0; j < HIST_SUB; j++) a[j] = _mm512_setzero_ps();
    for (int i = 0; i < num; i++, wl--) {
        __m512 v = _mm512_loadu_ps(ps[i] + e0);
        for (int j = 0; j < HIST_SUB; j++) a[j] = _mm512_fmadd_ps(_mm512_set1_ps(wl[j]), v, a[j]);
    }
    for (int j = 0; j < HIST_SUB; j++) {
        double *cj = c + (size_t)j * cs;
        __m256 lo = _mm512_castps512_ps256(a[j]);
        __m256 hi = _mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(a[j]), 1));
        _mm512_storeu_pd(cj, _mm512_add_pd(_mm512_loadu_pd(cj), _mm512_cvtps_pd(lo)));
        _mm512_storeu_pd(cj + 8, _mm512_add_pd(_mm512_loadu_pd(cj + 8), _mm512_cvtps_pd(hi)));
    }
}
#endif

/* One run of the samples into c for the future samples [jg, jg + jb), elements e0 ... */
static void old_run(int simd, const float *const *ps, int e0, int num, int jb, const float *wl,
                    double *c, size_t cs)
{
#ifdef HIST_X86
    if (simd == 2) old_kernel_avx512_16(ps, e0, num, wl, c, cs);
    else if (simd == 1 && jb == 6) old_kernel_avx2_6(ps, e0, num, wl, c, cs);
    else if (simd == 1) old_kernel_avx2_4(ps, e0, num, wl, c, cs);
    else
#endif
        old_kernel(ps, e0, num, jb, wl, c, cs);
}

static int simd_wanted = 2;

int stf_history_simd(int level)
{
    if (level >= 0) simd_wanted = level;
    int have = 0;
#ifdef HIST_X86
    have = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("fma") ? 2
           : __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")     ? 1
                                                                                 : 0;
#endif
    return simd_wanted < have ? simd_wanted : have;
}

double stf_history_error_bound(const stf_history *h)
{
    /* gamma_k = k u / (1 - k u): k roundings of unit roundoff u (Higham, Accuracy and
       Stability of Numerical Algorithms, 3.1). The double sums: at most cap + 1 roundings on
       any term (one product, the additions after it). */
    double ud = 0x1p-53, uf = 0x1p-24, m = h->cap + 1.0;
    double dbl = m * ud / (1.0 - m * ud);
    if (!blocked_sum(h)) return dbl;
    double k = HIST_RUN + 1.0, flt = k * uf / (1.0 - k * uf); /* see "Precision" above */
    return flt + dbl * (1.0 + flt);
}

/* Adds the runs of samples ps (num of them, oldest first, the oldest at lag L from the
 * block's start: weight w_{j+L-i} for sum j and sample i) into the sums c of the rows j of
 * bands (HIST_SUB rows) b0 and on, elements [0, cnt) of a chunk. */
static void add_runs(const stf_history *h, int simd, const float *const *ps, int num, int L,
                     int b0, int cnt, double *c, size_t cs)
{
    const int *group = old_group[simd];
    for (int b = b0 * HIST_SUB; b < h->tblock; b += HIST_SUB)
        for (int g = 0; g < 3 && group[g] < HIST_SUB; g++)
            for (int e = 0; e < cnt; e += OLD_EB)
                old_run(simd, ps, e, num, group[g + 1] - group[g], h->wf + L + b + group[g],
                        c + (size_t)(b + group[g]) * cs + (size_t)e, cs);
}

/* old_j for the rows of the sub-blocks from j0's on, elements [lo, lo + cnt), summed in
 * place in old (rows 3 n_old apart).
 * more: the same thread takes the chunk after next (its samples are prefetched into L2
 * while this one is summed: a chunk's 4 lines of a slot are 12 n bytes from the next slot's,
 * too far apart for the hardware prefetcher; one chunk ahead is too late). The kernel reads
 * and sums up to OLD_EB - 1 elements past cnt, inside the rows (3 n_alloc >= 3 n + 48):
 * rows not in use, whose samples are zero, and so are their sums (+0, as a new particle's
 * must be). */
static void old_chunk(const stf_history *h, int simd, int j0, int lo, int cnt, int more)
{
    int d = h->cap - 1, b0 = j0 / HIST_SUB;
    size_t row = (size_t)h->n_alloc * 3, cs = (size_t)h->n_old * 3;
    double *c = h->old + lo;
    for (int j = b0 * HIST_SUB; j < h->tblock; j++)
        memset(c + (size_t)j * cs, 0, (size_t)cnt * sizeof *c);
    /* samples n0 - L, L = d - j0 .. 1, oldest first (the oldest is in slot head + 1), in runs
       of lags (16 r, 16 r + 16]; lag from sample n0 + j: j + L */
    int s = h->head + 1 == h->cap ? 0 : h->head + 1;
    for (int L = d - j0; L >= 1;) {
        int num = (L - 1) % HIST_RUN + 1;
        const float *ps[HIST_RUN];
        for (int i = 0; i < num; i++) {
            ps[i] = h->ring + (size_t)s * row + lo;
            if (more) /* the chunk after next */
                for (int e = 0; e < HIST_CHUNK; e += 16)
                    __builtin_prefetch(ps[i] + 2 * HIST_CHUNK + e, 0, 2);
            s = s + 1 == h->cap ? 0 : s + 1;
        }
        add_runs(h, simd, ps, num, L, b0, cnt, c, cs);
        L -= num;
    }
}

/* The run of sub-block q - 1 of the block (its HIST_SUB samples, from sample n0 + 16 (q-1)
 * in slot s0) into old_j, j >= 16 q, for a chunk. */
static void mid_chunk(const stf_history *h, int simd, int q, int s0, int lo, int cnt)
{
    size_t row = (size_t)h->n_alloc * 3, cs = (size_t)h->n_old * 3;
    const float *ps[HIST_SUB];
    for (int i = 0; i < HIST_SUB; i++)
        ps[i] = h->ring + (size_t)((s0 + i) % h->cap) * row + lo;
    add_runs(h, simd, ps, HIST_SUB, -(q - 1) * HIST_SUB, q, cnt, h->old + lo, cs);
}

static size_t old_count(const stf_history *h, int n_alloc)
{
    return (size_t)n_alloc * 3 * (size_t)h->tblock;
}

/* old_j for j in [j0, tblock) of the block starting at sample n0 (= newest - j0). */
static int fill_old(stf_history *h, long n0, int j0)
{
    int len = 3 * h->rows;
    if (h->n_old != h->n_alloc) { /* a valid old covers every particle the ring holds */
        h->old_n0 = -1;
        free(h->old);
        /* zeroed: a particle added in the middle of a block (past the n filled for) has a
           zero past, as its ring rows do, and +0 is what a pass would give it */
        h->old = calloc(old_count(h, h->n_alloc), sizeof *h->old);
        h->n_old = h->old ? h->n_alloc : 0;
        if (!h->old) return -1;
    }
    int nchunks = (len + HIST_CHUNK - 1) / HIST_CHUNK, simd = stf_history_simd(-1);
#pragma omp parallel for schedule(static)
    for (int c = 0; c < nchunks; c++) {
        int lo = c * HIST_CHUNK, cnt = len - lo < HIST_CHUNK ? len - lo : HIST_CHUNK;
        old_chunk(h, simd, j0, lo, cnt, c + 2 < nchunks);
    }
    h->old_n0 = n0;
    h->old_mid = 0;
    return 0;
}

/* Adds sub-block old_mid + 1's run to old (at the start of sub-block old_mid + 2). */
static void add_mid(stf_history *h, long t, long n0)
{
    int q = h->old_mid + 1, len = 3 * h->rows;
    long age = t - (n0 + (long)(q - 1) * HIST_SUB); /* of the sub-block's oldest sample */
    int s0 = (int)(((long)h->head - age) % h->cap);
    if (s0 < 0) s0 += h->cap;
    int nchunks = (len + HIST_CHUNK - 1) / HIST_CHUNK, simd = stf_history_simd(-1);
#pragma omp parallel for schedule(static)
    for (int c = 0; c < nchunks; c++) {
        int lo = c * HIST_CHUNK, cnt = len - lo < HIST_CHUNK ? len - lo : HIST_CHUNK;
        mid_chunk(h, simd, q, s0, lo, cnt);
    }
    h->old_mid = q;
}

/* The sums of the rows' elements [lo, lo + cnt) (lo, cnt multiples of 3) into D, by
 * particle (particles past n, none in use, are left out). */
static void store_rows(const stf_history *h, const double *acc, int lo, int cnt, int n)
{
    for (int r = lo / 3; r < (lo + cnt) / 3; r++) {
        int p = h->part[r];
        if (p < n)
            for (int k = 0; k < 3; k++) h->D[3 * (size_t)p + (size_t)k] = acc[3 * r - lo + k];
    }
}

/* acc += c v_{t-k}, the sample at lag k (slot head - k), for the elements [lo, lo + cnt). */
static inline __attribute__((always_inline)) void add_lag(const stf_history *h, int k, double c,
                                                          int lo, int cnt, double *restrict acc)
{
    int s = h->head - k;
    if (s < 0) s += h->cap;
    const float *r = h->ring + (size_t)s * (size_t)h->n_alloc * 3 + lo;
    for (int e = 0; e < cnt; e++) acc[e] += c * r[e];
}

/* acc = old_j + sum_{k=j..0} w_k v_{t-k} for the elements [lo, lo + cnt): the block's own
 * samples, oldest first, streamed slot by slot while the sums stay in L1. */
static STF_VECTOR_CLONES void newer_part(const stf_history *h, int j, int lo, int cnt,
                                         double *restrict acc)
{
    const double *old = h->old + (size_t)j * (size_t)h->n_old * 3 + lo;
    for (int e = 0; e < cnt; e++) acc[e] = old[e];
    for (int k = j % HIST_SUB; k >= 0; k--) add_lag(h, k, h->w[k], lo, cnt, acc);
}

static int derivative_blocked(stf_history *h, int n)
{
    long t = h->pushed - 1, n0 = t - t % h->tblock;
    int j = (int)(t - n0);
    if (h->old_n0 != n0 && fill_old(h, n0, j) != 0) return -1;
    while (h->old_mid < j / HIST_SUB) add_mid(h, t, n0); /* the sub-blocks before j's */
    /* Before the ring is full, the oldest sample (p = 0 of Eq. 3, at lag t) takes the
       end-point weight a_{0,t} (1 for t = 0) where the sum gave it the interior w_t: the
       difference is added to it (the direct sum below does the same in one pass). */
    int m = t < h->cap ? (int)t : -1;
    double fix = m < 0 ? 0.0 : (t == 0 ? 1.0 : stf_history_weight(h->q, 0, t)) - h->w[m];
    int len = 3 * h->rows, nblocks = (len + HIST_NEWER - 1) / HIST_NEWER;
#pragma omp parallel for schedule(static)
    for (int b = 0; b < nblocks; b++) {
        int lo = b * HIST_NEWER, cnt = len - lo < HIST_NEWER ? len - lo : HIST_NEWER;
        double buf[HIST_NEWER]; /* by row, in L1 while the samples stream past */
        double *acc = h->mapped || n < h->rows ? buf : h->D + lo;
        newer_part(h, j, lo, cnt, acc);
        if (m >= 0) add_lag(h, m, fix, lo, cnt, acc);
        if (acc == buf) store_rows(h, acc, lo, cnt, n);
    }
    return 0;
}

/* acc = sum_{k=0..m} w_k v_{t-k} for the elements [lo, lo + cnt), w_m = w_end: the lags in
 * the same order whatever the blocks (or threads), from lag 0 to the end point. */
static STF_VECTOR_CLONES void direct_sum(const stf_history *h, int m, double w_end, int lo,
                                         int cnt, double *restrict acc)
{
    for (int e = 0; e < cnt; e++) acc[e] = 0.0;
    for (int k = 0; k <= m; k++) add_lag(h, k, k < m ? h->w[k] : w_end, lo, cnt, acc);
}

void stf_history_derivative(stf_history *h, int n)
{
    if (h->terms) return; /* the soe push computed D */
    if (n > h->rows) n = h->rows; /* (a particle without samples: its D is left as it was) */
    /* the blocked sum (falls back to the direct one below when out of memory) */
    if (blocked_sum(h) && derivative_blocked(h, n) == 0) return;
    /* m = the oldest lag present. While fewer than cap samples exist, the oldest one is p = 0
     * of Eq. 3 and takes the end-point weight a_{0,n}. */
    long last = h->pushed - 1;
    int m = last < h->cap ? (int)last : h->cap - 1;
    double w_end = last < h->cap ? stf_history_weight(h->q, 0, last) : h->w[m];
    if (last == 0) w_end = 1.0;
    int len = 3 * h->rows;
    /* Blocks of rows: each block's sums stay in L1 while every slot streams past. */
    int nblocks = (len + HIST_NEWER - 1) / HIST_NEWER;
#pragma omp parallel for schedule(static)
    for (int b = 0; b < nblocks; b++) {
        int lo = b * HIST_NEWER, cnt = len - lo < HIST_NEWER ? len - lo : HIST_NEWER;
        double buf[HIST_NEWER]; /* by row, in L1 while the samples stream past */
        double *acc = h->mapped || n < h->rows ? buf : h->D + lo;
        direct_sum(h, m, w_end, lo, cnt, acc);
        if (acc == buf) store_rows(h, acc, lo, cnt, n);
    }
}

/* Reorders the m rows of 3 elements of each of `rows` arrays of T, `stride` elements apart,
 * in place, row i taking row perm[i] < m for i < n <= m (each array is copied to a scratch
 * array, then gathered back), and zeroes each array past the n rows: particles added later
 * have a zero past. One scratch row per thread, not a
 * second copy of everything (the ring is 12 n d bytes: a new one every re-sort cost more in
 * page faults than the permutation itself). 0 / -1. */
#define PERMUTE_ROWS(T, name)                                                                 \
    static int name(T *a, size_t stride, int rows, const int *perm, int n, int m)             \
    {                                                                                         \
        int failed = 0;                                                                       \
        _Pragma("omp parallel reduction(| : failed)")                                          \
        {                                                                                     \
            T *tmp = malloc((size_t)m * 3 * sizeof *tmp);                                     \
            if (!tmp) failed = 1;                                                             \
            _Pragma("omp for schedule(static)")                                               \
            for (int s = 0; s < rows; s++) {                                                  \
                if (!tmp) continue;                                                           \
                T *row = a + (size_t)s * stride;                                              \
                memcpy(tmp, row, (size_t)m * 3 * sizeof *tmp);                                \
                for (int i = 0; i < n; i++)                                                   \
                    for (int c = 0; c < 3; c++)                                               \
                        row[3 * i + c] = tmp[3 * (size_t)perm[i] + (size_t)c];                \
                memset(row + (size_t)n * 3, 0, (stride - (size_t)n * 3) * sizeof *row);       \
            }                                                                                 \
            free(tmp);                                                                        \
        }                                                                                     \
        return failed ? -1 : 0;                                                               \
    }
PERMUTE_ROWS(float, permute_rows_f)
PERMUTE_ROWS(double, permute_rows_d)

/* The rows are gathered so that row i holds particle i again (perm taken through the rows),
 * the rows past n zeroed: after particles were removed, or a re-sort of a short ring. */
static int permute_gather(stf_history *h, const int *perm, int n)
{
    int rows = h->rows, *src = malloc((size_t)(2 * rows + 1) * sizeof *src);
    if (!src) return -1;
    int *row_of = src + rows; /* row_of[particle] */
    for (int r = 0; r < rows; r++) row_of[h->part[r]] = r;
    for (int i = 0; i < n; i++) src[i] = row_of[perm[i]];
    int rc = permute_rows_f(h->ring, (size_t)h->n_alloc * 3, h->cap, src, n, rows);
    /* old is per row: reordered, it equals a recomputed one. Not reordered (none valid, or
       out of memory), it is dropped: a pass fills only the rows in use, and a particle added
       later in the block takes a row past them, whose older sums must be zero */
    if (rc == 0 && (h->old_n0 < 0 ||
                    permute_rows_d(h->old, (size_t)h->n_old * 3, h->tblock, src, n, rows) != 0)) {
        free(h->old);
        h->old = NULL;
        h->n_old = 0;
        h->old_n0 = -1; /* recomputed at the next step */
    }
    free(src);
    if (rc != 0) return -1;
    for (int r = 0; r < rows; r++) h->part[r] = r < n ? r : -1;
    h->mapped = 0;
    h->rows = n;
    return 0;
}

int stf_history_permute(stf_history *h, const int *perm, int n)
{
    if (h->terms) return stf_history_soe_permute(h, perm, n);
    /* particles added since the last push get their rows first: perm names particles up to
       the count before the permutation, which may exceed n (some removed) and the rows */
    int before = n;
    for (int i = 0; i < n; i++) before = perm[i] >= before ? perm[i] + 1 : before;
    if (before > h->n_alloc) return -1;
    add_rows(h, before);
    /* a short ring is moved as before (cheaper than the map's gathers and scatters) */
    if (n < h->rows || h->cap <= HIST_MAP_SLOTS) return permute_gather(h, perm, n);
    /* A re-sort of a long ring: only the row -> particle map changes; the ring (12 n d
       bytes) and old stay where they are. */
    int *inv = malloc((size_t)(n + 1) * sizeof *inv);
    if (!inv) return -1;
    for (int i = 0; i < n; i++) inv[perm[i]] = i;
    for (int r = 0; r < n; r++) h->part[r] = inv[h->part[r]];
    h->mapped = 1;
    free(inv);
    return 0;
}

int stf_history_ring_set(stf_history *h, const float *src, int rows, const int *part, int n)
{
    if (rows < n || stf_history_resize(h, rows) != 0) return -1;
    /* part must name each of the particles 0 .. rows - 1 once */
    char *seen = calloc((size_t)rows + 1, 1);
    if (!seen) return -1;
    int ok = 1, identity = 1;
    for (int r = 0; r < rows && ok; r++) {
        ok = part[r] >= 0 && part[r] < rows && !seen[part[r]];
        if (ok) seen[part[r]] = 1;
        identity &= part[r] == r;
    }
    free(seen);
    if (!ok) return -1;
    size_t row = (size_t)rows * 3, orow = (size_t)h->n_alloc * 3;
    for (int r = 0; r < h->n_alloc; r++) h->part[r] = r < rows ? part[r] : -1;
    h->mapped = !identity;
    h->rows = rows;
    for (int s = 0; s < h->cap; s++) {
        float *dst = h->ring + (size_t)s * orow;
        memcpy(dst, src + (size_t)s * row, row * sizeof *dst);
        memset(dst + row, 0, (orow - row) * sizeof *dst);
    }
    h->old_n0 = -1;
    return 0;
}

size_t stf_history_bytes(const stf_history *h)
{
    if (h->terms) return stf_history_soe_bytes(h);
    return (size_t)h->n_alloc *
               ((size_t)h->cap * 3 * sizeof(float) + 3 * sizeof(double) + sizeof(int)) +
           (size_t)h->cap * sizeof(double) +
           (h->wf ? (size_t)(h->cap + HIST_TBLOCK) * sizeof(float) : 0) +
           (h->old ? old_count(h, h->n_old) * sizeof(double) : 0);
}

int stf_history_set_slots(stf_history *h, int cap)
{
    while (h->window == 0 && h->cap < cap)
        if (grow_slots(h) != 0) return -1;
    return h->cap == cap ? 0 : -1;
}
