/* collider.c - signed distances to solids and the collision stage of the step. */
#include "collider.h"

#include <ccd/ccd.h>
#include <ccd/quat.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fluid.h"

static void to_local(const collider *c, const double x[3], double p[3])
{
    double d[3] = {x[0] - c->pos[0], x[1] - c->pos[1], x[2] - c->pos[2]};
    const double *R = c->rot;
    for (int a = 0; a < 3; a++) p[a] = R[a] * d[0] + R[3 + a] * d[1] + R[6 + a] * d[2];
}

static double norm3(const double a[3]) { return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

static double sdf_box(const double p[3], const double half[3], double n[3])
{
    double q[3], out[3];
    int inside_axis = 0;
    double inside_max = -1e300;
    for (int a = 0; a < 3; a++) {
        q[a] = fabs(p[a]) - half[a];
        out[a] = q[a] > 0 ? q[a] : 0;
        if (q[a] > inside_max) inside_max = q[a], inside_axis = a;
    }
    double o = norm3(out);
    if (o > 0) {
        for (int a = 0; a < 3; a++) n[a] = (p[a] < 0 ? -out[a] : out[a]) / o;
        return o;
    }
    n[0] = n[1] = n[2] = 0; /* inside: leave through the nearest face */
    n[inside_axis] = p[inside_axis] < 0 ? -1 : 1;
    return inside_max;
}

static double sdf_capsule(const double p[3], double r, double hl, double n[3])
{
    double z = p[2] < -hl ? -hl : (p[2] > hl ? hl : p[2]);
    double d[3] = {p[0], p[1], p[2] - z};
    double len = norm3(d);
    if (len < 1e-15) { /* on the axis: any radial direction will do */
        n[0] = 1, n[1] = 0, n[2] = 0;
        return -r;
    }
    for (int a = 0; a < 3; a++) n[a] = d[a] / len;
    return len - r;
}

static double sdf_cylinder(const double p[3], double r, double hl, double n[3])
{
    double rho = sqrt(p[0] * p[0] + p[1] * p[1]);
    double dr = rho - r, dz = fabs(p[2]) - hl;
    double er[3] = {1, 0, 0};
    if (rho > 1e-15) er[0] = p[0] / rho, er[1] = p[1] / rho;
    double sz = p[2] < 0 ? -1 : 1;
    if (dr > 0 && dz > 0) { /* beside a rim edge */
        double len = sqrt(dr * dr + dz * dz);
        for (int a = 0; a < 2; a++) n[a] = er[a] * dr / len;
        n[2] = sz * dz / len;
        return len;
    }
    if (dr > dz) {
        n[0] = er[0], n[1] = er[1], n[2] = 0;
        return dr;
    }
    n[0] = n[1] = 0, n[2] = sz;
    return dz;
}

/* Open-top box, local origin at the centre of the floor's top face; the inside is free.
 * two_sided (stf_wall_two_sided: walls at least a spacing thick): the walls and the floor are
 * solid from both sides, and a point in them leaves by the nearest of the inner box, the rim
 * (a wall's top) and the outer faces, so a particle from inside that went less than half the
 * wall deep goes back in, and one from outside (a splash landing against an outer face) goes
 * back out (the adaptive substep control keeps particles from crossing a wall's mid-plane in
 * one substep: stf_sim.c). Otherwise the outside is free and a point in a wall goes back in
 * (or up through the rim). */
static double sdf_container(const double p[3], const double half[3], double wall, int two_sided,
                            double n[3])
{
    double hx = half[0], hy = half[1], top = 2.0 * half[2];
    int over = fabs(p[0]) <= hx + wall && fabs(p[1]) <= hy + wall; /* the footprint */
    int in_wall_column = fabs(p[0]) > hx || fabs(p[1]) > hy;
    if (!two_sided && (!over || p[2] < -wall)) { /* thin walls: free outside */
        n[0] = n[1] = 0, n[2] = 1;
        return 1e30;
    }
    if (!over) { /* beside the container: the outer box's faces, edges and rims */
        double c[3] = {p[0], p[1], p[2] - 0.5 * (top - wall)};
        double hb[3] = {hx + wall, hy + wall, 0.5 * (top + wall)};
        return sdf_box(c, hb, n);
    }
    if (p[2] > top) { /* above: free over the opening, a wall's rim below over a wall */
        n[0] = n[1] = 0, n[2] = 1;
        return in_wall_column ? p[2] - top : 1e30;
    }
    if (p[2] < -wall) { /* under the floor */
        n[0] = n[1] = 0, n[2] = -1;
        return -wall - p[2];
    }
    double q[3] = {fabs(p[0]) - hx, fabs(p[1]) - hy, -p[2]};
    /* inside or on the inner surface (<=: on it the way back below has length 0, and -p[2]
       is -0.0 on the floor), the nearest wall or the floor */
    if (q[0] <= 0 && q[1] <= 0 && q[2] <= 0) {
        double d = -q[0];
        n[0] = p[0] < 0 ? 1 : -1, n[1] = 0, n[2] = 0;
        if (-q[1] < d) d = -q[1], n[0] = 0, n[1] = p[1] < 0 ? 1 : -1, n[2] = 0;
        if (-q[2] < d) d = -q[2], n[0] = 0, n[1] = 0, n[2] = 1;
        return d;
    }
    /* In the walls or floor: back to the inner box by the shortest way, up through the rim
       (a particle landing on a wall's top), or out through an outer face, whichever is
       nearest (the inner box on a tie). */
    double out[3] = {q[0] > 0 ? q[0] : 0, q[1] > 0 ? q[1] : 0, q[2] > 0 ? q[2] : 0};
    double o = norm3(out);
    double ox = hx + wall - fabs(p[0]), oy = hy + wall - fabs(p[1]), oz = p[2] + wall;
    if (!two_sided) ox = oy = oz = 1e30;
    double rim = in_wall_column ? top - p[2] : 1e30;
    if (rim < o && rim <= ox && rim <= oy && rim <= oz) {
        n[0] = n[1] = 0, n[2] = 1;
        return -rim;
    }
    double outer = fmin(ox, fmin(oy, oz));
    if (outer < o) {
        n[0] = n[1] = n[2] = 0;
        if (outer == ox) n[0] = p[0] < 0 ? -1 : 1;
        else if (outer == oy) n[1] = p[1] < 0 ? -1 : 1;
        else n[2] = -1;
        return -outer;
    }
    n[0] = p[0] < 0 ? out[0] / o : -out[0] / o;
    n[1] = p[1] < 0 ? out[1] / o : -out[1] / o;
    n[2] = out[2] / o;
    return -o;
}

/* libccd support functions: a convex hull and a point (the particle centre). */
typedef struct hull_obj {
    const collider *c;
} hull_obj;

static void support_hull(const void *obj, const ccd_vec3_t *dir, ccd_vec3_t *vec)
{
    const collider *c = ((const hull_obj *)obj)->c;
    double dl[3], dw[3] = {ccdVec3X(dir), ccdVec3Y(dir), ccdVec3Z(dir)};
    const double *R = c->rot;
    for (int a = 0; a < 3; a++) dl[a] = R[a] * dw[0] + R[3 + a] * dw[1] + R[6 + a] * dw[2];
    int best = 0;
    double bd = -1e300;
    for (int k = 0; k < c->def.npoints; k++) {
        const double *q = c->points + 3 * k;
        double d = q[0] * dl[0] + q[1] * dl[1] + q[2] * dl[2];
        if (d > bd) bd = d, best = k;
    }
    double w[3];
    stf_collider_world_dir(c, c->points + 3 * best, w);
    ccdVec3Set(vec, w[0] + c->pos[0], w[1] + c->pos[1], w[2] + c->pos[2]);
}

static void center_hull(const void *obj, ccd_vec3_t *center)
{
    const collider *c = ((const hull_obj *)obj)->c;
    ccdVec3Set(center, c->pos[0], c->pos[1], c->pos[2]);
}

static void support_point(const void *obj, const ccd_vec3_t *dir, ccd_vec3_t *vec)
{
    const double *x = obj;
    (void)dir;
    ccdVec3Set(vec, x[0], x[1], x[2]);
}

static void center_point(const void *obj, ccd_vec3_t *center)
{
    const double *x = obj;
    ccdVec3Set(center, x[0], x[1], x[2]);
}

/* n = r / |r|, or +z when r is zero: the way out from a hull's origin. */
static void out_from_origin(const double r[3], double n[3])
{
    double l = norm3(r);
    if (l > 0) n[0] = r[0] / l, n[1] = r[1] / l, n[2] = r[2] / l;
    else n[0] = n[1] = 0, n[2] = 1;
}

/* The point of the affine hull of the m points s (m <= 4) nearest the origin, as weights
 * lam (summing to 1): the Gram system [G 1; 1' 0]. Returns -1 when it is singular. */
static int affine_nearest(const double (*s)[3], int m, double lam[4])
{
    double A[5][6];
    for (int i = 0; i < m; i++) {
        for (int j = 0; j < m; j++)
            A[i][j] = s[i][0] * s[j][0] + s[i][1] * s[j][1] + s[i][2] * s[j][2];
        A[i][m] = 1, A[i][m + 1] = 0;
    }
    for (int j = 0; j < m; j++) A[m][j] = 1;
    A[m][m] = 0, A[m][m + 1] = 1;
    int N = m + 1;
    double scale = 0;
    for (int i = 0; i < m; i++) scale = fmax(scale, A[i][i]);
    for (int col = 0; col < N; col++) { /* Gauss-Jordan, partial pivoting */
        int piv = col;
        for (int r = col + 1; r < N; r++)
            if (fabs(A[r][col]) > fabs(A[piv][col])) piv = r;
        if (!(fabs(A[piv][col]) > 1e-13 * (scale > 1 ? scale : 1) * (col < m ? 1 : 1e-3)))
            return -1;
        for (int k = 0; k <= N; k++) {
            double t = A[col][k];
            A[col][k] = A[piv][k], A[piv][k] = t;
        }
        for (int r = 0; r < N; r++) {
            if (r == col) continue;
            double fct = A[r][col] / A[col][col];
            for (int k = col; k <= N; k++) A[r][k] -= fct * A[col][k];
        }
    }
    for (int i = 0; i < m; i++) lam[i] = A[i][N] / A[i][i];
    return 0;
}

/* Distance from the local point p to the hull of the body-frame points when p is outside
 * (GJK on the points moved by -p: the hull point nearest the origin). Sets the outward unit
 * normal nl (local); returns the distance, 0 when p is inside or on the hull. */
static double hull_distance(const collider *c, const double p[3], double nl[3])
{
    const double *P = c->points;
    int np = c->def.npoints;
    double W[4][3], v[3];
    int m = 1;
    for (int a = 0; a < 3; a++) W[0][a] = P[a] - p[a], v[a] = W[0][a];
    double tol = 1e-24 * (c->bound * c->bound + 1e-30);
    int inside = 0;
    for (int it = 0; it < 64; it++) {
        double vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
        if (vv <= tol) { /* the origin is on the hull: touching */
            inside = 1;
            break;
        }
        int best = 0;
        double bd = 1e300;
        for (int k = 0; k < np; k++) {
            double d = (P[3 * k] - p[0]) * v[0] + (P[3 * k + 1] - p[1]) * v[1] +
                       (P[3 * k + 2] - p[2]) * v[2];
            if (d < bd) bd = d, best = k;
        }
        if (vv - bd <= 1e-12 * vv) break; /* no point nearer along -v: v is it */
        for (int a = 0; a < 3; a++) W[m][a] = P[3 * best + a] - p[a];
        m++;
        /* the sub-simplex holding the nearest point: try every subset, keep the nearest
           one whose weights are all positive */
        double bestn = 1e300, bv[3] = {v[0], v[1], v[2]}, bw[4][3];
        int bm = 0;
        for (int mask = 1; mask < (1 << m); mask++) {
            double S[4][3], lam[4];
            int k = 0;
            for (int i = 0; i < m; i++)
                if (mask >> i & 1) memcpy(S[k++], W[i], sizeof S[0]);
            if (affine_nearest((const double (*)[3])S, k, lam) != 0) continue;
            int ok = 1;
            for (int i = 0; i < k; i++) ok &= lam[i] > 0;
            if (!ok) continue;
            double q[3] = {0, 0, 0};
            for (int i = 0; i < k; i++)
                for (int a = 0; a < 3; a++) q[a] += lam[i] * S[i][a];
            double qq = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
            if (qq < bestn) {
                bestn = qq, bm = k;
                for (int a = 0; a < 3; a++) bv[a] = q[a];
                memcpy(bw, S, (size_t)k * sizeof S[0]);
            }
        }
        if (bm == 0 || !(bestn < vv)) break; /* no progress: v is as near as it gets */
        m = bm;
        memcpy(W, bw, (size_t)m * sizeof W[0]);
        for (int a = 0; a < 3; a++) v[a] = bv[a];
        if (m == 4) { /* a tetrahedron around the origin: inside */
            inside = 1;
            break;
        }
    }
    double len = norm3(v);
    if (inside || !(len > 0)) { /* touching (libccd saw no overlap): out from the origin */
        out_from_origin(p, nl);
        return 0;
    }
    for (int a = 0; a < 3; a++) nl[a] = -v[a] / len;
    return len;
}

static double sdf_convex(const collider *c, const double x[3], double n[3])
{
    ccd_t ccd;
    CCD_INIT(&ccd);
    ccd.support1 = support_hull;
    ccd.support2 = support_point;
    ccd.center1 = center_hull;
    ccd.center2 = center_point;
    ccd.epa_tolerance = 1e-9;
    ccd.max_iterations = 100;
    hull_obj h = {c};
    ccd_real_t depth;
    ccd_vec3_t dir, pos;
    /* GJK + EPA, not MPR: MPR measures the depth along the line from the hull's centre to the
       point, which overestimates it away from the face normals (by up to 11 cm for a
       40 x 20 x 10 cm box, tested); EPA finds the shortest way out. */
    if (ccdGJKPenetration(&h, x, &ccd, &depth, &dir, &pos) != 0) {
        /* outside: the distance (collisions act within half a spacing, wall pressure
           within h), by GJK on the hull's points */
        double p[3], nl[3];
        to_local(c, x, p);
        double d = hull_distance(c, p, nl);
        stf_collider_world_dir(c, nl, n);
        return d;
    }
    /* dir: the direction to move the point to separate it, i.e. out of the hull. */
    n[0] = ccdVec3X(&dir), n[1] = ccdVec3Y(&dir), n[2] = ccdVec3Z(&dir);
    double len = norm3(n);
    if (!(len > 0.5 && len < 2) || !(depth > 1e-12 * c->bound)) {
        /* A point on the surface (depth 0): EPA has no direction, and gives NaN at a corner
           or a tangent at a face. Out along the line from the hull's origin instead. */
        double r[3] = {x[0] - c->pos[0], x[1] - c->pos[1], x[2] - c->pos[2]};
        out_from_origin(r, n);
        return isfinite(depth) ? -depth : 0.0;
    }
    return -depth;
}

double stf_collider_sdf(const collider *c, const double x[3], double n[3])
{
    double p[3], nl[3], d;
    switch (c->def.shape) {
    case STF_SHAPE_PLANE: {
        double nw[3];
        stf_collider_world_dir(c, c->def.normal, nw);
        n[0] = nw[0], n[1] = nw[1], n[2] = nw[2];
        return nw[0] * (x[0] - c->pos[0]) + nw[1] * (x[1] - c->pos[1]) +
               nw[2] * (x[2] - c->pos[2]) - c->def.offset;
    }
    case STF_SHAPE_CONVEX:
        return sdf_convex(c, x, n);
    case STF_SHAPE_SPHERE: {
        double dd[3] = {x[0] - c->pos[0], x[1] - c->pos[1], x[2] - c->pos[2]};
        double len = norm3(dd);
        if (len < 1e-15) {
            n[0] = 0, n[1] = 0, n[2] = 1;
            return -c->def.radius;
        }
        for (int a = 0; a < 3; a++) n[a] = dd[a] / len;
        return len - c->def.radius;
    }
    default:
        break;
    }
    to_local(c, x, p);
    if (c->def.shape == STF_SHAPE_BOX) d = sdf_box(p, c->def.half, nl);
    else if (c->def.shape == STF_SHAPE_CAPSULE)
        d = sdf_capsule(p, c->def.radius, c->def.half_length, nl);
    else if (c->def.shape == STF_SHAPE_CYLINDER)
        d = sdf_cylinder(p, c->def.radius, c->def.half_length, nl);
    else d = sdf_container(p, c->def.half, c->def.wall, c->two_sided, nl);
    stf_collider_world_dir(c, nl, n);
    return d;
}

int stf_collider_container_faces(const collider *c, const double x[3], double d[5], double n[5][3])
{
    if (c->def.shape != STF_SHAPE_CONTAINER) return 0;
    double p[3];
    to_local(c, x, p);
    const double *half = c->def.half;
    double wall = c->def.wall;
    if (!(fabs(p[0]) <= half[0] + wall && fabs(p[1]) <= half[1] + wall && p[2] >= -wall &&
          p[2] <= 2.0 * half[2]))
        return 0;
    static const double nl[5][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
    d[0] = p[0] + half[0], d[1] = half[0] - p[0];
    d[2] = p[1] + half[1], d[3] = half[1] - p[1];
    d[4] = p[2];
    for (int k = 0; k < 5; k++) stf_collider_world_dir(c, nl[k], n[k]);
    return 5;
}

int stf_collider_box_faces(const collider *c, const double x[3], double d[6], double n[6][3])
{
    if (c->def.shape != STF_SHAPE_BOX) return 0;
    double p[3];
    to_local(c, x, p);
    for (int a = 0; a < 3; a++) {
        double e[3] = {0, 0, 0};
        d[2 * a] = p[a] - c->def.half[a], d[2 * a + 1] = -p[a] - c->def.half[a];
        e[a] = 1;
        stf_collider_world_dir(c, e, n[2 * a]);
        for (int b = 0; b < 3; b++) n[2 * a + 1][b] = -n[2 * a][b];
    }
    return 6;
}

void stf_collider_velocity_at(const collider *c, const double x[3], double v[3])
{
    double r[3] = {x[0] - c->pos[0], x[1] - c->pos[1], x[2] - c->pos[2]};
    const double *w = c->angvel;
    v[0] = c->vel[0] + w[1] * r[2] - w[2] * r[1];
    v[1] = c->vel[1] + w[2] * r[0] - w[0] * r[2];
    v[2] = c->vel[2] + w[0] * r[1] - w[1] * r[0];
}

/* The radius of the sphere about the body origin that holds the shape (m); -1 for planes
 * and containers, which reach every particle. Exact for every shape. */
static double shape_bound(const stf_collider_def *d, const double *points)
{
    switch (d->shape) {
    case STF_SHAPE_SPHERE: return d->radius;
    case STF_SHAPE_BOX: return norm3(d->half);
    case STF_SHAPE_CAPSULE: return d->half_length + d->radius;
    case STF_SHAPE_CYLINDER: return sqrt(d->radius * d->radius + d->half_length * d->half_length);
    case STF_SHAPE_CONVEX: {
        double b = 0;
        for (int k = 0; k < d->npoints; k++) {
            double r = norm3(points + 3 * k);
            if (r > b) b = r;
        }
        return b;
    }
    default: return -1;
    }
}

int stf_collider_init(collider *c, const stf_collider_def *def, char *err, size_t errlen)
{
    memset(c, 0, sizeof *c);
    c->def = *def;
    c->def.points = NULL;
    const char *bad = NULL;
    switch (def->shape) {
    case STF_SHAPE_PLANE:
        if (!(norm3(def->normal) > 0)) bad = "plane normal must be non-zero";
        break;
    case STF_SHAPE_SPHERE:
        if (!(def->radius > 0)) bad = "sphere radius must be > 0";
        break;
    case STF_SHAPE_BOX:
        if (!(def->half[0] > 0 && def->half[1] > 0 && def->half[2] > 0))
            bad = "box half extents must be > 0";
        break;
    case STF_SHAPE_CAPSULE:
    case STF_SHAPE_CYLINDER:
        if (!(def->radius > 0 && def->half_length > 0))
            bad = "radius and half_length must be > 0";
        break;
    case STF_SHAPE_CONTAINER:
        if (!(def->half[0] > 0 && def->half[1] > 0 && def->half[2] > 0 && def->wall >= 0))
            bad = "container half extents must be > 0 and wall >= 0";
        break;
    case STF_SHAPE_CONVEX:
        if (!def->points || def->npoints < 4) bad = "convex shape needs at least 4 points";
        break;
    default:
        bad = "unknown shape";
    }
    if (!bad && !(def->friction >= 0 && def->friction <= 1)) bad = "friction must be in [0,1]";
    if (bad) {
        snprintf(err, errlen, "collider: %s", bad);
        return -1;
    }
    if (def->shape == STF_SHAPE_PLANE) {
        double len = norm3(def->normal);
        for (int a = 0; a < 3; a++) c->def.normal[a] = def->normal[a] / len;
    }
    if (def->shape == STF_SHAPE_CONVEX) {
        c->points = malloc((size_t)def->npoints * 3 * sizeof *c->points);
        if (!c->points) {
            snprintf(err, errlen, "collider: out of memory");
            return -1;
        }
        memcpy(c->points, def->points, (size_t)def->npoints * 3 * sizeof *c->points);
    }
    c->rot[0] = c->rot[4] = c->rot[8] = 1;
    c->bound = shape_bound(&c->def, c->points);
    return 0;
}

void stf_collider_free(collider *c)
{
    free(c->points);
    c->points = NULL;
}

void stf_collider_take_reaction(collider *c, const double *imp, const double *x, const char *hit,
                            int n, int part)
{
    double J[3] = {0, 0, 0}, M[3] = {0, 0, 0};
    for (int i = 0; i < n; i++) {
        if (!hit[i]) continue;
        const double *p = imp + 3 * i;
        double r[3] = {x[3 * i] - c->pos[0], x[3 * i + 1] - c->pos[1], x[3 * i + 2] - c->pos[2]};
        J[0] -= p[0], J[1] -= p[1], J[2] -= p[2];
        M[0] -= r[1] * p[2] - r[2] * p[1];
        M[1] -= r[2] * p[0] - r[0] * p[2];
        M[2] -= r[0] * p[1] - r[1] * p[0];
    }
    for (int a = 0; a < 3; a++) c->impulse[a] += J[a], c->moment[a] += M[a], c->part[part][a] += J[a];
}

/* Projects particle i out of collider c, stops its approach, and applies Coulomb friction:
 * the tangential slip relative to the surface drops by at most friction times the normal
 * velocity change, so the result does not depend on dt. Stores the impulse given to the
 * particle in imp and the projection in proj. rp: the contact radius (m). Returns 1 on contact. */
static int collide_one(stf_fluid *f, const collider *c, int i, double dt, double rp,
                       double *imp, double *proj)
{
    double *x = f->x + 3 * i, nrm[3];
    if (!stf_collider_near(c, x, rp)) return 0;
    double d = stf_collider_sdf(c, x, nrm);
    if (d >= rp) return 0;
    /* The penetration is removed from the position only (xprev moves along), so it adds no
       velocity: a particle squeezed between two solids is not shot out (it was, at 30 m/s,
       between a bowling ball and the floor). Velocity changes below carry the momentum. */
    for (int a = 0; a < 3; a++) {
        proj[3 * i + a] = (rp - d) * nrm[a];
        x[a] += proj[3 * i + a];
        f->xprev[3 * i + a] += proj[3 * i + a];
    }
    /* The stop: a particle still approaching (a wall moving into the fluid) takes the
       surface's normal velocity. The projection above has already taken the step's approach
       back (the particle is at the contact radius), so the stop moves xprev, not x: the
       particle stays at the contact radius. Moving x as well stopped it twice: it ended dt |vn|
       beyond the contact radius, at rest, so the wall layers were lifted on every substep by an
       amount in phase with the pressure on them. In the Carreau-Yasuda model that lift drove
       a still column's vertical mode (the held sphere's tank of 3 spacings without the sphere:
       the fluid's mean vertical velocity swung by 23 mm/s sd, period 30 ms, not decaying over
       0.8 s; held spheres' force sd 0.95-2.1 rho V g, 0.03-0.30 rho V g without the lift) and
       was a slip layer of thickness ~ |vn| dt (cli_settling's sphere: -1.3%, -13.8%, -24.6%
       at dt 2, 1, 0.5 ms with it). The velocity change and the impulse are the same. */
    double jn = 0; /* normal velocity change, m/s */
    double vb[3], vrel[3];
    stf_collider_velocity_at(c, x, vb);
    for (int a = 0; a < 3; a++) vrel[a] = (x[a] - f->xprev[3 * i + a]) / dt - vb[a];
    double vn = vrel[0] * nrm[0] + vrel[1] * nrm[1] + vrel[2] * nrm[2];
    if (vn < 0) {
        jn = -vn;
        for (int a = 0; a < 3; a++) {
            double e = dt * vn * nrm[a];
            f->xprev[3 * i + a] += e;
            proj[3 * i + a] += e;
        }
    }
    double vt[3], vt2 = 0, cut = 0;
    for (int a = 0; a < 3; a++) {
        vt[a] = vrel[a] - vn * nrm[a];
        vt2 += vt[a] * vt[a];
    }
    if (vt2 > 0) {
        cut = c->def.friction * jn / sqrt(vt2);
        if (cut > 1) cut = 1;
        for (int a = 0; a < 3; a++) x[a] -= dt * cut * vt[a];
    }
    for (int a = 0; a < 3; a++) imp[3 * i + a] = f->mass * (jn * nrm[a] - cut * vt[a]);
    return 1;
}

/* The collider's share of the collisions, in particle order. A particle's angular momentum
 * m x × v moves by xprev × imp for its velocity change (xprev after the projection: the step
 * ends at x = xprev + dt v), and by m delta × v for the projection delta, which moves it
 * without changing its velocity v (before the velocity change). The collider takes back the
 * impulses at xprev, and the projections as a shift sum(m delta) of its own (a dynamic body
 * moves by -shift / M: the centre of mass stays) and a couple -m delta × (v - vel), vel the
 * collider's velocity at its origin: with the shift's M (-shift / M) × vel = -sum m delta ×
 * vel it makes up m delta × v exactly, and it depends on relative velocities only. */
static void take_collisions(collider *c, const stf_fluid *f, double dt)
{
    double J[3] = {0, 0, 0}, M[3] = {0, 0, 0}, S[3] = {0, 0, 0}, m = f->mass;
    double idt = 1.0 / dt, im = 1.0 / m;
    for (int i = 0; i < f->n; i++) {
        if (!f->hit[i]) continue;
        const double *p = f->dx + 3 * i, *xp = f->xprev + 3 * i, *x = f->x + 3 * i;
        double r[3] = {xp[0] - c->pos[0], xp[1] - c->pos[1], xp[2] - c->pos[2]};
        double md[3], u[3]; /* m delta; velocity before the change, relative to vel */
        for (int a = 0; a < 3; a++) {
            md[a] = m * f->dproj[3 * i + a];
            u[a] = (x[a] - xp[a]) * idt - p[a] * im - c->vel[a];
            J[a] -= p[a];
            S[a] += md[a];
        }
        M[0] -= r[1] * p[2] - r[2] * p[1] + md[1] * u[2] - md[2] * u[1];
        M[1] -= r[2] * p[0] - r[0] * p[2] + md[2] * u[0] - md[0] * u[2];
        M[2] -= r[0] * p[1] - r[1] * p[0] + md[0] * u[1] - md[1] * u[0];
    }
    for (int a = 0; a < 3; a++) {
        c->impulse[a] += J[a], c->moment[a] += M[a], c->shift[a] += S[a];
        c->part[STF_PART_CONTACT][a] += J[a];
    }
}

void stf_collide_all(stf_fluid *f, double dt)
{
    int n = f->n;
    for (int k = 0; k < f->ncolliders; k++) {
        collider *c = &f->colliders[k];
        char *hit = f->hit;
        /* the contact radius (fluid.c, cy.c): the container's and the planes', or a body's */
        int wall = c->def.shape == STF_SHAPE_CONTAINER || c->def.shape == STF_SHAPE_PLANE;
        double rp = wall ? f->contact : f->contact_body;
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++) hit[i] = (char)collide_one(f, c, i, dt, rp, f->dx, f->dproj);
        take_collisions(c, f, dt);
    }
}

int stf_collider_extent(const stf_collider_def *def, double *inradius, double *bound)
{
    char err[128];
    collider c;
    if (stf_collider_init(&c, def, err, sizeof err) != 0) return -1;
    *bound = c.bound;
    const double *h = def->half;
    switch (def->shape) {
    case STF_SHAPE_SPHERE:
    case STF_SHAPE_CAPSULE: *inradius = def->radius; break;
    case STF_SHAPE_BOX: *inradius = fmin(h[0], fmin(h[1], h[2])); break;
    case STF_SHAPE_CYLINDER: *inradius = fmin(def->radius, def->half_length); break;
    case STF_SHAPE_CONVEX: {
        /* the depth of the origin inside the hull; 0 when the hull does not hold it */
        double n[3], origin[3] = {0, 0, 0};
        *inradius = fmax(0.0, -stf_collider_sdf(&c, origin, n));
        break;
    }
    default: *inradius = -1;
    }
    stf_collider_free(&c);
    return *bound < 0 ? -1 : 0;
}

int stf_collider_volumes(const stf_collider_def *def, double band, double *vol, double *vol_band)
{
    char err[128];
    collider c;
    if (!(band > 0) || stf_collider_init(&c, def, err, sizeof err) != 0) return -1;
    if (c.bound < 0) {
        stf_collider_free(&c);
        return -1;
    }
    /* the cells of an N^3 grid over the cube that holds the shape and its band, each counted
       by the share of it the distance at its midpoint puts inside (d = 0 on the surface:
       half), which follows a smooth surface that cuts a cell: second order in the cell */
    enum { N = 64 };
    double half = c.bound + band, cell = 2 * half / N, in_row[N], band_row[N];
    /* by slab, summed in order: the volumes do not depend on the thread count */
#pragma omp parallel for schedule(static)
    for (int a = 0; a < N; a++) {
        in_row[a] = band_row[a] = 0;
        for (int b = 0; b < N; b++)
            for (int k = 0; k < N; k++) {
                double x[3] = {-half + (a + 0.5) * cell, -half + (b + 0.5) * cell,
                               -half + (k + 0.5) * cell}, n[3];
                double d = stf_collider_sdf(&c, x, n);
                double in = fmin(1.0, fmax(0.0, 0.5 - d / cell));
                double in_band = fmin(1.0, fmax(0.0, 0.5 - (d - band) / cell));
                in_row[a] += in;
                band_row[a] += in_band - in;
            }
    }
    double inside = 0, shell = 0;
    for (int a = 0; a < N; a++) inside += in_row[a], shell += band_row[a];
    stf_collider_free(&c);
    *vol = inside * cell * cell * cell;
    *vol_band = shell * cell * cell * cell;
    return 0;
}
