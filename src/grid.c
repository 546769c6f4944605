/* grid.c - spatial hashing and neighbour lists. */
#include "grid.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

/* Verlet skin as a fraction of h: candidates within 1.25 h; rebuilt when a particle has moved
 * h/8 (at impact speeds every few steps, at rest rarely). */
#define SKIN 0.25

static uint32_t cell_hash(int64_t ix, int64_t iy, int64_t iz)
{
    /* Teschner et al. 2003 primes; unsigned arithmetic wraps by definition. */
    return ((uint32_t)ix * 73856093u) ^ ((uint32_t)iy * 19349663u) ^ ((uint32_t)iz * 83492791u);
}

/* floor(x inv) as an integer, without a call to floor (gcc calls libm for it on baseline
 * x86-64): truncate, then step down for negative non-integers. Positions are far inside the
 * int64 range. */
static int64_t cell_of(double x, double inv)
{
    double u = x * inv;
    int64_t c = (int64_t)u;
    return c - (u < (double)c);
}

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
    if (n <= g->n_alloc && g->off) return 0; /* off (n + 1) is written even for n = 0 */
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
    int32_t *ccount = realloc(g->ccount, (size_t)cap * sizeof *ccount);
    if (!ccount) return -1;
    g->ccount = ccount;
    size_t *off = realloc(g->off, ((size_t)cap + 1) * sizeof *off);
    if (!off) return -1;
    g->off = off;
    size_t *noff = realloc(g->noff, (size_t)cap * sizeof *noff);
    if (!noff) return -1;
    g->noff = noff;
    size_t *woff = realloc(g->woff, ((size_t)cap + 1) * sizeof *woff);
    if (!woff) return -1;
    g->woff = woff;
    uint8_t *gained = realloc(g->gained, (size_t)cap * sizeof *gained);
    if (!gained) return -1;
    g->gained = gained;
    double *xref = realloc(g->xref, (size_t)cap * 3 * sizeof *xref);
    if (!xref) return -1;
    g->xref = xref;
    g->n_alloc = cap;
    g->valid = 0;
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

/* The particles of the (deduplicated) buckets of one cell's 27 neighbour cells, in the
 * order find_candidates visits them, with their positions side by side: every particle of
 * that cell tests the same contiguous run instead of hashing 27 cells and gathering
 * scattered positions again.
 *
 * The positions are float32, relative to the cell's corner o, and the test is float32
 * (eight at a time): the candidates are a superset of the pairs closer than rc. Error bound
 * (u = 2^-24): a coordinate x - o lies in [-rc, 2 rc), rounded to float within 2 rc u; the
 * difference of two is within 3 rc, rounded within 3 rc u: each offset is within 6 rc u of
 * the exact one, the distance within 6 sqrt(3) rc u < 11 rc u, and the float sum of the
 * three squares adds at most 4 u relative (Higham's gamma_4), so a pair closer than rc has
 * a float distance squared below rc^2 (1 + 27 u); the limit is rc^2 (1 + 64 u). The few
 * extra candidates (at most 4e-6 rc outside) cost nothing: the filter tests the distance in
 * double every step, and a pair missing from the list is still at least rc apart. */
enum { RUN_PAD = 8 }; /* runs are padded to a multiple of eight entries */

typedef struct cell_run {
    int64_t c[3]; /* the cell the run is for */
    double o[3];  /* its corner, m */
    int have;     /* 0: empty */
    int len, cap;
    int32_t *j;
    float *x, *y, *z; /* positions relative to o */
} cell_run;

static int run_reserve(cell_run *r, int len)
{
    if (len <= r->cap) return 0;
    int cap = len + len / 2 + 64;
    int32_t *j = realloc(r->j, (size_t)cap * sizeof *j);
    if (j) r->j = j;
    float *x = realloc(r->x, (size_t)cap * sizeof *x);
    if (x) r->x = x;
    float *y = realloc(r->y, (size_t)cap * sizeof *y);
    if (y) r->y = y;
    float *z = realloc(r->z, (size_t)cap * sizeof *z);
    if (z) r->z = z;
    if (!j || !x || !y || !z) return -1;
    r->cap = cap;
    return 0;
}

