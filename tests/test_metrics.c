/* test_metrics.c - the fluid metrics of src/io/metrics.h on output files whose answer is known
 * by construction (written with the real HDF5 writer, read back by stf_metrics_compute):
 * finger_height is the 95th percentile of the column heights of the fluid body over their
 * median (drops flying free of the body do not count), impact_time is the first drop in centre-of-mass speed,
 * solid_duration runs from it until the radius of gyration passes 1.5x its start,
 * com_rebound_height and final_com_height follow the centre of mass, splash_height the
 * fluid's top (99th percentile of the heights). */
#define _POSIX_C_SOURCE 200809L
#include "h5io.h"
#include "metrics.h"
#include "test_util.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

enum { NC = 10, NPART = NC * NC }; /* a 10 x 10 grid of columns, one particle each */

static const double S = 0.01; /* spacing, m: the columns are 2 spacings wide */

/* A connected layer: a 20 x 20 lattice at one spacing (10 x 10 columns of 2 x 2 particles) at
 * z = 0.05 m. With fingers, 9 columns carry a stack of 4 particles, one spacing apart, up
 * to 0.09 m. Then `drops` particles fly free at 0.5 m over as many other columns (a gap of
 * 0.41 m: splash). Returns the particle count. */
enum { LAYER = 400, MAXP = LAYER + 9 * 4 + 20 };
static int surface(int fingers, int drops, double *x)
{
    int n = 0;
    for (int i = 0; i < LAYER; i++, n++) {
        x[3 * n] = (i % 20 + 0.5) * S;
        x[3 * n + 1] = (i / 20 + 0.5) * S;
        x[3 * n + 2] = 0.05;
    }
    for (int c = 90; fingers && c < 99; c++) /* column c: lattice cells 2 (c % 10), 2 (c / 10) */
        for (int k = 1; k <= 4; k++, n++) {
            x[3 * n] = (2 * (c % NC) + 0.5) * S;
            x[3 * n + 1] = (2 * (c / NC) + 0.5) * S;
            x[3 * n + 2] = 0.05 + k * S;
        }
    for (int c = 0; c < drops; c++, n++) {
        x[3 * n] = (2 * (c % NC) + 0.5) * S;
        x[3 * n + 1] = (2 * (c / NC) + 0.5) * S;
        x[3 * n + 2] = 0.5;
    }
    return n;
}

/* A new output file with the lattice spacing S (NULL, reported, when it cannot be made). */
static stf_h5 *new_file(const char *path)
{
    char err[512];
    stf_h5 *h = NULL;
    CHECK(stf_h5_create(path, &h, err, sizeof err) == 0, "create: %s", err);
    if (h) stf_h5_attr_double(h, "spacing", S);
    return h;
}

/* Closes the file and reads its metrics back into m. */
static void close_and_measure(stf_h5 *h, const char *path, stf_metrics *m)
{
    char err[512];
    CHECK(stf_h5_close(h, err, sizeof err) == 0, "close: %s", err);
    CHECK(stf_metrics_compute(path, m, err, sizeof err) == 0, "metrics: %s", err);
}

/* Four frames: 0-1 flat, 2-3 with fingers (the second half, which counts) and drops. */
static void finger_run(const char *path, int drops, stf_metrics *m)
{
    stf_h5 *h = new_file(path);
    if (!h) return;
    static double x[3 * MAXP], v[3 * MAXP];
    for (int f = 0; f < 4; f++) {
        int n = surface(f >= 2, f >= 2 ? drops : 0, x);
        CHECK(stf_h5_write_frame(h, 0.1 * f, n, x, v, NULL, NULL) == 0, "frame %d", f);
    }
    close_and_measure(h, path, m);
}

static void test_finger_height(const char *path)
{
    stf_metrics m;
    /* sorted column heights: 91 at 0.05, 9 at 0.09; the 95th percentile is rank 94.05,
     * between two 0.09 columns; the median 0.05 */
    finger_run(path, 1, &m);
    CHECK_NEAR(m.finger_height, 0.04, 1e-6, "finger_height");
    CHECK(m.impact_time != m.impact_time, "no impact in a still layer: %g", m.impact_time);
    /* 20 drops over 20 columns (more than the top 5%): counted as columns, they would make
     * the 95th percentile 0.5 m; they are not part of the fluid body, so the fingers remain */
    finger_run(path, 20, &m);
    CHECK_NEAR(m.finger_height, 0.04, 1e-6, "finger_height with 20 drops of splash");
}

