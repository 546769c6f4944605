/* cy_internal.h - internal to the Carreau-Yasuda solver (cy*.c): the solver's state and
 * what its files share. The files, each named after the part of the second paper it does
 * (Zhang, Ban, Wang, Liu, Symmetry 2017; the citation is at the top of cy.c):
 *   cy.c            set-up, the step (Algorithm 2) and its CFL substeps, statistics,
 *                   checkpoints;
 *   stf_cy_neighbours.c the neighbour search of a non-periodic fluid and the compact pair lists;
 *   cy_density.c    the density (Eq. 6), S_i (Eq. 20-21), the pairs' gradients and weights;
 *   cy_pressure.c   the pressure projection (Algorithm 1, Eq. 19-21);
 *   cy_viscosity.c  the strain rate and the viscosity (Eq. 3, 9, 22), the viscous step,
 *                   explicit or implicit by conjugate gradients (Eq. 23-26);
 *   cy_walls.c      solid walls as lattice half-spaces (tables by distance), their impulses. */
#ifndef STF_CY_INTERNAL_H
#define STF_CY_INTERNAL_H

#include "cy.h"

#include <stdint.h>
#include <stdlib.h>

#define PI 3.14159265358979323846
/* lattice layers of a wall within the support h <= 5 s: ceil(h / s) + 2 */
#define WALL_LAYERS 7
#define SPHERE_TABS 8
#define SPHERE_BINS 256

/* A neighbour pair: j and grad W_ij (1/m^4, float: the pair arrays are streamed on every
 * pass, so their size is the cost). */
typedef struct cy_pair {
    int32_t j;
    float g[3];
} cy_pair;

