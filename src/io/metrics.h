/* metrics.h - the run metrics (`stf report`, `expect:` blocks), computed from an output file.
 *
 * Definitions (the one place they live):
 * - surface_height: top of the fluid at t = 0: the highest particle centre + spacing/2.
 * Body metrics, for a body of radius R (a sphere's radius; the half height for other shapes,
 * "body.NAME.half_height"), with S = surface_height and depth(t) = S - the body's lowest point
 * (centre z - its reach below the centre: with a "body.NAME.shape" attribute the shape's
 * support along -z at the sample's orientation, so a box or a cylinder lying on its side
 * counts from its true underside; else R). A body "on the surface" has depth <= R/2: at most
 * a quarter of a sphere's diameter in the fluid. A sample whose centre is beside the fluid (its
 * x or y outside the fluid's extent at t = 0, half a spacing past the outermost particles) has
 * no depth: it is not in contact, on the surface, at rest on it or sunk (a ball on the floor
 * beside a pool is none of these).
 * - first_contact_time: the first sample with depth > 0.
 * - penetration_depth: the largest depth within STF_PENETRATION_WINDOW (0.5 s) of contact.
 * - bounce: after contact, the centre rises by at least bounce_min_rise from a local minimum
 *   and the body is on the surface (depth <= R/2) at the peak of that rise;
 *   max_rebound_height is the largest such rise (local minimum to the next peak). A heave of a
 *   body that stays deep in the fluid, or a sunk body lifted by the slosh, is no bounce.
 * - roll_distance: horizontal path length after contact over the samples where the body is
 *   on the surface (both ends of a sample interval at depth <= R/2).
 * - rolling_ratio: the mean of |omega_h| R / |v_h| over that path, weighted by path length,
 *   over the intervals where |v_h| > STF_REST_SPEED (omega_h, v_h: the horizontal parts of
 *   the angular and linear velocity): 1 for rolling without slip, 0 for sliding; NAN when the
 *   body never moves faster than that on the surface.
 * - rest_on_surface: the longest time span after contact over which the body's speed stays
 *   below STF_REST_SPEED (0.05 m/s) and its depth <= R (from the span's first sample to the
 *   first sample that breaks it, or the run's end); rest_time: when that span starts (NAN and
 *   rest_on_surface 0 if never).
 * - sink_time: the first time, from the start of that rest on (from contact when it never
 *   rests), that the body's top (centre z + its reach above the centre) is below S;
 *   float_duration = sink_time - first_contact_time.
 * These replace the loose definitions of earlier versions (contact within a spacing of the
 * surface, a "bounce" of a body deep under, roll counted while the centre was above S, rest
 * at any depth), which let a plunging ball pass as bouncing, rolling and resting.
 * - fluid.com_rebound_height: the largest rise of the fluid's centre of mass above any
 *   earlier height of it (a dropped blob's rebound; 0 if it never rises).
 * - fluid.splash_height: the same rise for the fluid's top, the 99th percentile of the
 *   particle heights per frame (so a few flying droplets do not count): how far the top of
 *   the fluid climbs again after it has come down (a splash, a crown, a jet; 0 if it only
 *   comes down or settles).
 * - fluid.finger_height: the fluid's surface as columns (cells of 2 spacings in x, y; a
 *   column's height is its highest particle; with a container, only the particles that
 *   have not escaped it). Only the fluid body counts: particles joined to each other by
 *   chains of neighbours closer than STF_LINK_SPACINGS spacings form a connected piece, and
 *   the pieces holding at least a tenth of the particles (and always the largest) are the
 *   body; drops and spray flying free of it (a gap of half a spacing between spheres one
 *   spacing wide, visible in `stf render`) are splash, not fingers, which stand on the
 *   surface. Per frame, the 95th percentile of the column
 *   heights minus their median: how far the tallest 5% of the surface (fingers, clusters)
 *   stands above the typical surface; a single splashed particle does not count. Averaged
 *   over the frames of the second half of the run (the driven steady state).
 *   surface_roughness: standard deviation of the same column heights in the last frame.
 * - fluid.final_com_height: height of the fluid's centre of mass in the last frame.
 * - fluid.impact_time: the first frame at which the speed of the fluid's centre of mass is
 *   lower than at the frame before (a falling blob has hit something); NAN if never.
 * - fluid.solid_duration: time from impact_time until the fluid's radius of gyration (RMS
 *   distance of the particles from their centre of mass) first exceeds 1.5 times its value
 *   at t = 0: how long a dropped blob keeps its shape before it spreads as a liquid. If it
 *   never spreads that far, time_end - impact_time (a lower bound); NAN without an impact.
 * - fluid.density_error_max: how far the pool's mean density strays from the material's:
 *   in each frame, the bulk (particles in the container shrunk by Rc = 3 spacings, at least Rc
 *   under the median surface column and Rc clear of every body's half height) is sampled at
 *   each of its particles by the number density sum_j (1 - r_j^2/Rc^2)^2 over the particles
 *   within Rc (itself included) divided by the weight's integral 32 pi Rc^3 / 105, times the
 *   spacing^3: the density over the material's (the particle mass is density * spacing^3).
 *   A smooth weight reads a lattice and a liquid at the same number density alike (a plain
 *   count within Rc would read the initial lattice 9% dense); the model's own kernel density,
 *   which a solver holds at rest, may hide a denser packing, this does not.
 *   density_error_max: |mean - 1|, largest over the frames after the first;
 *   density_error_local: the largest over those frames of the 95th percentile of |sample - 1|
 *   (about 110 particles in Rc: a bound on local compression, not exact);
 *   density_error_first: mean - 1 on the first frame (the estimator's error on the lattice).
 * - fluid.escaped: particles of the last frame outside the container's inner box (grown by
 *   one spacing; the open top is not a wall up to twice the container height). */
