/* grid.h - uniform-grid neighbour search (Teschner et al. spatial hashing).
 *
 * Cells of size h + skin are hashed into a power-of-two table; particles are counting-sorted
 * by bucket. Each particle gets a candidate list (r < h + skin), the lists laid end to end in
 * particle order. They are rebuilt only when two particles that may be closer than h now
 * have moved more than the skin relative to each other since the last rebuild (Verlet
 * lists), or when the particles were reordered. Every step the candidates are filtered to
 * the neighbours within h, into rows packed in the candidates' space (grid_row). The
 * rebuilds depend on the positions only and the lists are built in parallel with no shared
 * writes, so the lists (and the order of every sum over them) do not depend on the thread
 * count. */
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
    int32_t *nbr;      /* neighbour indices: particle i's at nbr + noff[i] (grid_row) */
    int32_t *count;    /* n: neighbours of each particle */
    size_t *off;       /* n + 1: where each particle's candidate row starts in cand */
    size_t *noff;      /* n: where its neighbour row starts in nbr */
    uint8_t *gained;   /* n: 1 when the last filter found a neighbour the one before had not
                          (always after a rebuild, and on periodic grids) */
    uint64_t *inb;     /* one bit per candidate: a neighbour at the last filter */
    size_t *woff;      /* n + 1: where each particle's bits start in inb, words */
    size_t inb_cap;    /* words inb holds */
    int inb_fresh;     /* 1 after a rebuild: the next filter marks every row gained */
    size_t nbr_cap;    /* entries nbr holds */
    int stride;        /* periodic grids: row capacity (off[i] = i stride); grows */
    int n_alloc;       /* particles the arrays hold */
    uint32_t nbuckets_alloc;
    /* Verlet candidates */
    int32_t *cand;     /* candidate indices (r < h + skin at the rebuild), row i at off[i] */
    int32_t *ccount;   /* n: candidates of each particle (the length of its rows) */
    size_t cand_cap;   /* entries cand holds */
    int32_t **buf;     /* nbuf: each thread's candidate lists during a rebuild */
    size_t *buf_cap;   /* nbuf: entries each holds */
    int nbuf;
    double *box;       /* nbox * 6: displacement bounds per bucket (stf_grid_due) */
    size_t nbox;
    double *xref;      /* 3n: positions at the last rebuild */
    int nref;          /* particle count at the last rebuild */
    double href;       /* h at the last rebuild, m */
    int valid;         /* 0: rebuild the candidates at the next stf_grid_build (set on reorder) */
    long rebuilds, builds; /* statistics */
    double skin;       /* Verlet skin, fraction of h, set by the owner (0: the default 0.25);
                          a flow that moves more than skin/2 every step rebuilds every step,
                          and then a thin skin costs less */
    double skin_used;  /* the skin of the current candidate lists */
    int plain;         /* 1: the plain C candidate search even where AVX2 is there (tests) */
    /* Periodic axes (set by the owner before building; zero: not periodic): along axis a
       with period[a] > 0 (>= 3 cells) cells wrap with that period from origin[a], and
       neighbours are found by the nearest image. */
    double period[3];  /* m */
    double origin[3];  /* m */
    int ncell[3];      /* cells along a periodic axis */
} stf_grid;

/* Rebuilds buckets and neighbour lists for n particles at x (3n) with radius h.
 * Returns 0, or -1 when out of memory. */
int stf_grid_build(stf_grid *g, const double *x, int n, double h);
/* stf_grid_build for a caller that has just asked stf_grid_due about these same positions (count, h):
 * rebuilds the candidates only if they are invalid, without checking the moves again. */
int stf_grid_build_checked(stf_grid *g, const double *x, int n, double h);
/* 1 when the next stf_grid_build will rebuild the candidates (two particles that may be closer
 * than h moved more than the skin relative to each other, the count or h changed, or they
 * were invalidated). */
int stf_grid_due(stf_grid *g, const double *x, int n, double h);
/* The particles' order along a Morton curve of the candidate cells (into order): for re-sorting
 * the particles. Invalidates. 0 / -1. */
int stf_grid_sort(stf_grid *g, const double *x, int n, double h);
void stf_grid_free(stf_grid *g);
/* The particles were renumbered: the next stf_grid_build rebuilds its candidates. */
static inline void grid_invalidate(stf_grid *g) { g->valid = 0; }
size_t stf_grid_bytes(const stf_grid *g);
/* Checkpoints: rebuilds the candidate lists from the positions xref (3n) of their last
 * rebuild, with radius h and the skin (fraction of h) they had: the same lists in the same
 * order as then. 0 / -1 (out of memory). */
int stf_grid_restore(stf_grid *g, const double *xref, int n, double h, double skin_used);

/* Particle i's neighbours within h (count[i] of them), after stf_grid_build. */
static inline const int32_t *grid_row(const stf_grid *g, int i) { return g->nbr + g->noff[i]; }

/* Asks for particle i's neighbour row ahead of a pass that visits the particles in order. */
static inline void grid_prefetch(const stf_grid *g, int i, int n)
{
    if (i >= n) return;
    const char *p = (const char *)grid_row(g, i);
    for (int b = 0; b < g->count[i] * 4; b += 64) __builtin_prefetch(p + b);
}

#endif