/* A ball of 100 points: centre of mass at com, radius scaled by scale, all moving at vz. */
static void ball(double com, double scale, double vz, double *x, double *v)
{
    for (int i = 0; i < NPART; i++) {
        double a = 2.399963 * i, z = 1.0 - 2.0 * (i + 0.5) / NPART, r = sqrt(1 - z * z);
        double p[3] = {r * cos(a), r * sin(a), z};
        for (int c = 0; c < 3; c++) {
            x[3 * i + c] = 0.05 * scale * p[c] + (c == 2 ? com : 0);
            v[3 * i + c] = c == 2 ? vz : 0;
        }
    }
}

static void test_drop(const char *path)
{
    /* t = 0 .. 0.7 s: falls faster until 0.2 s, hits (speed drops at 0.3 s), rebounds to
     * 0.5 m, spreads: 1.0, 1.0, 1.0, 1.0, 1.2, 1.4, 1.6, 1.8 times its radius */
    static const double com[] = {1.0, 0.9, 0.7, 0.4, 0.5, 0.45, 0.42, 0.41};
    static const double vz[] = {-0.5, -1.5, -2.5, -0.5, 0.4, -0.2, -0.1, 0.0};
    static const double scale[] = {1.0, 1.0, 1.0, 1.0, 1.2, 1.4, 1.6, 1.8};
    stf_h5 *h = new_file(path);
    if (!h) return;
    double x[3 * NPART], v[3 * NPART];
    for (int f = 0; f < 8; f++) {
        ball(com[f], scale[f], vz[f], x, v);
        CHECK(stf_h5_write_frame(h, 0.1 * f, NPART, x, v, NULL, NULL) == 0, "frame %d", f);
    }
    stf_metrics m;
    close_and_measure(h, path, &m);
    CHECK_NEAR(m.impact_time, 0.3, 1e-12, "impact_time");
    CHECK_NEAR(m.solid_duration, 0.3, 1e-12, "solid_duration (1.6 > 1.5 at 0.6 s)");
    CHECK_NEAR(m.com_rebound_height, 0.1, 1e-6, "com_rebound_height");
    CHECK_NEAR(m.final_com_height, 0.41, 1e-6, "final_com_height");
    /* the top (99th percentile of z: 0.9702 of the radius above the centre, ranks of the
     * 100 points' z = 0.99 - 0.02 k) comes down to 0.4 + 0.05 * 0.9702 at 0.3 s and rises to
     * 0.5 + 0.06 * 0.9702 at 0.4 s */
    CHECK_NEAR(m.splash_height, 0.1 + 0.01 * 0.9702, 1e-6, "splash_height");
    double got;
    CHECK(stf_metrics_get(&m, "fluid.splash_height", &got) == 0 && got == m.splash_height,
          "expect key fluid.splash_height");
    CHECK(stf_metrics_get(&m, "fluid.solid_duration", &got) == 0 && got == m.solid_duration,
          "expect key fluid.solid_duration");
    CHECK(stf_metrics_get(&m, "fluid.impact_time", &got) == 0, "expect key fluid.impact_time");
    CHECK(stf_metrics_get(&m, "fluid.final_com_height", &got) == 0, "key final_com_height");
}

/* A file over the flat layer of surface(0, 0) (its one frame at t = 0) for a body NAME of the
 * given half height; min_rise > 0 sets bounce_min_rise. NULL when the file cannot be made. */
