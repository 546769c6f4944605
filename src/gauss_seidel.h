/* gauss_seidel.h - springs as compliant constraints, Gauss-Seidel over coloured cells
 * (gauss_seidel.c). Allocated only for a fluid with relaxation: gauss_seidel. */
#ifndef STF_GAUSS_SEIDEL_H
#define STF_GAUSS_SEIDEL_H

#include <stddef.h>
#include <stdint.h>

typedef struct stf_fluid stf_fluid;

typedef struct stf_gs {
    int32_t *cell_of;      /* n: each particle's cell */
    int32_t *start;        /* ncells + 1: first member of each cell */
    int32_t *members;      /* n: particles by cell, in index order within a cell */
    int32_t *colour_cells; /* the non-empty cells, colour by colour */
    int32_t colour_start[28];
    long dim[3];           /* cells along each axis */
    double *lambda;        /* per spring slot: the constraint's accumulated multiplier, m */
    size_t cap_n, cap_m, cap_c, cap_cc, cap_lambda;
} stf_gs;

/* Relaxes the springs of f (rows as springs.c left them) for def.iterations sweeps.
 * khist_scale: Eq. 6's factor (0 without history). Returns 0, -1 out of memory. */
int stf_gs_springs(stf_fluid *f, double dt, double khist_scale);
void stf_gs_free(stf_gs *g);

#endif
