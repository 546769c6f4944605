/* test_mesh.c - the bodies' surface meshes (src/body_mesh.c) that the XDMF sidecar shows:
 * every shape's mesh is closed (each edge in two triangles, once each way), faces outward
 * (positive enclosed volume, close to the shape's), spans the shape's extent, and is placed
 * by a position and a quaternion; a convex hull keeps only its boundary points' faces. */
#include "body_mesh.h"
#include "test_util.h"

#include <stdlib.h>
#include <string.h>

static const double PI_ = 3.14159265358979323846;

/* 1 if every directed edge appears once and its reverse once. */
static int closed(const stf_mesh *m)
{
    int bad = 0;
    for (int a = 0; a < m->nt && !bad; a++)
        for (int e = 0; e < 3 && !bad; e++) {
            int32_t u = m->t[3 * a + e], v = m->t[3 * a + (e + 1) % 3];
            int same = 0, rev = 0;
            for (int b = 0; b < m->nt; b++)
                for (int f = 0; f < 3; f++) {
                    int32_t x = m->t[3 * b + f], y = m->t[3 * b + (f + 1) % 3];
                    same += x == u && y == v;
                    rev += x == v && y == u;
                }
            bad = same != 1 || rev != 1 || u == v;
        }
    return !bad;
}

static double volume(const stf_mesh *m)
{
    double vol = 0;
    for (int a = 0; a < m->nt; a++) {
        const double *p = m->v + 3 * m->t[3 * a], *q = m->v + 3 * m->t[3 * a + 1],
                     *r = m->v + 3 * m->t[3 * a + 2];
        vol += (p[0] * (q[1] * r[2] - q[2] * r[1]) - p[1] * (q[0] * r[2] - q[2] * r[0]) +
                p[2] * (q[0] * r[1] - q[1] * r[0])) / 6;
    }
    return vol;
}

static void extent(const stf_mesh *m, double lo[3], double hi[3])
{
    for (int c = 0; c < 3; c++) lo[c] = 1e300, hi[c] = -1e300;
    for (int i = 0; i < m->nv; i++)
        for (int c = 0; c < 3; c++) {
            lo[c] = fmin(lo[c], m->v[3 * i + c]);
            hi[c] = fmax(hi[c], m->v[3 * i + c]);
        }
}

/* Builds def's mesh and checks it: closed, volume within rel of vol, extent half[c]. */
static void check_shape(const char *what, const stf_collider_def *def, double vol, double rel,
                        const double half[3])
{
    stf_mesh m;
    CHECK(stf_mesh_build(def, &m) == 0, "%s: no mesh", what);
    if (!m.nt) return;
    CHECK(closed(&m), "%s: not closed", what);
    double v = volume(&m);
    CHECK(v > 0 && fabs(v - vol) <= rel * vol, "%s: volume %g, want %g", what, v, vol);
    double lo[3], hi[3];
    extent(&m, lo, hi);
    for (int c = 0; c < 3; c++) {
        CHECK_NEAR(hi[c], half[c], 1e-12, what);
        CHECK_NEAR(lo[c], -half[c], 1e-12, what);
    }
    for (int i = 0; i < 3 * m.nt; i++) CHECK(m.t[i] >= 0 && m.t[i] < m.nv, "%s: index", what);
    stf_mesh_free(&m);
}

