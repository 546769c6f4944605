/* test_history.c - the fractional derivative of the paper's Eq. 3.
 *
 *  1. stf_history_weight(q, p, n) is the closed form a_{p,n} of Eq. 3 (end point, interior,
 *     newest sample).
 *  2. The scheme is the product-trapezoidal rule for the Riemann-Liouville integral of order
 *     1-q of v, hence exact for piecewise-linear v. For a constant velocity v from t = 0
 *     (x = v t) the Caputo derivative is D^q x = v t^(1-q) / Gamma(2-q), and
 *     dt^(1-q)/Gamma(3-q) * sum_p a_{p,n} v must equal it to round-off, for every n. Checked
 *     with the weights directly and through the library's history ring (src/history.h).
 *  3. The window mode (Eq. 6, start index n-d): once more than d+1 samples were pushed, D is
 *     v * sum_{k=0..d} w_k with the interior weights, which telescopes to
 *     (d+1)^(2-q) - d^(2-q); it stays constant and below the full history's (2-q) n^(1-q).
 *  4. The window's time-blocked sum against Eq. 3 written out, and bit for bit the same
 *     whenever its older part was taken, with the AVX2 or the plain code.
 *
 * Tolerances. The samples are float32 (the ring); Eq. 3 is written out here in double over
 * the same float32 values, so the difference is the rounding of the library's sum alone.
 * Summed in double (full history, a window before it fills or of at most 16 steps) that is
 * a few 1e-16 per term. A long window in steady state takes its older samples' products in
 * float, summed in float over runs of 16 lags and the runs in double (history.c,
 * old_chunk): with u = 2^-24, the weight and the product are rounded once each (2u) and a
 * run's sum at most 15 times (15u), so |D - Eq. 3| <= gamma_17 S + (double terms), where
 * S = sum |a_{p,n} v_p| and gamma_k = k u / (1 - k u) (Higham, 3.1): 1.01e-6 S. That bound is
 * stf_history_error_bound(); a test fails above it (a wrong weight, lag or sample gives an error
 * of order S). With all v_p of one sign, S = |D|.
 */
#include "history.h"
#include "stf.h"
#include "test_util.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

static const double qs[3] = {0.2, 0.5, 0.8};

/* Eq. 3 written out independently of the library. */
static double eq3(double q, long p, long n)
{
    double e = 2.0 - q;
    if (p == n) return 1.0;
    if (p == 0) return pow((double)(n - 1), e) - pow((double)n, 1.0 - q) * ((double)n + q - 2.0);
    return pow((double)(n - p - 1), e) - 2.0 * pow((double)(n - p), e) + pow((double)(n - p + 1), e);
}

static void test_weights(void)
{
    static const long ns[] = {1, 2, 3, 5, 10, 57, 150, 1000};
    for (int iq = 0; iq < 3; iq++) {
        double q = qs[iq];
        for (size_t in = 0; in < sizeof ns / sizeof ns[0]; in++) {
            long n = ns[in];
            long ps[] = {0, 1, n / 3, n / 2, n - 2, n - 1, n};
            for (size_t ip = 0; ip < sizeof ps / sizeof ps[0]; ip++) {
                long p = ps[ip];
                if (p < 0 || p > n) continue;
                double want = eq3(q, p, n), got = stf_history_weight(q, p, n);
                CHECK(fabs(got - want) <= 1e-13 * fabs(want) + 1e-15,
                      "q=%g p=%ld n=%ld: a=%.17g, Eq. 3 gives %.17g", q, p, n, got, want);
            }
        }
        /* A few values by hand: a_{n,n} = 1; a_{0,1} = 1 - q; a_{0,2} = 1 - 2^(1-q) q;
           the first interior weight a_{n-1,n} = 2^(2-q) - 2. */
        CHECK_NEAR(stf_history_weight(q, 7, 7), 1.0, 0.0, "a_{n,n}");
        CHECK_NEAR(stf_history_weight(q, 0, 1), 1.0 - q, 1e-15, "a_{0,1}");
        CHECK_NEAR(stf_history_weight(q, 0, 2), 1.0 - pow(2.0, 1.0 - q) * q, 1e-15, "a_{0,2}");
        CHECK_NEAR(stf_history_weight(q, 9, 10), pow(2.0, 2.0 - q) - 2.0, 1e-15, "a_{n-1,n}");
        /* Interior weights depend on the lag n-p only (what lets the library precompute them
           by lag), and shrink with the lag: the near past counts more (paper, Fig. 2). */
        CHECK(stf_history_weight(q, 5, 20) == stf_history_weight(q, 105, 120),
              "q=%g: interior weight depends on n-p only", q);
        for (long k = 1; k < 200; k++) {
            double wk = stf_history_weight(q, 1, k + 1), wk1 = stf_history_weight(q, 1, k + 2);
            CHECK(wk > 0 && wk1 < wk, "q=%g: interior weights positive and decreasing at lag %ld", q,
                  k);
        }
    }
}

