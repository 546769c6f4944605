/* h5io.c - the HDF5 output file of a run (H5Part layout + XDMF sidecar) and its reader.
 * See h5io.h for the layout. Every HDF5 id is closed before a function returns, so the
 * file can be closed (or the process killed after a flush) at any point. */
#define _POSIX_C_SOURCE 200809L /* nanosleep */
#define _DEFAULT_SOURCE          /* flock */
#include "h5io.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <time.h>
#include <unistd.h>

#include <hdf5.h>

#include "body_mesh.h"
#include "state.h"

#define FRAME_PREFIX "Step#"
#define FRAME_CHUNK 65536 /* particles per chunk of a frame dataset */
#define BODY_CHUNK 256    /* rows per chunk of a body series */
#define FORMAT_ATTR "stf_format"
#define FORMAT_NAME "stf-h5part-1"

static const char *const pos_names[3] = {"x", "y", "z"};
static const char *const vel_names[3] = {"vx", "vy", "vz"};

/* The body series: dataset name and columns (0 = one-dimensional). The first BODY_SERIES
 * are every file's (the reader needs them); fluid_force_parts (stf_h5_body_append) came
 * later: a file without it is read and resumed without it. */
enum { BODY_SERIES = 6, BODY_PARTS = BODY_SERIES, BODY_ALL };
static const char *const body_names[BODY_ALL] = {
    "time", "position", "quaternion", "velocity", "angular_velocity", "fluid_force",
    "fluid_force_parts"};
static const int body_cols[BODY_ALL] = {0, 3, 4, 3, 3, 3, 3 * STF_H5_FORCE_PARTS};

static void fmt_err(char *err, size_t errlen, const char *fmt, ...)
{
    if (!err || errlen == 0) return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, errlen, fmt, ap);
    va_end(ap);
}

static char *dup_str(const char *s)
{
    size_t len = strlen(s) + 1;
    char *d = malloc(len);
    if (d) memcpy(d, s, len);
    return d;
}

/* Closes an HDF5 id of any kind if it is valid (error paths close partial state). */
static void close_id(hid_t id)
{
    if (id < 0) return;
    switch (H5Iget_type(id)) {
    case H5I_FILE: H5Fclose(id); break;
    case H5I_GROUP: H5Gclose(id); break;
    case H5I_DATASET: H5Dclose(id); break;
    case H5I_DATASPACE: H5Sclose(id); break;
    case H5I_DATATYPE: H5Tclose(id); break;
    case H5I_ATTR: H5Aclose(id); break;
    case H5I_GENPROP_LST: H5Pclose(id); break;
    default: break;
    }
}

/* ====================================================================================
 * writer
 * ==================================================================================== */

typedef struct frame_info {
    double t;
    int n;
    int has_khist, has_id;
} frame_info;

/* A body row appended while the file is released (stf_h5_release): written at the next
 * opening, before anything else. */
typedef struct pending_row {
    char *name;
    double v[19 + 3 * STF_H5_FORCE_PARTS]; /* t, pos[3], quat[4], vel[3], angvel[3], force[3], parts */
} pending_row;

/* A body with a surface mesh under /body_meshes/NAME (stf_h5_body_mesh). */
typedef struct mesh_info {
    char *name;
    double *v;             /* 3*nv vertices in the body frame */
    int nv, nt;
    unsigned char *placed; /* placed[k]: /body_meshes/NAME/Step#k was written */
    int cap;
} mesh_info;

struct stf_h5 {
    hid_t file; /* -1 while released (stf_h5_release) */
    char *path;
    frame_info *frames;
    int nframes, cap;
    int ckpt_removed; /* 1 when a checkpoint was removed and none written since: its space
                         goes at the close (stf_h5_compact) */
    int readers_stay; /* the last opening found readers holding the file past LOCK_WAIT_MS */
    double xdmf_at, xdmf_cost; /* when the sidecar was last written (now_s), how long it took */
    pending_row *pending;
    int npending, cap_pending;
    mesh_info *meshes;
    int nmeshes;
    char err[256];
};

const char *stf_h5_last_error(const stf_h5 *h) { return h ? h->err : "no file"; }

/* File access properties that keep HDF5 from writing metadata between our flushes.
 *
 * A kill -9 must leave a readable file. HDF5's metadata cache evicts dirty entries (a
 * group's symbol table, a B-tree node) whenever it is full, so without this the file on disk
 * could name objects beyond the end-of-allocation the superblock records; h5py then fails
 * with "addr overflow" (3 of 80 kills during a frame every step, measured). With eviction
 * off, metadata reaches the disk only in H5Fflush, which we call after each complete frame
 * or body row; the cache is emptied by reopening the file when it grows (flush_and_bound). */
/* A new file access property list, and HDF5's default metadata cache configuration in
 * *mdc; -1 on failure. */
static hid_t default_mdc_fapl(H5AC_cache_config_t *mdc)
{
    hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
    memset(mdc, 0, sizeof *mdc);
    mdc->version = H5AC__CURR_CACHE_CONFIG_VERSION;
    if (fapl >= 0 && H5Pget_mdc_config(fapl, mdc) >= 0) return fapl;
    close_id(fapl);
    return -1;
}

static hid_t no_eviction_fapl(void)
{
    H5AC_cache_config_t mdc;
    hid_t fapl = default_mdc_fapl(&mdc);
    if (fapl < 0) return -1;
    mdc.evictions_enabled = 0;
    mdc.incr_mode = H5C_incr__off;
    mdc.flash_incr_mode = H5C_flash_incr__off;
    mdc.decr_mode = H5C_decr__off;
    if (H5Pset_mdc_config(fapl, &mdc) >= 0) return fapl;
    close_id(fapl);
    return -1;
}

/* The root group's symbol table sized up front: its name heap holds ROOT_HEAP_BYTES (about
 * 4,000 frame names) and a B-tree leaf 2 ROOT_SYM_K links, so linking a frame
 * (stf_h5_write_frame) rewrites them in place instead of moving them to the end of the
 * file. A move is what a kill inside the linking flush could tear: the root pointing at an
 * object past the end of allocation the superblock records, which HDF5 writes last (seen
 * once in CI, under load: "addr overflow"). The heap then stays put (checked with h5debug:
 * its data at the same address after 11 frames, where it had moved 320 kB down the file);
 * the leaf still splits once per ROOT_SYM_K frames past the first 2 ROOT_SYM_K (once per 4
 * before). The leaf size is the file's, for every group: about 3 kB more per group at 64
 * (measured: 10.44 MB against 10.06 MB for the bowling scene at 2.5 cm over 2 s, 61 frames). */
enum { ROOT_SYM_K = 64, ROOT_HEAP_BYTES = 64 << 10 };

static hid_t root_fcpl(void)
{
    hid_t fcpl = H5Pcreate(H5P_FILE_CREATE);
    if (fcpl < 0) return -1;
    if (H5Pset_sym_k(fcpl, 16, ROOT_SYM_K) >= 0 &&
        H5Pset_local_heap_size_hint(fcpl, ROOT_HEAP_BYTES) >= 0)
        return fcpl;
    close_id(fcpl);
    return -1;
}

enum { MDC_REOPEN_BYTES = 2 << 20 }; /* metadata kept in memory before the file is reopened */

/* Sharing the file with readers (stf_h5_release). HDF5 1.10 locks a file for as long as it
 * is open: exclusively for a writer, shared for a reader (flock), and an opening that finds a
 * conflicting lock fails at once ("unable to lock file"). A released writer holds nothing, so
 * readers open the file between frames; while the writer writes (it holds the exclusive lock)
 * a reader's opening fails and is to be tried again. A reader that keeps the file open
 * blocks the writer's next opening: the writer waits up to LOCK_WAIT_MS for it to close the
 * file (a viewer reading a frame does so quickly), then opens the file without locking and
 * writes anyway, so a reader left open (h5py in a notebook) neither stops nor fails the run.
 * Such a reader sees the file as it was when it opened it; one that opens it again sees the
 * new frames. While the writer writes past such a reader nothing locks the file, so another
 * opening can land in the middle of a frame's write and find its metadata half-written (an
 * error on reading, "addr overflow"): that reader is to open the file again. */
enum { LOCK_WAIT_MS = 250,        /* for readers to let go before writing past them */
       LOCK_FORCED_WAIT_S = 600 }; /* the same when HDF5_USE_FILE_LOCKING forces locking */

static void sleep_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

/* 1 if another process holds a lock on path (an HDF5 reader that has it open). */
static int locked_by_other(const char *path)
{
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC); /* no wait on a fifo */
    if (fd < 0) return 0;
    int held = flock(fd, LOCK_EX | LOCK_NB) != 0 && errno == EWOULDBLOCK;
    close(fd); /* releases the probe's lock if it got one */
    return held;
}

static herr_t find_lock_error(unsigned n, const H5E_error2_t *e, void *found)
{
    (void)n;
    if (e->min_num == H5E_CANTLOCKFILE) *(int *)found = 1;
    return 0;
}

/* 1 if the HDF5 call that just failed did so because the file was locked. */
static int failed_on_lock(void)
{
    int found = 0;
    H5Ewalk2(H5E_DEFAULT, H5E_WALK_DOWNWARD, find_lock_error, &found);
    return found;
}

/* H5Fopen(path, RDWR) with the no-eviction cache, with or without HDF5's file lock; when it
 * fails, *on_lock tells whether a lock held by another process was why. */
static hid_t open_rdwr(const char *path, int locking, int *on_lock)
{
    *on_lock = 0;
    hid_t fapl = no_eviction_fapl();
    if (fapl >= 0 && !locking && H5Pset_file_locking(fapl, 0, 1) < 0) {
        close_id(fapl);
        fapl = -1;
    }
    hid_t f = fapl < 0 ? -1 : H5Fopen(path, H5F_ACC_RDWR, fapl);
    if (f < 0 && fapl >= 0) *on_lock = failed_on_lock(); /* before the next call clears it */
    close_id(fapl);
    return f;
}

