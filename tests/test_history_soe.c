/* test_history_soe.c - the sum-of-exponentials history (src/history_soe.c) against the exact
 * full history of Eq. 3 (the ring of src/history.c, itself held to the Caputo derivative to
 * round-off by test_history).
 *
 *  1. The fit: the K exponentials reproduce the interior weights w_k to a relative error that
 *     falls with K (K = 16 below 2e-3 for lags 1 .. 1e5).
 *  2. Constant velocity from rest: D equals the Caputo derivative (2-q) n^(1-q) v to within
 *     the fit's error, for 10000 steps; the error falls with K.
 *  3. An irregular velocity signal: D within 1e-3 of the exact full history, relative to the
 *     history's scale sum_k |w_k| max|v|.
 *  4. Memory does not grow with the number of steps (the exact full history does), and
 *     reordering particles reorders their derivatives exactly.
 *  5. A fluid with history mode soe dropped on a floor: the same state with 1 and 2 threads
 *     (bit-identical hash), and its history stiffness is not zero.
 */
#include "history.h"
#include "stf.h"
#include "test_util.h"

#include <stdlib.h>

static const double qs[3] = {0.2, 0.5, 0.8};

static double weight(double q, double k) { return stf_history_weight(q, 1, (long)k + 1); }

static void test_fit(void)
{
    for (int iq = 0; iq < 3; iq++) {
        double q = qs[iq], prev = INFINITY;
        static const int Ks[] = {4, 8, 12, 16};
        for (int ik = 0; ik < 4; ik++) {
            int K = Ks[ik];
            double r[64], c[64], worst = 0;
            CHECK(stf_history_soe_fit(q, K, r, c) == 0, "fit q=%g K=%d", q, K);
            for (double k = 1; k <= 1e5; k = k < 300 ? k + 1 : round(k * 1.05)) {
                double s = 0;
                for (int j = 0; j < K; j++) s += c[j] * pow(r[j], k - 1);
                double rel = fabs(s / weight(q, k) - 1);
                if (rel > worst) worst = rel;
            }
            printf("fit q=%.1f K=%2d: worst relative weight error %.3g\n", q, K, worst);
            CHECK(worst < prev, "q=%g: K=%d error %.3g not below K-4's %.3g", q, K, worst, prev);
            prev = worst;
            if (K == 16) CHECK(worst < 2e-3, "q=%g K=16: weight error %.3g", q, worst);
        }
    }
}

static void test_constant_velocity(void)
{
    const double v[3] = {0.75, -0.5, 2.0};
    for (int iq = 0; iq < 3; iq++) {
        double q = qs[iq], prev = INFINITY;
        static const int Ks[] = {8, 16};
        for (int ik = 0; ik < 2; ik++) {
            stf_history h;
            CHECK(stf_history_soe_init(&h, q, Ks[ik], 1) == 0, "init");
            double worst = 0;
            for (long n = 0; n <= 10000; n++) {
                stf_history_push(&h, v, 1);
                stf_history_derivative(&h, 1);
                double want = n == 0 ? 1.0 : (2.0 - q) * pow((double)n, 1.0 - q);
                for (int a = 0; a < 3; a++) {
                    double rel = fabs(h.D[a] / (v[a] * want) - 1);
                    if (rel > worst) worst = rel;
                }
            }
            printf("constant velocity q=%.1f K=%2d: worst relative error %.3g over 10000 steps\n",
                   q, Ks[ik], worst);
            CHECK(worst < prev, "q=%g: error does not fall with K", q);
            if (Ks[ik] == 16) CHECK(worst < 1e-3, "q=%g K=16: error %.3g", q, worst);
            prev = worst;
            stf_history_free(&h);
        }
    }
}