/* Caputo (= Riemann-Liouville of order 1-q of v) derivative of x = v t. */
static double caputo_linear(double q, double v, double t) { return v * pow(t, 1.0 - q) / tgamma(2.0 - q); }

static void test_constant_velocity_direct(void)
{
    const double dt = 1e-3, v = 0.75;
    for (int iq = 0; iq < 3; iq++) {
        double q = qs[iq], worst = 0;
        double scale = pow(dt, 1.0 - q) / tgamma(3.0 - q);
        for (long n = 1; n <= 2000; n = n < 20 ? n + 1 : n + 97) {
            double s = 0;
            for (long p = 0; p <= n; p++) s += stf_history_weight(q, p, n) * v;
            double got = scale * s, want = caputo_linear(q, v, (double)n * dt);
            double rel = fabs(got - want) / want;
            if (rel > worst) worst = rel;
            CHECK(rel <= 1e-12, "q=%g n=%ld: scheme %.17g vs Caputo %.17g (rel %.3g)", q, n, got,
                  want, rel);
        }
        printf("direct sum, q=%.1f: worst relative error %.3g\n", q, worst);
    }
}

/* Through the library: stf_history_init/push/derivative with a full history (window 0). */
static void test_constant_velocity_library(void)
{
    const double dt = 1e-3;
    const int np = 3; /* three particles with different constant velocities */
    /* float32 ring: use values float represents exactly */
    const double v[9] = {0.75, -0.5, 2.0, 0.0, 1.25, -3.0, 0.125, 0.0, 0.0};
    CHECK_NEAR(stf_history_scale(0.5, dt), pow(dt, 0.5) / tgamma(2.5), 1e-18, "history_scale");
    for (int iq = 0; iq < 3; iq++) {
        double q = qs[iq], worst = 0;
        stf_history h;
        CHECK(stf_history_init(&h, q, 0, np) == 0, "history_init q=%g", q);
        double scale = stf_history_scale(q, dt);
        for (long n = 0; n <= 2000; n++) {
            CHECK(stf_history_push(&h, v, np) == 0, "push %ld", n);
            stf_history_derivative(&h, np);
            if (n == 0) {
                /* one sample: a_{0,0} = 1 */
                for (int c = 0; c < 3 * np; c++) CHECK_NEAR(h.D[c], v[c], 0.0, "D after 1 sample");
                continue;
            }
            double t = (double)n * dt;
            for (int c = 0; c < 3 * np; c++) {
                double want = caputo_linear(q, v[c], t), got = scale * h.D[c];
                double rel = want != 0 ? fabs(got - want) / fabs(want) : fabs(got);
                if (rel > worst) worst = rel;
                CHECK(rel <= 1e-12, "library q=%g n=%ld comp %d: %.17g vs Caputo %.17g (rel %.3g)",
                      q, n, c, got, want, rel);
            }
        }
        printf("library full history, q=%.1f: worst relative error %.3g over 2000 steps\n", q,
               worst);
        stf_history_free(&h);
    }
}

/* A linear ramp v = a t is also integrated exactly (second order scheme, exact for
 * piecewise-linear v): D^q x for x = a t^2/2 is a t^(2-q)/Gamma(3-q). */
static void test_linear_velocity_library(void)
{
    const double dt = 1.0 / 1024; /* so that v = n dt is exact in float32 */
    for (int iq = 0; iq < 3; iq++) {
        double q = qs[iq], worst = 0;
        stf_history h;
        CHECK(stf_history_init(&h, q, 0, 1) == 0, "init");
        for (long n = 0; n <= 1000; n++) {
            double vv[3] = {(double)n * dt, 0, 0};
            stf_history_push(&h, vv, 1);
            stf_history_derivative(&h, 1);
            if (n < 1) continue;
            double t = (double)n * dt;
            double got = stf_history_scale(q, dt) * h.D[0], want = pow(t, 2.0 - q) / tgamma(3.0 - q);
            double rel = fabs(got - want) / want;
            if (rel > worst) worst = rel;
            CHECK(rel <= 1e-11, "ramp q=%g n=%ld: %.17g vs %.17g (rel %.3g)", q, n, got, want, rel);
        }
        printf("library ramp, q=%.1f: worst relative error %.3g\n", q, worst);
        stf_history_free(&h);
    }
}

