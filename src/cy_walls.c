/* cy_walls.c - solid walls of the Carreau-Yasuda model. The second paper samples walls with
 * boundary particles; here every collider is a signed distance, and its wall counts as a
 * half-space of lattice particles (our choice, below). This file holds the walls' share of
 * Eq. 6 (density), Eq. 20-21 (the factor S_i), Algorithm 1 (the gradient sum G the pressure
 * pushes along), Eq. 9 and 22 (the strain rate sees the solid's velocity) and the viscous
 * force (Morris' mirror velocity, the central form's block; see cy_viscosity.c): tabulated by
 * distance once (stf_cy_tables, with the rest density rho0 of the lattice the blocks are filled
 * with), summed over the colliders at each particle every substep (stf_cy_walls_one), and the
 * impulses they gave the particles returned to the colliders (stf_cy_wall_reactions).
 *
 * Walls (any collider: container, ODE bodies) are a half-space of lattice particles at
 * rest density that move with the solid (tabulated by distance, as the Clavet model's
 * mirror particles in pressure.c): they add to density and S_i, take part in the
 * projection with the particle's own k_i, in the strain rate with the solid's velocity, and
 * in the viscous force with Morris' mirror velocity (zero relative velocity on the surface:
 * no slip). Every velocity change they cause is an impulse the collider receives back,
 * which is how ODE bodies feel buoyancy and drag. With wall_pressure mirror (ours) the wall's
 * lattice carries the particle's own pressure, as the Clavet model's mirror does, and its part
 * in the projection counts twice (cy_state.mirror: the push, the density change, S_i and the
 * reactions below); with wall_pressure hydrostatic the lattice carries that pressure plus the
 * hydrostatic difference, a fixed push (hydro_push), and a sphere's curvature comes from the
 * continuum (solid_sums, sphere_moments). Where two colliders meet, both count
 * (the corner's lattice twice); a container's own faces count one by one, with the
 * quarter-space behind each edge subtracted once (the triple corner's octant is then
 * missing once: at least 0.87 h from a particle, a small term). */
#include "cy_internal.h"

#include <math.h>
#include <omp.h>
#include <string.h>

/* Rest density: the kernel sum of the cubic lattice the blocks are filled with, so a block
 * starts at rho0; and the wall tables (a half-space of that lattice, first layer half a
 * spacing inside the solid, so a particle half a spacing from a wall sees the lattice). */