static void run_free(cell_run *r)
{
    free(r->j);
    free(r->x);
    free(r->y);
    free(r->z);
}

/* Fills r with the neighbour cells of cell c: cells in dz, dy, dx order, two cells sharing a
 * bucket visited once, each bucket's particles in their sorted order. 0 / -1. */
static int fill_run(const stf_grid *g, const double *x, const int64_t c[3], cell_run *r)
{
    uint32_t seen[27];
    int nseen = 0;
    r->len = 0;
    r->have = 0;
    for (int a = 0; a < 3; a++) r->o[a] = (double)c[a] * g->cell;
    for (int dz = -1; dz <= 1; dz++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                uint32_t b = cell_hash(c[0] + dx, c[1] + dy, c[2] + dz) & g->mask;
                int dup = 0; /* two cells may share a bucket: visit it once */
                for (int s = 0; s < nseen; s++) dup |= seen[s] == b;
                if (dup) continue;
                seen[nseen++] = b;
                int k0 = g->start[b], k1 = g->start[b + 1];
                if (run_reserve(r, r->len + (k1 - k0) + RUN_PAD) != 0) return -1;
                for (int k = k0; k < k1; k++) {
                    int j = g->order[k];
                    r->j[r->len] = j;
                    r->x[r->len] = (float)(x[3 * j] - r->o[0]);
                    r->y[r->len] = (float)(x[3 * j + 1] - r->o[1]);
                    r->z[r->len] = (float)(x[3 * j + 2] - r->o[2]);
                    r->len++;
                }
            }
    for (int m = r->len; m % RUN_PAD; m++) { /* padding no particle is near */
        r->j[m] = -1;
        r->x[m] = r->y[m] = r->z[m] = 1e30f; /* its distance squared is +inf */
    }
    memcpy(r->c, c, sizeof r->c);
    r->have = 1;
    return 0;
}

/* Writes particle i's candidates (float distance squared below lim, see cell_run; in the
 * run's order) to out, which has room for the whole run; returns how many. */
static int find_candidates(const double *x, int i, float lim, const cell_run *r, int32_t *out)
{
    int cnt = 0;
    float xi = (float)(x[3 * i] - r->o[0]), yi = (float)(x[3 * i + 1] - r->o[1]),
          zi = (float)(x[3 * i + 2] - r->o[2]);
    for (int m = 0; m < r->len; m++) {
        float rx = r->x[m] - xi, ry = r->y[m] - yi, rz = r->z[m] - zi;
        out[cnt] = r->j[m]; /* branch-free: kept or overwritten by the next */
        cnt += (rx * rx + ry * ry + rz * rz < lim) & (r->j[m] != i);
    }
    return cnt;
}

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define HAVE_AVX2_PATH 1
/* The AVX2 search and filter, unless the processor lacks AVX2 or a test asked for plain C. */
static int use_avx2(const stf_grid *g) { return !g->plain && __builtin_cpu_supports("avx2"); }
/* pshufb controls that move the int32 lanes picked by a 4-bit mask to the front, in order */
static const uint8_t compress4[16][16] = {
#define L(k) 4 * (k), 4 * (k) + 1, 4 * (k) + 2, 4 * (k) + 3
#define Z 0x80, 0x80, 0x80, 0x80
    {Z, Z, Z, Z},          {L(0), Z, Z, Z},       {L(1), Z, Z, Z},       {L(0), L(1), Z, Z},
    {L(2), Z, Z, Z},       {L(0), L(2), Z, Z},    {L(1), L(2), Z, Z},    {L(0), L(1), L(2), Z},
    {L(3), Z, Z, Z},       {L(0), L(3), Z, Z},    {L(1), L(3), Z, Z},    {L(0), L(1), L(3), Z},
    {L(2), L(3), Z, Z},    {L(0), L(2), L(3), Z}, {L(1), L(2), L(3), Z}, {L(0), L(1), L(2), L(3)},
#undef L
#undef Z
};

