/* springs.c - adjust springs (Clavet Alg. 4) and apply their displacements (Alg. 3, Eq. 6). */
#include "springs.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "fluid.h"
#include "gauss_seidel.h"

static int alloc_rows(stf_springs *s, int n_alloc, int stride)
{
    size_t slots = (size_t)n_alloc * (size_t)stride;
    int32_t *p = realloc(s->partner, slots * sizeof *p);
    if (p) s->partner = p;
    int32_t *p2 = realloc(s->partner2, slots * sizeof *p2);
    if (p2) s->partner2 = p2;
    double *r = realloc(s->rest, slots * sizeof *r);
    if (r) s->rest = r;
    double *r2 = realloc(s->rest2, slots * sizeof *r2);
    if (r2) s->rest2 = r2;
    return p && p2 && r && r2 ? 0 : -1;
}

int stf_springs_init(stf_springs *s, int n)
{
    memset(s, 0, sizeof *s);
    s->stride = 32;
    s->nthreads = omp_get_max_threads();
    return stf_springs_resize(s, n);
}

void stf_springs_free(stf_springs *s)
{
    free(s->partner);
    free(s->partner2);
    free(s->rest);
    free(s->rest2);
    free(s->count);
    free(s->count2);
    free(s->mark);
    free(s->gain);
    free(s->complete);
    memset(s, 0, sizeof *s);
}

int stf_springs_resize(stf_springs *s, int n)
{
    if (n <= s->n_alloc) return 0;
    int cap = n + n / 4 + 16;
    int32_t *c = realloc(s->count, (size_t)cap * sizeof *c);
    if (c) s->count = c;
    int32_t *c2 = realloc(s->count2, (size_t)cap * sizeof *c2);
    if (c2) s->count2 = c2;
    int64_t *m = realloc(s->mark, (size_t)cap * (size_t)s->nthreads * sizeof *m);
    if (m) s->mark = m;
    double *g = realloc(s->gain, (size_t)cap * sizeof *g);
    if (g) s->gain = g;
    uint8_t *cm = realloc(s->complete, (size_t)cap * sizeof *cm);
    if (cm) s->complete = cm;
    if (!c || !c2 || !m || !g || !cm || alloc_rows(s, cap, s->stride) != 0) return -1;
    /* Rows keep their stride, so existing lists stay where they are. */
    memset(s->count + s->n_alloc, 0, (size_t)(cap - s->n_alloc) * sizeof *c);
    memset(s->complete + s->n_alloc, 0, (size_t)(cap - s->n_alloc) * sizeof *cm);
    for (size_t k = 0; k < (size_t)cap * (size_t)s->nthreads; k++) s->mark[k] = -1;
    s->n_alloc = cap;
    return 0;
}

/* Widens every row (a particle gained more springs than the stride holds). */
static int widen(stf_springs *s, int n, int stride)
{
    int32_t *p = malloc((size_t)s->n_alloc * (size_t)stride * sizeof *p);
    double *r = malloc((size_t)s->n_alloc * (size_t)stride * sizeof *r);
    if (!p || !r) {
        free(p);
        free(r);
        return -1;
    }
    for (int i = 0; i < n; i++) {
        size_t to = (size_t)i * (size_t)stride, from = (size_t)i * (size_t)s->stride;
        memcpy(p + to, s->partner + from, (size_t)s->count[i] * sizeof *p);
        memcpy(r + to, s->rest + from, (size_t)s->count[i] * sizeof *r);
    }
    free(s->partner);
    free(s->rest);
    s->partner = p;
    s->rest = r;
    s->stride = stride;
    free(s->partner2);
    free(s->rest2);
    s->partner2 = NULL;
    s->rest2 = NULL;
    int32_t *p2 = malloc((size_t)s->n_alloc * (size_t)stride * sizeof *p2);
    double *r2 = malloc((size_t)s->n_alloc * (size_t)stride * sizeof *r2);
    s->partner2 = p2;
    s->rest2 = r2;
    return p2 && r2 ? 0 : -1;
}

/* Clavet Alg. 4 for one spring: the rest length creeps towards the current length once the
 * deformation exceeds yield_ratio * L (plasticity). */