void stf_cy_tables(stf_fluid *f, cy_state *c)
{
    double s = f->def.spacing, h = f->h, m = f->mass;
    int k = (int)ceil(h / s) + 1;
    double sum = 0;
    for (int a = -k; a <= k; a++)
        for (int b = -k; b <= k; b++)
            for (int e = -k; e <= k; e++)
                sum += kernel_w(s * sqrt((double)(a * a + b * b + e * e)), h);
    c->rho0 = m * sum;
    memset(c->wall_layer, 0, sizeof c->wall_layer); /* k + 1 <= WALL_LAYERS: h <= 5 s */
    for (int bin = 0; bin <= WALL_BINS; bin++) {
        double d = h * bin / WALL_BINS, rho = 0, grad = 0, lap = 0, cn = 0, ct = 0, hn = 0, ht = 0;
        double dd = d > 0.05 * s ? d : 0.05 * s;
        for (int layer = 0; layer <= k; layer++) {
            double lrho = rho, lgrad = grad, llap = lap, lcn = cn, lct = ct;
            for (int a = -k; a <= k; a++)
                for (int e = -k; e <= k; e++) {
                    double dz = d + s * (0.5 + layer), dx = a * s, dy = e * s;
                    double r = sqrt(dx * dx + dy * dy + dz * dz);
                    if (r >= h) continue;
                    rho += m * kernel_w(r, h);
                    grad += -m * kernel_dw(r, h) * dz / r;
                    /* Morris et al. (1997): the wall particle b moves with v_w - (d_b/d)
                       (v_i - v_w), d_b its depth in the solid, so the velocity is zero on the
                       surface itself; d_b/d capped at 1.5 */
                    double depth = s * (0.5 + layer), ratio = depth / dd;
                    double l = m * kernel_dw(r, h) * r / (r * r + 0.01 * h * h) *
                               (1 + (ratio < 1.5 ? ratio : 1.5));
                    lap += l;
                    /* the central form's block: (d + 2) l x x^T / r^2, normal and one
                       tangential component (the two tangential ones are equal) */
                    cn += 5 * l * dz * dz / (r * r);
                    ct += 5 * l * 0.5 * (dx * dx + dy * dy) / (r * r);
                    /* the hydrostatic moments: sum m (dW/dr / r) x x^T */
                    hn += m * kernel_dw(r, h) / r * dz * dz;
                    ht += m * kernel_dw(r, h) / r * 0.5 * (dx * dx + dy * dy);
                }
            double(*L)[WALL_BINS + 1] = c->wall_layer[layer];
            L[0][bin] = rho - lrho, L[1][bin] = grad - lgrad, L[2][bin] = lap - llap;
            L[3][bin] = cn - lcn, L[4][bin] = ct - lct;
        }
        c->wall_hn[bin] = hn;
        c->wall_ht[bin] = ht;
        c->wall_lap[bin] = lap;
        c->wall_cn[bin] = cn;
        c->wall_ct[bin] = ct;
        c->wall_rho[bin] = rho;
        c->wall_grad[bin] = grad;
    }
    for (int b1 = 0; b1 <= WALL_BINS; b1++)
        for (int b2 = 0; b2 <= WALL_BINS; b2++) {
            double d1 = h * b1 / WALL_BINS, d2 = h * b2 / WALL_BINS;
            double rho = 0, g1 = 0, g2 = 0, lap = 0, c11 = 0, c22 = 0, c12 = 0, cee = 0;
            double h11 = 0, h22 = 0, h12 = 0, hee = 0;
            for (int l1 = 0; l1 <= k; l1++)
                for (int l2 = 0; l2 <= k; l2++)
                    for (int a = -k; a <= k; a++) {
                        double z1 = d1 + s * (0.5 + l1), z2 = d2 + s * (0.5 + l2), e = a * s;
                        double r = sqrt(z1 * z1 + z2 * z2 + e * e);
                        if (r >= h) continue;
                        rho += m * kernel_w(r, h);
                        g1 += -m * kernel_dw(r, h) * z1 / r;
                        g2 += -m * kernel_dw(r, h) * z2 / r;
                        /* mirror velocity ratio at its cap (the corner is deep in the solid) */
                        double l = m * kernel_dw(r, h) * r / (r * r + 0.01 * h * h) * 2.5;
                        lap += l;
                        c11 += 5 * l * z1 * z1 / (r * r);
                        c22 += 5 * l * z2 * z2 / (r * r);
                        c12 += 5 * l * z1 * z2 / (r * r);
                        cee += 5 * l * e * e / (r * r);
                        double hf = m * kernel_dw(r, h) / r;
                        h11 += hf * z1 * z1, h22 += hf * z2 * z2, h12 += hf * z1 * z2, hee += hf * e * e;
                    }
            c->quad_rho[b1][b2] = rho;
            c->quad_g1[b1][b2] = g1;
            c->quad_g2[b1][b2] = g2;
            c->quad_lap[b1][b2] = lap;
            c->quad_c11[b1][b2] = c11;
            c->quad_c22[b1][b2] = c22;
            c->quad_c12[b1][b2] = c12;
            c->quad_cee[b1][b2] = cee;
            c->quad_h11[b1][b2] = h11, c->quad_h22[b1][b2] = h22;
            c->quad_h12[b1][b2] = h12, c->quad_hee[b1][b2] = hee;
        }
}

/* The quarter-space terms at distances d1, d2 (< h) from two perpendicular faces (bilinear). */
static void quad_at(const cy_state *c, double d1, double d2, double h, double *rho, double *g1,
                    double *g2, double *lap, double qc[4], double hq[4])
{
    double u = d1 / h * WALL_BINS, w = d2 / h * WALL_BINS;
    u = u < 0 ? 0 : u > WALL_BINS - 1e-9 ? WALL_BINS - 1e-9 : u;
    w = w < 0 ? 0 : w > WALL_BINS - 1e-9 ? WALL_BINS - 1e-9 : w;
    int i = (int)u, j = (int)w;
    double t = u - i, q = w - j;
    double c00 = (1 - t) * (1 - q), c10 = t * (1 - q), c01 = (1 - t) * q, c11 = t * q;
#define BILIN(T) (c00 * c->T[i][j] + c10 * c->T[i + 1][j] + c01 * c->T[i][j + 1] + c11 * c->T[i + 1][j + 1])
    *rho = BILIN(quad_rho);
    *g1 = BILIN(quad_g1);
    *g2 = BILIN(quad_g2);
    *lap = BILIN(quad_lap);
    qc[0] = BILIN(quad_c11);
    qc[1] = BILIN(quad_c22);
    qc[2] = BILIN(quad_c12);
    qc[3] = BILIN(quad_cee);
    hq[0] = BILIN(quad_h11);
    hq[1] = BILIN(quad_h22);
    hq[2] = BILIN(quad_h12);
    hq[3] = BILIN(quad_hee);
#undef BILIN
}

/* A wall's sums at particle i, in the order of the face terms: density, the normal gradient
 * magnitude, Morris' lap, the central form's normal and tangential blocks, the hydrostatic
 * normal and tangential moments. */
enum { F_RHO, F_GRAD, F_LAP, F_CN, F_CT, F_HN, F_HT, F_COUNT };

