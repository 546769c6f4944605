/* pressure.c - Clavet's double density relaxation (Alg. 2), Jacobi form, with solid walls.
 *
 * Densities are kernel sums rho_i = sum (1-r/h)^2 and rho_near_i = sum (1-r/h)^3 over the
 * neighbours; P = k (rho - rho0), P_near = k_near rho_near. Clavet moves i and j apart by
 * D/2 each while visiting i; visiting j later adds j's own D. Gathering both halves at once,
 * particle i moves by -dt^2/2 ((P_i+P_j)(1-q) + (Pn_i+Pn_j)(1-q)^2) along r_ij/r: the
 * gradient of one energy, E = sum_i h [k (rho_i - rho0)^2 / 4 + k_near rho_near,i^2 / 6],
 * times -dt^2/2.
 *
 * Walls: a particle near a solid misses the neighbours the solid takes the place of, so its
 * density is too low, and it is pulled towards the wall by negative pressure; a floating
 * body then displaces more fluid than its volume and Archimedes fails. Each collider
 * therefore counts as a half-space filled with lattice sites, whose sums depend only on the
 * distance d to the surface and are tabulated once; the push they give is an impulse the
 * collider receives back. Two sets of sites (stf.h, enum stf_relax_wall):
 *  - mirror: sites fixed at d + s/2, d + 3s/2, ... (normal to the wall) carrying the
 *    particle's own pressure plus the hydrostatic difference. Their push is twice what the
 *    particle's own density term gives, so it is not the gradient of E: a closed box under
 *    pressure heats up (src/README.md, "The relaxation's walls").
 *  - ghost: the sites are the mirror image of the particle's own lattice, at 2d, 2d + s, ...
 *    (the first one the particle's own image), so they move twice as fast as the particle
 *    towards the wall. The wall term of rho_i then has twice the slope, and the push
 *    dt^2 (P_i F1 + Pn_i F2), the same form as the mirror's, is exactly -dt^2/2 grad E. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "fluid.h"

enum { W_RHO, W_RHO_NEAR, W_F1, W_F2, W_A, W_B, W_COUNT };

void stf_pressure_wall_table(stf_fluid *f)
{
    double s = f->def.spacing, h = f->h;
    int m = (int)ceil(h / s) + 1, ghost = f->def.relax_wall == STF_RELAX_WALL_GHOST;
    for (int b = 0; b <= WALL_BINS; b++) {
        double d = h * b / WALL_BINS, sum[W_COUNT] = {0, 0, 0, 0, 0, 0};
        /* virtual sites: a lattice filling the solid, first layer s/2 inside it (mirror), or
           the particle's own lattice reflected in the wall (ghost) */
        for (int layer = 0; layer <= m; layer++)
            for (int a = -m; a <= m; a++)
                for (int c = -m; c <= m; c++) {
                    double dz = ghost ? 2 * d + s * layer : d + s * (0.5 + layer);
                    double dx = a * s, dy = c * s, r = sqrt(dx * dx + dy * dy + dz * dz);
                    if (r >= h) continue;
                    /* r = 0: the particle's own image at the wall, the push along n */
                    double w = 1 - r / h, cosn = r > 0 ? dz / r : 1.0;
                    sum[W_RHO] += w * w;
                    sum[W_RHO_NEAR] += w * w * w;
                    sum[W_F1] += w * cosn;
                    sum[W_F2] += w * w * cosn;
                    sum[W_A] += r > 0 ? w * dz * dz / r : 0.0;
                    sum[W_B] += r > 0 ? w * dx * dx / r : 0.0;
                }
        for (int k = 0; k < W_COUNT; k++) f->wall_table[k][b] = sum[k];
    }
    /* The pressure gradient that holds the fluid up against gravity. In the bulk, a linear
       pressure field G gives particle i the displacement -dt^2/2 M G, M = sum (1-q) dz^2/r
       over the lattice neighbours; it cancels gravity's g dt^2 when G = 2 g / M. */
    double M = 0;
    for (int a = -m; a <= m; a++)
        for (int b = -m; b <= m; b++)
            for (int c = -m; c <= m; c++) {
                double r = s * sqrt((double)(a * a + b * b + c * c));
                if (r > 0 && r < h) M += (1 - r / h) * (c * s) * (c * s) / r;
            }
    /* The ghost's sites carry no pressure of their own: nothing to correct */
    int grav = (f->def.effects & STF_EFFECT_GRAVITY) != 0 && !ghost;
    for (int a = 0; a < 3; a++) f->grad_p[a] = grav ? 2.0 * f->def.gravity[a] / M : 0.0;
}