static void test_window(void)
{
    static const int ds[] = {1, 5, 150};
    const double v[3] = {0.75, -0.5, 2.0};
    for (int iq = 0; iq < 3; iq++) {
        double q = qs[iq];
        for (size_t id = 0; id < sizeof ds / sizeof ds[0]; id++) {
            int d = ds[id];
            stf_history hw, hf;
            CHECK(stf_history_init(&hw, q, d, 1) == 0, "init window");
            CHECK(stf_history_init(&hf, q, 0, 1) == 0, "init full");
            double truncated = 0; /* sum_{k=0..d} w_k, interior weights by lag */
            for (int k = 0; k <= d; k++) truncated += k == 0 ? 1.0 : stf_history_weight(q, 1, k + 1);
            double closed = pow(d + 1.0, 2.0 - q) - pow((double)d, 2.0 - q);
            CHECK(fabs(truncated - closed) <= 1e-11 * closed,
                  "q=%g d=%d: truncated weight sum %.17g vs (d+1)^(2-q)-d^(2-q) = %.17g", q, d,
                  truncated, closed);
            int total = 3 * d + 20;
            for (int s = 1; s <= total; s++) {
                stf_history_push(&hw, v, 1);
                stf_history_push(&hf, v, 1);
                stf_history_derivative(&hw, 1);
                stf_history_derivative(&hf, 1);
                long n = s - 1; /* index of the newest sample */
                if (s <= d + 1) {
                    /* The window holds everything so far: the full history, to the window's
                       error bound (a long window sums in float32 blocks from the start; the
                       terms have one sign, so S = |D|), 1e-13 the reference's rounding. */
                    double tol = stf_history_error_bound(&hw) + 1e-13;
                    for (int c = 0; c < 3; c++)
                        CHECK(fabs(hw.D[c] - hf.D[c]) <= tol * fabs(hf.D[c]),
                              "q=%g d=%d n=%ld: window %.17g vs full %.17g before it fills", q, d,
                              n, hw.D[c], hf.D[c]);
                } else {
                    /* terms of one sign: S = |want|; 1e-13: the reference's own rounding */
                    double tol = stf_history_error_bound(&hw) + 1e-13;
                    CHECK(tol < (d > 16 ? 1.1e-6 : 1e-12), "q=%g d=%d: error bound %.3g", q, d,
                          tol);
                    for (int c = 0; c < 3; c++) {
                        double want = v[c] * truncated;
                        CHECK(fabs(hw.D[c] - want) <= tol * fabs(want),
                              "q=%g d=%d n=%ld: window D %.17g vs v*sum w_k %.17g", q, d, n,
                              hw.D[c], want);
                        /* bounded: below the full history's (2-q) n^(1-q) v */
                        CHECK(fabs(hw.D[c]) < fabs(hf.D[c]),
                              "q=%g d=%d n=%ld: window |D| %.17g not below full |D| %.17g", q, d,
                              n, hw.D[c], hf.D[c]);
                    }
                }
            }
            /* full history keeps growing like n^(1-q): check it against the closed form */
            double full_sum = (2.0 - q) * pow((double)(total - 1), 1.0 - q);
            CHECK(fabs(hf.D[0] - v[0] * full_sum) <= 1e-12 * full_sum * v[0],
                  "full sum %.17g vs (2-q) n^(1-q) v = %.17g", hf.D[0], v[0] * full_sum);
            stf_history_free(&hw);
            stf_history_free(&hf);
        }
    }
}

/* The window's time-blocked sum (history.c: the older samples' part of the next 16 sums in
 * one pass) against Eq. 3 written out, for an irregular signal on 7 particles, across block
 * boundaries and a re-sort in the middle of a block (the particles reversed at sample 45),
 * from the first sample on (before the window fills, with the oldest sample's end-point
 * weight). */