/* Of four entries j at offsets (rx, ry, rz), those closer than sqrt(lim) and not masked out
 * by `skip` (a 4-bit mask), packed in order to out: stores all four lanes, returns the 4-bit
 * mask of those that count. No FMA: the same rounding as the plain loops. */
__attribute__((target("avx2"), always_inline)) static inline int
pack_near4(int32_t *out, __m128i j, __m256d rx, __m256d ry, __m256d rz, __m256d lim, int skip)
{
    __m256d d2 = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(rx, rx), _mm256_mul_pd(ry, ry)),
                               _mm256_mul_pd(rz, rz));
    int near = _mm256_movemask_pd(_mm256_cmp_pd(d2, lim, _CMP_LT_OQ)) & ~skip;
    __m128i ctl = _mm_loadu_si128((const __m128i *)compress4[near]);
    _mm_storeu_si128((__m128i *)out, _mm_shuffle_epi8(j, ctl));
    return near;
}

/* find_candidates eight entries at a time with no branch: the hits of each four are packed
 * to the front of a vector (a shuffle table) and stored at the end of the list so far (out
 * has room for the whole run plus eight), the same list in the same order. Hand-written
 * because the compiler does not vectorise the compare-and-pack loop: the plain C of
 * find_candidates takes about twice as long. Float distances, as find_candidates (filter_one
 * then keeps the neighbours in double). No FMA: the same roundings as find_candidates. */
__attribute__((target("avx2"))) static int find_candidates_avx2(const double *x, int i,
                                                                 float lim, const cell_run *r,
                                                                 int32_t *out)
{
    __m256 px = _mm256_set1_ps((float)(x[3 * i] - r->o[0])),
           py = _mm256_set1_ps((float)(x[3 * i + 1] - r->o[1])),
           pz = _mm256_set1_ps((float)(x[3 * i + 2] - r->o[2])), vlim = _mm256_set1_ps(lim);
    __m256i self = _mm256_set1_epi32(i);
    int cnt = 0;
    for (int m = 0; m < r->len; m += 8) {
        __m256 rx = _mm256_sub_ps(_mm256_loadu_ps(r->x + m), px);
        __m256 ry = _mm256_sub_ps(_mm256_loadu_ps(r->y + m), py);
        __m256 rz = _mm256_sub_ps(_mm256_loadu_ps(r->z + m), pz);
        __m256 d2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(rx, rx), _mm256_mul_ps(ry, ry)),
                                  _mm256_mul_ps(rz, rz));
        __m256i j = _mm256_loadu_si256((const __m256i *)(r->j + m));
        int is_self = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(j, self)));
        int near = _mm256_movemask_ps(_mm256_cmp_ps(d2, vlim, _CMP_LT_OQ)) & ~is_self;
        __m128i lo = _mm256_castsi256_si128(j), hi = _mm256_extracti128_si256(j, 1);
        __m128i clo = _mm_loadu_si128((const __m128i *)compress4[near & 15]),
                chi = _mm_loadu_si128((const __m128i *)compress4[near >> 4]);
        _mm_storeu_si128((__m128i *)(out + cnt), _mm_shuffle_epi8(lo, clo));
        cnt += __builtin_popcount((unsigned)near & 15u);
        _mm_storeu_si128((__m128i *)(out + cnt), _mm_shuffle_epi8(hi, chi));
        cnt += __builtin_popcount((unsigned)near >> 4);
    }
    return cnt;
}
#endif

/* The array whose pointer is at p holds at least need elements of `size` bytes (*cap of
 * them, with room to grow). The pointer is read and written as bytes (any object pointer
 * type; no aliasing through void *). 0 / -1. */
static int grow(void *p, size_t *cap, size_t need, size_t size)
{
    if (need <= *cap) return 0;
    size_t c = need + need / 4 + 1024;
    void *old, *q;
    memcpy(&old, p, sizeof old);
    q = realloc(old, c * size);
    if (!q) return -1;
    memcpy(p, &q, sizeof q);
    *cap = c;
    return 0;
}

/* Candidate lists within h + skin, and the reference positions. Each thread searches a
 * contiguous range of particles (in memory order, so consecutive ones mostly share a cell
 * and its run) into its own buffer; then the lists are laid end to end in particle order
 * (row i at off[i], ccount[i] long); the neighbour rows go in the same space (see
 * stf_grid_build_checked). */