/* The sums of a flat wall at distance d. */
static void wall_at(const cy_state *c, double d, double h, double v[F_COUNT])
{
    double u = d / h * WALL_BINS;
    if (u < 0) u = 0;
    if (u >= WALL_BINS) {
        for (int q = 0; q < F_COUNT; q++) v[q] = 0;
        return;
    }
    int b = (int)u;
    double t = u - b;
    v[F_RHO] = (1 - t) * c->wall_rho[b] + t * c->wall_rho[b + 1];
    v[F_GRAD] = (1 - t) * c->wall_grad[b] + t * c->wall_grad[b + 1];
    v[F_LAP] = (1 - t) * c->wall_lap[b] + t * c->wall_lap[b + 1];
    v[F_CN] = (1 - t) * c->wall_cn[b] + t * c->wall_cn[b + 1];
    v[F_CT] = (1 - t) * c->wall_ct[b] + t * c->wall_ct[b + 1];
    v[F_HN] = (1 - t) * c->wall_hn[b] + t * c->wall_hn[b + 1];
    v[F_HT] = (1 - t) * c->wall_ht[b] + t * c->wall_ht[b + 1];
}

/* Adds a face's sums v, n its normal out of the solid, to the wall sums of wall_term. */
static void add_face(const double v[F_COUNT], const double n[3], double G[3], double *rho,
                     double *lap, double M[9], double H[9])
{
    *rho += v[F_RHO];
    *lap += v[F_LAP];
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            M[3 * a + b] += (v[F_CN] - v[F_CT]) * n[a] * n[b] + (a == b ? v[F_CT] : 0);
            H[3 * a + b] += (v[F_HN] - v[F_HT]) * n[a] * n[b] + (a == b ? v[F_HT] : 0);
        }
    for (int a = 0; a < 3; a++) G[a] -= v[F_GRAD] * n[a];
}

/* A sphere's wall at distance d from its surface (radius R): the half-space's layers, each
 * weighed by its shell's curvature. The lattice plane s (l + 1/2) inside a flat wall becomes
 * the shell of radius R_l = R - s (l + 1/2) at the same areal density, and for any function of
 * distance the integral over a shell seen from the distance c = R + d of the centre is R_l / c
 * times the integral over a plane at the same nearest distance c - R_l (the sphere's
 * area element 2 pi R_l^2 sin(t) dt, with r dr = R_l c sin(t) dt). So the density and
 * Morris' viscous sum of layer l are R_l / c times the plane's, and the gradient sum (the
 * derivative of that product in c) is R_l / c (grad_l + rho_l / c). A flat table counts too much
 * solid beside a sphere: at half a spacing from it, 1.67 times the first shell's density for
 * R = 2 s, 1.4 times for 3 s, 1.1 times even for 10 s; the drag of a settling sphere was 20%
 * high with it, at every resolution tried (tests/README.md). The central form's tangential and
 * normal blocks take the same R_l / c (not exact: their weights are not functions of distance
 * alone). Layers whose shell would have no radius are left out. */
static void sphere_at(const cy_state *c, double d, double R, double s, double h, double out[5])
{
    double u = d / h * WALL_BINS;
    for (int q = 0; q < 5; q++) out[q] = 0;
    if (u >= WALL_BINS) return;
    if (u < 0) u = 0;
    int b = (int)u;
    double t = u - b, cen = R + d > 0.05 * s ? R + d : 0.05 * s;
    for (int l = 0; l < WALL_LAYERS; l++) {
        double Rl = R - s * (0.5 + l);
        if (Rl <= 0) break;
        double L[5];
        for (int q = 0; q < 5; q++)
            L[q] = (1 - t) * c->wall_layer[l][q][b] + t * c->wall_layer[l][q][b + 1];
        double w = Rl / cen;
        out[0] += w * L[0];
        out[1] += w * (L[1] + L[0] / cen);
        out[2] += w * L[2], out[3] += w * L[3], out[4] += w * L[4];
    }
}

/* Gauss-Legendre, 4 points on [-1, 1]: the sphere's integrals below */
static const double glx[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                             0.8611363115940526};
static const double glw[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                             0.3478548451374538};

/* The hydrostatic moments (normal, one tangential) of a sphere's lattice at distance d from
 * its surface, exactly for shells: layer l is the shell of radius R_l = R - s (l + 1/2) at
 * areal density 1 / s^2, and sum m (dW/dr / r) x x^T over it is, with r^2 = R_l^2 + c^2 -
 * 2 R_l c cos(t) (c = R + d, r dr = R_l c sin(t) dt), 2 pi m R_l / (s^2 c) times the integral
 * over r of dW/dr times the component: (R_l cos(t) - c)^2 normal, (R_l^2 - (R_l cos(t))^2) / 2
 * tangential. Gauss-Legendre, 4 points on each side of h / 2 (the kernel's kink). */