static void test_window_blocked(int D, int T, int FLIP)
{
    enum { NP = 7, TMAX = 700 };
    const double q = 0.5;
    static double sig[TMAX][NP][3]; /* the velocity of original particle i at sample t */
    for (int t = 0; t < T; t++)
        for (int i = 0; i < NP; i++)
            for (int c = 0; c < 3; c++)
                sig[t][i][c] = (float)(sin(0.37 * t + 1.3 * i + 2.1 * c) + 0.01 * (t % 7) - 0.2 * c);
    /* (float: the ring keeps float32 samples, so the reference sums the same values) */
    stf_history h;
    CHECK(stf_history_init(&h, q, D, NP) == 0, "init");
    int perm[NP], at[NP]; /* at[k]: original particle held at index k */
    for (int k = 0; k < NP; k++) at[k] = k, perm[k] = NP - 1 - k;
    double worst = 0;
    for (int t = 0; t < T; t++) {
        if (t == FLIP) {
            CHECK(stf_history_permute(&h, perm, NP) == 0, "permute");
            for (int k = 0; k < NP; k++) at[k] = NP - 1 - k;
        }
        double v[NP * 3];
        for (int k = 0; k < NP; k++)
            for (int c = 0; c < 3; c++) v[3 * k + c] = sig[t][at[k]][c];
        CHECK(stf_history_push(&h, v, NP) == 0, "push");
        stf_history_derivative(&h, NP);
        for (int k = 0; k < NP; k++)
            for (int c = 0; c < 3; c++) {
                double want = 0, scale = 0;
                if (t < D + 1) /* before the window fills: every sample p of Eq. 3 */
                    for (int p = 0; p <= t; p++) {
                        double term = eq3(q, p, t) * sig[p][at[k]][c];
                        want += term, scale += fabs(term);
                    }
                else
                    for (int lag = 0; lag <= D; lag++) {
                        double term = eq3(q, 1, lag + 1) * sig[t - lag][at[k]][c];
                        if (lag == 0) term = sig[t][at[k]][c];
                        want += term, scale += fabs(term);
                    }
                double err = fabs(h.D[3 * k + c] - want) / scale; /* in units of S */
                if (err > worst) worst = err;
            }
    }
    /* the library's rounding (header comment) plus the reference's, D + 2 double terms */
    double bound = stf_history_error_bound(&h) + 1e-13;
    CHECK(worst <= bound, "blocked window sum: worst error %.3g S, bound %.3g S", worst, bound);
    printf("test_history: blocked window sum (d = %d, %d samples, re-sort mid-block): worst "
           "error %.2g S (bound %.2g S, S = sum |a v|)\n", D, T, worst, bound);
    stf_history_free(&h);
}

/* The sum for a sample is a function of the samples alone: a twin whose block's older part
 * is taken again in the middle of a block (a resize, as after a resume), with 2 threads, or
 * with each vector code the CPU has and the plain C code, gives the same bits as an
 * uninterrupted run. */
static void test_window_recompute(int D, int T, int RESIZE)
{
    enum { NP = 37 };
    const double q = 0.5;
    int best = stf_history_simd(-1);
    stf_history a, b, c[3];
    CHECK(stf_history_init(&a, q, D, NP) == 0 && stf_history_init(&b, q, D, NP) == 0, "init");
    for (int l = 0; l < best; l++) CHECK(stf_history_init(&c[l], q, D, NP) == 0, "init");
    long differ_b = 0, differ_c[3] = {0}, checked = 0;
    for (int t = 0; t < T; t++) {
        double v[NP * 3];
        for (int e = 0; e < 3 * NP; e++) v[e] = sin(0.11 * t + 0.7 * e) * (1 + e % 5);
        if (t == RESIZE) CHECK(stf_history_resize(&b, 4 * NP) == 0, "resize");
        stf_history_push(&a, v, NP), stf_history_push(&b, v, NP);
        stf_history_derivative(&a, NP);
        stf_set_threads(2);
        stf_history_derivative(&b, NP);
        stf_set_threads(1);
        for (int l = 0; l < best; l++) { /* a = the best level */
            stf_history_simd(l);
            stf_history_push(&c[l], v, NP);
            stf_history_derivative(&c[l], NP);
        }
        stf_history_simd(2);
        if (t <= D) continue;
        for (int e = 0; e < 3 * NP; e++) {
            differ_b += memcmp(&a.D[e], &b.D[e], sizeof(double)) != 0;
            for (int l = 0; l < best; l++)
                differ_c[l] += memcmp(&a.D[e], &c[l].D[e], sizeof(double)) != 0;
            checked++;
        }
    }
    CHECK(differ_b == 0, "%ld of %ld sums differ after a resize mid-block (2 threads)", differ_b,
          checked);
    for (int l = 0; l < best; l++)
        CHECK(differ_c[l] == 0, "%ld of %ld sums differ between vector level %d and %d",
              differ_c[l], checked, best, l);
    printf("test_history: d = %d, resize at sample %d, 2 threads, vector levels 0..%d (0: plain "
           "C, 1: AVX2, 2: AVX-512): %ld sums bit-identical\n", D, RESIZE, best, checked);
    stf_history_free(&a), stf_history_free(&b);
    for (int l = 0; l < best; l++) stf_history_free(&c[l]);
}