static int rebuild(stf_grid *g, const double *x, int n, double h)
{
    g->valid = 0; /* until it succeeds: a failure leaves ccount, off and cand half new */
    g->skin_used = g->skin > 0 ? g->skin : SKIN;
    double rc = h * (1.0 + g->skin_used);
    g->cell = rc;
    if (sort_by_bucket(g, x, n) != 0) return -1;
    double inv = 1.0 / rc;
    float lim = (float)(rc * rc * (1.0 + 0x1p-18)); /* rc^2 (1 + 64 u), see cell_run */
#ifdef HAVE_AVX2_PATH
    int avx2 = use_avx2(g);
#endif
    int threads = omp_get_max_threads();
    if (threads > g->nbuf) { /* the threads' buffers, kept from one rebuild to the next */
        int32_t **buf = realloc(g->buf, (size_t)threads * sizeof *buf);
        if (!buf) return -1;
        g->buf = buf;
        size_t *cap = realloc(g->buf_cap, (size_t)threads * sizeof *cap);
        if (!cap) return -1;
        g->buf_cap = cap;
        for (int t = g->nbuf; t < threads; t++) g->buf[t] = NULL, g->buf_cap[t] = 0;
        g->nbuf = threads;
    }
    int failed = 0;
#pragma omp parallel
    {
        int nt = omp_get_num_threads(), t = omp_get_thread_num();
        int lo = (int)((int64_t)n * t / nt), hi = (int)((int64_t)n * (t + 1) / nt);
        cell_run r = {0};
        int32_t **buf = &g->buf[t];
        size_t len = 0, *cap = &g->buf_cap[t];
        int bad = 0;
        for (int i = lo; i < hi && !bad; i++) {
            int64_t c[3] = {cell_of(x[3 * i], inv), cell_of(x[3 * i + 1], inv),
                            cell_of(x[3 * i + 2], inv)};
            if (!(r.have && c[0] == r.c[0] && c[1] == r.c[1] && c[2] == r.c[2]) &&
                fill_run(g, x, c, &r) != 0) {
                bad = 1;
                break;
            }
            if (grow(buf, cap, len + (size_t)r.len + RUN_PAD, sizeof **buf) != 0) {
                bad = 1;
                break;
            }
#ifdef HAVE_AVX2_PATH
            if (avx2) g->ccount[i] = find_candidates_avx2(x, i, lim, &r, *buf + len);
            else
#endif
                g->ccount[i] = find_candidates(x, i, lim, &r, *buf + len);
            len += (size_t)g->ccount[i];
        }
        run_free(&r);
        if (bad) {
#pragma omp atomic write
            failed = 1;
        }
#pragma omp barrier
#pragma omp single
        if (!failed) {
            g->off[0] = 0;
            g->woff[0] = 0;
            for (int i = 0; i < n; i++) {
                g->off[i + 1] = g->off[i] + (size_t)g->ccount[i];
                g->woff[i + 1] = g->woff[i] + ((size_t)g->ccount[i] + 63) / 64;
            }
            if (grow(&g->cand, &g->cand_cap, g->off[n], sizeof *g->cand) != 0 ||
                grow(&g->nbr, &g->nbr_cap, g->off[n], sizeof *g->nbr) != 0 ||
                grow(&g->inb, &g->inb_cap, g->woff[n], sizeof *g->inb) != 0)
                failed = 1;
        } /* implied barrier */
        if (!failed && len > 0) memcpy(g->cand + g->off[lo], *buf, len * sizeof **buf);
    }
    if (failed) return -1;
    if (n > 0) memcpy(g->xref, x, (size_t)n * 3 * sizeof *x); /* x may be NULL for n = 0 */
    g->nref = n;
    g->href = h;
    g->valid = 1;
    g->inb_fresh = 1; /* the bits of the old rows mean nothing for the new candidates */
    g->rebuilds++;
    return 0;
}