static double plastic_rest(double L, double r, double gamma, double alpha, double dt)
{
    double tol = gamma * L;
    /* Branch-free (stretched or compressed is a coin toss with yield_ratio 0): the branch
       not taken adds (dt alpha) * +-0, which leaves L's bits as they are (L > 0). Same values
       as: r > L + tol ? L + dt alpha (r - L - tol) : r < L - tol ? L - dt alpha (L - tol - r) : L */
    double up = (double)(r > L + tol) * (r - L - tol);
    double down = (double)(r < L - tol) * (L - tol - r);
    return L + dt * alpha * up - dt * alpha * down;
}

/* The springs of one particle are processed in blocks of at most SPRING_CHUNK: first the
 * arithmetic over the block in a loop the compiler vectorizes, gathering the partners'
 * positions and history sums straight from the arrays, then the sums in list order, so the
 * results are those of one spring at a time. The old springs are a block of their
 * own list row; the new ones are collected from the neighbour row first.
 *
 * Measured (bowling ball, 20K particles, one thread): staging the gathers in arrays first
 * cost 20% more; the gathers, not the square roots and the division, are most of the cost
 * (the history's square root in float saved nothing, summing in 4 interleaved lanes
 * instead of in order saved nothing), so the arithmetic stays in double, in list order. */
#define SPRING_CHUNK 64

/* The results of a block. */
typedef struct spring_chunk {
    int32_t jn[SPRING_CHUNK]; /* partners of the new springs being collected */
    double L[SPRING_CHUNK], kh[SPRING_CHUNK], c[SPRING_CHUNK];
    double tx[SPRING_CHUNK], ty[SPRING_CHUNK], tz[SPRING_CHUNK];
    double brk[SPRING_CHUNK]; /* 1: the spring breaks (or is not made) */
} spring_chunk;

typedef struct spring_acc {
    double d[3], ksum, csum;
    int cnt, nbrk; /* springs kept (and new), springs broken or not made */
} spring_acc;

/* A thread's springs that did not fit their particle's row (stride slots), in order; they
 * are appended once the rows are widened (stf_springs_step). */
typedef struct spring_spill {
    struct spilled {
        int32_t i, j;
        double L;
    } *e;
    size_t len, cap;
    int failed; /* out of memory */
} spring_spill;

static void spill(spring_spill *sp, int i, int j, double L)
{
    if (sp->len == sp->cap) {
        size_t cap = sp->cap ? 2 * sp->cap : 256;
        struct spilled *e = realloc(sp->e, cap * sizeof *e);
        if (!e) {
            sp->failed = 1;
            return;
        }
        sp->e = e;
        sp->cap = cap;
    }
    sp->e[sp->len++] = (struct spilled){i, j, L};
}

/* The arithmetic of Alg. 4 and Alg. 3 with Eq. 6 (unsaturated) for the m springs of particle i to
 * js[0..m) with old rest lengths L0s (fresh: new springs, which start at their length), into
 * ch; hist: with the history stiffness (Eq. 6). Branch-free, so it vectorizes; inlined with
 * constant fresh and hist, so each case is a loop of its own with no conditional loads. */