/* stf_history_permute(h, map, n) with at (the tracked identity of each of h's particles)
 * permuted alike: at[k] becomes at[map[k]]. */
static void permute_tracked(stf_history *h, int *at, const int *map, int n, const char *what)
{
    int *nat = malloc((size_t)n * sizeof *nat);
    if (!nat) exit(1);
    for (int k = 0; k < n; k++) nat[k] = at[map[k]];
    memcpy(at, nat, (size_t)n * sizeof *nat);
    free(nat);
    CHECK(stf_history_permute(h, map, n) == 0, "%s", what);
}

/* Particles removed (stf_history_permute with fewer particles, the rows gathered again) and
 * re-sorts (only the row -> particle map changes): each kept particle's sums are bit for bit
 * those of a twin that only ever held the kept particles, in their final order. */
static void test_window_remove(void)
{
    enum { NP = 40, KEEP = 25, D = 300, T = 420, SORT = 100, REMOVE = 350 };
    const double q = 0.5;
    stf_history a, b;
    CHECK(stf_history_init(&a, q, D, NP) == 0 && stf_history_init(&b, q, D, KEEP) == 0, "init");
    int at[NP], keep[KEEP], sort[NP]; /* at[k]: original particle at index k of a */
    for (int k = 0; k < NP; k++) at[k] = k, sort[k] = (7 * k + 3) % NP; /* 7 coprime to 40 */
    for (int k = 0; k < KEEP; k++) keep[k] = (3 * k + 1) % NP; /* indices of a at REMOVE */
    int na = NP;
    long differ = 0, checked = 0;
    for (int t = 0; t < T; t++) {
        if (t == SORT) permute_tracked(&a, at, sort, NP, "re-sort");
        if (t == REMOVE) {
            permute_tracked(&a, at, keep, KEEP, "remove");
            na = KEEP;
        }
        /* b holds, at index k, the particle a ends with at k: the one at index keep[k] after
           the re-sort, sort[keep[k]] (at is the identity before it) */
        double va[NP * 3], vb[KEEP * 3];
        for (int k = 0; k < na; k++)
            for (int c = 0; c < 3; c++)
                va[3 * k + c] = sin(0.05 * t + 0.9 * at[k] + c) * (1 + at[k] % 3);
        for (int k = 0; k < KEEP; k++) {
            int o = sort[keep[k]];
            for (int c = 0; c < 3; c++) vb[3 * k + c] = sin(0.05 * t + 0.9 * o + c) * (1 + o % 3);
        }
        CHECK(stf_history_push(&a, va, na) == 0 && stf_history_push(&b, vb, KEEP) == 0, "push");
        stf_history_derivative(&a, na);
        stf_history_derivative(&b, KEEP);
        if (t < D + 1) continue;
        for (int k = 0; k < KEEP; k++) {
            int ia = t >= REMOVE ? k : keep[k];
            for (int c = 0; c < 3; c++, checked++)
                differ += memcmp(&a.D[3 * ia + c], &b.D[3 * k + c], sizeof(double)) != 0;
        }
    }
    CHECK(differ == 0, "%ld of %ld sums differ after a re-sort and a removal", differ, checked);
    printf("test_history: re-sort at %d, %d of %d particles removed at %d (d = %d): %ld sums "
           "bit-identical to the kept particles' twin\n", SORT, NP - KEEP, NP, REMOVE, D, checked);
    stf_history_free(&a), stf_history_free(&b);
}

/* Re-sorts in the middle of blocks (all particles reversed, then neighbours swapped), of a
 * short ring (d < 256: the rows are gathered) and a long one (the row -> particle map alone
 * changes): each particle's sums are bit for bit those of a twin that was never re-sorted. */