/* The two largest displacements since the last rebuild, m (max is exact: thread-independent). */
static void most_moved(const stf_grid *g, const double *x, int n, double *d1, double *d2)
{
    double m1 = 0, m2 = 0; /* squared, m1 >= m2 */
#pragma omp parallel
    {
        double t1 = 0, t2 = 0;
#pragma omp for schedule(static)
        for (int i = 0; i < n; i++) {
            double dx = x[3 * i] - g->xref[3 * i], dy = x[3 * i + 1] - g->xref[3 * i + 1],
                   dz = x[3 * i + 2] - g->xref[3 * i + 2];
            double q = dx * dx + dy * dy + dz * dz;
            if (q > t2) {
                if (q > t1) t2 = t1, t1 = q;
                else t2 = q;
            }
        }
#pragma omp critical(stf_grid_most_moved)
        { /* merge the threads' two largest: the result is the two largest of all */
            if (t1 > m1) m2 = m1 > t2 ? m1 : t2, m1 = t1;
            else if (t1 > m2) m2 = t1;
        }
    }
    *d1 = sqrt(m1);
    *d2 = sqrt(m2);
}

/* The filters also keep one bit per candidate, set when it is a neighbour (inb, 64 to a word
 * from woff[i]), and set gained[i] when a bit went from 0 to 1 since the last filter: a
 * particle that gained no neighbour has no pair it has not seen (springs.c skips its search
 * for new springs). inb_fresh (after a rebuild): every row counts as gained. */
static inline void put_bits(stf_grid *g, int i, size_t w, uint64_t bits, int *gained)
{
    uint64_t *word = g->inb + g->woff[i] + w;
    *gained |= (bits & ~*word) != 0;
    *word = bits;
}

/* Particle i's neighbours within h: its candidates filtered, in their order, to out (room
 * for every candidate); the candidates a word of bits at a time. */
static int filter_one(stf_grid *g, const double *x, int i, double h2, int32_t *out)
{
    const int32_t *c = g->cand + g->off[i];
    int cnt = 0, m = g->ccount[i], gained = g->inb_fresh; /* locals: out could alias them */
    double xi = x[3 * i], yi = x[3 * i + 1], zi = x[3 * i + 2];
    for (int k0 = 0; k0 < m; k0 += 64) {
        int k1 = m - k0 < 64 ? m : k0 + 64;
        uint64_t bits = 0;
        for (int k = k0; k < k1; k++) {
            int j = c[k];
            double rx = x[3 * j] - xi, ry = x[3 * j + 1] - yi, rz = x[3 * j + 2] - zi;
            int in = rx * rx + ry * ry + rz * rz < h2;
            out[cnt] = j; /* branch-free: half the candidates are kept, unpredictably */
            cnt += in;
            bits |= (uint64_t)in << (k - k0);
        }
        put_bits(g, i, (size_t)k0 / 64, bits, &gained);
    }
    g->gained[i] = (uint8_t)gained;
    return cnt;
}

#ifdef HAVE_AVX2_PATH
/* filter_one four candidates at a time: their positions loaded one by one (a hardware gather
 * is slower here), the distances and the packing of the hits as in find_candidates_avx2.
 * Its 4-wide stores stay inside the room out has: four candidates k..k+3 write at most to
 * cnt + 3 <= k + 3 < ccount[i]. */
