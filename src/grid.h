/* grid.h - uniform-grid neighbour search (Teschner et al. spatial hashing).
 *
 * Cells of size h are hashed into a power-of-two table; particles are counting-sorted by
 * bucket. Each particle then gets the list of its neighbours (r < h) in a fixed-stride table,
 * built in parallel with no shared writes, so the lists do not depend on the thread count. */
#ifndef STF_GRID_H
#define STF_GRID_H

#include <stddef.h>
#include <stdint.h>

typedef struct stf_grid {
    double cell;       /* cell size, m */
    uint32_t mask;     /* nbuckets - 1 */
    uint32_t *key;     /* n: bucket of each particle */
    int32_t *order;    /* n: particle indices sorted by bucket (stable) */
    int32_t *start;    /* nbuckets + 1: first entry of each bucket in order */
    int32_t *nbr;      /* n * stride: neighbour indices */
    int32_t *count;    /* n: neighbours of each particle */
    int stride;        /* capacity per particle; grows when a particle has more */
    int n_alloc;       /* particles the arrays hold */
    uint32_t nbuckets_alloc;
    /* Periodic axes (set by the owner before building; zero: not periodic): along axis a
       with period[a] > 0 (>= 3 cells) cells wrap with that period from origin[a], and
       neighbours are found by the nearest image. */
    double period[3];  /* m */
    double origin[3];  /* m */
    int ncell[3];      /* cells along a periodic axis */
} stf_grid;

/* Rebuilds buckets and neighbour lists for n particles at x (3n) with radius h.
 * Returns 0, or -1 when out of memory. */
int grid_build(stf_grid *g, const double *x, int n, double h);
void grid_free(stf_grid *g);
size_t grid_bytes(const stf_grid *g);

#endif