static void test_window_resort(int D)
{
    enum { NP = 700 };
    const int T = D + 140, FAR = D + 41, NEAR = D + 73;
    const double q = 0.7;
    stf_history a, b;
    CHECK(stf_history_init(&a, q, D, NP) == 0 && stf_history_init(&b, q, D, NP) == 0, "init");
    static int at[NP], perm[NP]; /* at[k]: b's particle at index k of a */
    for (int k = 0; k < NP; k++) at[k] = k;
    static double va[NP * 3], vb[NP * 3];
    long differ = 0, checked = 0;
    for (int t = 0; t < T; t++) {
        if (t == FAR || t == NEAR) {
            for (int k = 0; k < NP; k++) /* reversed; or neighbours swapped in pairs */
                perm[k] = t == FAR ? NP - 1 - k : (k ^ 1) < NP ? k ^ 1 : k;
            permute_tracked(&a, at, perm, NP, "re-sort");
            /* short ring: row k holds particle k again; long: the map follows them */
            int p0 = D < 256 ? 0 : t == FAR ? NP - 1 : NP - 2;
            CHECK(a.part[0] == p0, "d=%d t=%d: row 0 holds particle %d, not %d", D, t,
                  a.part[0], p0);
        }
        for (int e = 0; e < 3 * NP; e++) vb[e] = sin(0.13 * t + 0.37 * e) + 0.1 * (e % 7);
        for (int k = 0; k < NP; k++)
            for (int c = 0; c < 3; c++) va[3 * k + c] = vb[3 * at[k] + c];
        stf_history_push(&a, va, NP), stf_history_push(&b, vb, NP);
        stf_history_derivative(&a, NP), stf_history_derivative(&b, NP);
        for (int k = 0; k < NP; k++)
            for (int c = 0; c < 3; c++, checked++)
                differ += memcmp(&a.D[3 * k + c], &b.D[3 * at[k] + c], sizeof(double)) != 0;
    }
    CHECK(differ == 0, "%ld of %ld sums differ after re-sorts", differ, checked);
    printf("test_history: d = %d (%s), re-sorts at %d and %d, %d particles: %ld sums "
           "bit-identical to a twin never re-sorted\n", D, D < 256 ? "rows gathered" : "map",
           FAR, NEAR, NP, checked);
    stf_history_free(&a), stf_history_free(&b);
}

/* Particles added since the last push (no row yet), then some particles removed before the
 * next push (stf_fluid_add_particle then stf_fluid_remove_inside between two steps): perm
 * names particles up to the count before the removal, past the rows in use. Each kept
 * particle's sums are bit for bit those of a twin that held the kept particles in their
 * final order from the start, the added ones with a zero past. Short ring (rows gathered)
 * and long ring (row -> particle map, re-sorted first). */
static void test_window_add_then_remove(int D)
{
    enum { NP = 20, ADD = 3, T0 = 50 };
    const int T = D + 120, SORT = 17;
    const double q = 0.6;
    int nall = NP + ADD, keep[NP + ADD], nkeep = 0, sort[NP];
    for (int k = 0; k < NP; k++) sort[k] = (3 * k + 2) % NP; /* 3 coprime to 20 */
    for (int k = 0; k < nall; k++)
        if (k % 4 != 1) keep[nkeep++] = k; /* old indices kept, some added ones among them */
    stf_history a, b;
    CHECK(stf_history_init(&a, q, D, nall) == 0 && stf_history_init(&b, q, D, nkeep) == 0, "init");
    int at[NP + ADD]; /* at[k]: the signal index of a's particle k */
    for (int k = 0; k < nall; k++) at[k] = k;
    int na = NP;
    long differ = 0, checked = 0;
    for (int t = 0; t < T; t++) {
        if (t == SORT) permute_tracked(&a, at, sort, NP, "re-sort");
        if (t == T0) { /* ADD particles appended, then the others removed, no push between */
            permute_tracked(&a, at, keep, nkeep, "remove after adding");
            na = nkeep;
        }
        /* a's particle k carries the signal of particle at[k] */
        double va[(NP + ADD) * 3], vb[(NP + ADD) * 3];
        for (int k = 0; k < na; k++)
            for (int c = 0; c < 3; c++) va[3 * k + c] = sin(0.05 * t + 0.9 * at[k] + c) + 0.1 * c;
        /* b's particle k: the signal a's particle k carries from T0 on */
        int bsig[NP + ADD];
        for (int k = 0; k < nkeep; k++) bsig[k] = keep[k] < NP ? sort[keep[k]] : keep[k];
        for (int k = 0; k < nkeep; k++)
            for (int c = 0; c < 3; c++)
                vb[3 * k + c] = bsig[k] >= NP && t < T0
                                    ? 0.0
                                    : sin(0.05 * t + 0.9 * bsig[k] + c) + 0.1 * c;
        CHECK(stf_history_push(&a, va, na) == 0 && stf_history_push(&b, vb, nkeep) == 0, "push");
        stf_history_derivative(&a, na);
        stf_history_derivative(&b, nkeep);
        if (t < T0) continue;
        for (int e = 0; e < 3 * nkeep; e++, checked++)
            differ += memcmp(&a.D[e], &b.D[e], sizeof(double)) != 0;
    }
    CHECK(differ == 0, "d=%d: %ld of %ld sums differ after particles were added, then others "
          "removed before a push", D, differ, checked);
    printf("test_history: d = %d, %d particles added and %d removed before one push: %ld sums "
           "bit-identical to the twin\n", D, ADD, nall - nkeep, checked);
    stf_history_free(&a), stf_history_free(&b);
}