__attribute__((target("avx2"))) static int filter_one_avx2(stf_grid *g, const double *x, int i,
                                                           double h2, int32_t *out)
{
    const int32_t *c = g->cand + g->off[i];
    int m = g->ccount[i], cnt = 0, gained = g->inb_fresh;
    double xi = x[3 * i], yi = x[3 * i + 1], zi = x[3 * i + 2];
    __m256d px = _mm256_set1_pd(xi), py = _mm256_set1_pd(yi), pz = _mm256_set1_pd(zi),
            lim = _mm256_set1_pd(h2);
    for (int k0 = 0; k0 < m; k0 += 64) { /* a word of bits at a time */
        int k1 = m - k0 < 64 ? m : k0 + 64, k = k0;
        uint64_t bits = 0;
        for (; k + 4 <= k1; k += 4) {
            const double *a = x + 3 * c[k], *b = x + 3 * c[k + 1], *e = x + 3 * c[k + 2],
                         *f = x + 3 * c[k + 3];
            __m256d rx = _mm256_sub_pd(_mm256_set_pd(f[0], e[0], b[0], a[0]), px);
            __m256d ry = _mm256_sub_pd(_mm256_set_pd(f[1], e[1], b[1], a[1]), py);
            __m256d rz = _mm256_sub_pd(_mm256_set_pd(f[2], e[2], b[2], a[2]), pz);
            int near = pack_near4(out + cnt, _mm_loadu_si128((const __m128i *)(c + k)), rx, ry,
                                  rz, lim, 0);
            cnt += __builtin_popcount((unsigned)near);
            bits |= (uint64_t)near << (k - k0);
        }
        for (; k < k1; k++) { /* the last word's last few */
            int j = c[k];
            double rx = x[3 * j] - xi, ry = x[3 * j + 1] - yi, rz = x[3 * j + 2] - zi;
            int in = rx * rx + ry * ry + rz * rz < h2;
            out[cnt] = j;
            cnt += in;
            bits |= (uint64_t)in << (k - k0);
        }
        put_bits(g, i, (size_t)k0 / 64, bits, &gained);
    }
    g->gained[i] = (uint8_t)gained;
    return cnt;
}
#endif

/* 1 when every two particles that may be closer than h now moved less than lim relative to
 * each other since the rebuild: the particles are bucketed by their current cells (of size
 * h + skin, so two particles closer than h are in neighbouring cells), each bucket gets the
 * bounding box of its particles' displacements, and for every cell and each of its 27
 * neighbours the box around both boxes must be narrower than lim across. A flow that carries
 * a region along as a whole (the fluid pushed ahead of an impact) does not ask for new lists
 * however far it goes. 0 when some pair may have, or when out of memory. */
static int relative_moves_ok(stf_grid *g, const double *x, int n, double lim)
{
    if (sort_by_bucket(g, x, n) != 0) return 0;
    size_t nb = (size_t)g->mask + 1;
    if (nb > g->nbox) {
        double *box = realloc(g->box, nb * 6 * sizeof *box);
        if (!box) return 0;
        g->box = box;
        g->nbox = nb;
    }
#pragma omp parallel for schedule(static)
    for (size_t b = 0; b < nb; b++) {
        if (g->start[b] == g->start[b + 1]) continue; /* empty: never read */
        double *bb = g->box + 6 * b; /* lo[3], hi[3] of the displacements */
        for (int a = 0; a < 3; a++) bb[a] = INFINITY, bb[3 + a] = -INFINITY;
        for (int k = g->start[b]; k < g->start[b + 1]; k++) {
            int i = g->order[k];
            for (int a = 0; a < 3; a++) {
                double d = x[3 * i + a] - g->xref[3 * i + a];
                bb[a] = d < bb[a] ? d : bb[a];
                bb[3 + a] = d > bb[3 + a] ? d : bb[3 + a];
            }
        }
    }
    double inv = 1.0 / g->cell, lim2 = lim * lim;
    int ok = 1;
#pragma omp parallel
    {
        int64_t last[3] = {0, 0, 0};
        int have = 0;
#pragma omp for schedule(static) reduction(& : ok)
        for (int k = 0; k < n; k++) {
            int i = g->order[k];
            int64_t c[3] = {cell_of(x[3 * i], inv), cell_of(x[3 * i + 1], inv),
                            cell_of(x[3 * i + 2], inv)};
            /* once per cell: consecutive particles of a bucket mostly share one */
            if (have && c[0] == last[0] && c[1] == last[1] && c[2] == last[2]) continue;
            memcpy(last, c, sizeof last);
            have = 1;
            const double *mine = g->box + 6 * (size_t)g->key[i];
            for (int dz = -1; dz <= 1; dz++)
                for (int dy = -1; dy <= 1; dy++)
                    for (int dx = -1; dx <= 1; dx++) {
                        uint32_t b = cell_hash(c[0] + dx, c[1] + dy, c[2] + dz) & g->mask;
                        if (g->start[b] == g->start[b + 1]) continue; /* empty */
                        const double *o = g->box + 6 * (size_t)b;
                        double w2 = 0;
                        for (int a = 0; a < 3; a++) {
                            double hi = mine[3 + a] > o[3 + a] ? mine[3 + a] : o[3 + a];
                            double lo = mine[a] < o[a] ? mine[a] : o[a];
                            double w = hi - lo;
                            w2 += w * w;
                        }
                        ok &= w2 <= lim2;
                    }
        }
    }
    return ok;
}