static void test_irregular(void)
{
    const int np = 4, steps = 6000;
    double *v = malloc(3 * (size_t)np * sizeof *v);
    for (int iq = 0; iq < 3; iq++) {
        double q = qs[iq];
        stf_history hs, hf;
        CHECK(stf_history_soe_init(&hs, q, 16, np) == 0, "init soe");
        CHECK(stf_history_init(&hf, q, 0, np) == 0, "init full");
        double worst = 0, wsum = 1; /* sum_k |w_k| up to the newest lag */
        for (int n = 0; n < steps; n++) {
            for (int i = 0; i < 3 * np; i++) /* impacts, oscillation and drift */
                v[i] = sin(0.013 * n * (i + 1)) + (n % 997 < 50 ? 3.0 : 0.0) - 0.2 * (i % 3) +
                       1e-4 * n;
            stf_history_push(&hs, v, np);
            stf_history_push(&hf, v, np);
            stf_history_derivative(&hs, np);
            stf_history_derivative(&hf, np);
            if (n > 0) wsum += weight(q, n);
            double vmax = 3.0 + 1.0 + 0.4 + 1e-4 * n;
            for (int i = 0; i < 3 * np; i++) {
                double e = fabs(hs.D[i] - hf.D[i]) / (wsum * vmax);
                if (e > worst) worst = e;
            }
        }
        printf("irregular velocity q=%.1f K=16: worst error %.3g of the history scale\n", q, worst);
        CHECK(worst < 1e-3, "q=%g: soe vs exact full history %.3g", q, worst);
        /* O(1) memory: the soe store did not grow; the exact full history did */
        size_t before = stf_history_bytes(&hs), full_before = stf_history_bytes(&hf);
        for (int n = 0; n < 200; n++) {
            stf_history_push(&hs, v, np);
            stf_history_push(&hf, v, np);
        }
        CHECK(stf_history_bytes(&hs) == before, "soe memory grew %zu -> %zu", before, stf_history_bytes(&hs));
        CHECK(stf_history_bytes(&hf) >= full_before, "full history memory");
        /* K running sums, v0 and D per particle (doubles), and the fit's 2K numbers */
        CHECK(stf_history_bytes(&hs) == (size_t)hs.n_alloc * (3 * 16 + 6) * 8 + 2 * 16 * 8,
              "soe bytes %zu for %d particle slots", stf_history_bytes(&hs), hs.n_alloc);
        stf_history_free(&hs);
        stf_history_free(&hf);
    }
    free(v);
}

/* Permuting between two pushes gives the permuted result of the unpermuted run. */
static void test_permute(void)
{
    const int np = 3;
    stf_history a, b;
    CHECK(stf_history_soe_init(&a, 0.5, 12, np) == 0 && stf_history_soe_init(&b, 0.5, 12, np) == 0, "init");
    double v[9], vp[9];
    int perm[3] = {2, 0, 1};
    for (int n = 0; n < 300; n++) {
        for (int i = 0; i < 9; i++) v[i] = cos(0.05 * n * (i + 1));
        for (int i = 0; i < np; i++)
            for (int c = 0; c < 3; c++) vp[3 * i + c] = v[3 * perm[i] + c];
        stf_history_push(&a, v, np);
        if (n == 150) CHECK(stf_history_permute(&b, perm, np) == 0, "permute");
        stf_history_push(&b, n >= 150 ? vp : v, np);
    }
    for (int i = 0; i < np; i++)
        for (int c = 0; c < 3; c++)
            CHECK(b.D[3 * i + c] == a.D[3 * perm[i] + c], "particle %d comp %d: %.17g vs %.17g", i,
                  c, b.D[3 * i + c], a.D[3 * perm[i] + c]);
    stf_history_free(&a);
    stf_history_free(&b);
}

static uint64_t drop_run(int threads, float *kmax)
{
    stf_set_threads(threads);
    stf_fluid_def d = stf_default_fluid_def();
    d.spacing = 0.02;
    d.history_mode = STF_HISTORY_SOE;
    d.terms = 12;
    stf_fluid *f;
    char err[256];
    if (stf_fluid_create(&d, &f, err, sizeof err) != 0) return 0;
    stf_collider_def floor = stf_default_collider_def();
    floor.shape = STF_SHAPE_PLANE;
    floor.stick = 1;
    CHECK(stf_fluid_add_collider(f, &floor, err, sizeof err) == 0, "%s", err);
    double lo[3] = {0, 0, 0.05}, hi[3] = {0.16, 0.16, 0.21}, v[3] = {0, 0, -1.5};
    stf_fluid_add_block(f, lo, hi, v);
    for (int s = 0; s < 120; s++) CHECK(stf_fluid_step(f, 1e-3) == 0, "%s", stf_fluid_failure(f));
    float *k = malloc((size_t)stf_fluid_count(f) * sizeof *k);
    stf_fluid_get_history_stiffness(f, k);
    *kmax = 0;
    for (int i = 0; i < stf_fluid_count(f); i++) *kmax = k[i] > *kmax ? k[i] : *kmax;
    free(k);
    uint64_t h = stf_fluid_hash(f);
    stf_fluid_destroy(f);
    return h;
}

static void test_fluid_threads(void)
{
    float k1, k2;
    uint64_t h1 = drop_run(1, &k1), h2 = drop_run(2, &k2);
    CHECK(h1 != 0 && h1 == h2, "soe fluid: 1 thread %016llx vs 2 threads %016llx",
          (unsigned long long)h1, (unsigned long long)h2);
    CHECK(k1 > 0, "soe fluid: no history stiffness after the impact");
    printf("soe fluid: 1 and 2 threads %s, largest mean history stiffness %g 1/s^2\n",
           h1 == h2 ? "bit-identical" : "DIFFER", k1);
    stf_set_threads(1);
}

int main(void)
{
    stf_set_threads(1);
    test_fit();
    test_constant_velocity();
    test_irregular();
    test_permute();
    test_fluid_threads();
    return test_result("test_history_soe");
}