/* Particles removed in the middle of a block while the scratch for reordering the block's
 * older sums runs out (the address space capped with setrlimit: a real allocation failure,
 * after the ring's own reordering succeeded), then, after the next step, particles added
 * before the block ends:
 * the added particles have a zero past, so their sums are bit for bit those of a twin that
 * held zeros before. Not under ASan (its shadow memory does not fit under the cap). */
static void test_window_remove_out_of_memory(void)
{
#if !defined(__SANITIZE_ADDRESS__)
    enum { NP = 100000, KEEP = NP - 1000, ADD = 5, D = 20, T0 = 40, T1 = 42, T = 48 };
    const double q = 0.5;
#if defined(M_MMAP_THRESHOLD)
    /* large blocks mapped, none in memory freed before (run first): the cap bites */
    mallopt(M_MMAP_THRESHOLD, 64 * 1024);
#endif
    stf_history a, b;
    CHECK(stf_history_init(&a, q, D, NP) == 0 && stf_history_init(&b, q, D, ADD) == 0, "init");
    double *va = malloc((size_t)NP * 3 * sizeof *va), vb[ADD * 3];
    int *keep = malloc((size_t)KEEP * sizeof *keep);
    for (int k = 0; k < KEEP; k++) keep[k] = k; /* the last 1000 removed */
    int na = NP, capped = 0;
    long differ = 0, checked = 0;
    for (int t = 0; t < T; t++) {
        if (t == T0) { /* 8 samples into a block of 16 */
            long pages = 0;
            FILE *f = fopen("/proc/self/statm", "r");
            if (f && fscanf(f, "%ld", &pages) == 1) {
                /* room for the ring's scratch (12 n bytes and 8 n of indices) and not for
                   the older sums' (24 n) */
                struct rlimit old, cap;
                getrlimit(RLIMIT_AS, &old);
                cap = old;
                cap.rlim_cur = (rlim_t)pages * 4096 + (rlim_t)NP * 28;
                if (cap.rlim_cur < old.rlim_cur && setrlimit(RLIMIT_AS, &cap) == 0) {
                    CHECK(stf_history_permute(&a, keep, KEEP) == 0, "remove under the cap");
                    setrlimit(RLIMIT_AS, &old);
                    capped = 1;
                }
            }
            if (f) fclose(f);
            if (!capped) CHECK(stf_history_permute(&a, keep, KEEP) == 0, "remove");
            na = KEEP;
        }
        if (t == T1) na = KEEP + ADD; /* ADD particles appended in the same block */
        for (int k = 0; k < na; k++)
            for (int c = 0; c < 3; c++)
                va[3 * k + c] = k >= KEEP ? 1.0 + 0.1 * (k - KEEP) + c
                                          : sin(0.3 * t + 0.001 * k + c) + 2.0;
        for (int k = 0; k < ADD; k++)
            for (int c = 0; c < 3; c++) vb[3 * k + c] = t < T1 ? 0.0 : va[3 * (KEEP + k) + c];
        CHECK(stf_history_push(&a, va, na) == 0 && stf_history_push(&b, vb, ADD) == 0, "push");
        stf_history_derivative(&a, na);
        stf_history_derivative(&b, ADD);
        if (t < T1) continue;
        for (int e = 0; e < 3 * ADD; e++, checked++)
            differ += memcmp(&a.D[3 * KEEP + e], &b.D[e], sizeof(double)) != 0;
    }
    CHECK(differ == 0, "%ld of %ld sums of particles added after a removal that ran out of "
          "memory differ from their zero-past twin (e.g. %.17g vs %.17g)", differ, checked,
          a.D[3 * KEEP], b.D[0]);
    printf("test_history: removal under a %s address space, then %d particles added "
           "mid-block: %ld sums bit-identical to the zero-past twin\n",
           capped ? "capped" : "(cap not set)", ADD, checked);
    free(va), free(keep);
    stf_history_free(&a), stf_history_free(&b);
#endif
}