/* Opens h->path for writing into h->file, waiting for or writing past readers that hold
 * it (see above). Returns 0, or -1 with h->err set. */
static int open_file(stf_h5 *h)
{
    int waited = 0, budget = h->readers_stay ? 0 : LOCK_WAIT_MS, unexplained = 0, on_lock;
    for (;;) {
        if ((h->file = open_rdwr(h->path, 1, &on_lock)) >= 0) {
            h->readers_stay = 0;
            return 0;
        }
        if (!on_lock) { /* not a reader's lock: try once more, then give up */
            if (++unexplained == 2) break;
            sleep_ms(10);
            continue;
        }
        if (waited < budget) {
            sleep_ms(10);
            waited += 10;
            continue;
        }
        if ((h->file = open_rdwr(h->path, 0, &on_lock)) >= 0) {
            h->readers_stay = 1;
            return 0;
        }
        /* HDF5_USE_FILE_LOCKING=TRUE overrides the property: wait for the readers */
        const char *env = getenv("HDF5_USE_FILE_LOCKING");
        int forced = env && strcmp(env, "FALSE") != 0 && strcmp(env, "0") != 0;
        if (!forced || waited >= budget + 1000 * LOCK_FORCED_WAIT_S) break;
        sleep_ms(100);
        waited += 100;
    }
    snprintf(h->err, sizeof h->err, "cannot open %s for writing%s", h->path,
             waited > budget ? " (other processes hold it open)" : "");
    return -1;
}

static int write_pending(stf_h5 *h);

/* Opens the file again after stf_h5_release, and writes the body rows kept meanwhile.
 * Every writing call starts with it. Returns 0 or -1 with h->err set. */
static int ensure_open(stf_h5 *h)
{
    if (h->file >= 0) return 0;
    if (open_file(h) != 0) return -1;
    return write_pending(h);
}

/* Flushes the file; then, when the cache holds more than MDC_REOPEN_BYTES (it never evicts,
 * see no_eviction_fapl), closes and reopens the file to empty it. Returns 0 or -1. */
static int flush_and_bound(stf_h5 *h)
{
    if (H5Fflush(h->file, H5F_SCOPE_GLOBAL) < 0) return -1;
    size_t max_size = 0, min_clean = 0, cur_size = 0;
    int entries = 0;
    if (H5Fget_mdc_size(h->file, &max_size, &min_clean, &cur_size, &entries) < 0) return -1;
    if (cur_size <= MDC_REOPEN_BYTES) return 0;
    H5Fclose(h->file);
    H5garbage_collect(); /* HDF5 keeps freed cache entries on its free lists otherwise */
    return open_file(h);
}

static int write_xdmf(const stf_h5 *h, char *err, size_t errlen);

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The sidecar is rewritten whole (it lists every frame), so at a release only when
 * XDMF_EVERY_S have passed since the last time and at most 5% of the time goes to it: a
 * viewer of a running simulation sees frames at most a second or so old. */
enum { XDMF_EVERY_S = 1 };

int stf_h5_release(stf_h5 *h)
{
    if (!h) return -1;
    if (h->file < 0) return 0;
    int rc = 0;
    double t0 = now_s();
    if (h->xdmf_at == 0 || t0 - h->xdmf_at >= fmax(XDMF_EVERY_S, 20 * h->xdmf_cost)) {
        rc = write_xdmf(h, h->err, sizeof h->err);
        h->xdmf_at = now_s();
        h->xdmf_cost = h->xdmf_at - t0;
    }
    if (H5Fclose(h->file) < 0 && rc == 0) {
        snprintf(h->err, sizeof h->err, "%s: error closing HDF5 file", h->path);
        rc = -1;
    }
    h->file = -1;
    H5garbage_collect();
    return rc;
}

int stf_h5_flush_for_reading(stf_h5 *h)
{
    if (!h || ensure_open(h) != 0) return -1;
    return stf_h5_release(h);
}

int stf_h5_create(const char *path, stf_h5 **out, char *err, size_t errlen)
{
    *out = NULL;
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL); /* we report errors ourselves */
    stf_h5 *h = calloc(1, sizeof *h);
    if (!h || !(h->path = dup_str(path))) {
        free(h);
        fmt_err(err, errlen, "%s: out of memory", path);
        return -1;
    }
    h->file = -1;
    /* An earlier output that a reader holds open is unlinked, not truncated: the reader
     * keeps its file (and does not stop this one being created). */
    if (locked_by_other(path)) remove(path);
    /* Probe with stdio first: HDF5's own failure says nothing about why. */
    FILE *probe = fopen(path, "wb");
    if (!probe) {
        fmt_err(err, errlen, "%s: %s", path, strerror(errno));
        free(h->path);
        free(h);
        return -1;
    }
    fclose(probe);
    /* Default (earliest) format: no superblock status flags, so a file left by a killed
     * writer opens without h5clear. */
    hid_t fapl = no_eviction_fapl(), fcpl = root_fcpl();
    h->file = fapl < 0 || fcpl < 0 ? -1 : H5Fcreate(path, H5F_ACC_TRUNC, fcpl, fapl);
    close_id(fapl);
    close_id(fcpl);
    if (h->file < 0) {
        fmt_err(err, errlen, "%s: cannot create HDF5 file", path);
        free(h->path);
        free(h);
        return -1;
    }
    if (stf_h5_attr_string(h, FORMAT_ATTR, FORMAT_NAME) != 0) {
        fmt_err(err, errlen, "%s: %s", path, h->err);
        stf_h5_abort(h);
        return -1;
    }
    *out = h;
    return 0;
}

/* Writes a scalar attribute on obj, replacing one of the same name. */
static int put_attr(hid_t obj, const char *name, hid_t ftype, hid_t mtype, const void *buf)
{
    htri_t exists = H5Aexists(obj, name);
    if (exists < 0 || (exists > 0 && H5Adelete(obj, name) < 0)) return -1;
    hid_t space = H5Screate(H5S_SCALAR);
    hid_t a = space < 0 ? -1 : H5Acreate2(obj, name, ftype, space, H5P_DEFAULT, H5P_DEFAULT);
    int rc = (a >= 0 && H5Awrite(a, mtype, buf) >= 0) ? 0 : -1;
    close_id(a);
    close_id(space);
    return rc;
}

/* Variable-length UTF-8 string: no 64 KiB attribute limit (the text lives in the global
 * heap) and h5py reads it as str. */
static int put_attr_string(hid_t obj, const char *name, const char *value)
{
    hid_t t = H5Tcopy(H5T_C_S1);
    if (t < 0) return -1;
    int rc = -1;
    if (H5Tset_size(t, H5T_VARIABLE) >= 0 && H5Tset_cset(t, H5T_CSET_UTF8) >= 0)
        rc = put_attr(obj, name, t, t, &value);
    H5Tclose(t);
    return rc;
}

/* 1 (and h->err) when name is empty or the file cannot be opened again. */
static int bad_args(stf_h5 *h, const char *name)
{
    if (!h) return 1;
    if (!name || !*name) {
        snprintf(h->err, sizeof h->err, "empty attribute name");
        return 1;
    }
    return ensure_open(h) != 0;
}

int stf_h5_attr_string(stf_h5 *h, const char *name, const char *value)
{
    if (bad_args(h, name)) return -1;
    if (put_attr_string(h->file, name, value ? value : "") == 0) return 0;
    snprintf(h->err, sizeof h->err, "cannot write attribute %s", name);
    return -1;
}

int stf_h5_attr_double(stf_h5 *h, const char *name, double value)
{
    if (bad_args(h, name)) return -1;
    if (put_attr(h->file, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value) == 0) return 0;
    snprintf(h->err, sizeof h->err, "cannot write attribute %s", name);
    return -1;
}

int stf_h5_attr_long(stf_h5 *h, const char *name, long value)
{
    if (bad_args(h, name)) return -1;
    if (put_attr(h->file, name, H5T_STD_I64LE, H5T_NATIVE_LONG, &value) == 0) return 0;
    snprintf(h->err, sizeof h->err, "cannot write attribute %s", name);
    return -1;
}

/* Writes a 1-D dataset of n elements. Chunked + shuffle + deflate when n > 0; an empty
 * dataset stays contiguous (a chunk size of 0 is invalid). */
