/* history_soe.c - the fractional derivative with a sum of exponentials (history mode soe).
 *
 * Eq. 3 with the full history is D_n = v_n + sum_{k=1}^{n-1} w_k v_{n-k} + a_{0,n} v_0, the
 * interior weights w_k = (k-1)^e - 2 k^e + (k+1)^e (e = 2 - q) depending on the lag k only.
 * They fall off like a power law (w_k ~ (2-q)(1-q) k^-q), which K exponentials fit well over
 * many decades of lags: w_k ~ sum_j c_j r_j^(k-1), r_j = exp(-lambda_j). Then
 *
 *   T_j(n) = sum_{k=1}^{n-1} r_j^(k-1) v_{n-k}   obeys   T_j(n+1) = v_n + r_j T_j(n),
 *
 * so each step costs O(K) per particle whatever the length of the history, and the memory is
 * K vectors per particle (plus v_0 for the end-point weight a_{0,n}, which is exact). The
 * sums are kept in double: a float32 T with r_j close to 1 adds a rounding error each step
 * that piles up over the 1/lambda_j steps the term remembers.
 *
 * The fit: lambda_j log-spaced from 0.3/H to 3 (H = 1e5 lags, 100 s at dt = 1 ms); c_j by
 * least squares on the relative error at every lag up to 200 and 400 log-spaced lags up to
 * H (Householder QR). Worst relative error of the weights (tests/test_history_soe.c), q = 0.5:
 * 3e-2 (K = 8), 1.5e-3 (K = 12), 4e-4 (K = 16; 2e-4 to 1.7e-3 for q = 0.2 to 0.8); of D for
 * a constant velocity over 10000 steps, K = 16: 1e-5 to 6e-5. Beyond H lags the fit decays
 * exponentially (it forgets faster than Eq. 3). Memory: 24 n (K + 2) bytes (T, v0, D). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "history.h"
#include "stf.h"

#define SOE_HORIZON 1e5
#define SOE_LAMBDA_MAX 3.0

static double interior_weight(double q, double k)
{
    double e = 2.0 - q;
    return pow(k - 1.0, e) - 2.0 * pow(k, e) + pow(k + 1.0, e);
}

/* Least squares min |A x - b| for A (m x K, row-major, m >= K) by Householder QR; A and b
 * are overwritten. Returns 0, or -1 when A is rank deficient. */
static int lstsq(double *A, double *b, int m, int K, double *x)
{
    for (int j = 0; j < K; j++) {
        double norm = 0;
        for (int i = j; i < m; i++) norm += A[i * K + j] * A[i * K + j];
        norm = sqrt(norm);
        if (norm == 0) return -1;
        double alpha = A[j * K + j] > 0 ? -norm : norm;
        /* v = a_j - alpha e_j, stored in column j below the diagonal (v_j in place) */
        A[j * K + j] -= alpha;
        double vv = 0;
        for (int i = j; i < m; i++) vv += A[i * K + j] * A[i * K + j];
        for (int c = j + 1; c < K; c++) {
            double s = 0;
            for (int i = j; i < m; i++) s += A[i * K + j] * A[i * K + c];
            s = 2 * s / vv;
            for (int i = j; i < m; i++) A[i * K + c] -= s * A[i * K + j];
        }
        double s = 0;
        for (int i = j; i < m; i++) s += A[i * K + j] * b[i];
        s = 2 * s / vv;
        for (int i = j; i < m; i++) b[i] -= s * A[i * K + j];
        A[j * K + j] = alpha; /* R's diagonal */
    }
    for (int j = K - 1; j >= 0; j--) {
        double s = b[j];
        for (int c = j + 1; c < K; c++) s -= A[j * K + c] * x[c];
        x[j] = s / A[j * K + j];
    }
    return 0;
}

int stf_history_soe_fit(double q, int K, double *r, double *c)
{
    int m = 0, cap = 200 + 400 + 1;
    double *lag = malloc((size_t)cap * sizeof *lag);
    double *A = malloc((size_t)cap * (size_t)K * sizeof *A);
    double *b = malloc((size_t)cap * sizeof *b);
    double *lam = malloc((size_t)K * sizeof *lam);
    int rc = -1;
    if (!lag || !A || !b || !lam) goto out;
    for (int k = 1; k <= 200; k++) lag[m++] = k;
    for (int i = 1; i <= 400; i++) {
        double k = round(200.0 * pow(SOE_HORIZON / 200.0, i / 400.0));
        if (k > lag[m - 1]) lag[m++] = k;
    }
    for (int j = 0; j < K; j++)
        lam[j] = K == 1 ? 1.0 / SOE_HORIZON
                        : (0.3 / SOE_HORIZON) * pow(SOE_LAMBDA_MAX * SOE_HORIZON / 0.3, (double)j / (K - 1));
    for (int i = 0; i < m; i++) {
        double w = interior_weight(q, lag[i]);
        for (int j = 0; j < K; j++) A[i * K + j] = exp(-lam[j] * (lag[i] - 1.0)) / w;
        b[i] = 1.0;
    }
    if (lstsq(A, b, m, K, c) != 0) goto out;
    for (int j = 0; j < K; j++) r[j] = exp(-lam[j]);
    rc = 0;
out:
    free(lag);
    free(A);
    free(b);
    free(lam);
    return rc;
}