static stf_h5 *body_over_layer(const char *path, const char *name, double half_height,
                               double min_rise)
{
    stf_h5 *h = new_file(path);
    if (!h) return NULL;
    char key[64];
    snprintf(key, sizeof key, "body.%s.half_height", name);
    if (min_rise > 0) stf_h5_attr_double(h, "bounce_min_rise", min_rise);
    stf_h5_attr_double(h, key, half_height);
    static double x[3 * MAXP], v[3 * MAXP];
    int n = surface(0, 0, x);
    CHECK(stf_h5_write_frame(h, 0.0, n, x, v, NULL, NULL) == 0, "frame");
    return h;
}

/* A piecewise-linear path sampled every 10 ms: phase k runs from t[k] with velocity v[k]
 * (and angular velocity w[k]); position and velocity of sample t (the velocity of the interval
 * ending at t, so sums over intervals see the phase that made them). */
typedef struct path_phase {
    double t, v[3], w[3];
} path_phase;

static void write_path(stf_h5 *h, const char *name, const double x0[3], const path_phase *ph,
                       int nph, double t_end)
{
    const double q[4] = {1, 0, 0, 0}, f[3] = {0};
    for (int i = 0; i * 0.01 <= t_end + 1e-9; i++) {
        double t = i * 0.01, pos[3] = {x0[0], x0[1], x0[2]};
        int k = 0; /* the phase of the interval ending at t */
        for (int j = 0; j < nph; j++)
            if (ph[j].t < t - 0.005) k = j;
        for (int j = 0; j < nph; j++) { /* integrate the phases up to t, exactly */
            double a = ph[j].t, b = j + 1 < nph ? ph[j + 1].t : 1e9;
            double dt = (t < b ? t : b) - a;
            if (dt > 0)
                for (int c = 0; c < 3; c++) pos[c] += ph[j].v[c] * dt;
        }
        CHECK(stf_h5_body_append(h, name, t, pos, q, ph[k].v, ph[k].w, f, NULL) == 0, "row %d", i);
    }
}

/* A ball of radius R = 0.1 m over a flat layer (surface S = 0.05 m + spacing/2 = 0.055 m; on
 * the surface while its centre is above S + R/2 = 0.105 m): it falls to contact, sinks in
 * 3.5 cm, bounces 3 cm, rolls 5 cm without slip and slides 5 cm, rests 1.5 s (the last 0.5 s
 * creeping down slower than 5 cm/s), then sinks. Every metric is known. */
static const path_phase BALL_PATH[8] = {
    {0.0, {0, 0, -1.5}, {0, 0, 0}},   /* z 0.3 -> 0.15: contact at the sample 0.10 */
    {0.1, {0, 0, -0.3}, {0, 0, 0}},   /* -> 0.12: depth 0.035 */
    {0.2, {0, 0, 0.3}, {0, 0, 0}},    /* -> 0.15: a bounce of 3 cm, its peak at depth 0.005 */
    {0.3, {0.5, 0, -0.05}, {0, 5, 0}},/* rolls 5 cm (omega R = v), to z = 0.145 */
    {0.4, {0.5, 0, -0.15}, {0, 0, 0}},/* slides 5 cm, to z = 0.13 */
    {0.5, {0, 0, 0}, {0, 0, 0}},      /* rests at depth 0.025 */
    {1.5, {0, 0, -0.04}, {0, 0, 0}},  /* creeps (slow: still resting) to z = 0.11 */
    {2.0, {0, 0, -0.2}, {0, 0, 0}},   /* sinks: top below S when z < -0.045, t > 2.775 */
};

/* BALL_PATH from x0 over the layer, measured into m; 0 when the file holds the one body. */
static int measure_ball_path(const char *path, const double x0[3], stf_metrics *m)
{
    stf_h5 *h = body_over_layer(path, "ball", 0.1, 0.01);
    if (!h) return -1;
    write_path(h, "ball", x0, BALL_PATH, 8, 3.0);
    close_and_measure(h, path, m);
    CHECK(m->nbodies == 1, "bodies %d", m->nbodies);
    return m->nbodies == 1 ? 0 : -1;
}

