/* body_mesh.c - triangle surfaces of the body shapes (body_mesh.h). Round shapes are
 * surfaces of revolution about the local z axis; a convex point set's hull is found by
 * testing every plane through three of its points. */
#include "body_mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

enum { RING = 32,   /* vertices around z */
       LAT = 16 };  /* pole-to-pole segments of a sphere (a capsule's caps get LAT/2 each) */

void stf_mesh_free(stf_mesh *m)
{
    if (!m) return;
    free(m->v);
    free(m->t);
    memset(m, 0, sizeof *m);
}

static int mesh_alloc(stf_mesh *m, int nv, int nt)
{
    m->v = malloc(sizeof *m->v * 3 * (size_t)nv);
    m->t = malloc(sizeof *m->t * 3 * (size_t)nt);
    m->nv = m->nt = 0;
    if (m->v && m->t) return 0;
    stf_mesh_free(m);
    return -1;
}

static void put_v(stf_mesh *m, double x, double y, double z)
{
    double *p = m->v + 3 * m->nv++;
    p[0] = x, p[1] = y, p[2] = z;
}

static void put_t(stf_mesh *m, int a, int b, int c)
{
    int32_t *p = m->t + 3 * m->nt++;
    p[0] = a, p[1] = b, p[2] = c;
}

/* The surface of revolution of the profile (r[i], z[i]), i = 0..np-1, from the top pole
 * (r = 0) to the bottom pole (r = 0), z decreasing: a pole vertex at each end, a ring of
 * RING vertices at each inner profile point. */
static int lathe(stf_mesh *m, const double *r, const double *z, int np)
{
    int rings = np - 2;
    if (mesh_alloc(m, rings * RING + 2, 2 * RING * rings) != 0) return -1;
    put_v(m, 0, 0, z[0]);
    for (int i = 1; i <= rings; i++)
        for (int j = 0; j < RING; j++) {
            double phi = 2 * PI * j / RING;
            put_v(m, r[i] * cos(phi), r[i] * sin(phi), z[i]);
        }
    put_v(m, 0, 0, z[np - 1]);
    int bottom = m->nv - 1;
    for (int j = 0; j < RING; j++) put_t(m, 0, 1 + j, 1 + (j + 1) % RING);
    for (int i = 0; i + 1 < rings; i++)
        for (int j = 0; j < RING; j++) {
            int a = 1 + i * RING + j, b = 1 + i * RING + (j + 1) % RING;
            put_t(m, a, a + RING, b + RING);
            put_t(m, a, b + RING, b);
        }
    int last = 1 + (rings - 1) * RING;
    for (int j = 0; j < RING; j++) put_t(m, last + j, bottom, last + (j + 1) % RING);
    return 0;
}

/* A sphere of radius R (hl = 0) or a capsule: hemispheres at z = +-hl. */
static int round_body(stf_mesh *m, double R, double hl)
{
    int caps = hl > 0, np = LAT + 1 + caps;
    double r[LAT + 2], z[LAT + 2];
    for (int i = 0, k = 0; i <= LAT; i++) {
        double th = PI * i / LAT;
        if (caps && 2 * i == LAT) { /* the cylinder between the caps' equators */
            r[k] = R, z[k++] = hl;
            r[k] = R, z[k++] = -hl;
            continue;
        }
        r[k] = i == 0 || i == LAT ? 0 : R * sin(th);
        z[k++] = R * cos(th) + (caps ? (2 * i < LAT ? hl : -hl) : 0);
    }
    return lathe(m, r, z, np);
}

static int cylinder(stf_mesh *m, double R, double hl)
{
    const double r[4] = {0, R, R, 0}, z[4] = {hl, hl, -hl, -hl};
    return lathe(m, r, z, 4);
}