static void sphere_moments(double d, double R, double s, double h, double m, double *hn, double *ht)
{
    double c = R + d;
    *hn = *ht = 0;
    for (int l = 0; l < WALL_LAYERS; l++) {
        double Rl = R - s * (0.5 + l);
        if (Rl <= 0) break;
        double r0 = fabs(c - Rl), r1 = c + Rl < h ? c + Rl : h, sn = 0, st = 0;
        if (r0 >= h) continue;
        double cuts[3] = {r0, r0 < 0.5 * h && r1 > 0.5 * h ? 0.5 * h : r0, r1};
        for (int seg = 0; seg < 2; seg++) {
            double a = cuts[seg], b = cuts[seg + 1];
            if (b <= a) continue;
            for (int q = 0; q < 4; q++) {
                double r = 0.5 * (a + b) + 0.5 * (b - a) * glx[q], wq = 0.5 * (b - a) * glw[q];
                double zc = (Rl * Rl + c * c - r * r) / (2 * c), dw = kernel_dw(r, h);
                sn += wq * dw * (zc - c) * (zc - c);
                st += wq * dw * 0.5 * (Rl * Rl - zc * zc);
            }
        }
        double k = 2 * PI * m * Rl / (s * s * c);
        *hn += k * sn;
        *ht += k * st;
    }
}

/* The continuum's density and normal gradient of a solid (of density 1) at distance d from
 * its surface: q[0] = int W dV, q[1] = -d/dd of it, for a ball of radius R > 0 (by its shells
 * of radius u, seen at c = R + d over the area element 2 pi u r dr / c, r dr = u c sin(t) dt,
 * dr/dc = (c - u cos t) / r) or a half-space (R = 0: its planes at depth u, 2 pi r dr, dr/dd =
 * (d + u) / r). Gauss-Legendre, 4 x 4 points over the solid's depth and 4 x 4 over r. The
 * sphere's wall term of wall_pressure hydrostatic is the flat table times the ratio of the two
 * (sphere_at's shells were 11% short of the ball's volume at 1.5 spacings: the held sphere felt
 * 0.77 rho V g, 0.93 with the ratio; tests/README.md). */
static void solid_sums(double d, double R, double h, double q[2])
{
    q[0] = q[1] = 0;
    double c = R + d, top = R > 0 ? R : h - d; /* the solid's depth within h */
    double lo = R > 0 && R > h - d ? R - (h - d) : 0;
    if (top <= lo) return;
    for (int sa = 0; sa < 4; sa++) {
        double a0 = lo + (top - lo) * sa / 4, a1 = lo + (top - lo) * (sa + 1) / 4;
        for (int qa = 0; qa < 4; qa++) {
            double u = 0.5 * (a0 + a1) + 0.5 * (a1 - a0) * glx[qa], wu = 0.5 * (a1 - a0) * glw[qa];
            double r0 = R > 0 ? fabs(c - u) : d + u, r1 = R > 0 && c + u < h ? c + u : h;
            if (r0 >= h) continue;
            for (int sb = 0; sb < 4; sb++) {
                double b0 = r0 + (r1 - r0) * sb / 4, b1 = r0 + (r1 - r0) * (sb + 1) / 4;
                for (int qb = 0; qb < 4; qb++) {
                    double r = 0.5 * (b0 + b1) + 0.5 * (b1 - b0) * glx[qb];
                    double wr = 0.5 * (b1 - b0) * glw[qb], jac, dn;
                    if (R > 0) {
                        double zc = (u * u + c * c - r * r) / (2 * c);
                        jac = 2 * PI * u * r / c, dn = (c - zc) / r;
                    } else {
                        jac = 2 * PI * r, dn = (d + u) / r;
                    }
                    q[0] += wu * wr * jac * kernel_w(r, h);
                    q[1] -= wu * wr * jac * kernel_dw(r, h) * dn;
                }
            }
        }
    }
}

/* A sphere's terms at distance d (q[0], q[1]: the ball over the half-space of solid_sums,
 * density and normal gradient; q[2], q[3]: sphere_moments), computed. */
static void sphere_terms_at(const stf_fluid *f, double R, double d, double q[4])
{
    double qs[2], qf[2], h = f->h;
    solid_sums(d, R, h, qs), solid_sums(d, 0, h, qf);
    q[0] = qf[0] > 0 ? qs[0] / qf[0] : 0;
    q[1] = qf[1] > 0 ? qs[1] / qf[1] : 0;
    sphere_moments(d, R, f->def.spacing, h, f->mass, &q[2], &q[3]);
}

/* Tabulates sphere_terms_at by distance for every sphere collider's radius not yet in
 * cy_state's tables (serial, before the parallel wall pass: the quadratures took a tenth of a
 * Carreau-Yasuda step beside a sphere). */
void stf_cy_sphere_tables(stf_fluid *f)
{
    cy_state *c = f->cy;
    if (!c->hydro) return;
    for (int k = 0; k < f->ncolliders; k++) {
        const collider *col = &f->colliders[k];
        if (col->def.shape != STF_SHAPE_SPHERE || c->nsphere_tab == SPHERE_TABS) continue;
        int t = 0;
        while (t < c->nsphere_tab && c->sphere_tab[t].R != col->def.radius) t++;
        if (t < c->nsphere_tab) continue;
        c->sphere_tab[t].R = col->def.radius;
        for (int b = 0; b <= SPHERE_BINS; b++) {
            double q[4];
            sphere_terms_at(f, col->def.radius, f->h * b / SPHERE_BINS, q);
            for (int a = 0; a < 4; a++) c->sphere_tab[t].q[a][b] = q[a];
        }
        c->nsphere_tab++;
    }
}