static void test_body(const char *path)
{
    const double x0[3] = {0.05, 0.1, 0.3}; /* over the layer (x, y in [0, 0.2] m) throughout */
    stf_metrics m;
    if (measure_ball_path(path, x0, &m) != 0) return;
    const stf_body_metrics *b = &m.bodies[0];
    CHECK_NEAR(b->radius, 0.1, 1e-12, "radius");
    CHECK_NEAR(b->first_contact_time, 0.10, 1e-9, "first_contact_time (depth > 0)");
    CHECK_NEAR(b->penetration_depth, 0.035, 1e-9, "penetration_depth");
    CHECK(b->bounces == 1, "bounces %d", b->bounces);
    CHECK_NEAR(b->max_rebound_height, 0.03, 1e-9, "max_rebound_height");
    CHECK_NEAR(b->roll_distance, 0.10, 1e-9, "roll_distance (on the surface)");
    CHECK_NEAR(b->rolling_ratio, 0.5, 1e-6, "rolling_ratio: half the path rolled, half slid");
    CHECK_NEAR(b->rest_time, 0.51, 1e-9, "rest_time");
    CHECK_NEAR(b->rest_on_surface, 1.5, 1e-9, "rest_on_surface (0.51 to 2.01)");
    CHECK_NEAR(b->sink_time, 2.78, 1e-9, "sink_time");
    CHECK_NEAR(b->float_duration, 2.68, 1e-9, "float_duration");
}

/* A plunge: the ball of test_body comes in at 1 m/s down and 1 m/s along x, goes 1.55 R deep,
 * heaves 2.5 cm while deep and sinks. The heave is no bounce, the path under the surface is no
 * roll, a slow moment deep in the fluid is no rest: under the loose definitions of earlier
 * versions this ball bounced and rolled. */
static void test_plunge(const char *path)
{
    stf_h5 *h = body_over_layer(path, "ball", 0.1, 0.01);
    if (!h) return;
    const path_phase ph[] = {
        {0.0, {1, 0, -1}, {0, 0, 0}},      /* z 0.2 -> 0.0 (depth 0.155); on the surface to z 0.105 */
        {0.2, {0, 0, 0.25}, {0, 0, 0}},    /* heaves to 0.025 (depth 0.13) */
        {0.3, {0, 0, -0.02}, {0, 0, 0}},   /* slow, 1 s, deep: depth 0.13 to 0.15 > R */
        {1.3, {0, 0, -0.3}, {0, 0, 0}},    /* sinks: top below S when z < -0.045, t > 1.4667 */
    };
    const double x0[3] = {-0.01, 0.1, 0.2}; /* over the layer from t = 0.01 s on */
    write_path(h, "ball", x0, ph, 4, 2.5);
    stf_metrics m;
    close_and_measure(h, path, &m);
    CHECK(m.nbodies == 1, "bodies %d", m.nbodies);
    if (m.nbodies != 1) return;
    const stf_body_metrics *b = &m.bodies[0];
    CHECK_NEAR(b->first_contact_time, 0.05, 1e-9, "first_contact_time of the plunge");
    CHECK(b->penetration_depth >= 1.5 * 0.1, "penetration_depth %g", b->penetration_depth);
    CHECK_NEAR(b->penetration_depth, 0.155, 1e-9, "penetration_depth (at t = 0.2)");
    CHECK(b->bounces == 0, "a heave 1.3 R deep is no bounce (bounces %d)", b->bounces);
    /* on the surface from contact (z 0.15) to z >= 0.105: the samples 0.05 .. 0.09 */
    CHECK_NEAR(b->roll_distance, 0.04, 1e-9, "roll_distance of the plunge: its first 4 cm only");
    CHECK_NEAR(b->rolling_ratio, 0.0, 1e-12, "rolling_ratio of a slide");
    CHECK(b->rest_on_surface == 0, "rest_on_surface %g deep in the fluid", b->rest_on_surface);
    CHECK(b->rest_time != b->rest_time, "rest_time %g", b->rest_time);
    CHECK_NEAR(b->sink_time, 1.47, 1e-9, "sink_time of the plunge");
}