int stf_grid_due(stf_grid *g, const double *x, int n, double h)
{
    if (!g->valid || n != g->nref || h != g->href) {
        g->valid = 0;
        return 1;
    }
    /* A pair missing from the candidates was at least h + skin apart at the rebuild; to be
       closer than h now, the two must have moved more than the skin relative to each other.
       No pair can while the two largest displacements add up to at most that; else the
       pairs that can be close now are checked (relative_moves_ok). */
    double d1, d2, lim = g->skin_used * h;
    most_moved(g, x, n, &d1, &d2);
    if (d1 + d2 > lim && !relative_moves_ok(g, x, n, lim)) g->valid = 0;
    return !g->valid;
}

/* Spreads the low 21 bits of v to every third bit (Morton interleave). */
static uint64_t spread3(uint64_t v)
{
    v &= 0x1fffff;
    v = (v | v << 32) & 0x1f00000000ffffull;
    v = (v | v << 16) & 0x1f0000ff0000ffull;
    v = (v | v << 8) & 0x100f00f00f00f00full;
    v = (v | v << 4) & 0x10c30c30c30c30c3ull;
    v = (v | v << 2) & 0x1249249249249249ull;
    return v;
}

typedef struct morton_item {
    uint64_t key;
    int32_t i;
} morton_item;

static int morton_cmp(const void *a, const void *b)
{
    const morton_item *p = a, *q = b;
    if (p->key != q->key) return p->key < q->key ? -1 : 1;
    return (p->i > q->i) - (p->i < q->i); /* a total order: deterministic */
}

/* Particles in Morton (Z-curve) order of the cells the candidate search uses (size h + skin,
 * the same cell boundaries): neighbours in all three directions are near in memory (the
 * bucket order of the hash scatters them), which keeps the neighbour loops in cache at large
 * particle counts, and the particles of a cell are consecutive, so the candidate search
 * gathers each cell's run once. */
int stf_grid_sort(stf_grid *g, const double *x, int n, double h)
{
    if (ensure_particles(g, n) != 0) return -1;
    g->valid = 0;
    if (n == 0) return 0;
    morton_item *it = malloc((size_t)n * sizeof *it);
    if (!it) return -1;
    double inv = 1.0 / (h * (1.0 + (g->skin > 0 ? g->skin : SKIN)));
    double lo[3] = {INFINITY, INFINITY, INFINITY};
    for (int i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) lo[a] = fmin(lo[a], x[3 * i + a]);
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        uint64_t c[3];
        for (int a = 0; a < 3; a++) {
            double u = floor(x[3 * i + a] * inv) - floor(lo[a] * inv);
            c[a] = u < 0 ? 0 : u > 0x1fffff ? 0x1fffff : (uint64_t)u;
        }
        it[i].key = spread3(c[0]) | spread3(c[1]) << 1 | spread3(c[2]) << 2;
        it[i].i = i;
    }
    qsort(it, (size_t)n, sizeof *it, morton_cmp);
    for (int i = 0; i < n; i++) g->order[i] = it[i].i;
    free(it);
    return 0;
}

/* Neighbours of i across periodic seams (r < sqrt(h2)): cells wrap and distances use the
 * nearest image. Periodic grids skip the Verlet candidates and rebuild every step. */
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