/* A checkpoint's copy of the ring (its rows in use, slot by slot, and their particles)
 * loaded into a new history (stf_history_ring_set) after re-sorts of a ring long enough to
 * be mapped: the sums that follow are bit for bit the same. A map that names a particle
 * twice is refused. */
static void test_window_ring_copy(void)
{
    enum { NP = 30, D = 260, T = 400, SAVE = 310 };
    const double q = 0.3;
    stf_history a, b;
    CHECK(stf_history_init(&a, q, D, NP) == 0, "init");
    int perm[NP];
    for (int k = 0; k < NP; k++) perm[k] = (11 * k + 5) % NP;
    double v[NP * 3];
    long differ = 0, checked = 0;
    for (int t = 0; t < T; t++) {
        if (t % 37 == 0) /* both re-sorted alike once the copy exists */
            CHECK(stf_history_permute(&a, perm, NP) == 0 &&
                      (t < SAVE || stf_history_permute(&b, perm, NP) == 0),
                  "re-sort");
        if (t == SAVE) {
            CHECK(a.mapped && a.rows == NP, "the re-sorts map the rows");
            float *ring = malloc((size_t)a.cap * NP * 3 * sizeof *ring);
            CHECK(ring && stf_history_init(&b, q, D, NP) == 0, "init the copy");
            for (int s = 0; s < a.cap; s++)
                memcpy(ring + (size_t)s * NP * 3, a.ring + (size_t)s * (size_t)a.n_alloc * 3,
                       NP * 3 * sizeof *ring);
            int twice[NP];
            memcpy(twice, a.part, sizeof twice);
            twice[1] = twice[0];
            CHECK(stf_history_ring_set(&b, ring, NP, twice, NP) != 0, "a particle named twice");
            CHECK(stf_history_ring_set(&b, ring, NP, a.part, NP) == 0, "ring_set");
            b.pushed = a.pushed, b.head = a.head;
            free(ring);
        }
        for (int e = 0; e < 3 * NP; e++) v[e] = cos(0.07 * t + 0.3 * e);
        stf_history_push(&a, v, NP);
        stf_history_derivative(&a, NP);
        if (t < SAVE) continue;
        stf_history_push(&b, v, NP);
        stf_history_derivative(&b, NP);
        for (int e = 0; e < 3 * NP; e++, checked++)
            differ += memcmp(&a.D[e], &b.D[e], sizeof(double)) != 0;
    }
    CHECK(differ == 0, "%ld of %ld sums differ after the ring was copied", differ, checked);
    printf("test_history: ring copied out and in at sample %d after re-sorts: %ld sums "
           "bit-identical\n", SAVE, checked);
    stf_history_free(&a), stf_history_free(&b);
}

int main(void)
{
    /* A handful of particles: one thread (spinning OpenMP threads only slow the thousands of
       tiny parallel loops down on a busy machine; results do not depend on it). */
    stf_set_threads(1);
    test_window_remove_out_of_memory(); /* first: no memory freed before */
    test_weights();
    test_constant_velocity_direct();
    test_constant_velocity_library();
    test_linear_velocity_library();
    test_window();
    test_window_blocked(40, 140, 45);
    test_window_blocked(300, 420, 333); /* blocks of 32 (d >= 256), re-sort 13 into one */
    test_window_recompute(70, 200, 123); /* 123: 11 samples into a block of 16 */
    test_window_recompute(300, 420, 373); /* 373: 21 into a block of 32 (its second half) */
    test_window_recompute(300, 420, 325); /* 325: 5 into its first half */
    test_window_resort(40);
    test_window_resort(260);
    test_window_remove();
    test_window_ring_copy();
    test_window_add_then_remove(40);
    test_window_add_then_remove(300);
    return test_result("test_history");
}