#ifndef STF_METRICS_H
#define STF_METRICS_H

#include <stddef.h>

#define STF_METRICS_MAX_BODIES 16
#define STF_REST_SPEED 0.05 /* m/s: a body slower than this rests; rolling_ratio counts faster */
#define STF_PENETRATION_WINDOW 0.5 /* s after contact over which penetration_depth is taken */
#define STF_LINK_SPACINGS 1.5 /* spacings: neighbours closer than this are connected (finger_height) */

typedef struct stf_body_metrics {
    char name[64];
    double radius;             /* m: R of the definitions above */
    double first_contact_time; /* s, NAN if never */
    double penetration_depth;  /* m, NAN if never in contact (an upper bound on it then fails) */
    int bounces;
    double max_rebound_height; /* m */
    double roll_distance;      /* m */
    double rolling_ratio;      /* 1, NAN if it never moved on the surface */
    double rest_on_surface;    /* s, 0 if it never rested on the surface */
    double rest_time;          /* s, start of that rest, NAN if never */
    double sink_time;          /* s, NAN if never */
    double float_duration;     /* s, NAN if it never touched or never sank */
    double final_position[3];  /* m */
} stf_body_metrics;

typedef struct stf_metrics {
    double time_end;       /* s */
    double surface_height; /* m */
    int nbodies;
    stf_body_metrics bodies[STF_METRICS_MAX_BODIES];
    long particles;
    long escaped;
    double max_speed;          /* m/s, the largest particle speed in the saved frames */
    int nan;
    double com_rebound_height; /* m */
    double finger_height;      /* m */
    double surface_roughness;  /* m */
    double final_com_height;   /* m */
    double impact_time;        /* s, NAN if never */
    double solid_duration;     /* s, NAN without an impact */
    double splash_height;      /* m */
    double density_error_max;  /* 1, NAN without a container or a bulk to sample */
    double density_error_local;/* 1, NAN likewise */
    double density_error_first;/* 1: the same estimate on the first frame (the estimator's own
                                  error on the initial lattice), NAN likewise */
} stf_metrics;

/* The metric names an expect block may use, NULL-terminated: a body's (after "NAME." or
 * alone for the first body) and the fluid's (after "fluid."). */
extern const char *const stf_body_metric_names[];
extern const char *const stf_fluid_metric_names[];

/* Computes the metrics of the run in path. Returns 0, or 2 with a message (bad file). */
int stf_metrics_compute(const char *path, stf_metrics *m, char *err, size_t errlen);
/* The metrics as a JSON object (malloc'ed): {"time_end", "surface_height", "bodies": {NAME:
 * {"radius", ... body metrics ..., "final_position": [x, y, z]}}, "fluid": {"particles",
 * "escaped", "max_speed", "nan", ... fluid metrics ...}}; a metric that never happened is null. */
char *stf_metrics_json(const stf_metrics *m);
/* Looks up a metric by expectation key ("bounces", "ball.sink_time", "fluid.escaped",
 * "time_end"). Returns 0 and the value (NAN for null), or -1 if the key names nothing. */
int stf_metrics_get(const stf_metrics *m, const char *key, double *value);

#endif
