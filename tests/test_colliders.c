/* test_colliders.c - signed distances of every collider shape against their exact values,
 * the libccd (GJK + EPA) convex hull against the analytic box, and removal of overlapping
 * particles at set-up. */
#include <math.h>
#include <stdlib.h>

#include "stf.h"
#include "test_util.h"

static stf_fluid *fluid(void)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.jitter = 0; /* a lattice at rest: any motion comes from the body */
    d.effects = STF_EFFECT_PRESSURE;
    d.spacing = 0.01;
    char err[256];
    stf_fluid *f;
    if (stf_fluid_create(&d, &f, err, sizeof err)) exit(1);
    return f;
}

static int add(stf_fluid *f, stf_collider_def c)
{
    char err[256];
    int id = stf_fluid_add_collider(f, &c, err, sizeof err);
    CHECK(id >= 0, "%s", err);
    return id;
}

/* A rotation by angle a about z, row-major. */
static void rot_z(double a, double R[9])
{
    double c = cos(a), s = sin(a);
    double r[9] = {c, -s, 0, s, c, 0, 0, 0, 1};
    for (int k = 0; k < 9; k++) R[k] = r[k];
}

static void test_shapes(void)
{
    stf_fluid *f = fluid();
    stf_collider_def c = stf_default_collider_def();
    double R[9], v0[3] = {0, 0, 0};
    rot_z(0.3, R);

    c.shape = STF_SHAPE_SPHERE, c.radius = 0.1;
    int sphere = add(f, c);
    stf_fluid_set_collider_state(f, sphere, (double[3]){1, 2, 3}, R, v0, v0);
    CHECK_NEAR(stf_fluid_collider_distance(f, sphere, (double[3]){1.3, 2, 3}), 0.2, 1e-12, "sphere outside");
    CHECK_NEAR(stf_fluid_collider_distance(f, sphere, (double[3]){1, 2, 3.05}), -0.05, 1e-12, "sphere inside");

    c.shape = STF_SHAPE_BOX, c.half[0] = 0.2, c.half[1] = 0.1, c.half[2] = 0.05;
    int box = add(f, c);
    stf_fluid_set_collider_state(f, box, (double[3]){0, 0, 0}, R, v0, v0);
    /* a point on the rotated local x axis, 0.1 beyond the face */
    double px[3] = {0.3 * cos(0.3), 0.3 * sin(0.3), 0};
    CHECK_NEAR(stf_fluid_collider_distance(f, box, px), 0.1, 1e-12, "box face");
    CHECK_NEAR(stf_fluid_collider_distance(f, box, (double[3]){0, 0, 0.01}), -0.04, 1e-12, "box inside");
    double corner[3] = {0.2 * cos(0.3) - 0.1 * sin(0.3), 0.2 * sin(0.3) + 0.1 * cos(0.3), 0.05 + 0.03};
    CHECK_NEAR(stf_fluid_collider_distance(f, box, corner), 0.03, 1e-12, "box edge");

    c.shape = STF_SHAPE_CAPSULE, c.radius = 0.05, c.half_length = 0.1;
    int cap = add(f, c);
    stf_fluid_set_collider_state(f, cap, (double[3]){0, 0, 0}, NULL, v0, v0);
    CHECK_NEAR(stf_fluid_collider_distance(f, cap, (double[3]){0, 0, 0.2}), 0.05, 1e-12, "capsule tip");
    CHECK_NEAR(stf_fluid_collider_distance(f, cap, (double[3]){0.02, 0, 0.05}), -0.03, 1e-12, "capsule side");

    c.shape = STF_SHAPE_CYLINDER;
    int cyl = add(f, c);
    stf_fluid_set_collider_state(f, cyl, (double[3]){0, 0, 0}, NULL, v0, v0);
    CHECK_NEAR(stf_fluid_collider_distance(f, cyl, (double[3]){0, 0, 0.13}), 0.03, 1e-12, "cylinder cap");
    CHECK_NEAR(stf_fluid_collider_distance(f, cyl, (double[3]){0.08, 0.0, 0.13}), sqrt(0.03 * 0.03 * 2), 1e-12, "cylinder rim");

    c.shape = STF_SHAPE_PLANE, c.normal[0] = 0, c.normal[1] = 0, c.normal[2] = 2, c.offset = 0.1;
    int plane = add(f, c);
    CHECK_NEAR(stf_fluid_collider_distance(f, plane, (double[3]){5, 5, 0.25}), 0.15, 1e-12, "plane");

    c.shape = STF_SHAPE_CONTAINER, c.half[0] = 0.2, c.half[1] = 0.1, c.half[2] = 0.15, c.wall = 0.02;
    int box_in = add(f, c);
    CHECK_NEAR(stf_fluid_collider_distance(f, box_in, (double[3]){0.15, 0, 0.1}), 0.05, 1e-12, "container wall");
    CHECK_NEAR(stf_fluid_collider_distance(f, box_in, (double[3]){0, 0, 0.02}), 0.02, 1e-12, "container floor");
    CHECK_NEAR(stf_fluid_collider_distance(f, box_in, (double[3]){0.21, 0, 0.1}), -0.01, 1e-12, "in the wall");
    CHECK(stf_fluid_collider_distance(f, box_in, (double[3]){0.5, 0, 0.1}) > 0.1, "outside is free");
    stf_fluid_destroy(f);
}