/* Linear interpolation in the wall table at distance d (clamped to [0, h]). */
static void wall_sums(const stf_fluid *f, double d, double out[W_COUNT])
{
    double u = d / f->h * WALL_BINS;
    if (u < 0) u = 0;
    if (u >= WALL_BINS) {
        for (int k = 0; k < W_COUNT; k++) out[k] = 0;
        return;
    }
    int b = (int)u;
    double t = u - b;
    for (int k = 0; k < W_COUNT; k++)
        out[k] = (1 - t) * f->wall_table[k][b] + t * f->wall_table[k][b + 1];
}

/* 1 when x is certainly farther than h from collider c's surface, by a sphere test: the
 * collider's bounding sphere (radius c->bound about c->pos) holds the solid, and for these
 * shapes the distance function is the exact distance outside, so it is at least the
 * distance to that sphere. The margin covers rounding, so the distance skipped would have
 * been >= h anyway (same results). Convex hulls too (the GJK distance outside is exact).
 * Planes and containers (bound < 0) are always asked. */
static int wall_far(const collider *c, const double x[3], double h)
{
    int shape = c->def.shape;
    if (c->bound < 0 || !(shape == STF_SHAPE_SPHERE || shape == STF_SHAPE_BOX ||
                          shape == STF_SHAPE_CAPSULE || shape == STF_SHAPE_CYLINDER ||
                          shape == STF_SHAPE_CONVEX))
        return 0;
    double dx = x[0] - c->pos[0], dy = x[1] - c->pos[1], dz = x[2] - c->pos[2];
    double R = (c->bound + h) * (1.0 + 1e-9);
    return dx * dx + dy * dy + dz * dz > R * R;
}

/* Neighbours are taken in chunks: the arithmetic in a loop the compiler vectorizes (AVX2
 * where the processor has it: the same results), gathering the neighbours' positions and
 * pressures straight from the arrays (staged in arrays first, they cost 4% more: the
 * gathers, not the square roots and divisions, are most of the cost), then summed in list
 * order. */
#define PCHUNK 64

STF_VECTOR_CLONES
static void density_one(stf_fluid *f, int i)
{
    const double *x = f->x;
    double h = f->h, inv_h = 1.0 / h, rho = 0, rho_near = 0;
    grid_prefetch(&f->grid, i + 2, f->n);
    const int32_t *nb = grid_row(&f->grid, i);
    double xi = x[3 * i], yi = x[3 * i + 1], zi = x[3 * i + 2];
    double w2[PCHUNK], w3[PCHUNK];
    for (int k0 = 0; k0 < f->grid.count[i]; k0 += PCHUNK) {
        int m = f->grid.count[i] - k0 < PCHUNK ? f->grid.count[i] - k0 : PCHUNK;
        const int32_t *js = nb + k0;
        for (int e = 0; e < m; e++) {
            int j = js[e];
            double rx = x[3 * j] - xi, ry = x[3 * j + 1] - yi, rz = x[3 * j + 2] - zi;
            double r2 = rx * rx + ry * ry + rz * rz;
            double a = 1.0 - sqrt(r2) * inv_h;
            int in = r2 < h * h; /* out: adds +0, which leaves the sums' bits as they are */
            w2[e] = in ? a * a : 0.0;
            w3[e] = in ? a * a * a : 0.0;
        }
        for (int e = 0; e < m; e++) {
            rho += w2[e];
            rho_near += w3[e];
        }
    }
    for (int c = 0; c < f->ncolliders; c++) {
        double nrm[3], w[W_COUNT];
        if (wall_far(&f->colliders[c], x + 3 * i, h)) continue;
        double d = stf_collider_sdf(&f->colliders[c], x + 3 * i, nrm);
        if (d >= h) continue;
        wall_sums(f, d, w);
        rho += w[W_RHO];
        rho_near += w[W_RHO_NEAR];
    }
    /* Store pressures, not densities: both halves of a pair need them. */
    double P = f->def.k * (rho - f->rest_density);
    double Pn = f->def.k_near * (rho_near - f->rest_near);
    if (!f->def.tension) { /* no pull below rest: a free surface is not a stretched skin */
        P = P > 0 ? P : 0;
        Pn = Pn > 0 ? Pn : 0;
    }
    f->rho[i] = P;
    f->rho_near[i] = Pn;
}