/* The ball of test_body's path, moved 0.25 m along x: it falls, bounces, rolls, rests and goes
 * under the layer's height beside the layer (x from 0.3 to 0.4 m, the layer's extent is 0 to
 * 0.2 m): none of it is contact, a bounce, a roll, a rest on the surface or sinking. Then the
 * same path near the layer's edge (x0 = 0.157 m: it rolls from there at 0.3 s and leaves the
 * layer between the samples at 0.38 s, x = 0.197 m, and 0.39 s, x = 0.202 m): contact at
 * 0.10 s, the bounce, 4 cm of roll (the 8 intervals over the layer of the 10 rolled), and no
 * rest or sinking beside it. */
static void test_beside(const char *path)
{
    for (int k = 0; k < 2; k++) {
        const double x0[3] = {k ? 0.157 : 0.3, 0.1, 0.3};
        stf_metrics m;
        if (measure_ball_path(path, x0, &m) != 0) return;
        const stf_body_metrics *b = &m.bodies[0];
        if (k == 0) {
            CHECK(isnan(b->first_contact_time) && isnan(b->penetration_depth) && b->bounces == 0 &&
                      b->roll_distance == 0 && b->rest_on_surface == 0 && isnan(b->sink_time),
                  "a ball beside the layer: contact %g, penetration %g, bounces %d, roll %g, "
                  "rest %g, sink %g", b->first_contact_time, b->penetration_depth, b->bounces,
                  b->roll_distance, b->rest_on_surface, b->sink_time);
        } else {
            CHECK_NEAR(b->first_contact_time, 0.10, 1e-9, "first_contact_time over the edge");
            CHECK(b->bounces == 1, "bounces over the edge %d", b->bounces);
            CHECK_NEAR(b->roll_distance, 0.04, 1e-9, "roll_distance: over the layer only");
            CHECK(b->rest_on_surface == 0 && isnan(b->sink_time),
                  "rest %g, sink %g beside the layer", b->rest_on_surface, b->sink_time);
        }
    }
}

/* A body that touches and rises clearly (a bounce) in the run's last sample: the bounce is
 * counted, so its rise is the max_rebound_height (not 0 with bounces 1). */
static void test_bounce_at_end(const char *path)
{
    stf_h5 *h = body_over_layer(path, "ball", 0.1, 0.01);
    if (!h) return;
    const double q[4] = {1, 0, 0, 0}, w[3] = {0}, f[3] = {0}, zs[] = {0.16, 0.14, 0.12, 0.14};
    for (int i = 0; i < 4; i++) {
        double pos[3] = {0.1, 0.1, zs[i]}, vel[3] = {0, 0, 0};
        CHECK(stf_h5_body_append(h, "ball", 0.01 * i, pos, q, vel, w, f, NULL) == 0, "row %d", i);
    }
    stf_metrics m;
    close_and_measure(h, path, &m);
    CHECK(m.nbodies == 1 && m.bodies[0].bounces == 1, "bounces %d", m.bodies[0].bounces);
    CHECK_NEAR(m.bodies[0].max_rebound_height, 0.02, 1e-9, "max_rebound_height of a last-sample bounce");
}

/* A slab (box, half extents 0.03 x 0.005 x 0.005 m) turned 90 degrees about y: it stands
 * 0.03 m below and above its centre, not its local half height 0.005 m. It comes down at
 * 1 m/s from z = 0.202 over the surface at 0.055 m (samples every 5 ms): its underside is
 * below the surface at z < 0.085 (t > 0.117 s: the sample at 0.12 s), its top at z < 0.025
 * (t > 0.177 s: 0.18 s). */
static void test_turned_slab(const char *path)
{
    stf_h5 *h = body_over_layer(path, "slab", 0.005, 0);
    if (!h) return;
    stf_h5_attr_string(h, "body.slab.shape", "box 0.03 0.005 0.005");
    const double q[4] = {sqrt(0.5), 0, sqrt(0.5), 0}, w[3] = {0}, f[3] = {0};
    for (int i = 0; i <= 40; i++) {
        double t = 0.005 * i, pos[3] = {0.1, 0.1, 0.202 - t}, vel[3] = {0, 0, -1};
        CHECK(stf_h5_body_append(h, "slab", t, pos, q, vel, w, f, NULL) == 0, "row %d", i);
    }
    stf_metrics m;
    close_and_measure(h, path, &m);
    CHECK(m.nbodies == 1, "bodies %d", m.nbodies);
    if (m.nbodies != 1) return;
    CHECK_NEAR(m.bodies[0].first_contact_time, 0.12, 1e-9, "first_contact_time of the turned slab");
    CHECK_NEAR(m.bodies[0].sink_time, 0.18, 1e-9, "sink_time of the turned slab");
}