/* The convex hull of a box's corners (libccd GJK+EPA) gives the box's penetration depth, and
 * its distance outside. */
static void test_convex(void)
{
    stf_fluid *f = fluid();
    const double hx = 0.2, hy = 0.1, hz = 0.05;
    double pts[24];
    for (int k = 0; k < 8; k++) {
        pts[3 * k] = (k & 1) ? hx : -hx;
        pts[3 * k + 1] = (k & 2) ? hy : -hy;
        pts[3 * k + 2] = (k & 4) ? hz : -hz;
    }
    stf_collider_def c = stf_default_collider_def();
    c.shape = STF_SHAPE_CONVEX, c.points = pts, c.npoints = 8;
    int hull = add(f, c);
    c.shape = STF_SHAPE_BOX, c.points = NULL, c.npoints = 0, c.half[0] = hx, c.half[1] = hy, c.half[2] = hz;
    int box = add(f, c);
    double R[9], v0[3] = {0, 0, 0}, pos[3] = {0.3, -0.2, 0.1};
    rot_z(0.7, R);
    stf_fluid_set_collider_state(f, hull, pos, R, v0, v0);
    stf_fluid_set_collider_state(f, box, pos, R, v0, v0);
    double worst = 0, worst_out = 0;
    unsigned s = 7;
    int nout = 0;
    for (int k = 0; k < 400; k++) {
        double x[3];
        for (int a = 0; a < 3; a++) {
            s = s * 1664525u + 1013904223u;
            x[a] = pos[a] + (k < 200 ? 0.18 : 0.6) * ((s >> 8) / 16777216.0 - 0.5);
        }
        double db = stf_fluid_collider_distance(f, box, x);
        double dh = stf_fluid_collider_distance(f, hull, x);
        if (db < 0) worst = fmax(worst, fabs(dh - db));
        /* outside: the distance too, within the reach of collisions and wall pressure (h),
           as for every other shape */
        else if (db < 0.05) worst_out = fmax(worst_out, fabs(dh - db)), nout++;
    }
    printf("convex vs box: worst depth difference %.3g m; outside (%d points within 5 cm) "
           "%.3g m\n", worst, nout, worst_out);
    CHECK(worst < 1e-6, "EPA depth differs from the box by %g m", worst);
    CHECK(nout > 20 && worst_out < 1e-9, "the hull's distance outside differs from the box's by %g m",
          worst_out);
    stf_fluid_destroy(f);
}