/* A unit vector for the coincident pair (i, j), from their persistent ids: the same line
 * for both, pointing from i to j, so the pair's two halves stay exact negatives. Without it
 * particles that start (or land) on the same spot get identical pushes, stay together
 * forever, and their doubled density drives the pressure up without bound. */
static void coincident_direction(int32_t id_i, int32_t id_j, double *ex, double *ey, double *ez)
{
    uint32_t lo = (uint32_t)(id_i < id_j ? id_i : id_j), hi = (uint32_t)(id_i < id_j ? id_j : id_i);
    uint32_t hsh = lo * 2654435761u ^ (hi + 0x9e3779b9u + (lo << 6) + (lo >> 2));
    double v[3];
    for (int a = 0; a < 3; a++) {
        hsh ^= hsh >> 15;
        hsh *= 2246822519u;
        hsh ^= hsh >> 13;
        v[a] = (double)(hsh & 0xffff) / 32768.0 - 1.0;
    }
    double len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(len > 1e-3)) v[0] = 1, v[1] = v[2] = 0, len = 1;
    double sign = id_i < id_j ? 1.0 : -1.0;
    *ex = sign * v[0] / len;
    *ey = sign * v[1] / len;
    *ez = sign * v[2] / len;
}

STF_VECTOR_CLONES
static void relax_one(stf_fluid *f, int i, double dt)
{
    const double *x = f->x, *P = f->rho, *Pn = f->rho_near;
    double h = f->h, inv_h = 1.0 / h, dx = 0, dy = 0, dz = 0, tiny = 1e-12 * h;
    double half_dt2 = 0.5 * dt * dt;
    grid_prefetch(&f->grid, i + 2, f->n);
    const int32_t *nb = grid_row(&f->grid, i);
    double xi = x[3 * i], yi = x[3 * i + 1], zi = x[3 * i + 2], Pi = P[i], Pni = Pn[i];
    double tx[PCHUNK], ty[PCHUNK], tz[PCHUNK];
    int same[PCHUNK];
    for (int k0 = 0; k0 < f->grid.count[i]; k0 += PCHUNK) {
        int m = f->grid.count[i] - k0 < PCHUNK ? f->grid.count[i] - k0 : PCHUNK;
        const int32_t *js = nb + k0;
        int any_same = 0;
        for (int e = 0; e < m; e++) {
            int j = js[e];
            double rx = x[3 * j] - xi, ry = x[3 * j + 1] - yi, rz = x[3 * j + 2] - zi;
            double r = sqrt(rx * rx + ry * ry + rz * rz);
            double a = 1.0 - r * inv_h, len = r > tiny ? r : 1.0;
            double D = half_dt2 * ((Pi + P[j]) * a + (Pni + Pn[j]) * a * a) / len;
            int in = (r < h) & (r > tiny); /* out: adds +-0 (the sums are never -0) */
            same[e] = r <= tiny;
            any_same |= same[e];
            tx[e] = in ? D * rx : 0.0;
            ty[e] = in ? D * ry : 0.0;
            tz[e] = in ? D * rz : 0.0;
        }
        if (any_same) /* coincident: separate along a direction chosen by the ids */
            for (int e = 0; e < m; e++) {
                if (!same[e]) continue;
                int j = js[e];
                double ex, ey, ez;
                coincident_direction(f->id[i], f->id[j], &ex, &ey, &ez);
                double D = half_dt2 * ((Pi + P[j]) + (Pni + Pn[j]));
                tx[e] = D * ex, ty[e] = D * ey, tz[e] = D * ez;
            }
        for (int e = 0; e < m; e++) {
            dx -= tx[e];
            dy -= ty[e];
            dz -= tz[e];
        }
    }
    f->dx[3 * i] = dx;
    f->dx[3 * i + 1] = dy;
    f->dx[3 * i + 2] = dz;
}