static inline __attribute__((always_inline)) void
spring_ops(const stf_fluid *f, int i, const int32_t *js, const double *L0s, int m, double dt,
           double khist_scale, spring_chunk *restrict ch, const int fresh, const int hist)
{
    double h = f->h, inv_h = 1.0 / h, tiny = 1e-12 * h, k_min = f->def.k_min, onset = f->def.k_onset;
    double dt2 = dt * dt;
    double gamma = f->def.yield_ratio, alpha = f->def.plasticity, dtn = f->dt_now;
    double alpha_liq = f->def.liquid_plasticity >= 0 ? f->def.liquid_plasticity : alpha;
    const double *x = f->x, *D = f->hist.D;
    const double *Dp = f->Dprev && f->Dprev_ok ? f->Dprev : NULL; /* springs.passive */
    double xi = x[3 * i], yi = x[3 * i + 1], zi = x[3 * i + 2];
    double Dxi = 0, Dyi = 0, Dzi = 0;
    if (hist) Dxi = D[3 * i], Dyi = D[3 * i + 1], Dzi = D[3 * i + 2];
    for (int e = 0; e < m; e++) {
        int j = js[e];
        double rx = x[3 * j] - xi, ry = x[3 * j + 1] - yi, rz = x[3 * j + 2] - zi;
        double r = sqrt(rx * rx + ry * ry + rz * rz);
        double kh = 0.0;
        if (hist) {
            double ex = Dxi - D[3 * j], ey = Dyi - D[3 * j + 1], ez = Dzi - D[3 * j + 2];
            kh = khist_scale * sqrt(ex * ex + ey * ey + ez * ez); /* Eq. 6 */
            kh = kh > onset ? kh - onset : 0.0; /* thickening starts at the onset */
        }
        double L, brk; /* Alg. 4: springs longer than h break */
        if (fresh) {
            L = r;
            brk = (double)(r >= h);
        } else {
            /* a spring below the onset creeps at the liquid's rate (liquid_plasticity) */
            L = plastic_rest(L0s[e], r, gamma, kh > 0 ? alpha : alpha_liq, dtn);
            if (hist && Dp) { /* springs.passive: a stiffer spring keeps its energy */
                double px = Dp[3 * i] - Dp[3 * j], py = Dp[3 * i + 1] - Dp[3 * j + 1],
                       pz = Dp[3 * i + 2] - Dp[3 * j + 2];
                double ko = khist_scale * sqrt(px * px + py * py + pz * pz);
                ko = ko > onset ? ko - onset : 0.0;
                if (kh > ko) L = r - (r - L) * sqrt((k_min + ko) / (k_min + kh));
            }
            brk = (double)(L > h);
        }
        double kij = k_min + kh;
        double c = dt2 * kij * (1.0 - L * inv_h);
        double rs = r > tiny ? r : 1.0;
        double mag = 0.5 * c * (L - r) / rs;
        double ok = (double)(r > tiny); /* coincident: no direction to push along, and no gain */
        ch->L[e] = L;
        ch->brk[e] = brk;
        ch->kh[e] = ok > 0 ? kh : 0.0;
        ch->c[e] = ok > 0 ? c : 0.0;
        ch->tx[e] = ok > 0 ? mag * rx : 0.0;
        ch->ty[e] = ok > 0 ? mag * ry : 0.0;
        ch->tz[e] = ok > 0 ? mag * rz : 0.0;
    }
}

/* spring_ops over a block, then its sums in order into acc and the kept springs into the
 * new list (np, nL; past the stride into sp). L0s NULL: new springs. The new list may be the
 * old one, rewritten in place: a kept spring is written at or before the slot it was read
 * from, and the block was read into ch first. One clone per instruction set; the four cases
 * of spring_ops are four loops. */
STF_VECTOR_CLONES
static void spring_block(const stf_fluid *f, int i, const int32_t *js, const double *L0s, int m,
                         double dt, double khist_scale, spring_chunk *ch, int32_t *np, double *nL,
                         int stride, spring_acc *acc, spring_spill *sp)
{
    int hist = khist_scale > 0; /* without history D is not read (kh is 0) */
    if (L0s && hist) spring_ops(f, i, js, L0s, m, dt, khist_scale, ch, 0, 1);
    else if (L0s) spring_ops(f, i, js, L0s, m, dt, khist_scale, ch, 0, 0);
    else if (hist) spring_ops(f, i, js, L0s, m, dt, khist_scale, ch, 1, 1);
    else spring_ops(f, i, js, L0s, m, dt, khist_scale, ch, 1, 0);
    /* in order, in locals (acc, np and nL might alias the block as far as the compiler knows) */
    double d0 = acc->d[0], d1 = acc->d[1], d2 = acc->d[2], ksum = acc->ksum, csum = acc->csum;
    int cnt = acc->cnt;
    int nbrk = acc->nbrk;
    for (int e = 0; e < m; e++) {
        if (ch->brk[e] != 0) {
            nbrk++;
            continue;
        }
        if (cnt < stride) {
            if (np + cnt != js + e) np[cnt] = js[e]; /* in place and nothing broke: it is there */
            nL[cnt] = ch->L[e];
        } else spill(sp, i, js[e], ch->L[e]);
        cnt++;
        ksum += ch->kh[e];
        csum += ch->c[e];
        d0 -= ch->tx[e];
        d1 -= ch->ty[e];
        d2 -= ch->tz[e];
    }
    acc->d[0] = d0, acc->d[1] = d1, acc->d[2] = d2, acc->ksum = ksum, acc->csum = csum;
    acc->cnt = cnt;
    acc->nbrk = nbrk;
}

