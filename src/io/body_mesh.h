/* body_mesh.h - internal: a triangle surface of a body's shape, for viewers (the XDMF
 * sidecar of a run's output, which ParaView draws; see h5io.h). */
#ifndef STF_BODY_MESH_H
#define STF_BODY_MESH_H

#include <stdint.h>

#include "stf.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct stf_mesh {
    double *v;  /* 3*nv vertex coordinates in the body frame, m */
    int nv;
    int32_t *t; /* 3*nt vertex indices, counter-clockwise seen from outside */
    int nt;
} stf_mesh;

/* Convex hulls of more points than this get no mesh (the hull is found by brute force). */
enum { STF_MESH_HULL_MAX = 64 };

/* The closed surface of a sphere, box, capsule, cylinder (rings of 32 vertices) or convex
 * hull in *m. Returns 0; 1 for a shape without one (plane, container, a flat or too large
 * convex point set: *m is empty); -1 when out of memory. */
int stf_mesh_build(const stf_collider_def *def, stf_mesh *m);
void stf_mesh_free(stf_mesh *m);

/* out (3*nv) = the vertices placed at pos with orientation quat (w, x, y, z, unit). */
/* The rotation (3x3, row-major, body -> world) of a unit quaternion (w, x, y, z). */
void stf_quat_matrix(const double quat[4], double R[9]);
void stf_mesh_place(const stf_mesh *m, const double pos[3], const double quat[4], float *out);

#ifdef __cplusplus
}
#endif
#endif