/* Particles that start inside a body are removed, and only those. */
static void test_remove_inside(void)
{
    stf_fluid *f = fluid();
    stf_fluid_add_block(f, (double[3]){-0.1, -0.1, -0.1}, (double[3]){0.1, 0.1, 0.1}, (double[3]){0, 0, 0});
    int n0 = stf_fluid_count(f);
    stf_collider_def c = stf_default_collider_def();
    c.shape = STF_SHAPE_SPHERE, c.radius = 0.05;
    int ball = add(f, c);
    stf_fluid_set_collider_state(f, ball, (double[3]){0, 0, 0}, NULL, NULL, NULL);
    int removed = stf_fluid_remove_inside(f, ball);
    int n = stf_fluid_count(f);
    double *x = malloc((size_t)n * 3 * sizeof *x);
    stf_fluid_get_positions(f, x);
    int inside = 0;
    for (int i = 0; i < n; i++) inside += stf_fluid_collider_distance(f, ball, x + 3 * i) < 0.005;
    /* the sphere's volume grown by half a spacing, in particles of 1 cm^3: about 697 */
    double expect = 4.0 / 3.0 * 3.14159265358979323846 * pow(0.055, 3) / 1e-6;
    printf("remove_inside: %d of %d removed (sphere + margin holds %.0f)\n", removed, n0, expect);
    CHECK(removed == n0 - n, "count mismatch");
    CHECK(inside == 0, "%d particles left inside the body", inside);
    CHECK(fabs(removed - expect) < 0.1 * expect, "removed %d, expected about %.0f", removed, expect);
    for (int k = 0; k < 20; k++) stf_fluid_step(f, 1e-3);
    stf_fluid_get_positions(f, x);
    double vmax = 0, *v = malloc((size_t)n * 3 * sizeof *v);
    stf_fluid_get_velocities(f, v);
    for (int i = 0; i < n; i++) vmax = fmax(vmax, sqrt(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]));
    printf("remove_inside: max speed after 20 steps %.3g m/s\n", vmax);
    CHECK(vmax < 0.5, "the fluid around the body exploded: %g m/s", vmax);
    free(x);
    free(v);
    stf_fluid_destroy(f);
}

/* One particle at rest exactly on a solid's surface (a face, an edge, a corner, or the floor
 * at z = 0, where -z is -0.0) stays finite and is pushed out to at least half a spacing: in
 * one step from a face, in three from a corner (one face per step). */
static void on_surface(const char *what, stf_collider_def c, const double x[3], double want_d,
                       int steps)
{
    stf_fluid *f = fluid();
    int id = add(f, c);
    stf_fluid_set_collider_state(f, id, (double[3]){0, 0, 0}, NULL, (double[3]){0, 0, 0},
                                 (double[3]){0, 0, 0});
    stf_fluid_add_particle(f, x, (double[3]){0, 0, 0});
    int rc = 0;
    for (int k = 0; k < steps && rc == 0; k++) rc = stf_fluid_step(f, 1e-3);
    CHECK(rc == 0, "%s: %s", what, stf_fluid_failure(f));
    double y[3];
    stf_fluid_get_positions(f, y);
    double d = stf_fluid_collider_distance(f, id, y);
    printf("on surface, %s: distance after %d step(s) %.3g m\n", what, steps, d);
    CHECK(isfinite(d) && d >= want_d - 1e-12 && d < 2 * want_d,
          "%s: distance %g after the step, want %g (or a bit more)", what, d, want_d);
    stf_fluid_destroy(f);
}

static void test_on_surface(void)
{
    const double rp = 0.005; /* half the spacing */
    stf_collider_def c = stf_default_collider_def();
    c.shape = STF_SHAPE_CONTAINER, c.half[0] = 0.05, c.half[1] = 0.05, c.half[2] = 0.1, c.wall = 0.02;
    on_surface("container wall", c, (double[3]){0.05, 0.01, 0.05}, rp, 1);
    on_surface("container floor", c, (double[3]){0.01, 0.02, 0}, rp, 1);
    on_surface("container corner", c, (double[3]){-0.05, 0.05, 0}, rp, 3);
}

/* A particle at rest exactly on a convex hull's surface (corner, face, edge) or at its centre
 * stays finite and is pushed out (EPA has no direction at depth 0). */
static void test_convex_on_surface(void)
{
    const double rp = 0.005;
    double pts[24];
    for (int k = 0; k < 8; k++) {
        pts[3 * k] = (k & 1) ? 0.05 : -0.05;
        pts[3 * k + 1] = (k & 2) ? 0.05 : -0.05;
        pts[3 * k + 2] = (k & 4) ? 0.05 : -0.05;
    }
    stf_collider_def h = stf_default_collider_def();
    h.shape = STF_SHAPE_CONVEX, h.points = pts, h.npoints = 8;
    /* a corner, a face, an edge and the centre: each ends out of the cube (not to half a
       spacing exactly: the hull reports penetration only, and the pressure's wall push of
       the same step may already have moved the particle out) */
    stf_fluid *f = fluid();
    int id = add(f, h);
    stf_fluid_set_collider_state(f, id, (double[3]){0, 0, 0}, NULL, (double[3]){0, 0, 0},
                                 (double[3]){0, 0, 0});
    const double at[4][3] = {{0.05, 0.05, 0.05}, {0.05, 0.01, 0.02}, {0.05, -0.05, 0.01}, {0, 0, 0}};
    for (int k = 0; k < 4; k++) stf_fluid_add_particle(f, at[k], (double[3]){0, 0, 0});
    int rc = stf_fluid_step(f, 1e-3);
    CHECK(rc == 0, "convex: %s", stf_fluid_failure(f));
    double y[12];
    stf_fluid_get_positions(f, y);
    for (int i = 0; i < 4; i++) {
        double o = 0; /* distance from the cube, exact */
        for (int a = 0; a < 3; a++) o += pow(fmax(fabs(y[3 * i + a]) - 0.05, 0), 2);
        o = sqrt(o);
        printf("on surface, convex, particle %d: %.3g m from the cube after one step\n", i, o);
        CHECK(isfinite(y[3 * i] + y[3 * i + 1] + y[3 * i + 2]) && o > 0.5 * rp, "convex: particle %d is %g m from the cube", i, o);
    }
    stf_fluid_destroy(f);
}