/* No fluid (every particle removed at setup, inside the body): surface_height is null, and
 * a body falling through the empty box never touches fluid nor rests on it. */
static void test_no_fluid(const char *path)
{
    stf_h5 *h = new_file(path);
    if (!h) return;
    stf_h5_attr_double(h, "body.ball.half_height", 0.05);
    double x[3] = {0}, v[3] = {0};
    CHECK(stf_h5_write_frame(h, 0.0, 0, x, v, NULL, NULL) == 0, "frame");
    const double q[4] = {1, 0, 0, 0}, w[3] = {0}, f[3] = {0};
    for (int i = 0; i < 4; i++) {
        double pos[3] = {0, 0, 0.1 - 0.0001 * i}, vel[3] = {0, 0, -0.01};
        CHECK(stf_h5_body_append(h, "ball", 0.01 * i, pos, q, vel, w, f, NULL) == 0, "row %d", i);
    }
    stf_metrics m;
    close_and_measure(h, path, &m);
    CHECK(m.surface_height != m.surface_height, "surface_height %g without fluid", m.surface_height);
    CHECK(m.nbodies == 1, "bodies %d", m.nbodies);
    if (m.nbodies != 1) return;
    CHECK(m.bodies[0].first_contact_time != m.bodies[0].first_contact_time,
          "first_contact_time %g without fluid", m.bodies[0].first_contact_time);
    CHECK(m.bodies[0].rest_time != m.bodies[0].rest_time, "rest_time %g without fluid",
          m.bodies[0].rest_time);
}

/* A run without a container where one particle has flown far (finite, 10^12 m away): the
 * surface columns would be 10^13 wide; the metrics stay finite and do not crash. */
static void test_far_particle(const char *path)
{
    stf_h5 *h = new_file(path);
    if (!h) return;
    static double x[3 * MAXP], v[3 * MAXP];
    int n = surface(0, 0, x);
    x[3 * (n - 1)] = 1e12;
    CHECK(stf_h5_write_frame(h, 0.0, n, x, v, NULL, NULL) == 0, "frame");
    stf_metrics m;
    close_and_measure(h, path, &m);
    CHECK(isfinite(m.finger_height) && m.finger_height >= 0, "finger_height %g", m.finger_height);
}

/* A body whose last row is not finite (a blown-up run): its final_position is JSON null, not
 * the invalid token nan. */
static void test_nan_body_json(const char *path)
{
    stf_h5 *h = body_over_layer(path, "ball", 0.05, 0);
    if (!h) return;
    const double q[4] = {1, 0, 0, 0}, w[3] = {0}, f[3] = {0};
    double pos[3] = {0, 0, NAN}, vel[3] = {0};
    CHECK(stf_h5_body_append(h, "ball", 0.0, pos, q, vel, w, f, NULL) == 0, "row");
    stf_metrics m;
    close_and_measure(h, path, &m);
    char *json = stf_metrics_json(&m);
    CHECK(json && !strstr(json, "nan]") && !strstr(json, "nan,"), "JSON with nan: %s", json ? json : "");
    free(json);
}

int main(void)
{
    char path[] = "/tmp/stf_test_metricsXXXXXX";
    int fd = mkstemp(path);
    if (fd < 0) return 1;
    close(fd);
    test_finger_height(path);
    test_drop(path);
    test_body(path);
    test_plunge(path);
    test_bounce_at_end(path);
    test_turned_slab(path);
    test_beside(path);
    test_no_fluid(path);
    test_far_particle(path);
    test_nan_body_json(path);
    unlink(path);
    char xmf[sizeof path + 8];
    snprintf(xmf, sizeof xmf, "%s.xmf", path);
    unlink(xmf);
    return test_result("test_metrics");
}
