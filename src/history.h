/* history.h - the fractional derivative of particle positions (paper Eq. 3).
 *
 * D^q x_n = dt^(1-q)/Gamma(3-q) * sum_p a_{p,n} v_p. Each particle keeps its past velocities in
 * a ring (float32, 12 bytes a vector as in the paper's Table 1); the weighted sum is taken once
 * per particle per step, so a spring needs only |D_i - D_j| (Eq. 6 takes the norm of the
 * difference of the two particles' weighted velocity sums, which is the difference of their D).
 * The ring is stored by time slot (slot s holds all particles' velocities of one step), so
 * the weighted sum streams through memory in a loop the compiler vectorizes. Row r of a slot
 * holds particle part[r]'s velocity: a re-sort renames the rows' particles instead of moving
 * the ring (12 n d bytes). */
#ifndef STF_HISTORY_H
#define STF_HISTORY_H

#include <stddef.h>

typedef struct stf_history {
    double q;     /* fractional order, (0,1) */
    int window;   /* d: lags kept beyond the newest sample; 0 for full history */
    int cap;      /* ring slots per particle */
    int n_alloc;  /* particles the ring holds */
    float *ring;  /* cap slots of 3 n_alloc velocities (slot-major), by row */
    int *part;    /* n_alloc: the particle whose samples row r holds, -1 none */
    int rows;     /* rows in use: rows 0 .. rows - 1 hold particles 0 .. rows - 1 in some order */
    int mapped;   /* 0: row r holds particle r (part is the identity) */
    long pushed;  /* samples pushed since the start */
    int head;     /* slot of the newest sample */
    double *w;    /* cap interior weights by lag: w[0] = 1, w[k] = a_{n-k,n} for 0 < k < n */
    float *wf;    /* window mode: w rounded to float32, then HIST_TBLOCK zeros (history.c) */
    double *D;    /* 3 n: sum_p a_{p,n} v_p (m/s), without the dt^(1-q)/Gamma(3-q) factor */
    /* window mode, time blocks (history.c, stf_history_derivative): the parts of the block's
     * tblock sums that come from samples older than the block, taken in one pass over the
     * ring at the block's start, and from its finished sub-blocks (a pure function of the
     * ring: recomputed, never saved) */
    double *old;  /* tblock * 3 n_old, by row */
    int n_old;    /* particles old was sized for */
    long old_n0;  /* sample index of the block old holds (-1: none) */
    int tblock;   /* the block's length (samples), a multiple of 16 */
    int old_mid;  /* the block's sub-blocks of 16 samples whose sums old includes */
    /* sum-of-exponentials mode (history_soe.c); terms == 0 for the exact ring */
    int terms;      /* K exponentials */
    double *soe_r;  /* K decay factors per step, exp(-lambda_j) */
    double *soe_c;  /* K weights c_j */
    double *soe_T;  /* n_alloc * K * 3: the running sums T_j */
    double *soe_v0; /* 3 n_alloc: the first sample (end-point weight a_{0,n}) */
} stf_history;

/* window = d steps (>= 1), or 0 for full history. Returns 0, -1 when out of memory. */
int stf_history_init(stf_history *h, double q, int window, int n);
void stf_history_free(stf_history *h);
/* Grows the particle count to n (new particles have a zero past). */
int stf_history_resize(stf_history *h, int n);
/* realloc of p from old_n to new_n elements of size bytes, the new ones zeroed; NULL (p
 * untouched) when out of memory. */
void *stf_history_grow_zeroed(void *p, size_t old_n, size_t new_n, size_t size);
/* Stores v (3n) as the newest sample. */
int stf_history_push(stf_history *h, const double *v, int n);
/* Computes D for every particle from the stored samples. */
void stf_history_derivative(stf_history *h, int n);
/* dt^(1-q) / Gamma(3-q): the factor that turns D into D^q x (m/s^q). */
double stf_history_scale(double q, double dt);
/* A bound on |D - sum_p a_{p,n} v_p| / sum_p |a_{p,n} v_p| for the samples as stored (float32),
 * for the latest stf_history_derivative: the roundings of the sum (window mode in steady state:
 * float products summed in short runs, about 1e-6; otherwise double, about d 1e-16). */
double stf_history_error_bound(const stf_history *h);
/* The window's sums use the CPU's vector unit up to `level`: 2 AVX-512, 1 AVX2 (each with
 * FMA), 0 the plain C code (all give the same bits); -1 leaves it. Process-wide, default 2 (tests compare the
 * levels). Returns the level in use (the highest the CPU has, at most `level`). */
int stf_history_simd(int level);
/* Reorders particles: new index i takes old index perm[i] (n fewer than before: the others
 * are removed). perm may name particles added since the last push (no samples yet). */
int stf_history_permute(stf_history *h, const int *perm, int n);
/* A checkpoint stores the ring as it is: cap slots of the first 3 rows floats of each slot
 * (rows in use: h->rows) and part (rows entries), written straight from the ring. This loads
 * that into a history made for n <= rows particles; -1 when part does not name each of the
 * particles 0 .. rows - 1 once, or out of memory. */
int stf_history_ring_set(stf_history *h, const float *src, int rows, const int *part, int n);
size_t stf_history_bytes(const stf_history *h);
/* Full history: grows the ring to cap slots per particle (doubling, as pushes do), for a
 * checkpoint that had that many. 0 / -1. */
int stf_history_set_slots(stf_history *h, int cap);

/* history_soe.c: Eq. 3 over the full history with the interior weights fitted by `terms`
 * exponentials (O(terms) time and memory per particle, whatever the history length). */
int stf_history_soe_init(stf_history *h, double q, int terms, int n);
int stf_history_soe_fit(double q, int K, double *r, double *c); /* w_k ~ sum c_j r_j^(k-1) */
int stf_history_soe_resize(stf_history *h, int n);
void stf_history_soe_push(stf_history *h, const double *v, int n); /* also computes D */
int stf_history_soe_permute(stf_history *h, const int *perm, int n);
size_t stf_history_soe_bytes(const stf_history *h);

#endif