typedef struct cy_state {
    int cap;             /* particles the arrays hold */
    double rho0;         /* rest density, kg/m^3 */
    double mirror;       /* the walls' weight in the projection: 1 (wall_pressure own), 2
                            (mirror: the wall's lattice carries the particle's pressure, and
                            sees its approach as a mirror does; cy_walls.c) */
    double wall_div;     /* the walls' weight in the predicted density (Eq. 19): mirror's,
                            but 2 with pressure_gradient offset and the own wall (ours: the
                            approach to a wall counts as a mirror's; cy_pressure.c) */
    double wall_rho[WALL_BINS + 1];  /* wall density by distance, kg/m^3 */
    double wall_grad[WALL_BINS + 1]; /* |sum_b m grad W_ib| by distance, kg/m^4 */
    double *rho, *S, *kappa, *ktot, *rhostar; /* n each */
    double *gw;          /* 3n: sum over walls of m grad W (points into the walls) */
    double *qw;          /* n: sum over walls of v_wall . (m grad W) */
    double *wv;          /* 9n: sum over walls of v_wall (x) m grad W (row-major) */
    double *nu;          /* n: kinematic viscosity of the step, m^2/s */
    double *b, *dv, *r, *p, *Ap; /* 3n each: viscosity solve */
    float *lap;          /* per pair (as pair): m (r.grad W)/(r^2 + 0.01 h^2), kg/m^5; the
                            central form: (d + 2) m / (S (r^2 + 0.01 h^2)), S = (dW/dr) / r,
                            so that it times g g^T (g = grad W = S r) is (d + 2) m S r r^T /
                            (r^2 + 0.01 h^2) (0 where S = 0) */
    double wall_lap[WALL_BINS + 1]; /* the same summed over a wall's lattice, with Morris'
                                       mirror velocity (see tables), by distance */
    /* The quarter-space behind two perpendicular faces of a container, by the distances to
       the two faces (d1, d2): counted by both faces' half-spaces, so subtracted once */
    double quad_rho[WALL_BINS + 1][WALL_BINS + 1];
    double quad_g1[WALL_BINS + 1][WALL_BINS + 1]; /* gradient sum along face 1's normal */
    double quad_g2[WALL_BINS + 1][WALL_BINS + 1];
    double quad_lap[WALL_BINS + 1][WALL_BINS + 1];
    double *lw;          /* n: sum over walls of wall_lap */
    double *lwv;         /* 3n: sum over walls of wall_lap * v_wall (central: of M_w v_wall) */
    /* The central form (viscosity_form central): a wall's lattice gives the 3 x 3 block
       M_w = sum_b (d + 2) m F_ib (1 + mirror ratio) x_ib x_ib^T / |x_ib|^2, F = (r.grad W)/
       (r^2 + 0.01 h^2): for a half-space, wall_cn n n^T + wall_ct (I - n n^T) by distance;
       for a container's quarter-space, in the frame of the two normals and the edge */
    double wall_cn[WALL_BINS + 1], wall_ct[WALL_BINS + 1];
    /* The half-space's sums layer by layer (layer l: the lattice plane s (l + 1/2) inside the
       solid), [l][0..4] = rho, grad, lap, cn, ct by distance: a sphere's wall weighs each
       layer by its shell's curvature (sphere_at in cy_walls.c) */
    double wall_layer[WALL_LAYERS][5][WALL_BINS + 1];
    double quad_c11[WALL_BINS + 1][WALL_BINS + 1], quad_c22[WALL_BINS + 1][WALL_BINS + 1];
    double quad_c12[WALL_BINS + 1][WALL_BINS + 1], quad_cee[WALL_BINS + 1][WALL_BINS + 1];
    double *lwm;         /* 9n (central): sum over walls of M_w, row-major */
    /* The hydrostatic difference the mirror's lattice carries (wall_pressure hydrostatic):
       the moments sum_b m (dW/dr / r) x_ib x_ib^T of a half-space, normal and one tangential
       component by distance, and of a container's quarter-space */
    double wall_hn[WALL_BINS + 1], wall_ht[WALL_BINS + 1];
    double quad_h11[WALL_BINS + 1][WALL_BINS + 1], quad_h22[WALL_BINS + 1][WALL_BINS + 1];
    double quad_h12[WALL_BINS + 1][WALL_BINS + 1], quad_hee[WALL_BINS + 1][WALL_BINS + 1];
    double *hw;          /* 3n: the walls' hydrostatic push on particle i, m/s^2 (or 0) */
    int hydro;           /* 1: the walls' lattice carries the hydrostatic difference */
    cy_pair *pair;       /* off[n]: each particle's neighbours within h, compact (CSR) */
    int32_t *off;        /* n + 1: particle i's pairs are pair[off[i] .. off[i + 1]) */
    size_t pair_cap;
    double *kr;          /* n: kappa_i / rho_i of the current iteration, m^5/(kg s^2) */
    double *irho;        /* n: 1 / rho_i */
    double *mu;          /* n: rho_i nu_i, dynamic viscosity, Pa s */
    /* The neighbour search of a non-periodic fluid (stf_cy_neighbours): a dense grid of cells
       (h across, h / XCELLS along x) over the particles' bounding box, the particles
       counting-sorted into it */
    int32_t *cstart;     /* ncell + 1: first sorted entry of each cell */
    size_t cell_cap;
    int32_t *cellof;     /* n: cell of each particle */
    int32_t *sid;        /* n: particle of each sorted entry */
    double *sx;          /* 3n: the sorted entries' positions, x then y then z (3 arrays) */
    int32_t *nbt;        /* n * nbs: neighbours within h, in cell order */
    int32_t *nbc;        /* n: how many */
    int nbs;             /* stride of nbt */
    int dense;           /* 1: this substep's lists are nbt/nbc, 0: the shared grid's */
    char *hit;
    int32_t *wlist;      /* n: the particles within h of one collider (surface_pressure) */
    /* A sphere's wall terms of wall_pressure hydrostatic by distance d in [0, h], for up to
       SPHERE_TABS radii (stf_cy_sphere_tables): [0], [1] the ball over the half-space of
       solid_sums (density, normal gradient), [2], [3] the hydrostatic moments
       (sphere_moments, normal and tangential); other radii and d < 0 are computed */
    struct { double R; double q[4][SPHERE_BINS + 1]; } sphere_tab[SPHERE_TABS];
    int nsphere_tab;
    int warm_n;          /* particles ktot holds the last step's totals of (0: none) */
    stf_solver_stats stats;
} cy_state;

