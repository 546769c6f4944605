/* springs.h - Clavet's plastic springs with the paper's history stiffness (Eq. 6).
 *
 * Each spring is stored on both of its particles (partner index and rest length), so every
 * particle updates and applies its own side in parallel with no shared writes; both sides see
 * the same inputs and compute bit-identical rest lengths, so the network stays symmetric. */
#ifndef STF_SPRINGS_H
#define STF_SPRINGS_H

#include <stddef.h>
#include <stdint.h>

typedef struct stf_springs {
    int stride;       /* slots per particle */
    int n_alloc;
    int32_t *partner; /* n_alloc * stride */
    double *rest;     /* n_alloc * stride: rest lengths L, m */
    int32_t *count;   /* n_alloc */
    int32_t *partner2, *count2; /* count2: the step's new counts (then swapped with count);
                                   partner2, rest2: stf_springs_permute's scratch (the step
                                   rewrites the rows in place) */
    double *rest2;
    int64_t *mark;    /* nthreads * n_alloc: which particle last saw a spring to j */
    int nthreads;
    double *gain;     /* n_alloc: sum of the spring gains dt^2 k (1 - L/h) of the particle,
                         then its saturation factor (springs.c, saturated_one) */
    uint8_t *complete; /* n_alloc: 1 when after the last step every neighbour of the particle
                          was a partner (springs.c, adjust_one) */
    int search_always; /* 1: search every neighbour row for new springs, complete or not
                          (tests: the skip changes no result) */
    long saturated_steps; /* steps in which the gains were scaled down (sum > 1 somewhere) */
    double max_gain;  /* largest sum of gains in the last step */
} stf_springs;

struct stf_fluid;
int stf_springs_init(stf_springs *s, int n);
void stf_springs_free(stf_springs *s);
int stf_springs_resize(stf_springs *s, int n);
/* Alg. 4 (add/remove springs, plasticity) and Alg. 3 (displacements, with Eq. 6 stiffness
 * when the history effect is on), on the predicted positions. Returns 0, -1 out of memory. */
int stf_springs_step(struct stf_fluid *f, double dt);
int stf_springs_permute(stf_springs *s, const int32_t *perm, const int32_t *inv, int n);
long stf_springs_total(const stf_springs *s, int n);
size_t stf_springs_bytes(const stf_springs *s);
/* Widens the rows of n particles to stride slots if they are narrower (checkpoints restore
 * the stride they had). 0 / -1. */
int stf_springs_reserve_stride(stf_springs *s, int n, int stride);

#endif