int main(void)
{
    stf_collider_def d = stf_default_collider_def();
    d.shape = STF_SHAPE_SPHERE;
    d.radius = 0.1;
    check_shape("sphere", &d, 4.0 / 3 * PI_ * 1e-3, 0.03, (double[3]){0.1, 0.1, 0.1});
    d.shape = STF_SHAPE_CAPSULE;
    d.half_length = 0.2;
    check_shape("capsule", &d, 4.0 / 3 * PI_ * 1e-3 + PI_ * 0.01 * 0.4, 0.03,
                (double[3]){0.1, 0.1, 0.3});
    d.shape = STF_SHAPE_CYLINDER;
    check_shape("cylinder", &d, PI_ * 0.01 * 0.4, 0.01, (double[3]){0.1, 0.1, 0.2});
    d.shape = STF_SHAPE_BOX;
    d.half[0] = 0.1, d.half[1] = 0.2, d.half[2] = 0.3;
    check_shape("box", &d, 8 * 0.1 * 0.2 * 0.3, 1e-12, d.half);

    /* convex: a cube's 8 corners (coplanar faces) plus its centre (not on the hull) */
    double cube[27];
    for (int i = 0; i < 8; i++)
        for (int c = 0; c < 3; c++) cube[3 * i + c] = (i >> c & 1) ? 0.05 : -0.05;
    cube[24] = cube[25] = cube[26] = 0;
    d.shape = STF_SHAPE_CONVEX;
    d.points = cube;
    d.npoints = 9;
    check_shape("convex cube", &d, 1e-3, 1e-9, (double[3]){0.05, 0.05, 0.05});
    stf_mesh m;
    CHECK(stf_mesh_build(&d, &m) == 0 && m.nt == 12, "cube hull: %d triangles, want 12", m.nt);
    stf_mesh_free(&m);
    /* random points on a sphere: a closed hull with 2n - 4 triangles */
    enum { NP = 40 };
    double pts[3 * NP];
    unsigned long long seed = 12345;
    for (int i = 0; i < NP; i++) {
        double x, y, z, r;
        do {
            x = test_urand(&seed), y = test_urand(&seed), z = test_urand(&seed);
            r = sqrt(x * x + y * y + z * z);
        } while (r < 0.1 || r > 1);
        pts[3 * i] = x / r, pts[3 * i + 1] = y / r, pts[3 * i + 2] = z / r;
    }
    d.points = pts;
    d.npoints = NP;
    CHECK(stf_mesh_build(&d, &m) == 0, "random hull");
    CHECK(m.nt == 2 * NP - 4, "random hull: %d triangles, want %d", m.nt, 2 * NP - 4);
    CHECK(closed(&m), "random hull not closed");
    CHECK(volume(&m) > 2 && volume(&m) < 4.0 / 3 * PI_, "random hull volume %g", volume(&m));
    stf_mesh_free(&m);
    /* flat, too many points, unbounded shapes: no mesh */
    double flat[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
    d.points = flat;
    d.npoints = 4;
    CHECK(stf_mesh_build(&d, &m) == 1 && !m.v && !m.t, "flat point set meshed");
    d.npoints = STF_MESH_HULL_MAX + 1;
    CHECK(stf_mesh_build(&d, &m) == 1, "too many points meshed");
    d.shape = STF_SHAPE_PLANE;
    CHECK(stf_mesh_build(&d, &m) == 1, "plane meshed");
    d.shape = STF_SHAPE_CONTAINER;
    CHECK(stf_mesh_build(&d, &m) == 1, "container meshed");

    /* placement: a quarter turn about z, then a shift */
    d.shape = STF_SHAPE_BOX;
    CHECK(stf_mesh_build(&d, &m) == 0, "box");
    const double pos[3] = {1, 2, 3}, q[4] = {sqrt(0.5), 0, 0, sqrt(0.5)};
    float *w = malloc(sizeof *w * 3 * (size_t)m.nv);
    if (w) {
        stf_mesh_place(&m, pos, q, w);
        for (int i = 0; i < m.nv; i++) { /* (x, y, z) -> (-y, x, z) + pos */
            CHECK_NEAR(w[3 * i], 1 - m.v[3 * i + 1], 1e-6, "placed x");
            CHECK_NEAR(w[3 * i + 1], 2 + m.v[3 * i], 1e-6, "placed y");
            CHECK_NEAR(w[3 * i + 2], 3 + m.v[3 * i + 2], 1e-6, "placed z");
        }
    }
    free(w);
    stf_mesh_free(&m);
    return test_result("test_mesh");
}