/* sphere_terms_at from the tables (linear in d, 256 bins over h: a held sphere of 1.5
 * spacings felt the same force within 5.3e-5 of it), or computed for a radius not in them and
 * inside the sphere (d < 0). The last bin runs to the ratio's 0 at d = h, where the flat
 * table it multiplies is 0 too. */
static void sphere_terms(const stf_fluid *f, double R, double d, double q[4])
{
    const cy_state *c = f->cy;
    int t = 0;
    while (t < c->nsphere_tab && c->sphere_tab[t].R != R) t++;
    double u = d / f->h * SPHERE_BINS;
    if (t == c->nsphere_tab || !(u >= 0)) {
        sphere_terms_at(f, R, d, q);
        return;
    }
    if (u >= SPHERE_BINS) u = SPHERE_BINS;
    int b = u < SPHERE_BINS ? (int)u : SPHERE_BINS - 1;
    double w = u - b;
    for (int a = 0; a < 4; a++) q[a] = (1 - w) * c->sphere_tab[t].q[a][b] + w * c->sphere_tab[t].q[a][b + 1];
}

/* Adds sign times the quarter-space behind two perpendicular planes at distances d1, d2 (< h),
 * n1 and n2 pointing from it to the particle, to the wall sums of wall_term. */
static void add_quarter(const cy_state *c, double sign, double d1, double d2, const double n1[3],
                        const double n2[3], double h, double G[3], double *rho, double *lap,
                        double M[9], double H[9])
{
    double r, g1, g2, l, qc[4], hq[4];
    quad_at(c, d1, d2, h, &r, &g1, &g2, &l, qc, hq);
    *rho += sign * r;
    *lap += sign * l;
    /* c11 n1 n1^T + c22 n2 n2^T + c12 (n1 n2^T + n2 n1^T) + cee (I - n1 n1^T - n2 n2^T) */
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            M[3 * a + b] += sign * ((qc[0] - qc[3]) * n1[a] * n1[b] + (qc[1] - qc[3]) * n2[a] * n2[b] +
                                    qc[2] * (n1[a] * n2[b] + n2[a] * n1[b]) + (a == b ? qc[3] : 0));
            H[3 * a + b] += sign * ((hq[0] - hq[3]) * n1[a] * n1[b] + (hq[1] - hq[3]) * n2[a] * n2[b] +
                                    hq[2] * (n1[a] * n2[b] + n2[a] * n1[b]) + (a == b ? hq[3] : 0));
        }
    for (int a = 0; a < 3; a++) G[a] -= sign * (g1 * n1[a] + g2 * n2[a]);
}

/* A box body's wall (wall_pressure hydrostatic): the solid is where its six half-spaces meet.
 * Beside one face (outside it alone) the face's half-space less the quarter-spaces beyond each
 * neighbouring face's plane within h (the nearest face's half-space alone counted solid beyond
 * the box's edges: a held cube 3 spacings wide felt 1.12 rho V g); beyond an edge (outside two
 * faces) the quarter-space behind both. Beyond a corner (outside three) the nearest face's
 * half-space, as before. Returns 0 beyond h. */
static int box_term(const stf_fluid *f, const collider *col, const double x[3], double G[3],
                    double *rho, double *lap, double M[9], double H[9])
{
    double d[6], n[6][3], h = f->h;
    stf_collider_box_faces(col, x, d, n);
    int out[3], nout = 0;
    for (int k = 0; k < 6; k++)
        if (d[k] > 0 && nout < 3) out[nout++] = k;
    if (nout == 0 || nout == 3) return -1; /* inside, or beyond a corner: the nearest face */
    if (nout == 2) {
        if (d[out[0]] >= h || d[out[1]] >= h) return 0;
        add_quarter(f->cy, 1, d[out[0]], d[out[1]], n[out[0]], n[out[1]], h, G, rho, lap, M, H);
        return 1;
    }
    int p = out[0];
    if (d[p] >= h) return 0;
    double v[F_COUNT];
    wall_at(f->cy, d[p], h, v);
    add_face(v, n[p], G, rho, lap, M, H);
    for (int q = 0; q < 6; q++) { /* the neighbouring faces: not p, not its opposite */
        if (q / 2 == p / 2 || -d[q] >= h) continue;
        double away[3] = {-n[q][0], -n[q][1], -n[q][2]};
        add_quarter(f->cy, -1, d[p], -d[q], n[p], away, h, G, rho, lap, M, H);
    }
    return 1;
}

