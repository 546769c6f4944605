/* collider.h - solids the particles collide with: analytic signed distances, libccd (GJK + EPA)
 * for convex hulls. Each collider sums the impulses it gives the fluid, so ode_glue can hand
 * the reaction to its rigid body. */
#ifndef STF_COLLIDER_H
#define STF_COLLIDER_H

#include "stf.h"

typedef struct collider {
    stf_collider_def def;
    double *points;   /* convex: own copy of the hull points (body frame) */
    double pos[3];    /* m, world */
    double rot[9];    /* body -> world, row-major */
    double vel[3];    /* m/s at pos */
    double angvel[3]; /* rad/s */
    double impulse[3];/* N s given to the collider during the last step */
    double part[STF_PARTS][3]; /* the impulse by the stage that gave it (STF_PART_...) */
    double moment[3]; /* N m s, about pos */
    double shift[3];  /* kg m: sum of m delta of the overlap removal (stf_fluid_collider_shift) */
    double bound;     /* m: radius of a sphere around pos holding the solid (<0: unbounded) */
    int two_sided;    /* container: its walls are solid from outside too (stf_wall_two_sided) */
} collider;

int stf_collider_init(collider *c, const stf_collider_def *def, char *err, size_t errlen);
void stf_collider_free(collider *c);
/* Near collider c, within margin (m) of its bounding sphere (every point of an unbounded
 * one)? A cheap test before the exact distance. */
static inline int stf_collider_near(const collider *c, const double x[3], double margin)
{
    if (c->bound < 0) return 1;
    double d[3] = {x[0] - c->pos[0], x[1] - c->pos[1], x[2] - c->pos[2]};
    double R = c->bound + margin;
    return d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= R * R;
}
/* Signed distance from x to the surface (m, > 0 outside the solid, may be a large positive
 * number when far) and the unit normal pointing out of the solid. */
double stf_collider_sdf(const collider *c, const double x[3], double n[3]);
/* A container's five inner faces (4 walls, floor) as planes: their signed distances from x
 * (m, > 0 inside) and inward unit normals. Returns 5, or 0 when c is not a container or x is
 * outside its shell. */
int stf_collider_container_faces(const collider *c, const double x[3], double d[5], double n[5][3]);
/* A box body's six face planes at x: signed distances d (positive outside) and outward
 * normals n (world); returns 6, or 0 when c is not a box. */
int stf_collider_box_faces(const collider *c, const double x[3], double d[6], double n[6][3]);
/* A direction (or an offset from pos) in the body frame, l, in world coordinates, w. */
static inline void stf_collider_world_dir(const collider *c, const double l[3], double w[3])
{
    const double *R = c->rot;
    for (int a = 0; a < 3; a++) w[a] = R[3 * a] * l[0] + R[3 * a + 1] * l[1] + R[3 * a + 2] * l[2];
}
/* Velocity of the collider's material at world point x. */
void stf_collider_velocity_at(const collider *c, const double x[3], double v[3]);
/* Adds the per-particle impulses imp (3n, N s, on the particles at positions x) to the
 * collider as their reaction, in particle order so the sum does not depend on threads.
 * x is where the impulse changes the particle's angular momentum: its position for a
 * velocity change, its position at the step's start (xprev) for a position change D in the
 * predict-relax stages (the step ends at x = xprev + dt v, so m x × v moves by
 * xprev × m D / dt). */
void stf_collider_take_reaction(collider *c, const double *imp, const double *x, const char *hit,
                            int n, int part);

#endif