static int write_1d(hid_t g, const char *name, hid_t ftype, hid_t mtype, hsize_t n,
                    const void *buf)
{
    hid_t space = H5Screate_simple(1, &n, NULL);
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    hid_t d = -1;
    int rc = -1;
    if (space < 0 || dcpl < 0) goto done;
    if (n > 0) {
        hsize_t chunk = n < FRAME_CHUNK ? n : FRAME_CHUNK;
        if (H5Pset_chunk(dcpl, 1, &chunk) < 0 || H5Pset_shuffle(dcpl) < 0 ||
            H5Pset_deflate(dcpl, 4) < 0)
            goto done;
    }
    d = H5Dcreate2(g, name, ftype, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    if (d < 0) goto done;
    if (n > 0 && H5Dwrite(d, mtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf) < 0) goto done;
    rc = 0;
done:
    close_id(d);
    close_id(dcpl);
    close_id(space);
    return rc;
}

/* Writes component c of the interleaved array src (3*n) as float32 dataset name. */
static int write_component(hid_t g, const char *name, int n, const double *src, int c,
                           float *buf)
{
    for (int i = 0; i < n; i++) buf[i] = (float)src[3 * i + c];
    return write_1d(g, name, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, (hsize_t)n, buf);
}

static int frame_datasets(hid_t g, int n, const double *xyz, const double *v,
                          const float *khist, const int32_t *id)
{
    float *buf = malloc((size_t)(n > 0 ? n : 1) * sizeof *buf);
    if (!buf) return -1;
    int rc = 0;
    for (int c = 0; c < 3 && rc == 0; c++) rc = write_component(g, pos_names[c], n, xyz, c, buf);
    for (int c = 0; c < 3 && rc == 0; c++) rc = write_component(g, vel_names[c], n, v, c, buf);
    free(buf);
    if (rc == 0 && khist)
        rc = write_1d(g, "khist", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, (hsize_t)n, khist);
    if (rc == 0 && id)
        rc = write_1d(g, "id", H5T_STD_I32LE, H5T_NATIVE_INT32, (hsize_t)n, id);
    return rc;
}

static int remember_frame(stf_h5 *h, double t, int n, int has_khist, int has_id)
{
    if (h->nframes == h->cap) {
        int cap = h->cap ? 2 * h->cap : 64;
        frame_info *f = realloc(h->frames, (size_t)cap * sizeof *f);
        if (!f) return -1;
        h->frames = f;
        h->cap = cap;
    }
    h->frames[h->nframes++] = (frame_info){t, n, has_khist, has_id};
    return 0;
}

int stf_h5_write_frame(stf_h5 *h, double t, int n, const double *xyz, const double *v,
                       const float *khist, const int32_t *id)
{
    if (!h) return -1;
    if (n < 0 || (n > 0 && (!xyz || !v))) {
        snprintf(h->err, sizeof h->err, "frame %d: bad arguments", h->nframes);
        return -1;
    }
    if (ensure_open(h) != 0) return -1;
    char gname[32];
    snprintf(gname, sizeof gname, FRAME_PREFIX "%d", h->nframes);
    /* The group is built unnamed and linked into / last, so the root's symbol table
     * changes only once the frame is complete (a killed run leaves no half frame under a
     * name). TimeValue goes last too: the reader treats a group without it as incomplete. */
    hid_t g = H5Gcreate_anon(h->file, H5P_DEFAULT, H5P_DEFAULT);
    /* Two flushes: HDF5 writes the superblock (and so the end of allocation it records)
     * after the objects, so a kill inside a flush can leave on disk an object that points
     * past that end. The first flush writes the new, still unreachable frame and the new
     * end; only the second writes the (small) change that links it. */
    int rc = (g >= 0 && frame_datasets(g, n, xyz, v, khist, id) == 0 &&
              put_attr(g, "TimeValue", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &t) == 0 &&
              H5Fflush(h->file, H5F_SCOPE_GLOBAL) >= 0 &&
              H5Olink(g, h->file, gname, H5P_DEFAULT, H5P_DEFAULT) >= 0)
                 ? 0 : -1;
    close_id(g);
    if (rc == 0 && flush_and_bound(h) < 0) rc = -1;
    if (rc == 0) rc = remember_frame(h, t, n, khist != NULL, id != NULL);
    if (rc != 0) snprintf(h->err, sizeof h->err, "cannot write frame %s", gname);
    return rc;
}

int stf_h5_frame_attr_double(stf_h5 *h, const char *name, double value)
{
    if (bad_args(h, name)) return -1;
    if (h->nframes < 1) {
        snprintf(h->err, sizeof h->err, "attribute %s: no frame written yet", name);
        return -1;
    }
    char gname[32];
    snprintf(gname, sizeof gname, FRAME_PREFIX "%d", h->nframes - 1);
    hid_t g = H5Gopen2(h->file, gname, H5P_DEFAULT);
    int rc = g >= 0 && put_attr(g, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value) == 0 ? 0 : -1;
    close_id(g);
    if (rc != 0) snprintf(h->err, sizeof h->err, "cannot write attribute %s of %s", name, gname);
    return rc;
}

/* Opens group name under parent, creating it if absent. */
static hid_t open_or_create_group(hid_t parent, const char *name, int *created)
{
    htri_t exists = H5Lexists(parent, name, H5P_DEFAULT);
    if (created) *created = exists == 0;
    if (exists < 0) return -1;
    if (exists) return H5Gopen2(parent, name, H5P_DEFAULT);
    return H5Gcreate2(parent, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
}

/* Creates an empty extendible series of `cols` columns (0 = 1-D). */
static int create_series(hid_t g, const char *name, int cols)
{
    int rank = cols ? 2 : 1;
    hsize_t dims[2] = {0, (hsize_t)cols}, maxd[2] = {H5S_UNLIMITED, (hsize_t)cols};
    hsize_t chunk[2] = {BODY_CHUNK, (hsize_t)cols};
    hid_t space = H5Screate_simple(rank, dims, maxd);
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    hid_t d = -1;
    if (space >= 0 && dcpl >= 0 && H5Pset_chunk(dcpl, rank, chunk) >= 0)
        d = H5Dcreate2(g, name, H5T_IEEE_F64LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    int rc = d >= 0 ? 0 : -1;
    close_id(d);
    close_id(dcpl);
    close_id(space);
    return rc;
}

/* Appends one row (cols values, or 1 for a 1-D series) to series name in g. */
static int append_row(hid_t g, const char *name, int cols, const double *row)
{
    hid_t d = H5Dopen2(g, name, H5P_DEFAULT);
    hid_t fspace = -1, mspace = -1;
    int rc = -1, rank = cols ? 2 : 1;
    hsize_t dims[2] = {0, 0};
    if (d < 0) goto done;
    fspace = H5Dget_space(d);
    if (fspace < 0 || H5Sget_simple_extent_dims(fspace, dims, NULL) != rank) goto done;
    H5Sclose(fspace);
    fspace = -1;
    dims[0]++;
    if (H5Dset_extent(d, dims) < 0 || (fspace = H5Dget_space(d)) < 0) goto done;
    hsize_t start[2] = {dims[0] - 1, 0}, count[2] = {1, (hsize_t)cols};
    if (H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start, NULL, count, NULL) < 0) goto done;
    mspace = H5Screate_simple(rank, count, NULL);
    if (mspace >= 0 && H5Dwrite(d, H5T_NATIVE_DOUBLE, mspace, fspace, H5P_DEFAULT, row) >= 0)
        rc = 0;
done:
    close_id(mspace);
    close_id(fspace);
    close_id(d);
    return rc;
}

/* Series s of an existing body is missing: fluid_force_parts in a file from before it. */
static int series_missing(hid_t body, int s)
{
    return s == BODY_PARTS && H5Lexists(body, body_names[s], H5P_DEFAULT) <= 0;
}

static int body_rows(hid_t body, int created, const double *const rows[BODY_ALL])
{
    for (int s = 0; s < BODY_ALL; s++) {
        if (!created && series_missing(body, s)) continue; /* a resumed file from before it */
        if (created && create_series(body, body_names[s], body_cols[s]) != 0) return -1;
        if (append_row(body, body_names[s], body_cols[s], rows[s]) != 0) return -1;
    }
    return 0;
}

/* Appends one row to /bodies/NAME without flushing. */
static int put_body_row(stf_h5 *h, const char *name, const double *const rows[BODY_ALL])
{
    int created = 0;
    hid_t bodies = open_or_create_group(h->file, "bodies", NULL);
    hid_t body = bodies < 0 ? -1 : open_or_create_group(bodies, name, &created);
    int rc = body >= 0 ? body_rows(body, created, rows) : -1;
    close_id(body);
    close_id(bodies);
    if (rc != 0) snprintf(h->err, sizeof h->err, "cannot append to /bodies/%s", name);
    return rc;
}

/* Where each series starts in a pending_row's values. */
static const int row_at[BODY_ALL] = {0, 1, 4, 8, 11, 14, 17};

static void unpack_row(const pending_row *p, const double *rows[BODY_ALL])
{
    for (int s = 0; s < BODY_ALL; s++) rows[s] = p->v + row_at[s];
}

static void free_pending(stf_h5 *h)
{
    for (int i = 0; i < h->npending; i++) free(h->pending[i].name);
    h->npending = 0;
}

static int write_pending(stf_h5 *h)
{
    int rc = 0;
    for (int i = 0; i < h->npending && rc == 0; i++) {
        const double *rows[BODY_ALL];
        unpack_row(&h->pending[i], rows);
        rc = put_body_row(h, h->pending[i].name, rows);
    }
    if (h->npending && rc == 0 && flush_and_bound(h) < 0) {
        snprintf(h->err, sizeof h->err, "cannot write the body rows");
        rc = -1;
    }
    free_pending(h);
    return rc;
}

/* Keeps a row for the next opening (the file is released). */
static int keep_row(stf_h5 *h, const char *name, const double *const rows[BODY_ALL])
{
    if (h->npending == h->cap_pending) {
        int cap = h->cap_pending ? 2 * h->cap_pending : 64;
        pending_row *p = realloc(h->pending, (size_t)cap * sizeof *p);
        if (!p) return -1;
        h->pending = p;
        h->cap_pending = cap;
    }
    pending_row *p = &h->pending[h->npending];
    for (int s = 0; s < BODY_ALL; s++)
        memcpy(p->v + row_at[s], rows[s], sizeof(double) * (size_t)(body_cols[s] ? body_cols[s] : 1));
    if (!(p->name = dup_str(name))) return -1;
    h->npending++;
    return 0;
}

int stf_h5_body_append(stf_h5 *h, const char *name, double t, const double pos[3],
                       const double quat[4], const double vel[3], const double angvel[3],
                       const double force[3], const double *parts)
{
    if (!h) return -1;
    double unknown[3 * STF_H5_FORCE_PARTS];
    if (!parts) {
        for (int q = 0; q < 3 * STF_H5_FORCE_PARTS; q++) unknown[q] = NAN;
        parts = unknown;
    }
    if (!name || !*name || strchr(name, '/') || !strcmp(name, ".")) {
        snprintf(h->err, sizeof h->err, "bad body name \"%s\"", name ? name : "(null)");
        return -1;
    }
    const double *const rows[BODY_ALL] = {&t, pos, quat, vel, angvel, force, parts};
    if (h->file < 0) {
        if (keep_row(h, name, rows) == 0) return 0;
        snprintf(h->err, sizeof h->err, "out of memory");
        return -1;
    }
    int rc = put_body_row(h, name, rows);
    if (rc == 0 && flush_and_bound(h) < 0) {
        snprintf(h->err, sizeof h->err, "cannot append to /bodies/%s", name);
        rc = -1;
    }
    return rc;
}

int stf_h5_write_metrics_json(stf_h5 *h, const char *json)
{
    if (!h || ensure_open(h) != 0) return -1;
    hid_t g = open_or_create_group(h->file, "metrics", NULL);
    int rc = g >= 0 ? put_attr_string(g, "json", json ? json : "") : -1;
    close_id(g);
    if (rc == 0 && H5Fflush(h->file, H5F_SCOPE_GLOBAL) < 0) rc = -1;
    if (rc != 0) snprintf(h->err, sizeof h->err, "cannot write /metrics");
    return rc;
}

/* ---- body meshes ---- */

#define MESH_GROUP "body_meshes"

static mesh_info *find_mesh(const stf_h5 *h, const char *name)
{
    for (int i = 0; i < h->nmeshes; i++)
        if (!strcmp(h->meshes[i].name, name)) return &h->meshes[i];
    return NULL;
}

/* Registers a mesh (v: 3*nv doubles, owned by the entry from here on). */
static mesh_info *add_mesh(stf_h5 *h, const char *name, double *v, int nv, int nt)
{
    mesh_info *m = realloc(h->meshes, (size_t)(h->nmeshes + 1) * sizeof *m);
    char *n = dup_str(name);
    if (!m || !n) {
        if (m) h->meshes = m;
        free(n);
        free(v);
        return NULL;
    }
    h->meshes = m;
    m = &h->meshes[h->nmeshes++];
    *m = (mesh_info){n, v, nv, nt, NULL, 0};
    return m;
}

/* Marks frame k as placed. */
static int mark_placed(mesh_info *m, int k)
{
    if (k >= m->cap) {
        int cap = m->cap ? 2 * m->cap : 64;
        while (cap <= k) cap *= 2;
        unsigned char *p = realloc(m->placed, (size_t)cap);
        if (!p) return -1;
        memset(p + m->cap, 0, (size_t)(cap - m->cap));
        m->placed = p;
        m->cap = cap;
    }
    m->placed[k] = 1;
    return 0;
}

/* Writes a contiguous 2-D dataset of rows x cols as name in g. As for frames, it is written
 * unlinked and flushed before the link (stf_h5_write_frame): a kill leaves no half dataset. */
static int write_2d(hid_t g, const char *name, hid_t ftype, hid_t mtype, int rows, int cols,
                    const void *buf)
{
    hsize_t dims[2] = {(hsize_t)rows, (hsize_t)cols};
    hid_t space = H5Screate_simple(2, dims, NULL);
    hid_t d = space < 0 ? -1 : H5Dcreate_anon(g, ftype, space, H5P_DEFAULT, H5P_DEFAULT);
    int rc = d >= 0 && H5Dwrite(d, mtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf) >= 0 &&
                     H5Fflush(g, H5F_SCOPE_GLOBAL) >= 0 &&
                     H5Olink(d, g, name, H5P_DEFAULT, H5P_DEFAULT) >= 0
                 ? 0 : -1;
    close_id(d);
    close_id(space);
    return rc;
}

int stf_h5_body_mesh(stf_h5 *h, const char *name, const struct stf_collider_def *shape)
{
    if (!h) return -1;
    if (!name || !*name || strchr(name, '/') || !strcmp(name, ".") || find_mesh(h, name)) {
        snprintf(h->err, sizeof h->err, "bad or repeated body name \"%s\"", name ? name : "(null)");
        return -1;
    }
    stf_mesh mesh;
    int built = stf_mesh_build(shape, &mesh);
    if (built != 0) {
        if (built < 0) snprintf(h->err, sizeof h->err, "out of memory");
        return built;
    }
    if (ensure_open(h) != 0) {
        stf_mesh_free(&mesh);
        return -1;
    }
    hid_t all = open_or_create_group(h->file, MESH_GROUP, NULL);
    hid_t g = all < 0 ? -1 : H5Gcreate2(all, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    int rc = g >= 0 &&
                     write_2d(g, "vertices", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, mesh.nv, 3, mesh.v) == 0 &&
                     write_2d(g, "triangles", H5T_STD_I32LE, H5T_NATIVE_INT32, mesh.nt, 3, mesh.t) == 0 &&
                     flush_and_bound(h) == 0
                 ? 0 : -1;
    close_id(g);
    close_id(all);
    free(mesh.t);
    if (rc == 0 && !add_mesh(h, name, mesh.v, mesh.nv, mesh.nt)) rc = -1;
    else if (rc != 0) free(mesh.v);
    if (rc != 0) snprintf(h->err, sizeof h->err, "cannot write /" MESH_GROUP "/%s", name);
    return rc;
}

int stf_h5_body_pose(stf_h5 *h, const char *name, const double pos[3], const double quat[4])
{
    if (!h || !name) return -1;
    mesh_info *m = find_mesh(h, name);
    if (!m || h->nframes < 1) return 0; /* no mesh (or no frame) to place */
    if (ensure_open(h) != 0) return -1;
    int k = h->nframes - 1;
    char path[300];
    snprintf(path, sizeof path, MESH_GROUP "/%s/" FRAME_PREFIX "%d", name, k);
    float *w = malloc(sizeof *w * 3 * (size_t)m->nv);
    stf_mesh placed = {m->v, m->nv, NULL, 0};
    if (w) stf_mesh_place(&placed, pos, quat, w);
    int rc = w && write_2d(h->file, path, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, m->nv, 3, w) == 0 &&
                     flush_and_bound(h) == 0 && mark_placed(m, k) == 0
                 ? 0 : -1;
    free(w);
    if (rc != 0) snprintf(h->err, sizeof h->err, "cannot write /%.200s", path);
    return rc;
}

static void free_meshes(stf_h5 *h)
{
    for (int i = 0; i < h->nmeshes; i++) {
        free(h->meshes[i].name);
        free(h->meshes[i].v);
        free(h->meshes[i].placed);
    }
    free(h->meshes);
    h->meshes = NULL;
    h->nmeshes = 0;
}

/* ---- XDMF sidecar ---- */

/* OUT.h5 -> OUT.xmf (an extension is a dot in the last path component, not leading). */
static char *sidecar_path(const char *path)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    size_t stem = (dot && dot != base) ? (size_t)(dot - path) : strlen(path);
    char *x = malloc(stem + 5);
    if (!x) return NULL;
    memcpy(x, path, stem);
    memcpy(x + stem, ".xmf", 5);
    return x;
}

static void xml_escaped(FILE *f, const char *s)
{
    for (; *s; s++) {
        switch (*s) {
        case '&': fputs("&amp;", f); break;
        case '<': fputs("&lt;", f); break;
        case '>': fputs("&gt;", f); break;
        case '"': fputs("&quot;", f); break;
        default: fputc(*s, f);
        }
    }
}

static void xdmf_item(FILE *f, const char *h5name, int frame, const char *ds, int n,
                      const char *type)
{
    fprintf(f, "          <DataItem Dimensions=\"%d\" %s Format=\"HDF\">", n, type);
    xml_escaped(f, h5name);
    fprintf(f, ":/" FRAME_PREFIX "%d/%s</DataItem>\n", frame, ds);
}

static void xdmf_attribute(FILE *f, const char *h5name, int frame, const char *ds, int n,
                           const char *type)
{
    fprintf(f, "        <Attribute Name=\"%s\" AttributeType=\"Scalar\" Center=\"Node\">\n", ds);
    xdmf_item(f, h5name, frame, ds, n, type);
    fputs("        </Attribute>\n", f);
}

static const char f32[] = "NumberType=\"Float\" Precision=\"4\"";
static const char i32[] = "NumberType=\"Int\" Precision=\"4\"";
static const char f64[] = "NumberType=\"Float\" Precision=\"8\"";

static void xdmf_grid(FILE *f, const char *h5name, int i, const frame_info *fr)
{
    if (fr->n == 0) {
        /* XDMF readers reject zero-length arrays: mention the frame, but as a comment. */
        fprintf(f, "      <!-- " FRAME_PREFIX "%d: t = %.17g, no particles -->\n", i, fr->t);
        return;
    }
    fprintf(f, "      <Grid Name=\"" FRAME_PREFIX "%d\" GridType=\"Uniform\">\n", i);
    fprintf(f, "        <Time Value=\"%.17g\"/>\n", fr->t);
    fprintf(f, "        <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"%d\" "
               "NodesPerElement=\"1\"/>\n", fr->n);
    fputs("        <Geometry GeometryType=\"X_Y_Z\">\n", f);
    for (int c = 0; c < 3; c++) xdmf_item(f, h5name, i, pos_names[c], fr->n, f32);
    fputs("        </Geometry>\n", f);
    for (int c = 0; c < 3; c++) xdmf_attribute(f, h5name, i, vel_names[c], fr->n, f32);
    if (fr->has_khist) xdmf_attribute(f, h5name, i, "khist", fr->n, f32);
    if (fr->has_id) xdmf_attribute(f, h5name, i, "id", fr->n, i32);
    fputs("      </Grid>\n", f);
}

/* The temporal collection of body m: its mesh at each frame placed (stf_h5_body_pose). */
static void xdmf_body(FILE *f, const char *h5name, const stf_h5 *h, const mesh_info *m)
{
    int any = 0;
    for (int k = 0; k < h->nframes && k < m->cap && !any; k++) any = m->placed[k];
    if (!any) return;
    fputs("    <Grid Name=\"", f);
    xml_escaped(f, m->name);
    fputs("\" GridType=\"Collection\" CollectionType=\"Temporal\">\n", f);
    for (int k = 0; k < h->nframes && k < m->cap; k++) {
        if (!m->placed[k]) continue;
        fprintf(f, "      <Grid Name=\"" FRAME_PREFIX "%d\" GridType=\"Uniform\">\n", k);
        fprintf(f, "        <Time Value=\"%.17g\"/>\n", h->frames[k].t);
        fprintf(f, "        <Topology TopologyType=\"Triangle\" NumberOfElements=\"%d\">\n", m->nt);
        fprintf(f, "          <DataItem Dimensions=\"%d 3\" %s Format=\"HDF\">", m->nt, i32);
        xml_escaped(f, h5name);
        fputs(":/" MESH_GROUP "/", f);
        xml_escaped(f, m->name);
        fputs("/triangles</DataItem>\n        </Topology>\n", f);
        fputs("        <Geometry GeometryType=\"XYZ\">\n", f);
        fprintf(f, "          <DataItem Dimensions=\"%d 3\" %s Format=\"HDF\">", m->nv, f32);
        xml_escaped(f, h5name);
        fputs(":/" MESH_GROUP "/", f);
        xml_escaped(f, m->name);
        fprintf(f, "/" FRAME_PREFIX "%d</DataItem>\n        </Geometry>\n", k);
        /* the vertices in the body frame: colouring by them shows the body turn */
        fputs("        <Attribute Name=\"body_frame_position\" AttributeType=\"Vector\" "
              "Center=\"Node\">\n", f);
        fprintf(f, "          <DataItem Dimensions=\"%d 3\" %s Format=\"HDF\">", m->nv, f64);
        xml_escaped(f, h5name);
        fputs(":/" MESH_GROUP "/", f);
        xml_escaped(f, m->name);
        fputs("/vertices</DataItem>\n        </Attribute>\n      </Grid>\n", f);
    }
    fputs("    </Grid>\n", f);
}

/* Writes the sidecar for the frames so far: into PATH.xmf.part, renamed over PATH.xmf, so
 * that a viewer reading it while the run goes never sees half a file. */
static int write_xdmf(const stf_h5 *h, char *err, size_t errlen)
{
    char *xpath = sidecar_path(h->path);
    size_t len = xpath ? strlen(xpath) : 0;
    char *tmp = xpath ? malloc(len + 6) : NULL;
    if (!tmp) {
        fmt_err(err, errlen, "%s: out of memory", h->path);
        free(xpath);
        return -1;
    }
    memcpy(tmp, xpath, len);
    memcpy(tmp + len, ".part", 6);
    FILE *f = fopen(tmp, "w");
    if (!f) {
        fmt_err(err, errlen, "%s: %s", tmp, strerror(errno));
        free(tmp);
        free(xpath);
        return -1;
    }
    /* The data paths are relative to the sidecar, which sits next to the .h5 file. */
    const char *slash = strrchr(h->path, '/');
    const char *h5name = slash ? slash + 1 : h->path;
    fputs("<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
          "<Xdmf Version=\"2.0\">\n  <Domain>\n"
          "    <Grid Name=\"particles\" GridType=\"Collection\" CollectionType=\"Temporal\">\n",
          f);
    for (int i = 0; i < h->nframes; i++) xdmf_grid(f, h5name, i, &h->frames[i]);
    fputs("    </Grid>\n", f);
    for (int b = 0; b < h->nmeshes; b++) xdmf_body(f, h5name, h, &h->meshes[b]);
    fputs("  </Domain>\n</Xdmf>\n", f);
    int bad = ferror(f);
    if (fclose(f) != 0 || bad || rename(tmp, xpath) != 0) {
        fmt_err(err, errlen, "%s: write error", xpath);
        remove(tmp);
        free(tmp);
        free(xpath);
        return -1;
    }
    free(tmp);
    free(xpath);
    return 0;
}

static void free_writer(stf_h5 *h)
{
    free_pending(h);
    free(h->pending);
    free_meshes(h);
    free(h->frames);
    free(h->path);
    free(h);
}

/* Compaction (stf_h5_close). The checkpoints' space is not reused: the file is closed and
 * reopened between them (flush_and_bound), and the earliest file format (kept so that a
 * killed writer's file opens without h5clear) forgets freed space at a close. A 10 s bowling
 * run at 1.5 cm left a 3.7 GB file holding 184 MB of frames. So a file whose checkpoints are
 * gone is copied, object by object, into a new file that then replaces it. */
static herr_t compact_link(hid_t g, const char *name, const H5L_info_t *info, void *op)
{
    (void)info;
    return H5Ocopy(g, name, *(hid_t *)op, name, H5P_DEFAULT, H5P_DEFAULT) < 0 ? -1 : 0;
}

static herr_t compact_attr(hid_t loc, const char *name, const H5A_info_t *info, void *op)
{
    (void)info;
    hid_t a = H5Aopen(loc, name, H5P_DEFAULT);
    hid_t t = a < 0 ? -1 : H5Aget_type(a);
    hid_t s = a < 0 ? -1 : H5Aget_space(a);
    hssize_t np = s < 0 ? -1 : H5Sget_simple_extent_npoints(s);
    size_t size = t < 0 ? 0 : H5Tget_size(t);
    herr_t rc = -1;
    void *buf = np >= 0 && size > 0 ? calloc((size_t)(np > 0 ? np : 1), size) : NULL;
    if (buf && H5Aread(a, t, buf) >= 0) {
        hid_t b = H5Acreate2(*(hid_t *)op, name, t, s, H5P_DEFAULT, H5P_DEFAULT);
        if (b >= 0 && H5Awrite(b, t, buf) >= 0) rc = 0;
        close_id(b);
        if (H5Tis_variable_str(t) > 0 || H5Tget_class(t) == H5T_VLEN)
            H5Dvlen_reclaim(t, s, H5P_DEFAULT, buf);
    }
    free(buf);
    close_id(s);
    close_id(t);
    close_id(a);
    return rc;
}

int stf_h5_compact(const char *path, char *err, size_t errlen)
{
    size_t n = strlen(path);
    char *tmp = malloc(n + 9);
    if (!tmp) {
        fmt_err(err, errlen, "%s: out of memory", path);
        return -1;
    }
    memcpy(tmp, path, n);
    memcpy(tmp + n, ".compact", 9);
    hid_t src = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    hid_t dst = src < 0 ? -1 : H5Fcreate(tmp, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    int rc = dst >= 0 &&
                     H5Literate(src, H5_INDEX_NAME, H5_ITER_INC, NULL, compact_link, &dst) >= 0 &&
                     H5Aiterate2(src, H5_INDEX_NAME, H5_ITER_INC, NULL, compact_attr, &dst) >= 0
                 ? 0 : -1;
    if (dst >= 0 && H5Fclose(dst) < 0) rc = -1;
    if (src >= 0) H5Fclose(src);
    if (rc == 0 && rename(tmp, path) != 0) rc = -1;
    if (rc != 0) {
        remove(tmp);
        fmt_err(err, errlen, "%s: cannot compact the file (it is complete as it is)", path);
    }
    free(tmp);
    return rc;
}

int stf_h5_close(stf_h5 *h, char *err, size_t errlen)
{
    if (!h) return 0;
    int rc = 0;
    if (h->npending && ensure_open(h) != 0) { /* body rows kept since the release */
        fmt_err(err, errlen, "%s", h->err);
        rc = -1;
    }
    if (rc == 0 && write_xdmf(h, err, errlen) != 0) rc = -1;
    if (h->file >= 0 && H5Fclose(h->file) < 0 && rc == 0) {
        fmt_err(err, errlen, "%s: error closing HDF5 file", h->path);
        rc = -1;
    }
    /* checkpoints written and all removed: their space goes with a copy of the rest */
    if (rc == 0 && h->ckpt_removed) rc = stf_h5_compact(h->path, err, errlen);
    free_writer(h);
    return rc;
}

void stf_h5_abort(stf_h5 *h)
{
    if (!h) return;
    if (h->file >= 0) H5Fclose(h->file);
    free_writer(h);
}

/* ====================================================================================
 * reader
 * ==================================================================================== */

typedef struct rframe {
    long step; /* N of Step#N */
    double t;
    int n;
} rframe;

struct stf_h5r {
    hid_t file;
    rframe *frames;
    int nframes;
    char **bodies;
    int nbodies;
};

/* A growing list of names, filled by H5Literate. */
typedef struct name_list {
    char **names;
    int count, cap;
    int failed;
} name_list;

static herr_t collect_name(hid_t g, const char *name, const H5L_info_t *info, void *data)
{
    (void)g;
    (void)info;
    name_list *l = data;
    if (l->count == l->cap) {
        int cap = l->cap ? 2 * l->cap : 64;
        char **p = realloc(l->names, (size_t)cap * sizeof *p);
        if (!p) {
            l->failed = 1;
            return -1;
        }
        l->names = p;
        l->cap = cap;
    }
    if (!(l->names[l->count] = dup_str(name))) {
        l->failed = 1;
        return -1;
    }
    l->count++;
    return 0;
}

static void free_names(char **names, int count)
{
    for (int i = 0; i < count; i++) free(names[i]);
    free(names);
}

static int list_names(hid_t g, name_list *l)
{
    memset(l, 0, sizeof *l);
    hsize_t idx = 0;
    if (H5Literate(g, H5_INDEX_NAME, H5_ITER_INC, &idx, collect_name, l) < 0 || l->failed) {
        free_names(l->names, l->count);
        memset(l, 0, sizeof *l);
        return -1;
    }
    return 0;
}

/* "Step#N" with N a plain non-negative decimal -> N, else -1. */
static long frame_step(const char *name)
{
    size_t plen = strlen(FRAME_PREFIX);
    if (strncmp(name, FRAME_PREFIX, plen) != 0) return -1;
    const char *digits = name + plen;
    if (*digits < '0' || *digits > '9') return -1;
    char *end;
    errno = 0;
    long n = strtol(digits, &end, 10);
    return (*end || errno) ? -1 : n;
}

/* 1 if type t (closed here) is a standard IEEE float or integer. A damaged file can
 * declare, say, a 260-byte float, and HDF5 1.10's conversion of that to double writes out
 * of bounds: such data is refused before it is read. */
static int standard_number_type(hid_t t)
{
    if (t < 0) return 0;
    const hid_t ok[] = {H5T_IEEE_F32LE, H5T_IEEE_F64LE, H5T_IEEE_F32BE, H5T_IEEE_F64BE,
                        H5T_STD_I8LE,   H5T_STD_I16LE,  H5T_STD_I32LE,  H5T_STD_I64LE,
                        H5T_STD_U8LE,   H5T_STD_U16LE,  H5T_STD_U32LE,  H5T_STD_U64LE,
                        H5T_STD_I32BE,  H5T_STD_I64BE,  H5T_STD_U32BE,  H5T_STD_U64BE};
    int good = 0;
    for (size_t i = 0; i < sizeof ok / sizeof ok[0] && !good; i++)
        good = H5Tequal(t, ok[i]) > 0;
    H5Tclose(t);
    return good;
}

/* Number of elements of a 1-D dataset, or -1 (absent, wrong rank, too large, not a
 * standard number type). */
static long dataset_len_1d(hid_t g, const char *name)
{
    if (H5Lexists(g, name, H5P_DEFAULT) <= 0) return -1;
    hid_t d = H5Dopen2(g, name, H5P_DEFAULT);
    hid_t s = d < 0 ? -1 : H5Dget_space(d);
    hsize_t dim = 0;
    long len = -1;
    if (s >= 0 && standard_number_type(H5Dget_type(d)) && H5Sget_simple_extent_ndims(s) == 1 &&
        H5Sget_simple_extent_dims(s, &dim, NULL) == 1 && dim <= 0x7fffffff)
        len = (long)dim;
    close_id(s);
    close_id(d);
    return len;
}

static int read_attr_double(hid_t obj, const char *name, double *value)
{
    if (H5Aexists(obj, name) <= 0) return -1;
    hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
    hid_t s = a < 0 ? -1 : H5Aget_space(a);
    int rc = -1;
    if (s >= 0 && H5Sget_simple_extent_npoints(s) == 1 && standard_number_type(H5Aget_type(a)) &&
        H5Aread(a, H5T_NATIVE_DOUBLE, value) >= 0)
        rc = 0;
    close_id(s);
    close_id(a);
    return rc;
}

/* A frame is complete when it has TimeValue and six datasets of one common length. */
static int probe_frame(hid_t file, const char *name, rframe *fr)
{
    hid_t g = H5Gopen2(file, name, H5P_DEFAULT);
    if (g < 0) return -1;
    int ok = read_attr_double(g, "TimeValue", &fr->t) == 0;
    long n = dataset_len_1d(g, "x");
    for (int c = 0; c < 3 && ok; c++)
        ok = dataset_len_1d(g, pos_names[c]) == n && dataset_len_1d(g, vel_names[c]) == n;
    H5Gclose(g);
    if (!ok || n < 0) return -1;
    fr->n = (int)n;
    return 0;
}

static int cmp_frame(const void *a, const void *b)
{
    long x = ((const rframe *)a)->step, y = ((const rframe *)b)->step;
    return (x > y) - (x < y);
}

static int scan_frames(stf_h5r *r, const name_list *root)
{
    r->frames = malloc((size_t)(root->count > 0 ? root->count : 1) * sizeof *r->frames);
    if (!r->frames) return -1;
    for (int i = 0; i < root->count; i++) {
        rframe fr = {frame_step(root->names[i]), 0, 0};
        if (fr.step >= 0 && probe_frame(r->file, root->names[i], &fr) == 0)
            r->frames[r->nframes++] = fr;
    }
    qsort(r->frames, (size_t)r->nframes, sizeof *r->frames, cmp_frame);
    return 0;
}

static int scan_bodies(stf_h5r *r)
{
    if (H5Lexists(r->file, "bodies", H5P_DEFAULT) <= 0) return 0;
    hid_t g = H5Gopen2(r->file, "bodies", H5P_DEFAULT);
    if (g < 0) return 0; /* not a group: ignore */
    name_list l;
    int rc = list_names(g, &l);
    H5Gclose(g);
    r->bodies = l.names;
    r->nbodies = l.count;
    return rc;
}

/* Why the file is not ours, or NULL if it is. */
static const char *check_layout(stf_h5r *r)
{
    name_list root;
    if (list_names(r->file, &root) != 0) return "cannot list the root group";
    int has_frame_group = 0;
    for (int i = 0; i < root.count; i++) has_frame_group |= frame_step(root.names[i]) >= 0;
    int ours = has_frame_group || H5Aexists(r->file, FORMAT_ATTR) > 0;
    int rc = ours ? scan_frames(r, &root) : 0;
    free_names(root.names, root.count);
    if (!ours) return "no " FRAME_PREFIX "N groups";
    if (rc != 0 || scan_bodies(r) != 0) return "cannot read its index";
    return NULL;
}

int stf_h5r_open(const char *path, stf_h5r **out, char *err, size_t errlen)
{
    *out = NULL;
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    FILE *probe = fopen(path, "rb"); /* a missing file deserves its errno */
    if (!probe) {
        fmt_err(err, errlen, "%s: %s", path, strerror(errno));
        return -1;
    }
    unsigned char sig[8];
    int hdf5_sig = fread(sig, 1, sizeof sig, probe) == sizeof sig && !memcmp(sig, "\211HDF\r\n\032\n", 8);
    fclose(probe);
    stf_h5r *r = calloc(1, sizeof *r);
    if (!r) {
        fmt_err(err, errlen, "%s: out of memory", path);
        return -1;
    }
    r->file = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (r->file < 0) {
        if (hdf5_sig) /* an HDF5 start, an unreadable rest: a copy cut short, a run killed early */
            fmt_err(err, errlen, "%s: an HDF5 file that cannot be opened: cut short or damaged (a "
                                 "run killed before its first frame was written leaves one)", path);
        else fmt_err(err, errlen, "%s: not an stf output file (not a readable HDF5 file)", path);
        free(r);
        return -1;
    }
    const char *why = check_layout(r);
    if (why) {
        fmt_err(err, errlen, "%s: not an stf output file (%s)", path, why);
        stf_h5r_close(r);
        return -1;
    }
    *out = r;
    return 0;
}

void stf_h5r_close(stf_h5r *r)
{
    if (!r) return;
    close_id(r->file);
    free(r->frames);
    free_names(r->bodies, r->nbodies);
    free(r);
}

int stf_h5r_frames(const stf_h5r *r) { return r ? r->nframes : 0; }

static const rframe *get_frame(const stf_h5r *r, int frame)
{
    return (r && frame >= 0 && frame < r->nframes) ? &r->frames[frame] : NULL;
}

double stf_h5r_frame_time(const stf_h5r *r, int frame)
{
    const rframe *fr = get_frame(r, frame);
    return fr ? fr->t : NAN;
}

int stf_h5r_frame_count(const stf_h5r *r, int frame)
{
    const rframe *fr = get_frame(r, frame);
    return fr ? fr->n : -1;
}

static hid_t open_frame_group(const stf_h5r *r, const rframe *fr)
{
    char gname[32];
    snprintf(gname, sizeof gname, FRAME_PREFIX "%ld", fr->step);
    return H5Gopen2(r->file, gname, H5P_DEFAULT);
}

/* Reads three 1-D datasets into the interleaved out[3n], converting to double; the memory
 * hyperslab (start c, stride 3) does the interleaving without a temporary. */
static int read_interleaved(hid_t g, const char *const names[3], int n, double *out)
{
    hsize_t mdim = 3 * (hsize_t)n;
    hid_t mspace = H5Screate_simple(1, &mdim, NULL);
    int rc = mspace < 0 ? -1 : 0;
    for (int c = 0; c < 3 && rc == 0; c++) {
        hsize_t start = (hsize_t)c, stride = 3, count = (hsize_t)n;
        hid_t d = H5Dopen2(g, names[c], H5P_DEFAULT);
        if (d < 0 ||
            H5Sselect_hyperslab(mspace, H5S_SELECT_SET, &start, &stride, &count, NULL) < 0 ||
            H5Dread(d, H5T_NATIVE_DOUBLE, mspace, H5S_ALL, H5P_DEFAULT, out) < 0)
            rc = -1;
        close_id(d);
    }
    close_id(mspace);
    return rc;
}

int stf_h5r_read_frame(const stf_h5r *r, int frame, double *xyz, double *v)
{
    const rframe *fr = get_frame(r, frame);
    if (!fr) return -1;
    if (fr->n == 0 || (!xyz && !v)) return 0;
    hid_t g = open_frame_group(r, fr);
    if (g < 0) return -1;
    int rc = 0;
    if (xyz) rc = read_interleaved(g, pos_names, fr->n, xyz);
    if (rc == 0 && v) rc = read_interleaved(g, vel_names, fr->n, v);
    H5Gclose(g);
    return rc;
}

int stf_h5r_read_khist(const stf_h5r *r, int frame, float *k)
{
    const rframe *fr = get_frame(r, frame);
    if (!fr) return -1;
    hid_t g = open_frame_group(r, fr);
    if (g < 0) return -1;
    int rc = dataset_len_1d(g, "khist") == fr->n ? 0 : -1;
    if (rc == 0 && fr->n > 0) {
        hid_t d = H5Dopen2(g, "khist", H5P_DEFAULT);
        if (d < 0 || H5Dread(d, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, k) < 0)
            rc = -1;
        close_id(d);
    }
    H5Gclose(g);
    return rc;
}

int stf_h5r_attr_double(const stf_h5r *r, const char *name, double *value)
{
    return r ? read_attr_double(r->file, name, value) : -1;
}

/* Reads a scalar string attribute of either kind (variable or fixed length). */
static char *read_string(hid_t a, hid_t ftype)
{
    char *s = NULL;
    hid_t mt = H5Tcopy(H5T_C_S1);
    /* HDF5 does not convert between character sets: read in the file's. */
    if (mt < 0) return NULL;
    if (H5Tset_cset(mt, H5Tget_cset(ftype)) < 0) {
        H5Tclose(mt);
        return NULL;
    }
    if (H5Tis_variable_str(ftype) > 0) {
        char *vs = NULL;
        if (H5Tset_size(mt, H5T_VARIABLE) >= 0 && H5Aread(a, mt, &vs) >= 0 && vs) {
            s = dup_str(vs);
            H5free_memory(vs);
        }
    } else {
        size_t size = H5Tget_size(ftype);
        s = calloc(size + 1, 1); /* fixed strings need not be terminated */
        if (s && (H5Tset_size(mt, size + 1) < 0 || H5Aread(a, mt, s) < 0)) {
            free(s);
            s = NULL;
        }
    }
    H5Tclose(mt);
    return s;
}

char *stf_h5r_attr_string(const stf_h5r *r, const char *name)
{
    if (!r || H5Aexists(r->file, name) <= 0) return NULL;
    hid_t a = H5Aopen(r->file, name, H5P_DEFAULT);
    hid_t t = a < 0 ? -1 : H5Aget_type(a);
    hid_t s = a < 0 ? -1 : H5Aget_space(a);
    char *out = NULL;
    if (t >= 0 && s >= 0 && H5Tget_class(t) == H5T_STRING &&
        H5Sget_simple_extent_npoints(s) == 1)
        out = read_string(a, t);
    close_id(s);
    close_id(t);
    close_id(a);
    return out;
}

int stf_h5r_body_count(const stf_h5r *r) { return r ? r->nbodies : 0; }

const char *stf_h5r_body_name(const stf_h5r *r, int i)
{
    return (r && i >= 0 && i < r->nbodies) ? r->bodies[i] : NULL;
}

/* Rows of series s in body g if its shape is right, else -1. */
static long series_rows(hid_t g, int s)
{
    hid_t d = H5Dopen2(g, body_names[s], H5P_DEFAULT);
    hid_t sp = d < 0 ? -1 : H5Dget_space(d);
    int rank = body_cols[s] ? 2 : 1;
    hsize_t dims[2] = {0, 0};
    long rows = -1;
    if (sp >= 0 && standard_number_type(H5Dget_type(d)) &&
        H5Sget_simple_extent_dims(sp, dims, NULL) == rank &&
        (rank == 1 || dims[1] == (hsize_t)body_cols[s]) && dims[0] <= 0x7fffffff)
        rows = (long)dims[0];
    close_id(sp);
    close_id(d);
    return rows;
}

/* Reads the first `rows` rows of series s into a new array. */
static double *read_series(hid_t g, int s, long rows)
{
    int cols = body_cols[s] ? body_cols[s] : 1, rank = body_cols[s] ? 2 : 1;
    double *buf = malloc((size_t)(rows > 0 ? rows : 1) * (size_t)cols * sizeof *buf);
    if (!buf || rows == 0) return buf;
    hsize_t start[2] = {0, 0}, count[2] = {(hsize_t)rows, (hsize_t)cols};
    hid_t d = H5Dopen2(g, body_names[s], H5P_DEFAULT);
    hid_t fs = d < 0 ? -1 : H5Dget_space(d);
    hid_t ms = H5Screate_simple(rank, count, NULL);
    int ok = fs >= 0 && ms >= 0 &&
             H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, NULL, count, NULL) >= 0 &&
             H5Dread(d, H5T_NATIVE_DOUBLE, ms, fs, H5P_DEFAULT, buf) >= 0;
    close_id(ms);
    close_id(fs);
    close_id(d);
    if (!ok) {
        free(buf);
        return NULL;
    }
    return buf;
}

static hid_t open_body(const stf_h5r *r, const char *name)
{
    for (int i = 0; i < r->nbodies; i++) {
        if (strcmp(r->bodies[i], name) != 0) continue;
        hid_t b = H5Gopen2(r->file, "bodies", H5P_DEFAULT);
        hid_t g = b < 0 ? -1 : H5Gopen2(b, name, H5P_DEFAULT);
        close_id(b);
        return g;
    }
    return -1;
}

int stf_h5r_body_series(const stf_h5r *r, const char *name, double **time, double **pos,
                        double **quat, double **vel, double **angvel, double **force)
{
    double **outs[BODY_SERIES] = {time, pos, quat, vel, angvel, force};
    for (int s = 0; s < BODY_SERIES; s++)
        if (outs[s]) *outs[s] = NULL;
    hid_t g = r && name ? open_body(r, name) : -1;
    if (g < 0) return -1;
    /* A kill between two datasets' appends leaves them one row apart: use the shortest. */
    long rows = 0x7fffffff;
    for (int s = 0; s < BODY_SERIES && rows >= 0; s++) {
        long k = series_rows(g, s);
        rows = k < rows ? k : rows;
    }
    int rc = rows >= 0 ? 0 : -1;
    for (int s = 0; s < BODY_SERIES && rc == 0; s++)
        if (outs[s] && !(*outs[s] = read_series(g, s, rows))) rc = -1;
    H5Gclose(g);
    if (rc != 0) {
        for (int s = 0; s < BODY_SERIES; s++)
            if (outs[s]) {
                free(*outs[s]);
                *outs[s] = NULL;
            }
        return -1;
    }
    return (int)rows;
}

/* ====================================================================================
 * checkpoints
 * ==================================================================================== */

#define CKPT_NAME "checkpoint"
#define CKPT_NEW "checkpoint.new"

static hid_t state_file_type(int type)
{
    switch (type) {
    case STF_STATE_F64: return H5T_IEEE_F64LE;
    case STF_STATE_F32: return H5T_IEEE_F32LE;
    case STF_STATE_I32: return H5T_STD_I32LE;
    default: return H5T_STD_I64LE;
    }
}

static hid_t state_mem_type(int type)
{
    switch (type) {
    case STF_STATE_F64: return H5T_NATIVE_DOUBLE;
    case STF_STATE_F32: return H5T_NATIVE_FLOAT;
    case STF_STATE_I32: return H5T_NATIVE_INT32;
    default: return H5T_NATIVE_INT64;
    }
}

static int write_entry(hid_t g, const stf_state_entry *e)
{
    hsize_t n = e->count;
    hid_t space = H5Screate_simple(1, &n, NULL), mem = H5S_ALL;
    if (e->rows > 0 && n > 0) { /* rows runs of n / rows elements, stride apart */
        hsize_t dims[2] = {e->rows, e->stride}, start[2] = {0, 0}, count[2] = {e->rows, n / e->rows};
        mem = H5Screate_simple(2, dims, NULL);
        if (mem < 0 || H5Sselect_hyperslab(mem, H5S_SELECT_SET, start, NULL, count, NULL) < 0) {
            close_id(mem);
            mem = -1;
        }
    }
    hid_t d = space < 0 || mem < 0 ? -1
                                   : H5Dcreate2(g, e->name, state_file_type(e->type), space,
                                                H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    int rc = d >= 0 && (n == 0 || H5Dwrite(d, state_mem_type(e->type), mem, H5S_ALL,
                                           H5P_DEFAULT, e->data) >= 0)
                 ? 0 : -1;
    close_id(d);
    if (mem != H5S_ALL) close_id(mem);
    close_id(space);
    return rc;
}

static int unlink_if_there(hid_t file, const char *name)
{
    htri_t there = H5Lexists(file, name, H5P_DEFAULT);
    return there < 0 || (there > 0 && H5Ldelete(file, name, H5P_DEFAULT) < 0) ? -1 : 0;
}

int stf_h5_write_checkpoint(stf_h5 *h, const stf_state *st)
{
    if (!h || ensure_open(h) != 0) return -1;
    hid_t g = st->failed ? -1 : H5Gcreate_anon(h->file, H5P_DEFAULT, H5P_DEFAULT);
    int rc = g >= 0 ? 0 : -1;
    for (int k = 0; k < st->n && rc == 0; k++) rc = write_entry(g, &st->e[k]);
    /* as for frames: the unlinked group and the new end of allocation reach the disk
       before the link does (stf_h5_write_frame) */
    if (rc == 0 && (unlink_if_there(h->file, CKPT_NEW) != 0 ||
                    H5Fflush(h->file, H5F_SCOPE_GLOBAL) < 0 ||
                    H5Olink(g, h->file, CKPT_NEW, H5P_DEFAULT, H5P_DEFAULT) < 0 ||
                    H5Fflush(h->file, H5F_SCOPE_GLOBAL) < 0))
        rc = -1;
    close_id(g);
    if (rc == 0 && (unlink_if_there(h->file, CKPT_NAME) != 0 ||
                    H5Lmove(h->file, CKPT_NEW, h->file, CKPT_NAME, H5P_DEFAULT, H5P_DEFAULT) < 0 ||
                    flush_and_bound(h) < 0))
        rc = -1;
    if (rc != 0) snprintf(h->err, sizeof h->err, "cannot write /" CKPT_NAME);
    else h->ckpt_removed = 0;
    return rc;
}

int stf_h5_delete_checkpoint(stf_h5 *h)
{
    if (!h || ensure_open(h) != 0) return -1;
    /* this run's checkpoint or an earlier run's (a resumed file): its space goes at the close */
    int there = H5Lexists(h->file, CKPT_NAME, H5P_DEFAULT) > 0 || H5Lexists(h->file, CKPT_NEW, H5P_DEFAULT) > 0;
    if (unlink_if_there(h->file, CKPT_NEW) == 0 && unlink_if_there(h->file, CKPT_NAME) == 0 &&
        H5Fflush(h->file, H5F_SCOPE_GLOBAL) >= 0) {
        h->ckpt_removed |= there;
        return 0;
    }
    snprintf(h->err, sizeof h->err, "cannot remove /" CKPT_NAME);
    return -1;
}

/* Reads dataset name of g into a new entry of st. */
static int read_entry(hid_t g, const char *name, stf_state *st)
{
    static const int types[4] = {STF_STATE_F64, STF_STATE_F32, STF_STATE_I32, STF_STATE_I64};
    hid_t d = H5Dopen2(g, name, H5P_DEFAULT);
    hid_t t = d < 0 ? -1 : H5Dget_type(d);
    hid_t s = d < 0 ? -1 : H5Dget_space(d);
    int type = -1, rc = -1;
    for (int k = 0; k < 4 && t >= 0; k++)
        if (H5Tequal(t, state_file_type(types[k])) > 0) type = types[k];
    hsize_t n = 0;
    if (type >= 0 && s >= 0 && H5Sget_simple_extent_ndims(s) == 1 &&
        H5Sget_simple_extent_dims(s, &n, NULL) == 1 && n < ((hsize_t)1 << 40)) {
        void *buf = malloc((size_t)(n > 0 ? n : 1) * stf_state_type_size(type));
        if (buf && (n == 0 || H5Dread(d, state_mem_type(type), H5S_ALL, H5S_ALL, H5P_DEFAULT,
                                      buf) >= 0)) {
            stf_state_put_owned(st, name, type, (size_t)n, buf);
            rc = st->failed ? -1 : 0;
        } else {
            free(buf);
        }
    }
    close_id(s);
    close_id(t);
    close_id(d);
    return rc;
}

int stf_h5_read_checkpoint(const char *path, stf_state *st, char *err, size_t errlen)
{
    memset(st, 0, sizeof *st);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    hid_t file = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (file < 0) {
        fmt_err(err, errlen, "%s: not a readable HDF5 file", path);
        return -1;
    }
    const char *which = H5Lexists(file, CKPT_NEW, H5P_DEFAULT) > 0   ? CKPT_NEW
                        : H5Lexists(file, CKPT_NAME, H5P_DEFAULT) > 0 ? CKPT_NAME
                                                                      : NULL;
    if (!which) {
        H5Fclose(file);
        return 1;
    }
    hid_t g = H5Gopen2(file, which, H5P_DEFAULT);
    name_list l = {0};
    int rc = g >= 0 && list_names(g, &l) == 0 ? 0 : -1;
    for (int k = 0; rc == 0 && k < l.count; k++) rc = read_entry(g, l.names[k], st);
    free_names(l.names, l.count);
    close_id(g);
    H5Fclose(file);
    if (rc != 0) {
        fmt_err(err, errlen, "%s: cannot read /%s", path, which);
        stf_state_free(st);
    }
    return rc;
}

/* Cuts every series of every body to rows; -1 if one is shorter. */
static int truncate_bodies(hid_t file, long rows)
{
    if (H5Lexists(file, "bodies", H5P_DEFAULT) <= 0) return 0; /* a scene without bodies */
    hid_t g = H5Gopen2(file, "bodies", H5P_DEFAULT);
    name_list l;
    if (g < 0 || list_names(g, &l) != 0) {
        close_id(g);
        return -1;
    }
    int rc = 0;
    for (int b = 0; b < l.count && rc == 0; b++) {
        hid_t body = H5Gopen2(g, l.names[b], H5P_DEFAULT);
        for (int s = 0; s < BODY_ALL && rc == 0; s++) {
            if (body >= 0 && series_missing(body, s)) continue;
            hid_t d = body < 0 ? -1 : H5Dopen2(body, body_names[s], H5P_DEFAULT);
            hid_t sp = d < 0 ? -1 : H5Dget_space(d);
            hsize_t dims[2] = {0, 0};
            int rank = sp < 0 ? -1 : H5Sget_simple_extent_dims(sp, dims, NULL);
            rc = rank >= 1 && dims[0] >= (hsize_t)rows ? 0 : -1;
            dims[0] = (hsize_t)rows;
            if (rc == 0 && H5Dset_extent(d, dims) < 0) rc = -1;
            close_id(sp);
            close_id(d);
        }
        close_id(body);
    }
    free_names(l.names, l.count);
    H5Gclose(g);
    return rc;
}

/* Reads /body_meshes/NAME/vertices and the triangles' count into a new entry of h; marks
 * the frames below `frames` that have the mesh placed and removes the later ones. */
static int keep_mesh(stf_h5 *h, hid_t all, const char *name, int frames)
{
    hid_t g = H5Gopen2(all, name, H5P_DEFAULT);
    hid_t d = g < 0 ? -1 : H5Dopen2(g, "vertices", H5P_DEFAULT);
    hid_t s = d < 0 ? -1 : H5Dget_space(d);
    hid_t td = g < 0 ? -1 : H5Dopen2(g, "triangles", H5P_DEFAULT);
    hid_t ts = td < 0 ? -1 : H5Dget_space(td);
    hsize_t vd[2] = {0, 0}, tdims[2] = {0, 0};
    double *v = NULL;
    int rc = s >= 0 && ts >= 0 && H5Sget_simple_extent_dims(s, vd, NULL) == 2 && vd[1] == 3 &&
                     H5Sget_simple_extent_dims(ts, tdims, NULL) == 2 && tdims[1] == 3 &&
                     vd[0] > 0 && vd[0] < (1u << 24) && tdims[0] < (1u << 24)
                 ? 0 : -1;
    if (rc == 0 && (!(v = malloc(sizeof *v * 3 * (size_t)vd[0])) ||
                    H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v) < 0))
        rc = -1;
    close_id(ts);
    close_id(td);
    close_id(s);
    close_id(d);
    mesh_info *m = NULL;
    if (rc == 0 && !(m = add_mesh(h, name, v, (int)vd[0], (int)tdims[0]))) rc = -1;
    if (rc != 0 && !m) free(v);
    name_list l = {0};
    if (rc == 0 && list_names(g, &l) != 0) rc = -1;
    for (int i = 0; i < l.count && rc == 0; i++) {
        long k = frame_step(l.names[i]);
        if (k < 0) continue;
        if (k >= frames) rc = H5Ldelete(g, l.names[i], H5P_DEFAULT) < 0 ? -1 : 0;
        else rc = mark_placed(m, (int)k);
    }
    free_names(l.names, l.count);
    close_id(g);
    return rc;
}

static int keep_meshes(stf_h5 *h, int frames)
{
    if (H5Lexists(h->file, MESH_GROUP, H5P_DEFAULT) <= 0) return 0; /* none, or an older file */
    hid_t all = H5Gopen2(h->file, MESH_GROUP, H5P_DEFAULT);
    name_list l = {0};
    int rc = all >= 0 && list_names(all, &l) == 0 ? 0 : -1;
    for (int i = 0; i < l.count && rc == 0; i++) rc = keep_mesh(h, all, l.names[i], frames);
    free_names(l.names, l.count);
    close_id(all);
    return rc;
}

/* Checks that frames 0..frames-1 are complete and remembers them (for the sidecar). On
 * success drop holds the root's names with those of the later frames first (drop->count of
 * them; free with free_names(drop->names, drop->cap)). */
static int keep_frames(stf_h5 *h, int frames, name_list *drop)
{
    memset(drop, 0, sizeof *drop);
    name_list root;
    if (list_names(h->file, &root) != 0) return -1;
    int m = 0;
    for (int i = 0; i < root.count; i++) {
        if (frame_step(root.names[i]) >= frames) {
            char *t = root.names[m];
            root.names[m++] = root.names[i];
            root.names[i] = t;
        }
    }
    int rc = 0;
    for (int k = 0; k < frames && rc == 0; k++) {
        char gname[32];
        rframe fr = {k, 0, 0};
        snprintf(gname, sizeof gname, FRAME_PREFIX "%d", k);
        if (H5Lexists(h->file, gname, H5P_DEFAULT) <= 0 || probe_frame(h->file, gname, &fr) != 0) {
            rc = -1;
            break;
        }
        hid_t g = H5Gopen2(h->file, gname, H5P_DEFAULT);
        int has_khist = g >= 0 && H5Lexists(g, "khist", H5P_DEFAULT) > 0;
        int has_id = g >= 0 && H5Lexists(g, "id", H5P_DEFAULT) > 0;
        close_id(g);
        rc = remember_frame(h, fr.t, fr.n, has_khist, has_id);
    }
    if (rc != 0) {
        free_names(root.names, root.count);
        return -1;
    }
    drop->names = root.names;
    drop->count = m;
    drop->cap = root.count;
    return 0;
}

int stf_h5_open_resume(const char *path, int frames, long body_rows, stf_h5 **out, char *err,
                       size_t errlen)
{
    *out = NULL;
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    stf_h5 *h = calloc(1, sizeof *h);
    if (!h || !(h->path = dup_str(path))) {
        free(h);
        fmt_err(err, errlen, "%s: out of memory", path);
        return -1;
    }
    if (open_file(h) != 0) {
        fmt_err(err, errlen, "%s: cannot open the HDF5 file for writing", path);
        free_writer(h);
        return -1;
    }
    name_list drop;
    if (frames < 1 || keep_frames(h, frames, &drop) != 0) {
        fmt_err(err, errlen, "%s: the %d frames the checkpoint follows are not all there", path,
                frames);
        stf_h5_abort(h);
        return -1;
    }
    int rc = 0;
    for (int i = 0; i < drop.count && rc == 0; i++)
        rc = H5Ldelete(h->file, drop.names[i], H5P_DEFAULT) < 0 ? -1 : 0;
    free_names(drop.names, drop.cap);
    if (rc == 0) rc = truncate_bodies(h->file, body_rows);
    if (rc == 0) rc = keep_meshes(h, frames);
    if (rc == 0 && (H5Aexists(h->file, "exit_status") > 0 &&
                    H5Adelete(h->file, "exit_status") < 0))
        rc = -1;
    if (rc == 0) rc = unlink_if_there(h->file, "metrics");
    if (rc == 0 && flush_and_bound(h) < 0) rc = -1;
    if (rc != 0) {
        fmt_err(err, errlen, "%s: cannot cut the file back to its checkpoint", path);
        stf_h5_abort(h);
        return -1;
    }
    *out = h;
    return 0;
}