/* Collider k's wall term at particle i: returns 1 within h, with G = sum_b m grad W_ib
 * (pointing into the solid), the density it adds, the viscous terms (Morris' lap, the
 * central form's block M, row-major) and the solid's velocity there. A container
 * counts as its five faces, each a half-space of lattice (its signed distance alone would
 * show a particle near an edge only the nearer face: too little density there, and a jump
 * where the nearer face changes). */
static int wall_term(const stf_fluid *f, const collider *col, int i, double G[3], double *rho,
                     double *lap, double M[9], double vb[3], double H[9])
{
    const double *x = f->x + 3 * i;
    double h = f->h;
    if (!stf_collider_near(col, x, h)) return 0;
    *rho = *lap = 0;
    G[0] = G[1] = G[2] = 0;
    memset(M, 0, 9 * sizeof *M);
    memset(H, 0, 9 * sizeof *H);
    if (f->cy->hydro && col->def.shape == STF_SHAPE_BOX) {
        int b = box_term(f, col, x, G, rho, lap, M, H);
        if (b >= 0) {
            if (b) stf_collider_velocity_at(col, x, vb);
            return b;
        }
    }
    double fd[5], fn[5][3];
    int faces = stf_collider_container_faces(col, x, fd, fn), hit = 0;
    if (faces == 0) {
        double d = stf_collider_sdf(col, x, fn[0]);
        if (d >= h) return 0;
        fd[0] = d;
        faces = 1;
    }
    int sphere = col->def.shape == STF_SHAPE_SPHERE;
    for (int k = 0; k < faces; k++) {
        if (fd[k] >= h) continue;
        double v[F_COUNT];
        if (sphere) {
            sphere_at(f->cy, fd[k], col->def.radius, f->def.spacing, h, v);
            v[F_HN] = v[F_HT] = 0;
            if (f->cy->hydro) { /* curvature from the continuum: the flat table times ball / half-space */
                double q[4], flat[F_COUNT];
                sphere_terms(f, col->def.radius, fd[k], q);
                wall_at(f->cy, fd[k], h, flat);
                v[F_RHO] = flat[F_RHO] * q[0];
                v[F_GRAD] = flat[F_GRAD] * q[1];
                v[F_HN] = q[2], v[F_HT] = q[3];
            }
        } else {
            wall_at(f->cy, fd[k], h, v);
        }
        add_face(v, fn[k], G, rho, lap, M, H);
        hit = 1;
    }
    /* container edges: faces 0/1 (x) and 2/3 (y) meet each other and the floor (4) */
    static const int pairs[8][2] = {{0, 2}, {0, 3}, {1, 2}, {1, 3}, {0, 4}, {1, 4}, {2, 4}, {3, 4}};
    for (int e = 0; faces == 5 && e < 8; e++) {
        int p = pairs[e][0], q = pairs[e][1];
        if (fd[p] >= h || fd[q] >= h) continue;
        add_quarter(f->cy, -1, fd[p], fd[q], fn[p], fn[q], h, G, rho, lap, M, H);
    }
    if (hit) stf_collider_velocity_at(col, x, vb);
    return hit;
}

/* The acceleration the hydrostatic difference of a wall's lattice gives a particle
 * (wall_pressure hydrostatic): its sites carry y_i + g.(x_b - x_i) / rho0 (y = p / rho^2), so
 * the pair force -m (y_i + y_b) grad W_ib adds (1 / rho0) sum_b m (dW/dr / r) x_ib x_ib^T g =
 * H g / rho0. Zero without gravity or with the other walls. */
static void hydro_push(const stf_fluid *f, const double H[9], double out[3])
{
    const cy_state *c = f->cy;
    const double *g = f->def.gravity;
    int on = c->hydro && (f->def.effects & STF_EFFECT_GRAVITY);
    for (int a = 0; a < 3; a++)
        out[a] = on ? (H[3 * a] * g[0] + H[3 * a + 1] * g[1] + H[3 * a + 2] * g[2]) / c->rho0 : 0;
}

void stf_cy_walls_one(stf_fluid *f, int i)
{
    cy_state *c = f->cy;
    double *gw = c->gw + 3 * i, *wv = c->wv + 9 * i, *lwv = c->lwv + 3 * i, rho = 0, q = 0, lw = 0;
    double *lwm = c->lwm + 9 * i;
    int central = f->def.cy.viscosity_form == STF_VISCOSITY_CENTRAL;
    memset(gw, 0, 3 * sizeof *gw);
    memset(wv, 0, 9 * sizeof *wv);
    memset(lwv, 0, 3 * sizeof *lwv);
    memset(lwm, 0, 9 * sizeof *lwm);
    double *hw = c->hw + 3 * i;
    hw[0] = hw[1] = hw[2] = 0;
    for (int k = 0; k < f->ncolliders; k++) {
        double G[3] = {0, 0, 0}, r = 0, lap = 0, M[9], vb[3] = {0, 0, 0}, H[9], hp[3];
        if (!wall_term(f, &f->colliders[k], i, G, &r, &lap, M, vb, H)) continue;
        hydro_push(f, H, hp);
        for (int a = 0; a < 3; a++) hw[a] += hp[a];
        rho += r;
        lw += lap;
        if (central)
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++) {
                    lwm[3 * a + b] += M[3 * a + b];
                    lwv[a] += M[3 * a + b] * vb[b];
                }
        else
            for (int a = 0; a < 3; a++) lwv[a] += lap * vb[a];
        for (int a = 0; a < 3; a++) {
            gw[a] += G[a];
            q += vb[a] * G[a];
            for (int b = 0; b < 3; b++) wv[3 * a + b] += vb[a] * G[b];
        }
    }
    c->rho[i] = rho; /* the fluid's part is added in density_one */
    c->qw[i] = q;
    c->lw[i] = lw;
}

