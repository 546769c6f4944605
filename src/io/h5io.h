/* h5io.h - internal: the HDF5 output file of a run (H5Part layout) and its reader.
 *
 * Layout written by stf_h5_*:
 *   /                     root attributes (scene text, version, parameters, statistics)
 *   /Step#N               one group per frame, N = 0, 1, ... ; attribute TimeValue (double)
 *     x y z vx vy vz      float32[n]; optional khist float32[n], id int32[n]
 *   /bodies/NAME          extendible double series: time[N], position[N][3],
 *                         quaternion[N][4] (w x y z), velocity[N][3],
 *                         angular_velocity[N][3], fluid_force[N][3] (N, the mean
 *                         over the step before the row), fluid_force_parts[N][15]
 *                         (the same force by part: stf_h5_body_append)
 *   /metrics              string attribute "json"
 *   /checkpoint           while a run goes: its state for `stf run --resume` (see below)
 *   /body_meshes/NAME     for viewers, a body's surface (stf_h5_body_mesh): vertices
 *                         float64[V][3] in the body frame, triangles int32[T][3]
 *                         (counter-clockwise seen from outside), and Step#N float32[V][3],
 *                         the vertices in world coordinates at frame N
 * plus an XDMF sidecar OUT.xmf next to OUT.h5 for ParaView: a temporal collection of the
 * frames' particles ("particles", Polyvertex) and one per body with a mesh (its name,
 * Triangle), rewritten at every stf_h5_release and at stf_h5_close.
 *
 * The file is flushed after every frame and body row, so a killed run leaves a file that
 * stf_h5r_open can read up to the last complete frame.
 *
 * Readers while a run goes: the writer that calls stf_h5_release after each frame keeps the
 * file closed between frames, so other processes (h5py, ParaView) open it and see the
 * frames written so far. A reader that holds the file open while the writer wants to write
 * does not stop it: the writer waits a moment for it, then writes anyway (see h5io.c).
 */
#ifndef STF_H5IO_H
#define STF_H5IO_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- writer ---- */

typedef struct stf_h5 stf_h5;

/* Creates (truncates) path. Returns 0, or -1 with "PATH: why" in err. */
int stf_h5_create(const char *path, stf_h5 **out, char *err, size_t errlen);

/* Root attributes; an attribute of the same name is replaced. Return 0 or -1. */
int stf_h5_attr_string(stf_h5 *h, const char *name, const char *value);
int stf_h5_attr_double(stf_h5 *h, const char *name, double value);
int stf_h5_attr_long(stf_h5 *h, const char *name, long value);

/* Appends frame /Step#N at time t: n particles, xyz and v interleaved (3*n doubles each,
 * stored as float32); khist and id may be NULL. n may be 0. Flushes. Returns 0 or -1. */
int stf_h5_write_frame(stf_h5 *h, double t, int n, const double *xyz, const double *v,
                       const float *khist, const int32_t *id);

/* A double attribute on the last frame written (solver statistics of the steps since the
 * frame before). Returns 0 or -1. */
int stf_h5_frame_attr_double(stf_h5 *h, const char *name, double value);

/* Appends one row to /bodies/NAME (created on first call). NAME must not contain '/'.
 * parts: the fluid force by part (STF_H5_FORCE_PARTS rows of 3: pressure, viscosity,
 * contacts, stick, added mass; stf_ode_body_fluid_force_parts), NULL when not known (NaN).
 * Flushes. Returns 0 or -1. */
enum { STF_H5_FORCE_PARTS = 5 };
int stf_h5_body_append(stf_h5 *h, const char *name, double t, const double pos[3],
                       const double quat[4], const double vel[3], const double angvel[3],
                       const double force[3], const double *parts);

/* Writes /body_meshes/NAME/vertices and triangles: the surface of shape (a sphere, box,
 * capsule, cylinder or convex hull: body_mesh.h) in the body frame. Returns 0; 1 for a shape
 * without a surface (nothing written); -1. Call once per body, before its poses. */
struct stf_collider_def;
int stf_h5_body_mesh(stf_h5 *h, const char *name, const struct stf_collider_def *shape);

/* Writes /body_meshes/NAME/Step#N for the last frame N written: the body's mesh placed at
 * pos with orientation quat (w x y z). Returns 0 (also for a body without a mesh) or -1. */
int stf_h5_body_pose(stf_h5 *h, const char *name, const double pos[3], const double quat[4]);

/* Writes the XDMF sidecar for the frames so far and closes the file, so that other
 * processes can open it until the next call that writes, which opens it again: body rows
 * appended meanwhile are kept in memory and written then. Returns 0 or -1. */
int stf_h5_release(stf_h5 *h);

/* Writes what is pending and releases the file (stf_h5_release), so that reading the file
 * in this process (stf_h5r_open) sees everything. Call after the last frame. 0 or -1. */