/* Rebuilds particle i's spring list in place (Alg. 4) and, in the same pass over the same
 * distances, gathers the displacements of its new springs into f->dx (Alg. 3: the order of
 * the sums is that of the new list: the old springs kept, then the new ones in neighbour
 * order). A new spring starts at its current length, so it carries no force on creation
 * (mag = 0; its history stiffness counts in the mean). Returns its new count; the springs
 * past the stride go to sp. In place, the row is read and written while in cache: against
 * a second buffer the spring stage took 15-19% longer (one thread, bowling ball, d = 150).
 *
 * The search for new springs (every neighbour not yet a partner) is skipped when it cannot
 * find one: when after the last step every neighbour of i was a partner (complete: no spring
 * broke and none was refused) and i gained no neighbour since (the grid's filter says so),
 * every neighbour now is an old partner. Skipping it changes no result. */
static int adjust_one(stf_fluid *f, int i, int64_t stamp, int64_t *mark, double dt,
                      double khist_scale, spring_chunk *ch, spring_spill *sp)
{
    stf_springs *s = &f->springs;
    size_t row = (size_t)i * (size_t)s->stride;
    int32_t *np = s->partner + row;
    double *nL = s->rest + row;
    const int32_t *op = np;
    const double *oL = nL;
    int nold = s->count[i];
    int search = !s->complete[i] || f->grid.gained[i] || s->search_always;
    spring_acc acc = {{0, 0, 0}, 0, 0, 0, 0};
    if (i + 2 < f->n) { /* the rows of a particle two ahead: a few lines each, 384 B apart */
        const char *pp = (const char *)(op + 2 * (size_t)s->stride);
        const char *pl = (const char *)(oL + 2 * (size_t)s->stride);
        for (int b = 0; b < s->count[i + 2] * 4; b += 64) __builtin_prefetch(pp + b);
        for (int b = 0; b < s->count[i + 2] * 8; b += 64) __builtin_prefetch(pl + b);
        grid_prefetch(&f->grid, i + 2, f->n);
    }
    if (search)
        for (int k = 0; k < nold; k++) mark[op[k]] = stamp;
    for (int k0 = 0; k0 < nold; k0 += SPRING_CHUNK)
        spring_block(f, i, op + k0, oL + k0, nold - k0 < SPRING_CHUNK ? nold - k0 : SPRING_CHUNK,
                     dt, khist_scale, ch, np, nL, s->stride, &acc, sp);
    const int32_t *nb = grid_row(&f->grid, i);
    int m = 0;
    for (int k = 0; k < (search ? f->grid.count[i] : 0); k++) {
        int j = nb[k];
        if (mark[j] == stamp) continue;
        ch->jn[m++] = j;
        if (m == SPRING_CHUNK) {
            spring_block(f, i, ch->jn, NULL, m, dt, khist_scale, ch, np, nL, s->stride, &acc, sp);
            m = 0;
        }
    }
    if (m) spring_block(f, i, ch->jn, NULL, m, dt, khist_scale, ch, np, nL, s->stride, &acc, sp);
    for (int a = 0; a < 3; a++) f->dx[3 * i + a] = acc.d[a];
    if (f->khist_mean) f->khist_mean[i] = acc.cnt > 0 ? (float)(acc.ksum / acc.cnt) : 0.0f;
    s->gain[i] = acc.csum;
    s->complete[i] = acc.nbrk == 0;
    return acc.cnt;
}