/* ------------------------------------------------------------------ kernel (cubic spline) */

/* Cubic spline of support h (Monaghan's M4 written with q = r/h in [0,1]). */
static inline double kernel_w(double r, double h)
{
    double q = r / h, k = 8.0 / (PI * h * h * h);
    if (q >= 1) return 0;
    if (q <= 0.5) return k * (6 * q * q * q - 6 * q * q + 1);
    double a = 1 - q;
    return k * 2 * a * a * a;
}

/* dW/dr (<= 0). */
static inline double kernel_dw(double r, double h)
{
    double q = r / h, l = 48.0 / (PI * h * h * h * h);
    if (q >= 1) return 0;
    if (q <= 0.5) return l * q * (3 * q - 2);
    double a = 1 - q;
    return -l * a * a;
}

static inline int is_periodic(const stf_fluid *f)
{
    return f->def.periodic[0] > 0 || f->def.periodic[1] > 0 || f->def.periodic[2] > 0;
}

/* Morris' pair factor (mu_i + mu_b) / (rho_i rho_b) with a wall's lattice particles b (at
 * rho0, with the particle's own nu_i): the viscous force and its reaction on the collider. */
static inline double wall_visc(const cy_state *c, int i)
{
    return c->nu[i] * (c->rho[i] + c->rho0) / (c->rho[i] * c->rho0);
}

static inline int grow(double **p, size_t count)
{
    double *q = realloc(*p, (count ? count : 1) * sizeof *q);
    if (!q) return -1;
    *p = q;
    return 0;
}

static inline int grow_i32(int32_t **p, size_t count)
{
    int32_t *q = realloc(*p, (count ? count : 1) * sizeof *q);
    if (!q) return -1;
    *p = q;
    return 0;
}

/* stf_cy_neighbours.c: this substep's neighbour lists of a non-periodic fluid, in c->nbt, c->nbc
 * (returns 1; 0: the particles are too far-flung, use the shared grid; -1: out of memory);
 * then the compact pair offsets of whichever lists c->dense names, with room for the pairs
 * (0 / -1). */
int stf_cy_neighbours(stf_fluid *f);
int stf_cy_pair_offsets(stf_fluid *f);

/* cy_walls.c: the rest density and the wall tables (at creation); the walls' terms at
 * particle i (into c->gw, qw, wv, lw, lwv, lwm, and rho: the walls' part of the density);
 * the walls' impulses of the substep given back to the colliders. */
void stf_cy_tables(stf_fluid *f, cy_state *c);
void stf_cy_sphere_tables(stf_fluid *f);
void stf_cy_walls_one(stf_fluid *f, int i);
void stf_cy_wall_reactions(stf_fluid *f, double dt, int viscous);

/* cy_density.c: particle i's density (c->rho, added to the walls' part stf_cy_walls_one left
 * there), 1 / rho, S_i, and its pairs' gradients and viscous weights (c->pair, c->lap). */
void stf_cy_density_one(stf_fluid *f, int i);

/* cy_pressure.c: Algorithm 1 on f->v for a substep of dt, w the warm start's weight (0: from
 * zero pressure; c->kappa, kr and ktot as the density pass left them). */
void stf_cy_pressure_project(stf_fluid *f, double dt, double w);
void stf_cy_pressure_project_cg(stf_fluid *f, double dt, double w);

/* cy_viscosity.c: the viscosity step on f->v (v** -> v) for a substep of dt; leaves in c->r
 * the velocity the walls' viscous impulses are taken at (stf_cy_wall_reactions). */
void stf_cy_viscosity_solve(stf_fluid *f, double dt);

#endif