/* A 10 x 10 x 20 cm container with walls wall thick at the origin, added to f. */
static int add_container(stf_fluid *f, double wall)
{
    stf_collider_def c = stf_default_collider_def();
    c.shape = STF_SHAPE_CONTAINER, c.half[0] = 0.05, c.half[1] = 0.05, c.half[2] = 0.1, c.wall = wall;
    int id = add(f, c);
    stf_fluid_set_collider_state(f, id, (double[3]){0, 0, 0}, NULL, (double[3]){0, 0, 0},
                                 (double[3]){0, 0, 0});
    return id;
}

/* A fluid at 1 cm spacing (no jitter) with the given effects, in a container with 2 cm walls
 * (its collider id in *id). */
static stf_fluid *contained_fluid(unsigned effects, int *id)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.jitter = 0;
    d.effects = effects;
    d.spacing = 0.01;
    char err[256];
    stf_fluid *f;
    if (stf_fluid_create(&d, &f, err, sizeof err)) exit(1);
    *id = add_container(f, 0.02);
    return f;
}

/* A wall's rim is solid too: a particle falling on the top of a 2 cm container wall rests
 * on it (half a spacing above), it is not moved sideways into the container. */
static void test_rim(void)
{
    int id;
    stf_fluid *f = contained_fluid(STF_EFFECT_PRESSURE | STF_EFFECT_GRAVITY, &id);
    CHECK_NEAR(stf_fluid_collider_distance(f, id, (double[3]){0.06, 0, 0.203}), 0.003, 1e-12, "over the rim");
    CHECK_NEAR(stf_fluid_collider_distance(f, id, (double[3]){0.06, 0, 0.199}), -0.001, 1e-12, "in the rim");
    stf_fluid_add_particle(f, (double[3]){0.06, 0, 0.206}, (double[3]){0, 0, -0.5});
    for (int k = 0; k < 60; k++) CHECK(stf_fluid_step(f, 1e-3) == 0, "%s", stf_fluid_failure(f));
    double y[3];
    stf_fluid_get_positions(f, y);
    printf("rim: the particle dropped on the wall's top is at (%.4f, %.4f, %.4f) m after 60 ms "
           "(rim: x 0.05..0.07, top 0.2)\n", y[0], y[1], y[2]);
    CHECK(fabs(y[0] - 0.06) < 1e-3 && fabs(y[2] - 0.205) < 1e-3,
          "the particle left the rim for (%g, %g, %g)", y[0], y[1], y[2]);
    stf_fluid_destroy(f);
}

/* A container's walls and floor are solid from outside too: distances beside and under it,
 * a point in a wall nearer its outer face leaves outwards, and a particle thrown at an outer
 * face from outside bounces off it. Before, outside was free up to the wall and a particle
 * inside a wall always went back into the container: the splash got in through the wall. */