/* Alg. 3 with Eq. 6 for particle i over its current springs, saturated: gathers -D/2 of each
 * into f->dx (the second pass, run only when some gain sum exceeds 1; the common pass is fused
 * into adjust_one).
 *
 * Saturation. The pair (i, j) is pulled towards its rest length by the gain
 * c_ij = dt^2 k_ij (1 - L/h), half on each side. Taken together (Jacobi) the update of
 * particle i moves it by up to sum_j c_ij times its springs' deformations; by Gershgorin the
 * update's eigenvalues stay <= 1 (no overshoot) when that sum is <= 1 for every particle.
 * The history term can make k_ij arbitrarily large (at 100 times the bowling scene's k_hist,
 * sum c_ij reaches tens and the run blew up in 20 steps), so each gain is multiplied by
 * min(scale_i, scale_j), scale_i = min(1, 1 / sum_j c_ij): a spring never does more than
 * become rigid within the step. The factor is symmetric, so the two halves of a pair stay
 * exact negatives (momentum). The history stiffness and gains are recomputed by the fused
 * pass's formulas, except that the gain takes L / h where spring_ops takes L * (1 / h) (the
 * last bit may differ). */
static void saturated_one(stf_fluid *f, int i, double dt, double khist_scale, const double *scale)
{
    const stf_springs *s = &f->springs;
    const double *x = f->x;
    double d[3] = {0, 0, 0};
    size_t row = (size_t)i * (size_t)s->stride;
    const int32_t *p = s->partner + row;
    const double *Ls = s->rest + row;
    const double *D = f->hist.D;
    double h = f->h;
    for (int k = 0; k < s->count[i]; k++) {
        int j = p[k];
        double rx = x[3 * j] - x[3 * i], ry = x[3 * j + 1] - x[3 * i + 1],
               rz = x[3 * j + 2] - x[3 * i + 2];
        double r = sqrt(rx * rx + ry * ry + rz * rz);
        if (r <= 1e-12 * h) continue; /* coincident: no direction to push along */
        double kij = f->def.k_min, L = Ls[k];
        if (khist_scale > 0) {
            double ex = D[3 * i] - D[3 * j], ey = D[3 * i + 1] - D[3 * j + 1],
                   ez = D[3 * i + 2] - D[3 * j + 2];
            double kh = khist_scale * sqrt(ex * ex + ey * ey + ez * ez); /* Eq. 6 */
            kh = kh > f->def.k_onset ? kh - f->def.k_onset : 0.0; /* thickening starts at the onset */
            kij += kh;
        }
        double c = dt * dt * kij * (1.0 - L / h); /* the spring's gain */
        double mag = 0.5 * (c * (scale[i] < scale[j] ? scale[i] : scale[j])) * (L - r) / r;
        d[0] -= mag * rx;
        d[1] -= mag * ry;
        d[2] -= mag * rz;
    }
    for (int a = 0; a < 3; a++) f->dx[3 * i + a] = d[a];
}