/* The pressure's share of what stf_cy_wall_reactions gave collider col as viscous (the
 * reactions dt m (k_i / rho_i) G of the particles the walls reach, in pj), moved to the
 * pressure part: summed in particle order, so it does not depend on threads. */
static void pressure_part(const stf_fluid *f, collider *col, const double *pj)
{
    const cy_state *c = f->cy;
    double J[3] = {0, 0, 0};
    for (int i = 0; i < f->n; i++)
        if (c->hit[i])
            for (int a = 0; a < 3; a++) J[a] += pj[3 * i + a];
    for (int a = 0; a < 3; a++) {
        col->part[STF_PART_PRESSURE][a] += J[a];
        col->part[STF_PART_VISCOSITY][a] -= J[a];
    }
}

/* The fluid's pressure at point q (Pa): the pressures p_j = rho0 sum k_j of the particles in
 * list (m of them) within h of q, each carried to q hydrostatically (+ rho0 g.(q - x_j)), and
 * averaged with the kernel's weights (Shepard's); 0 where no particle is near, and never below
 * zero (the projection holds no tension). */
static double pressure_at(const stf_fluid *f, const int32_t *list, int m, const double q[3],
                          const double g[3])
{
    const cy_state *c = f->cy;
    double h = f->h, sw = 0, sp = 0;
    for (int k = 0; k < m; k++) {
        int j = list[k];
        const double *x = f->x + 3 * j;
        double d[3] = {q[0] - x[0], q[1] - x[1], q[2] - x[2]};
        double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        if (r2 >= h * h) continue;
        double w = kernel_w(sqrt(r2), h);
        sw += w;
        sp += w * c->rho0 * (c->ktot[j] + g[0] * d[0] + g[1] * d[1] + g[2] * d[2]);
    }
    double p = sw > 0 ? sp / sw : 0;
    return p > 0 ? p : 0;
}

/* Whether collider col takes its pressure force from its surface (surface_pressure). */
static int surface_body(const stf_fluid *f, const collider *col)
{
    return f->def.cy.pressure_gradient == STF_PRESSURE_GRADIENT_OFFSET && col->bound >= 0 &&
           (col->def.shape == STF_SHAPE_SPHERE || col->def.shape == STF_SHAPE_BOX);
}

/* A body's pressure force from the fluid's pressure on its surface, -sum p(q) n A over points
 * q about half a spacing apart (pressure_gradient offset, ours): a sphere's on a Fibonacci
 * lattice, a box's on a grid on each face. The particles' wall terms then carry only the
 * pressures offset by their neighbourhood's least (cy_pressure.c, grad_min_at), and that sum
 * no longer holds the absolute pressure; the surface integral does, and it does not depend on
 * how the particles next to the body happen to sit (gaps a few percent narrower in front of
 * a moving sphere than behind it, times the absolute pressure, were a resistance that grew
 * with its depth). Not equal and opposite to what the particles feel: the offset form is not
 * pairwise either. The particles within h of the body are those the reactions marked (c->hit). */