int stf_history_soe_init(stf_history *h, double q, int terms, int n)
{
    memset(h, 0, sizeof *h);
    h->q = q;
    h->terms = terms;
    h->head = -1;
    h->soe_r = malloc((size_t)terms * sizeof *h->soe_r);
    h->soe_c = malloc((size_t)terms * sizeof *h->soe_c);
    /* w stays a 1-slot array so "started" checks (w != NULL) hold as for the ring */
    h->w = malloc(sizeof *h->w);
    if (!h->soe_r || !h->soe_c || !h->w) return -1;
    h->w[0] = 1.0;
    if (stf_history_soe_fit(q, terms, h->soe_r, h->soe_c) != 0) return -1;
    return stf_history_resize(h, n);
}

int stf_history_soe_resize(stf_history *h, int n)
{
    if (n <= h->n_alloc) return 0;
    int cap = n + n / 4 + 16;
    size_t row = (size_t)h->terms * 3;
    size_t old = (size_t)h->n_alloc;
    double *T = stf_history_grow_zeroed(h->soe_T, old * row, (size_t)cap * row, sizeof *T);
    if (!T) return -1;
    h->soe_T = T;
    double *v0 = stf_history_grow_zeroed(h->soe_v0, old * 3, (size_t)cap * 3, sizeof *v0);
    if (!v0) return -1;
    h->soe_v0 = v0;
    double *D = stf_history_grow_zeroed(h->D, old * 3, (size_t)cap * 3, sizeof *D);
    if (!D) return -1;
    h->D = D;
    h->n_alloc = cap;
    return 0;
}

/* D_n from T(n), then T(n+1) = v_n + r T(n) (v_0 is the end point, never in T). */
void stf_history_soe_push(stf_history *h, const double *v, int n)
{
    long step = h->pushed++;
    h->head = 0;
    int K = h->terms;
    const double *r = h->soe_r, *c = h->soe_c;
    double a0 = step == 0 ? 1.0 : stf_history_weight(h->q, 0, step);
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        double *T = h->soe_T + (size_t)i * (size_t)K * 3, *v0 = h->soe_v0 + 3 * (size_t)i;
        const double *vi = v + 3 * (size_t)i;
        if (step == 0)
            for (int a = 0; a < 3; a++) v0[a] = vi[a];
        double s[3] = {0, 0, 0};
        for (int j = 0; j < K; j++)
            for (int a = 0; a < 3; a++) s[a] += c[j] * T[3 * j + a];
        for (int a = 0; a < 3; a++)
            h->D[3 * i + a] = step == 0 ? vi[a] : vi[a] + s[a] + a0 * v0[a];
        if (step > 0)
            for (int j = 0; j < K; j++)
                for (int a = 0; a < 3; a++) T[3 * j + a] = vi[a] + r[j] * T[3 * j + a];
    }
}

int stf_history_soe_permute(stf_history *h, const int *perm, int n)
{
    size_t row = (size_t)h->terms * 3;
    double *T = malloc((size_t)h->n_alloc * row * sizeof *T);
    double *v0 = malloc((size_t)h->n_alloc * 3 * sizeof *v0);
    if (!T || !v0) {
        free(T);
        free(v0);
        return -1;
    }
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        memcpy(T + (size_t)i * row, h->soe_T + (size_t)perm[i] * row, row * sizeof *T);
        memcpy(v0 + 3 * (size_t)i, h->soe_v0 + 3 * (size_t)perm[i], 3 * sizeof *v0);
    }
    memset(T + (size_t)n * row, 0, (size_t)(h->n_alloc - n) * row * sizeof *T);
    memset(v0 + (size_t)n * 3, 0, (size_t)(h->n_alloc - n) * 3 * sizeof *v0);
    free(h->soe_T);
    free(h->soe_v0);
    h->soe_T = T;
    h->soe_v0 = v0;
    return 0;
}

size_t stf_history_soe_bytes(const stf_history *h)
{
    return (size_t)h->n_alloc * ((size_t)h->terms * 3 + 3 + 3) * sizeof(double) +
           2 * (size_t)h->terms * sizeof(double);
}