/* The mirror particles' push on i from collider c (m), stored in push.
 *
 * A mirror particle j carries i's pressure plus the hydrostatic difference G.r_j (Clavet
 * pairs use (P_i + P_j)/2): with P_i alone, a face looking down (a floating body's bottom)
 * is pushed as if the fluid above it were as deep as the particle, and floats a third of a
 * spacing high; a floor is pushed too little. Tension-free fluid: the push never pulls. */
static int wall_push_one(stf_fluid *f, const collider *c, int i, double dt, double *push)
{
    double nrm[3], w[W_COUNT];
    if (wall_far(c, f->x + 3 * i, f->h)) return 0;
    double d = stf_collider_sdf(c, f->x + 3 * i, nrm);
    if (d >= f->h) return 0;
    wall_sums(f, d, w);
    const double *G = f->grad_p;
    double Gn = G[0] * nrm[0] + G[1] * nrm[1] + G[2] * nrm[2];
    double mag = dt * dt * (f->rho[i] * w[W_F1] + f->rho_near[i] * w[W_F2]);
    /* -dt^2/2 sum (G.r_j)(1-q) r_j/r: along n the moment A, along the wall B */
    double mag_n = mag - 0.5 * dt * dt * Gn * w[W_A];
    if (!f->def.tension && mag_n < 0) mag_n = 0;
    for (int a = 0; a < 3; a++)
        push[3 * i + a] = mag_n * nrm[a] - 0.5 * dt * dt * w[W_B] * (G[a] - Gn * nrm[a]);
    return 1;
}

void stf_pressure_relax(stf_fluid *f, double dt)
{
    int n = f->n;
    /* Dynamic chunks: each particle's result depends on the inputs only, not on the thread
       that computes it, and a thread that was held up (the cores are shared) or got the
       denser half of the fluid does not hold the other one up at the end of the pass. */
#pragma omp parallel for schedule(dynamic, 256)
    for (int i = 0; i < n; i++) density_one(f, i);
#pragma omp parallel for schedule(dynamic, 256)
    for (int i = 0; i < n; i++) relax_one(f, i, dt);
    /* Walls after the pairs, each collider's pushes gathered separately so its reaction is
     * summed in particle order. The pair displacements wait in xprev-free scratch: apply
     * them first, then the wall pushes (all from the same pressures). Each particle's push
     * depends on its own position and pressures only, so the pair displacement, the first
     * collider's push and its application are one pass over the particles. */
    if (f->ncolliders == 0) {
#pragma omp parallel for schedule(static)
        for (int i = 0; i < 3 * n; i++) f->x[i] += f->dx[i];
    }
    for (int c = 0; c < f->ncolliders; c++) {
        collider *col = &f->colliders[c];
        char *hit = f->hit;
        double *x = f->x, *push = f->dx, to_impulse = f->mass / dt;
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++) {
            if (c == 0)
                for (int a = 0; a < 3; a++) x[3 * i + a] += push[3 * i + a];
            hit[i] = (char)wall_push_one(f, col, i, dt, push);
            if (hit[i])
                for (int a = 0; a < 3; a++) {
                    x[3 * i + a] += push[3 * i + a];
                    push[3 * i + a] *= to_impulse; /* the impulse the particle got */
                }
        }
        /* at xprev: a displacement turns the particle about its position at the step's
           start (stf_collider_take_reaction) */
        stf_collider_take_reaction(col, f->dx, f->xprev, hit, n, STF_PART_PRESSURE);
    }
}