int stf_springs_step(stf_fluid *f, double dt)
{
    stf_springs *s = &f->springs;
    int n = f->n;
    if (omp_get_max_threads() > s->nthreads) { /* more threads than at creation */
        int64_t *m = realloc(s->mark, (size_t)s->n_alloc * (size_t)omp_get_max_threads() * sizeof *m);
        if (!m) return -1;
        s->mark = m;
        s->nthreads = omp_get_max_threads();
        for (size_t k = 0; k < (size_t)s->n_alloc * (size_t)s->nthreads; k++) s->mark[k] = -1;
    }
    double khist_scale = has(f, STF_EFFECT_HISTORY)
                             ? f->def.k_hist * stf_history_scale(f->def.q, dt)
                             : 0.0;
    if (f->def.reference_spacing > 0) khist_scale *= f->def.reference_spacing / f->def.spacing;
    double most_gain = 0; /* the largest sum of gains (saturated_one) */
    int most = 0, nt = omp_get_max_threads();
    spring_spill *spills = calloc((size_t)nt, sizeof *spills);
    if (!spills) return -1;
    int64_t base = (int64_t)f->steps * (int64_t)s->n_alloc;
#pragma omp parallel num_threads(nt) reduction(max : most, most_gain)
    {
        int64_t *mark = s->mark + (size_t)omp_get_thread_num() * (size_t)s->n_alloc;
        spring_spill *sp = &spills[omp_get_thread_num()];
        spring_chunk ch;
        /* dynamic chunks (see stf_pressure_relax): the stamps are per particle, so a particle's
           marks do not depend on which thread's array holds them */
#pragma omp for schedule(dynamic, 256)
        for (int i = 0; i < n; i++) {
            /* the row holds the first `stride` springs of the new list, the rest spilled
               (out of memory before they are appended: the count of what the row holds, a
               consistent state for a step that fails); into count2, as count[i + 2] is
               read ahead by another particle */
            int c = adjust_one(f, i, base + i, mark, dt, khist_scale, &ch, sp);
            s->count2[i] = c < s->stride ? c : s->stride;
            if (c > most) most = c;
            if (s->gain[i] > most_gain) most_gain = s->gain[i];
        }
    }
    int32_t *tc = s->count; /* the new counts */
    s->count = s->count2;
    s->count2 = tc;
    int rc = 0;
    for (int t = 0; t < nt; t++) rc |= spills[t].failed ? -1 : 0;
    if (rc == 0 && most > s->stride) { /* widen the rows, then append what did not fit */
        rc = widen(s, n, most + most / 2);
        for (int t = 0; t < nt && rc == 0; t++)
            for (size_t k = 0; k < spills[t].len; k++) { /* each particle's in order */
                const struct spilled *e = &spills[t].e[k];
                size_t slot = (size_t)e->i * (size_t)s->stride + (size_t)s->count[e->i]++;
                s->partner[slot] = e->j;
                s->rest[slot] = e->L;
            }
    }
    for (int t = 0; t < nt; t++) free(spills[t].e);
    free(spills);
    if (rc != 0) return -1;
    s->max_gain = most_gain;
    if (f->gs) return stf_gs_springs(f, dt, khist_scale); /* constraints instead (gauss_seidel.c) */
    if (most_gain > 1.0) { /* saturate (see saturated_one); the common case costs nothing more */
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++) {
            double g = s->gain[i];
            s->gain[i] = g > 1.0 ? 1.0 / g : 1.0;
        }
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++) saturated_one(f, i, dt, khist_scale, s->gain);
        s->saturated_steps++;
    }
    s->max_gain = most_gain;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < 3 * n; i++) f->x[i] += f->dx[i];
    return 0;
}

int stf_springs_permute(stf_springs *s, const int32_t *perm, const int32_t *inv, int n)
{
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        int o = perm[i];
        size_t from = (size_t)o * (size_t)s->stride, to = (size_t)i * (size_t)s->stride;
        int c = 0;
        for (int k = 0; k < s->count[o]; k++) {
            int j = inv[s->partner[from + (size_t)k]];
            if (j < 0) continue; /* the partner was removed */
            s->partner2[to + (size_t)c] = j;
            s->rest2[to + (size_t)c] = s->rest[from + (size_t)k];
            c++;
        }
        s->count2[i] = c;
        s->complete[i] = 0; /* searched again at the next step */
    }
    int32_t *tp = s->partner, *tc = s->count;
    double *tr = s->rest;
    s->partner = s->partner2, s->count = s->count2, s->rest = s->rest2;
    s->partner2 = tp, s->count2 = tc, s->rest2 = tr;
    return 0;
}

long stf_springs_total(const stf_springs *s, int n)
{
    long t = 0;
    for (int i = 0; i < n; i++) t += s->count[i];
    return t / 2;
}

size_t stf_springs_bytes(const stf_springs *s)
{
    return (size_t)s->n_alloc * ((size_t)s->stride * 2 * (sizeof(int32_t) + sizeof(double)) +
                                 2 * sizeof(int32_t) + (size_t)s->nthreads * sizeof(int64_t) + sizeof(double));
}

int stf_springs_reserve_stride(stf_springs *s, int n, int stride)
{
    return stride > s->stride ? widen(s, n, stride) : 0;
}