static void test_outer_faces(void)
{
    int id;
    stf_fluid *f = contained_fluid(STF_EFFECT_PRESSURE, &id);
    CHECK_NEAR(stf_fluid_collider_distance(f, id, (double[3]){0.08, 0, 0.05}), 0.01, 1e-12, "beside a wall");
    CHECK_NEAR(stf_fluid_collider_distance(f, id, (double[3]){0.08, 0.09, 0.05}), sqrt(0.0005), 1e-12,
               "beside an outer edge");
    CHECK_NEAR(stf_fluid_collider_distance(f, id, (double[3]){0, 0, -0.03}), 0.01, 1e-12, "under the floor");
    CHECK_NEAR(stf_fluid_collider_distance(f, id, (double[3]){0.065, 0, 0.05}), -0.005, 1e-12,
               "in a wall, nearer its outer face");
    CHECK_NEAR(stf_fluid_collider_distance(f, id, (double[3]){0.055, 0, 0.05}), -0.005, 1e-12,
               "in a wall, nearer its inner face");
    stf_fluid_add_particle(f, (double[3]){0.09, 0, 0.05}, (double[3]){-1, 0, 0});
    for (int k = 0; k < 50; k++) CHECK(stf_fluid_step(f, 1e-3) == 0, "%s", stf_fluid_failure(f));
    double y[3];
    stf_fluid_get_positions(f, y);
    printf("outer faces: a particle thrown at a wall from outside is at x = %.4f m after 50 ms "
           "(the wall: 0.05..0.07)\n", y[0]);
    CHECK(y[0] >= 0.07, "the particle got into the wall or through it: x = %g", y[0]);
    /* a wall thinner than a spacing stays one-way: outside free, inside it back in */
    int thin = add_container(f, 0.005);
    CHECK(stf_fluid_collider_distance(f, thin, (double[3]){0.06, 0, 0.05}) > 1, "beside a thin wall");
    CHECK_NEAR(stf_fluid_collider_distance(f, thin, (double[3]){0.054, 0, 0.05}), -0.004, 1e-12,
               "in a thin wall, nearer its outer face");
    stf_fluid_destroy(f);
}

/* stf_collider_volumes against the exact volumes of a sphere, a box and a capsule and of
 * the bands a spacing wide about them (the shell between the surface and its offset by b:
 * a sphere's 4/3 pi ((R+b)^3 - R^3); a box's faces, quarter cylinders on its edges and
 * eighth balls on its corners; a capsule's cylinder and ball shells), within 1%. */
static void test_volumes(void)
{
    const double pi = acos(-1.0), b = 0.01;
    stf_collider_def c = stf_default_collider_def();
    struct {
        const char *what;
        int shape;
        double r, hl, hx, hy, hz, vol, band;
    } cases[3] = {
        {"sphere", STF_SHAPE_SPHERE, 0.015, 0, 0, 0, 0, 0, 0},
        {"box", STF_SHAPE_BOX, 0, 0, 0.03, 0.02, 0.01, 0, 0},
        {"capsule", STF_SHAPE_CAPSULE, 0.01, 0.02, 0, 0, 0, 0, 0},
    };
    double R = cases[0].r;
    cases[0].vol = 4 * pi / 3 * R * R * R;
    cases[0].band = 4 * pi / 3 * (pow(R + b, 3) - R * R * R);
    double x = 2 * cases[1].hx, y = 2 * cases[1].hy, z = 2 * cases[1].hz;
    cases[1].vol = x * y * z;
    cases[1].band = 2 * b * (x * y + y * z + z * x) + pi * b * b * (x + y + z) + 4 * pi / 3 * b * b * b;
    double r = cases[2].r, L = 2 * cases[2].hl;
    cases[2].vol = pi * r * r * L + 4 * pi / 3 * r * r * r;
    cases[2].band = pi * ((r + b) * (r + b) - r * r) * L + 4 * pi / 3 * (pow(r + b, 3) - r * r * r);
    for (int k = 0; k < 3; k++) {
        c.shape = cases[k].shape, c.radius = cases[k].r, c.half_length = cases[k].hl;
        c.half[0] = cases[k].hx, c.half[1] = cases[k].hy, c.half[2] = cases[k].hz;
        double vol, band;
        CHECK(stf_collider_volumes(&c, b, &vol, &band) == 0, "%s: volumes", cases[k].what);
        CHECK(fabs(vol / cases[k].vol - 1) < 0.01 && fabs(band / cases[k].band - 1) < 0.01,
              "%s: volume %g (exact %g), band %g (exact %g)", cases[k].what, vol, cases[k].vol,
              band, cases[k].band);
        printf("volumes: %s %+.2f%%, its band %+.2f%%\n", cases[k].what, 100 * (vol / cases[k].vol - 1),
               100 * (band / cases[k].band - 1));
    }
    c.shape = STF_SHAPE_PLANE;
    double vol, band;
    CHECK(stf_collider_volumes(&c, b, &vol, &band) != 0, "a plane has no volume");
}

int main(void)
{
    test_volumes();
    test_shapes();
    test_on_surface();
    test_rim();
    test_outer_faces();
    test_convex_on_surface();
    test_convex();
    test_remove_inside();
    return test_result("test_colliders");
}