static int build_periodic(stf_grid *g, const double *x, int n, double h)
{
    g->cell = h;
    g->valid = 0;
    for (int a = 0; a < 3; a++) /* cells of at least h that tile the period */
        g->ncell[a] = g->period[a] > 0 ? (int)floor(g->period[a] / h) : 0;
    if (sort_by_bucket(g, x, n) != 0) return -1;
    if (g->stride == 0) g->stride = 64;
    for (;;) { /* rows stride apart, widened when one overflows */
        if (grow(&g->nbr, &g->nbr_cap, (size_t)n * (size_t)g->stride, sizeof *g->nbr) != 0) return -1;
        int most = 0;
#pragma omp parallel for schedule(static) reduction(max : most)
        for (int i = 0; i < n; i++) {
            g->count[i] = find_neighbours_periodic(g, x, i, h * h);
            if (g->count[i] > most) most = g->count[i];
        }
        if (most <= g->stride) break;
        g->stride = most + most / 2;
    }
    for (int i = 0; i <= n; i++) g->off[i] = (size_t)i * (size_t)g->stride;
    for (int i = 0; i < n; i++) g->noff[i] = g->off[i], g->gained[i] = 1;
    return 0;
}

int stf_grid_build(stf_grid *g, const double *x, int n, double h)
{
    if (!periodic(g)) stf_grid_due(g, x, n, h);
    return stf_grid_build_checked(g, x, n, h);
}

int stf_grid_build_checked(stf_grid *g, const double *x, int n, double h)
{
    if (ensure_particles(g, n) != 0) return -1;
    g->builds++;
    if (periodic(g)) return build_periodic(g, x, n, h);
    if (!g->valid && rebuild(g, x, n, h) != 0) return -1;
    /* Each thread filters a contiguous range of particles and packs their rows end to end
       from where the range's candidates start (a row is never longer than its candidates):
       the rows are read by every neighbour pass, and packed they take half the cache lines
       of rows spread over the candidates' space. The rows do not depend on the threads;
       where they lie does. */
#ifdef HAVE_AVX2_PATH
    int avx2 = use_avx2(g);
#endif
#pragma omp parallel
    {
        int nt = omp_get_num_threads(), t = omp_get_thread_num();
        int lo = (int)((int64_t)n * t / nt), hi = (int)((int64_t)n * (t + 1) / nt);
        size_t pos = lo < hi ? g->off[lo] : 0;
        for (int i = lo; i < hi; i++) {
            g->noff[i] = pos;
#ifdef HAVE_AVX2_PATH
            if (avx2) g->count[i] = filter_one_avx2(g, x, i, h * h, g->nbr + pos);
            else
#endif
                g->count[i] = filter_one(g, x, i, h * h, g->nbr + pos);
            pos += (size_t)g->count[i];
        }
    }
    g->inb_fresh = 0;
    return 0;
}

void stf_grid_free(stf_grid *g)
{
    free(g->key);
    free(g->order);
    free(g->start);
    free(g->nbr);
    free(g->count);
    free(g->cand);
    free(g->ccount);
    free(g->xref);
    free(g->off);
    free(g->noff);
    free(g->woff);
    free(g->gained);
    free(g->inb);
    free(g->box);
    for (int t = 0; t < g->nbuf; t++) free(g->buf[t]);
    free(g->buf);
    free(g->buf_cap);
    memset(g, 0, sizeof *g);
}

static size_t grid_buf_bytes(const stf_grid *g)
{
    size_t b = 0;
    for (int t = 0; t < g->nbuf; t++) b += g->buf_cap[t] * sizeof(int32_t);
    return b;
}

size_t stf_grid_bytes(const stf_grid *g)
{
    return (size_t)g->n_alloc * (sizeof(uint32_t) + 3 * sizeof(int32_t) + 3 * sizeof(double) +
                                 3 * sizeof(size_t) + sizeof(uint8_t)) +
           g->inb_cap * sizeof(uint64_t) +
           (g->cand_cap + g->nbr_cap) * sizeof(int32_t) + grid_buf_bytes(g) +
           g->nbox * 6 * sizeof(double) +
           ((size_t)g->nbuckets_alloc + 1) * sizeof(int32_t);
}

int stf_grid_restore(stf_grid *g, const double *xref, int n, double h, double skin_used)
{
    if (ensure_particles(g, n) != 0) return -1;
    double skin = g->skin;
    g->skin = skin_used;
    int rc = rebuild(g, xref, n, h);
    g->skin = skin;
    return rc;
}