static int box(stf_mesh *m, const double h[3])
{
    if (mesh_alloc(m, 8, 12) != 0) return -1;
    for (int i = 0; i < 8; i++) /* vertex i: bit 0 -> +x, bit 1 -> +y, bit 2 -> +z */
        put_v(m, i & 1 ? h[0] : -h[0], i & 2 ? h[1] : -h[1], i & 4 ? h[2] : -h[2]);
    /* each face as a counter-clockwise quad seen from outside */
    static const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                    {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (int f = 0; f < 6; f++) {
        put_t(m, quads[f][0], quads[f][1], quads[f][2]);
        put_t(m, quads[f][0], quads[f][2], quads[f][3]);
    }
    return 0;
}

static void sub3(const double *a, const double *b, double *d)
{
    d[0] = a[0] - b[0], d[1] = a[1] - b[1], d[2] = a[2] - b[2];
}

static void cross3(const double *a, const double *b, double *c)
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Appends the hull face through the coplanar points `set` (outward normal nrm) as a fan of
 * triangles over its boundary, counter-clockwise seen from outside: the points are
 * projected onto the plane and their 2-D hull is walked (Andrew's monotone chain). */
static void hull_face(stf_mesh *m, const double *p, uint64_t set, const double *nrm)
{
    double u[3], w[3], ax[3] = {1, 0, 0};
    if (fabs(nrm[0]) > 0.9 * sqrt(dot3(nrm, nrm))) ax[0] = 0, ax[1] = 1;
    cross3(nrm, ax, u);
    cross3(nrm, u, w); /* u x w is along nrm: counter-clockwise in (u, w) is seen from outside */
    int idx[STF_MESH_HULL_MAX], n = 0;
    double pu[STF_MESH_HULL_MAX], pv[STF_MESH_HULL_MAX];
    for (int i = 0; i < STF_MESH_HULL_MAX; i++)
        if (set >> i & 1) idx[n] = i, pu[n] = dot3(p + 3 * i, u), pv[n++] = dot3(p + 3 * i, w);
    /* sort by (pu, pv) */
    for (int a = 1; a < n; a++)
        for (int b = a; b > 0 && (pu[b] < pu[b - 1] || (pu[b] == pu[b - 1] && pv[b] < pv[b - 1])); b--) {
            double t = pu[b]; pu[b] = pu[b - 1]; pu[b - 1] = t;
            t = pv[b]; pv[b] = pv[b - 1]; pv[b - 1] = t;
            int k = idx[b]; idx[b] = idx[b - 1]; idx[b - 1] = k;
        }
    int hull[2 * STF_MESH_HULL_MAX], k = 0;
    for (int pass = 0; pass < 2; pass++) { /* lower chain left to right, upper right to left */
        int start = k;
        for (int s = 0; s < n; s++) {
            int i = pass ? n - 1 - s : s;
            while (k >= start + 2) {
                int a = hull[k - 2], b = hull[k - 1];
                double c = (pu[b] - pu[a]) * (pv[i] - pv[a]) - (pv[b] - pv[a]) * (pu[i] - pu[a]);
                if (c > 0) break;
                k--;
            }
            hull[k++] = i;
        }
        k--; /* the chain's last point starts the other chain */
    }
    for (int s = 1; s + 1 < k; s++) put_t(m, idx[hull[0]], idx[hull[s]], idx[hull[s + 1]]);
}

/* The convex hull of n points: every plane through three points with no point outside
 * bounds a face; each face (its set of coplanar points) is triangulated once. */
static int convex(stf_mesh *m, const double *p, int n)
{
    if (n < 4 || n > STF_MESH_HULL_MAX) return 1;
    double scale = 0;
    for (int i = 0; i < 3 * n; i++) scale = fmax(scale, fabs(p[i]));
    if (!(scale > 0)) return 1;
    if (mesh_alloc(m, n, 2 * n) != 0) return -1; /* a hull of n points has <= 2n - 4 faces */
    for (int i = 0; i < n; i++) put_v(m, p[3 * i], p[3 * i + 1], p[3 * i + 2]);
    uint64_t *done = malloc(sizeof *done * 2 * (size_t)n);
    int ndone = 0;
    if (!done) {
        stf_mesh_free(m);
        return -1;
    }
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++)
            for (int k = j + 1; k < n; k++) {
                double e1[3], e2[3], nrm[3];
                sub3(p + 3 * j, p + 3 * i, e1);
                sub3(p + 3 * k, p + 3 * i, e2);
                cross3(e1, e2, nrm);
                double len = sqrt(dot3(nrm, nrm));
                if (len <= 1e-12 * scale * scale) continue; /* collinear */
                double tol = 1e-9 * scale * len;
                int above = 0, below = 0;
                uint64_t set = 0;
                for (int q = 0; q < n; q++) {
                    double d[3];
                    sub3(p + 3 * q, p + 3 * i, d);
                    double s = dot3(nrm, d);
                    if (s > tol) above++;
                    else if (s < -tol) below++;
                    else set |= (uint64_t)1 << q;
                }
                if (above && below) continue;
                int seen = 0;
                for (int f = 0; f < ndone && !seen; f++) seen = done[f] == set;
                /* a hull of n points has at most 2n - 4 triangles (the allocation): a set of
                   faces inconsistent at the tolerance stops there */
                if (seen || ndone == 2 * n || m->nt + __builtin_popcountll(set) > 2 * n) continue;
                done[ndone++] = set;
                if (above) nrm[0] = -nrm[0], nrm[1] = -nrm[1], nrm[2] = -nrm[2];
                hull_face(m, p, set, nrm);
            }
    free(done);
    if (m->nt < 4) { /* flat: no volume */
        stf_mesh_free(m);
        return 1;
    }
    return 0;
}

int stf_mesh_build(const stf_collider_def *def, stf_mesh *m)
{
    memset(m, 0, sizeof *m);
    switch (def->shape) {
    case STF_SHAPE_SPHERE: return round_body(m, def->radius, 0);
    case STF_SHAPE_CAPSULE: return round_body(m, def->radius, def->half_length);
    case STF_SHAPE_CYLINDER: return cylinder(m, def->radius, def->half_length);
    case STF_SHAPE_BOX: return box(m, def->half);
    case STF_SHAPE_CONVEX: return def->points ? convex(m, def->points, def->npoints) : 1;
    default: return 1;
    }
}

void stf_quat_matrix(const double quat[4], double R[9])
{
    double w = quat[0], x = quat[1], y = quat[2], z = quat[3];
    const double M[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
                         2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                         2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
    for (int k = 0; k < 9; k++) R[k] = M[k];
}

void stf_mesh_place(const stf_mesh *m, const double pos[3], const double quat[4], float *out)
{
    double R[9];
    stf_quat_matrix(quat, R);
    for (int i = 0; i < m->nv; i++) {
        const double *v = m->v + 3 * i;
        for (int c = 0; c < 3; c++)
            out[3 * i + c] = (float)(pos[c] + R[3 * c] * v[0] + R[3 * c + 1] * v[1] + R[3 * c + 2] * v[2]);
    }
}