int stf_h5_flush_for_reading(stf_h5 *h);

/* Writes group /metrics with string attribute "json" (replaced if called again). */
int stf_h5_write_metrics_json(stf_h5 *h, const char *json);

/* Why the last failing call on h failed ("" if none). */
const char *stf_h5_last_error(const stf_h5 *h);

/* Writes the XDMF sidecar (path with its extension replaced by .xmf), closes the file and
 * frees h. Returns 0, or -1 with err (h is freed either way). */
int stf_h5_close(stf_h5 *h, char *err, size_t errlen);

/* Closes the file without a sidecar and frees h (error paths; body rows kept since a
 * release are lost). NULL is a no-op. */
void stf_h5_abort(stf_h5 *h);

/* ---- checkpoints (`stf run --resume`, see state.h) ----
 * /checkpoint holds one dataset per state entry (float64, float32, int32 or int64, 1-D,
 * uncompressed). It is replaced so that a kill at any moment leaves one complete
 * checkpoint: the new group is written unlinked and flushed, linked as /checkpoint.new and
 * flushed, then /checkpoint is removed, the new one renamed, and flushed again. A reader
 * prefers /checkpoint.new when it exists (the kill came between the two). */
struct stf_state;
/* Writes st as the new checkpoint. Returns 0 or -1. */
int stf_h5_write_checkpoint(stf_h5 *h, const struct stf_state *st);
/* Removes the checkpoint (a run that ended needs none). Returns 0 or -1. A file whose
 * checkpoints were all removed is compacted at stf_h5_close (their space is not reused:
 * stf_h5_compact). */
int stf_h5_delete_checkpoint(stf_h5 *h);
/* Copies the file at path object by object (root links and attributes) into path.compact
 * and renames that over path: the space freed objects held goes. Returns 0, or -1 with
 * "PATH: why" in err (path is then unchanged). */
int stf_h5_compact(const char *path, char *err, size_t errlen);
/* Reads the checkpoint of the output file path into st (owning its arrays). Returns 0; 1
 * when the file has none; -1 with "PATH: why" in err. */
int stf_h5_read_checkpoint(const char *path, struct stf_state *st, char *err, size_t errlen);
/* Opens an existing output to continue it from a checkpoint: keeps frames 0..frames-1 and
 * the first body_rows rows of every body series and drops what was written after them (a
 * run killed after its checkpoint); removes the end-of-run attributes (exit_status, /metrics)
 * so that a kill of the resumed run leaves a file that says it was killed. Returns 0, or -1
 * with "PATH: why" in err (the file is not changed unless its kept frames are all there). */
int stf_h5_open_resume(const char *path, int frames, long body_rows, stf_h5 **out, char *err,
                       size_t errlen);

/* ---- reader ---- */

typedef struct stf_h5r stf_h5r;

/* Opens an output file read-only (also one left by a killed run: incomplete frame groups
 * are skipped). Returns 0, or -1 with "PATH: not an stf output file (why)" or
 * "PATH: strerror" in err. */
int stf_h5r_open(const char *path, stf_h5r **out, char *err, size_t errlen);
void stf_h5r_close(stf_h5r *r);

int stf_h5r_frames(const stf_h5r *r);                 /* complete frames, sorted by N */
double stf_h5r_frame_time(const stf_h5r *r, int frame); /* NAN if out of range */
int stf_h5r_frame_count(const stf_h5r *r, int frame);   /* particles; -1 if out of range */

/* Reads frame into 3*n doubles each (interleaved); either pointer may be NULL. 0 / -1. */
int stf_h5r_read_frame(const stf_h5r *r, int frame, double *xyz, double *v);
/* Reads khist into n floats; -1 if the frame has none. */
int stf_h5r_read_khist(const stf_h5r *r, int frame, float *k);

/* Root attributes: -1 / NULL if absent. Numeric attributes of any type convert to double.
 * The string is malloc'ed; the caller frees it. */
int stf_h5r_attr_double(const stf_h5r *r, const char *name, double *value);
char *stf_h5r_attr_string(const stf_h5r *r, const char *name);

/* Bodies under /bodies, in name order. */
int stf_h5r_body_count(const stf_h5r *r);
const char *stf_h5r_body_name(const stf_h5r *r, int i); /* NULL if out of range */
/* Reads a body's series into malloc'ed arrays (caller frees; any pointer may be NULL):
 * time[N], pos[3N], quat[4N], vel[3N], angvel[3N], force[3N]. Returns N (>= 0; rows of a
 * series cut short by a kill are dropped) or -1 (no such body, read error). */
int stf_h5r_body_series(const stf_h5r *r, const char *name, double **time, double **pos,
                        double **quat, double **vel, double **angvel, double **force);

#ifdef __cplusplus
}
#endif
#endif