static void surface_pressure(stf_fluid *f, collider *col, double dt)
{
    cy_state *c = f->cy;
    int m = 0;
    for (int i = 0; i < f->n; i++)
        if (c->hit[i]) c->wlist[m++] = i;
    if (m == 0) return;
    static const double zero[3] = {0, 0, 0};
    const double *g = (f->def.effects & STF_EFFECT_GRAVITY) ? f->def.gravity : zero;
    double ds = 0.5 * f->def.spacing, F[3] = {0, 0, 0}, M[3] = {0, 0, 0};
    if (col->def.shape == STF_SHAPE_SPHERE) {
        double R = col->def.radius, area = 4 * PI * R * R;
        int N = (int)ceil(area / (ds * ds));
        N = N < 32 ? 32 : N;
        for (int k = 0; k < N; k++) { /* Fibonacci lattice: equal areas */
            double z = 1 - (2 * k + 1.0) / N, rxy = sqrt(1 - z * z), phi = k * PI * (3 - sqrt(5.0));
            double nrm[3] = {rxy * cos(phi), rxy * sin(phi), z}, q[3];
            for (int a = 0; a < 3; a++) q[a] = col->pos[a] + R * nrm[a];
            double pA = pressure_at(f, c->wlist, m, q, g) * area / N;
            for (int a = 0; a < 3; a++) F[a] -= pA * nrm[a];
        }
    } else {
        const double *hx = col->def.half;
        for (int face = 0; face < 6; face++) {
            int a0 = face / 2, a1 = (a0 + 1) % 3, a2 = (a0 + 2) % 3;
            double sg = face % 2 ? -1 : 1;
            int n1 = (int)ceil(2 * hx[a1] / ds), n2 = (int)ceil(2 * hx[a2] / ds);
            double A = (2 * hx[a1] / n1) * (2 * hx[a2] / n2), nl[3] = {0, 0, 0}, nrm[3];
            nl[a0] = sg;
            stf_collider_world_dir(col, nl, nrm);
            for (int i1 = 0; i1 < n1; i1++)
                for (int i2 = 0; i2 < n2; i2++) {
                    double l[3], r[3], q[3];
                    l[a0] = sg * hx[a0];
                    l[a1] = ((i1 + 0.5) / n1 * 2 - 1) * hx[a1];
                    l[a2] = ((i2 + 0.5) / n2 * 2 - 1) * hx[a2];
                    stf_collider_world_dir(col, l, r);
                    for (int a = 0; a < 3; a++) q[a] = col->pos[a] + r[a];
                    double pA = pressure_at(f, c->wlist, m, q, g) * A, Fq[3];
                    for (int a = 0; a < 3; a++) Fq[a] = -pA * nrm[a], F[a] += Fq[a];
                    M[0] += r[1] * Fq[2] - r[2] * Fq[1];
                    M[1] += r[2] * Fq[0] - r[0] * Fq[2];
                    M[2] += r[0] * Fq[1] - r[1] * Fq[0];
                }
        }
    }
    for (int a = 0; a < 3; a++) {
        col->impulse[a] += dt * F[a];
        col->part[STF_PART_PRESSURE][a] += dt * F[a];
        col->moment[a] += dt * M[a];
    }
}

/* The impulses the walls gave the particles during the step go back to the colliders:
 * pressure -dt (sum k_i / rho_i) G and, with viscous, viscous dt (the wall part of
 * viscous_one), the latter with the velocity u the viscous step evaluated (c->r,
 * viscosity_solve). The Clavet model's projection (stf_cy_pressure_stage) has no viscous
 * part here: its viscosity is Clavet's, between particles. */
void stf_cy_wall_reactions(stf_fluid *f, double dt, int viscous)
{
    cy_state *c = f->cy;
    int n = f->n;
    for (int k = 0; k < f->ncolliders; k++) {
        collider *col = &f->colliders[k];
        int surf = surface_body(f, col); /* its pressure from its surface, not from here */
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++) {
            double G[3] = {0, 0, 0}, rho = 0, lap = 0, M[9], vb[3] = {0, 0, 0}, H[9];
            c->hit[i] = (char)wall_term(f, col, i, G, &rho, &lap, M, vb, H);
            if (!c->hit[i]) continue;
            double P[3] = {0, 0, 0}; /* the pressure's velocity change on the particle is -dt P */
            if (!surf) {
                double ki = c->mirror * c->ktot[i] / c->rho[i], hp[3];
                hydro_push(f, H, hp);
                for (int a = 0; a < 3; a++) P[a] = ki * G[a] - hp[a];
            }
            if (viscous) /* the pressure's part, for pressure_part (Ap: the viscous solve's scratch) */
                for (int a = 0; a < 3; a++) c->Ap[3 * i + a] = f->mass * dt * P[a];
            if (!viscous) {
                for (int a = 0; a < 3; a++) c->dv[3 * i + a] = -f->mass * dt * P[a];
                continue;
            }
            if (f->def.cy.viscosity_form == STF_VISCOSITY_CENTRAL) {
                double ww = wall_visc(c, i), du[3];
                for (int a = 0; a < 3; a++) du[a] = c->r[3 * i + a] - vb[a];
                for (int a = 0; a < 3; a++) {
                    double Mu = M[3 * a] * du[0] + M[3 * a + 1] * du[1] + M[3 * a + 2] * du[2];
                    c->dv[3 * i + a] = f->mass * dt * (ww * Mu - P[a]);
                }
                continue;
            }
            double ww = wall_visc(c, i) * lap;
            for (int a = 0; a < 3; a++)
                c->dv[3 * i + a] = f->mass * dt * (ww * (c->r[3 * i + a] - vb[a]) - P[a]);
        }
        stf_collider_take_reaction(col, c->dv, f->x, c->hit, n,
                                   viscous ? STF_PART_VISCOSITY : STF_PART_PRESSURE);
        if (viscous) pressure_part(f, col, c->Ap);
        if (surf) surface_pressure(f, col, dt);
    }
}
