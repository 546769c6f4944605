/* metrics.h - the run metrics of DESIGN.md, computed from an output file.
 *
 * Definitions (the one place they live):
 * - surface_height: top of the fluid at t = 0: the highest particle centre + spacing/2.
 * - contact: a body's lowest point (centre z - half_height; with a "body.NAME.shape"
 *   attribute, the shape's reach below its centre at the sample's orientation, so a box
 *   or a cylinder lying on its side counts from its true underside) is within one spacing of
 *   surface_height. first_contact_time is the first body sample in contact.
 * - bounce: after first contact and before sink_time, the centre rises by at least
 *   bounce_min_rise above a local minimum; max_rebound_height is the largest such rise (local
 *   minimum to the next peak). A body that has sunk and is lifted by the fluid sloshing back
 *   off the floor does not bounce.
 * - roll_distance: horizontal path length after first contact while the centre is above
 *   surface_height.
 * - sink_time: first time the body's top (centre z + half_height, or the oriented reach
 *   above the centre as for contact) is below surface_height;
 *   float_duration = sink_time - first_contact_time.
 * - rest_time: the first time after first contact from which the body's speed stays below
 *   STF_REST_SPEED (0.05 m/s) until it sinks or the run ends (NAN if never);
 *   rest_duration = (sink_time, or the end of the run) - rest_time: how long it rests on
 *   the surface before it sinks.
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
 * - fluid.escaped: particles of the last frame outside the container's inner box (grown by
 *   one spacing; the open top is not a wall up to twice the container height). */
#ifndef STF_METRICS_H
#define STF_METRICS_H

#include <stddef.h>

#define STF_METRICS_MAX_BODIES 16
#define STF_REST_SPEED 0.05 /* m/s: a body slower than this rests (rest_time) */
#define STF_LINK_SPACINGS 1.5 /* spacings: neighbours closer than this are connected (finger_height) */

typedef struct stf_body_metrics {
    char name[64];
    double first_contact_time; /* s, NAN if never */
    int bounces;
    double max_rebound_height; /* m */
    double roll_distance;      /* m */
    double sink_time;          /* s, NAN if never */
    double float_duration;     /* s, NAN if it never touched or never sank */
    double rest_time;          /* s, NAN if it never came to rest above the surface */
    double rest_duration;      /* s, NAN if it never came to rest above the surface */
    double final_position[3];  /* m */
} stf_body_metrics;

typedef struct stf_metrics {
    double time_end;       /* s */
    double surface_height; /* m */
    int nbodies;
    stf_body_metrics bodies[STF_METRICS_MAX_BODIES];
    long particles;
    long escaped;
    double max_speed;          /* m/s */
    int nan;
    double com_rebound_height; /* m */
    double finger_height;      /* m */
    double surface_roughness;  /* m */
    double final_com_height;   /* m */
    double impact_time;        /* s, NAN if never */
    double solid_duration;     /* s, NAN without an impact */
    double splash_height;      /* m */
} stf_metrics;

/* Computes the metrics of the run in path. Returns 0, or 2 with a message (bad file). */
int stf_metrics_compute(const char *path, stf_metrics *m, char *err, size_t errlen);
/* The metrics as the JSON object of DESIGN.md (malloc'ed). */
char *stf_metrics_json(const stf_metrics *m);
/* Looks up a metric by expectation key ("bounces", "ball.sink_time", "fluid.escaped",
 * "time_end"). Returns 0 and the value (NAN for null), or -1 if the key names nothing. */
int stf_metrics_get(const stf_metrics *m, const char *key, double *value);

#endif
