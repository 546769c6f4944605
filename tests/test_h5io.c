/* test_h5io.c - the run output file: write frames, bodies, attributes and metrics, read
 * them back with the reader, check the XDMF sidecar, let h5dump and h5py open the file,
 * read a file left by a killed writer, and reject a file of random bytes; a writer that
 * releases the file between frames, with body meshes, readers in between and one in
 * another process holding it open. */
#define _POSIX_C_SOURCE 200809L
#include "h5io.h"
#include "stf.h"
#include "test_util.h"

#include <hdf5.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define NP 50 /* particles of the non-empty frames */
#define NROWS 5

static const double frame_t[4] = {0.0, 0.125, 0.25, 0.375};
static const int frame_n[4] = {NP, NP, NP, 0};

/* Deterministic, frame-dependent particle data. */
static void fill(int frame, int n, double *xyz, double *v, float *k, int32_t *id)
{
    for (int i = 0; i < 3 * n; i++) {
        xyz[i] = 0.01 * i + frame * 1.5 - 0.3;
        v[i] = -0.002 * i * (frame + 1) + 0.7;
    }
    for (int i = 0; i < n; i++) {
        k[i] = (float)(i * 0.25 + frame);
        id[i] = 1000 * frame + i;
    }
}

static void body_row(int row, double *t, double p[3], double q[4], double v[3], double w[3],
                     double f[3])
{
    *t = 0.01 * row;
    for (int c = 0; c < 3; c++) {
        p[c] = row + 0.1 * c;
        v[c] = -row - 0.2 * c;
        w[c] = 0.5 * row + c;
        f[c] = 100.0 * row - c;
    }
    for (int c = 0; c < 4; c++) q[c] = row * 0.01 + c;
}

/* A unique file name in the current directory (the build's tests/ dir under ctest). */
static void temp_name(char *buf, size_t len, const char *tag)
{
    snprintf(buf, len, "h5io_%s_XXXXXX", tag);
    int fd = mkstemp(buf);
    if (fd >= 0) close(fd);
}

static int write_frame_k(stf_h5 *h, int frame)
{
    double xyz[3 * NP], v[3 * NP];
    float k[NP];
    int32_t id[NP];
    fill(frame, frame_n[frame], xyz, v, k, id);
    return stf_h5_write_frame(h, frame_t[frame], frame_n[frame], xyz, v, k, id);
}

static void write_file(const char *path)
{
    char err[512];
    stf_h5 *h;
    CHECK(stf_h5_create(path, &h, err, sizeof err) == 0, "create: %s", err);
    if (!h) return;
    CHECK(stf_h5_attr_string(h, "scene", "name: test\nfluid: {}\n") == 0, "attr scene");
    CHECK(stf_h5_attr_string(h, "version", "0.0") == 0, "attr version");
    CHECK(stf_h5_attr_string(h, "version", "0.1.0") == 0, "attr version overwrite");
    CHECK(stf_h5_attr_double(h, "dt_min", 1e-5) == 0, "attr dt_min");
    CHECK(stf_h5_attr_long(h, "particles", 123456789012L) == 0, "attr particles");
    for (int f = 0; f < 4; f++) CHECK(write_frame_k(h, f) == 0, "frame %d", f);
    for (int row = 0; row < NROWS; row++) {
        double t, p[3], q[4], v[3], w[3], fo[3];
        body_row(row, &t, p, q, v, w, fo);
        CHECK(stf_h5_body_append(h, "ball", t, p, q, v, w, fo, NULL) == 0, "body row %d", row);
        if (row < 2) CHECK(stf_h5_body_append(h, "box", t, p, q, v, w, fo, NULL) == 0, "box row");
    }
    CHECK(stf_h5_body_append(h, "a/b", 0, frame_t, frame_t, frame_t, frame_t, frame_t, NULL) != 0,
          "body name with a slash accepted");
    CHECK(stf_h5_write_metrics_json(h, "{\"x\": 1}") == 0, "metrics");
    CHECK(stf_h5_close(h, err, sizeof err) == 0, "close: %s", err);
}

static void check_frames(const stf_h5r *r)
{
    CHECK(stf_h5r_frames(r) == 4, "frames %d", stf_h5r_frames(r));
    for (int f = 0; f < stf_h5r_frames(r) && f < 4; f++) {
        int n = frame_n[f];
        CHECK(stf_h5r_frame_count(r, f) == n, "frame %d count %d", f, stf_h5r_frame_count(r, f));
        CHECK_NEAR(stf_h5r_frame_time(r, f), frame_t[f], 0, "frame time");
        double xyz[3 * NP], v[3 * NP], gx[3 * NP], gv[3 * NP];
        float k[NP], gk[NP];
        int32_t id[NP];
        fill(f, n, xyz, v, k, id);
        CHECK(stf_h5r_read_frame(r, f, gx, gv) == 0, "read frame %d", f);
        CHECK(stf_h5r_read_khist(r, f, gk) == 0, "read khist %d", f);
        for (int i = 0; i < 3 * n; i++) {
            CHECK_NEAR(gx[i], xyz[i], 1e-6 * (1 + fabs(xyz[i])), "x");
            CHECK_NEAR(gv[i], v[i], 1e-6 * (1 + fabs(v[i])), "v");
        }
        for (int i = 0; i < n; i++) CHECK(gk[i] == k[i], "khist %d", i);
    }
    CHECK(stf_h5r_read_frame(r, 4, NULL, NULL) == -1, "frame out of range");
    CHECK(isnan(stf_h5r_frame_time(r, -1)), "time out of range");
}

static void check_bodies(const stf_h5r *r)
{
    CHECK(stf_h5r_body_count(r) == 2, "bodies %d", stf_h5r_body_count(r));
    CHECK(stf_h5r_body_name(r, 0) && !strcmp(stf_h5r_body_name(r, 0), "ball"), "name 0");
    CHECK(stf_h5r_body_name(r, 1) && !strcmp(stf_h5r_body_name(r, 1), "box"), "name 1");
    double *t, *p, *q, *v, *w, *f;
    int n = stf_h5r_body_series(r, "ball", &t, &p, &q, &v, &w, &f);
    CHECK(n == NROWS, "ball rows %d", n);
    for (int row = 0; row < n && row < NROWS; row++) {
        double et, ep[3], eq[4], ev[3], ew[3], ef[3];
        body_row(row, &et, ep, eq, ev, ew, ef);
        CHECK(t[row] == et, "time row %d", row);
        for (int c = 0; c < 3; c++) {
            CHECK(p[3 * row + c] == ep[c], "pos");
            CHECK(v[3 * row + c] == ev[c], "vel");
            CHECK(w[3 * row + c] == ew[c], "angvel");
            CHECK(f[3 * row + c] == ef[c], "force");
        }
        for (int c = 0; c < 4; c++) CHECK(q[4 * row + c] == eq[c], "quat");
    }
    free(t), free(p), free(q), free(v), free(w), free(f);
    CHECK(stf_h5r_body_series(r, "box", NULL, &p, NULL, NULL, NULL, NULL) == 2, "box rows");
    free(p);
    CHECK(stf_h5r_body_series(r, "nope", &t, NULL, NULL, NULL, NULL, NULL) == -1, "no body");
}

static void check_attrs(const stf_h5r *r)
{
    double d = 0;
    CHECK(stf_h5r_attr_double(r, "dt_min", &d) == 0 && d == 1e-5, "dt_min %g", d);
    CHECK(stf_h5r_attr_double(r, "particles", &d) == 0 && d == 123456789012.0, "particles");
    CHECK(stf_h5r_attr_double(r, "absent", &d) == -1, "absent attr");
    char *s = stf_h5r_attr_string(r, "version");
    CHECK(s && !strcmp(s, "0.1.0"), "version %s", s ? s : "(null)");
    free(s);
    s = stf_h5r_attr_string(r, "scene");
    CHECK(s && !strcmp(s, "name: test\nfluid: {}\n"), "scene");
    free(s);
    CHECK(stf_h5r_attr_string(r, "absent") == NULL, "absent string");
}

static void read_back(const char *path)
{
    char err[512];
    stf_h5r *r;
    CHECK(stf_h5r_open(path, &r, err, sizeof err) == 0, "open: %s", err);
    if (!r) return;
    check_frames(r);
    check_bodies(r);
    check_attrs(r);
    stf_h5r_close(r);
}

static void check_xdmf(const char *path)
{
    char xpath[256], buf[65536];
    snprintf(xpath, sizeof xpath, "%s.xmf", path);
    FILE *f = fopen(xpath, "r");
    CHECK(f != NULL, "no sidecar %s", xpath);
    if (!f) return;
    size_t len = fread(buf, 1, sizeof buf - 1, f);
    buf[len] = 0;
    fclose(f);
    for (int i = 0; i < 4; i++) {
        char want[300];
        snprintf(want, sizeof want, "Step#%d", i);
        CHECK(strstr(buf, want) != NULL, "sidecar lacks %s", want);
    }
    char want[300];
    snprintf(want, sizeof want, ">%s.h5:/Step#2/vz<", path);
    CHECK(strstr(buf, want) != NULL, "sidecar lacks %s", want);
    CHECK(strstr(buf, "CollectionType=\"Temporal\"") != NULL, "not temporal");
    remove(xpath);
}

/* Independent readers: h5dump and h5py. */
static void check_external(const char *path)
{
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "h5dump -H '%s' > /dev/null", path);
    CHECK(system(cmd) == 0, "%s", cmd);
    if (system("/usr/bin/python3 -c 'import h5py' 2>/dev/null") != 0) {
        printf("test_h5io: note: /usr/bin/python3 lacks h5py, skipping the h5py check\n");
        return;
    }
    snprintf(cmd, sizeof cmd,
             "/usr/bin/python3 -c \"import h5py,sys; f=h5py.File(sys.argv[1], 'r'); "
             "assert f['Step#2/x'].shape==(%d,); "
             "assert abs(f['Step#1'].attrs['TimeValue']-%.17g)<1e-12; "
             "assert f['bodies/ball/position'].shape==(%d,3); "
             "assert f['Step#3/x'].shape==(0,); "
             "assert f.attrs['version']=='0.1.0'; "
             "assert f['metrics'].attrs['json']=='{\\\"x\\\": 1}'\" '%s'",
             NP, frame_t[1], NROWS, path);
    CHECK(system(cmd) == 0, "%s", cmd);
}

/* A child writes two frames, starts a third group with only one dataset, and dies without
 * closing; the reader must see the two complete frames. */
static void check_killed(void)
{
    char path[64], err[512];
    temp_name(path, sizeof path, "killed");
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) {
        stf_h5 *h;
        if (stf_h5_create(path, &h, err, sizeof err) != 0) _exit(2);
        if (write_frame_k(h, 0) != 0 || write_frame_k(h, 1) != 0) _exit(3);
        /* Reopening an open file in the same process shares it: a way in to half a frame. */
        hid_t f = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
        hid_t g = H5Gcreate2(f, "Step#2", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        hsize_t n = 10;
        hid_t s = H5Screate_simple(1, &n, NULL);
        hid_t d = H5Dcreate2(g, "x", H5T_IEEE_F32LE, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        if (f < 0 || g < 0 || d < 0) _exit(4);
        H5Fflush(f, H5F_SCOPE_GLOBAL);
        raise(SIGKILL);
        _exit(5);
    }
    int status = 0;
    CHECK(pid > 0 && waitpid(pid, &status, 0) == pid, "fork/wait");
    CHECK(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL, "child status %d", status);
    stf_h5r *r;
    CHECK(stf_h5r_open(path, &r, err, sizeof err) == 0, "open killed: %s", err);
    if (r) {
        CHECK(stf_h5r_frames(r) == 2, "killed frames %d", stf_h5r_frames(r));
        double xyz[3 * NP], v[3 * NP], gx[3 * NP], gv[3 * NP];
        float k[NP];
        int32_t id[NP];
        fill(1, NP, xyz, v, k, id);
        CHECK(stf_h5r_frame_count(r, 1) == NP, "killed count");
        CHECK(stf_h5r_read_frame(r, 1, gx, gv) == 0, "killed read");
        for (int i = 0; i < 3 * NP; i++) CHECK_NEAR(gx[i], xyz[i], 1e-5, "killed x");
        stf_h5r_close(r);
    }
    remove(path);
}

static void check_corrupt(void)
{
    char path[64], err[512] = "";
    temp_name(path, sizeof path, "corrupt");
    FILE *f = fopen(path, "wb");
    srand(7);
    for (int i = 0; f && i < 4096; i++) fputc(rand() & 0xff, f);
    if (f) fclose(f);
    stf_h5r *r = (stf_h5r *)&r;
    CHECK(stf_h5r_open(path, &r, err, sizeof err) == -1, "random bytes opened");
    CHECK(r == NULL, "out not cleared");
    CHECK(strstr(err, path) && strstr(err, "not an stf output file"), "message: %s", err);
    remove(path);
    CHECK(stf_h5r_open(path, &r, err, sizeof err) == -1 && strstr(err, path), "missing: %s",
          err);
    stf_h5 *h;
    CHECK(stf_h5_create("/nonexistent-dir/x.h5", &h, err, sizeof err) == -1 &&
              strstr(err, "/nonexistent-dir/x.h5: "), "create in missing dir: %s", err);
}

/* 1 if dataset `name` exists in the file at path (opened read-only here). */
static int has_object(const char *path, const char *name)
{
    hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    int there = f >= 0 && H5Lexists(f, "body_meshes", H5P_DEFAULT) > 0 &&
                H5Lexists(f, "body_meshes/ball", H5P_DEFAULT) > 0 && H5Lexists(f, name, H5P_DEFAULT) > 0;
    if (f >= 0) H5Fclose(f);
    return there;
}

/* The mean of /body_meshes/ball/Step#k's vertices into c (a sphere's centre). */
static void mesh_centre(const char *path, int k, double c[3])
{
    char name[64];
    snprintf(name, sizeof name, "body_meshes/ball/Step#%d", k);
    c[0] = c[1] = c[2] = NAN;
    hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    hid_t d = f < 0 ? -1 : H5Dopen2(f, name, H5P_DEFAULT);
    hid_t s = d < 0 ? -1 : H5Dget_space(d);
    hsize_t dims[2] = {0, 0};
    if (s >= 0 && H5Sget_simple_extent_dims(s, dims, NULL) == 2 && dims[1] == 3 && dims[0] > 0) {
        float *v = malloc(sizeof *v * 3 * dims[0]);
        if (v && H5Dread(d, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, v) >= 0) {
            c[0] = c[1] = c[2] = 0;
            for (hsize_t i = 0; i < dims[0]; i++)
                for (int j = 0; j < 3; j++) c[j] += v[3 * i + (hsize_t)j] / (double)dims[0];
        }
        free(v);
    }
    if (s >= 0) H5Sclose(s);
    if (d >= 0) H5Dclose(d);
    if (f >= 0) H5Fclose(f);
}

static int file_has(const char *path, const char *text)
{
    static char buf[1 << 16];
    FILE *f = fopen(path, "r");
    size_t len = f ? fread(buf, 1, sizeof buf - 1, f) : 0;
    if (f) fclose(f);
    buf[len] = 0;
    return strstr(buf, text) != NULL;
}

/* A child that opens path with HDF5 (a reader's shared lock) and holds it for 1.5 s; returns
 * once it has the file open. */
static pid_t hold_open(const char *path)
{
    int fd[2];
    if (pipe(fd) != 0) return -1;
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) {
        close(fd[0]);
        hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
        char ok = f >= 0 ? 'y' : 'n';
        if (write(fd[1], &ok, 1) != 1) _exit(3);
        struct timespec ts = {1, 500000000L};
        nanosleep(&ts, NULL);
        int good = f >= 0 && H5Lexists(f, "Step#1", H5P_DEFAULT) > 0 && H5Fclose(f) >= 0;
        _exit(good ? 0 : 4);
    }
    close(fd[1]);
    char ok = 0;
    if (pid < 0 || read(fd[0], &ok, 1) != 1 || ok != 'y') pid = -1;
    close(fd[0]);
    return pid;
}

static void check_shared(void)
{
    char stem[64], path[80], xpath[80], err[512];
    temp_name(stem, sizeof stem, "shared");
    snprintf(path, sizeof path, "%s.h5", stem);
    snprintf(xpath, sizeof xpath, "%s.xmf", stem);
    stf_h5 *h;
    CHECK(stf_h5_create(path, &h, err, sizeof err) == 0, "create: %s", err);
    if (!h) return;
    stf_collider_def ball = stf_default_collider_def(), floor_def = ball;
    ball.shape = STF_SHAPE_SPHERE;
    ball.radius = 0.1;
    floor_def.shape = STF_SHAPE_PLANE;
    CHECK(stf_h5_body_mesh(h, "ball", &ball) == 0, "mesh: %s", stf_h5_last_error(h));
    CHECK(stf_h5_body_mesh(h, "floor", &floor_def) == 1, "a plane got a mesh");
    CHECK(stf_h5_body_mesh(h, "ball", &ball) == -1, "a body meshed twice");
    double p[3] = {1, 2, 3}, q[4] = {1, 0, 0, 0}, zero[3] = {0, 0, 0};
    pid_t holder = -1;
    for (int fr = 0; fr < 3; fr++) {
        CHECK(write_frame_k(h, fr) == 0, "frame %d: %s", fr, stf_h5_last_error(h));
        p[2] = 3 - fr;
        CHECK(stf_h5_body_pose(h, "ball", p, q) == 0, "pose %d: %s", fr, stf_h5_last_error(h));
        CHECK(stf_h5_body_pose(h, "floor", p, q) == 0, "pose of a body without a mesh");
        CHECK(stf_h5_release(h) == 0, "release %d: %s", fr, stf_h5_last_error(h));
        CHECK(file_has(xpath, "TopologyType=\"Triangle\""), "sidecar %d: no body grid", fr);
        /* released: body rows wait in memory */
        for (int row = 0; row < 2; row++)
            CHECK(stf_h5_body_append(h, "ball", fr + 0.1 * row, p, q, zero, zero, zero, NULL) == 0,
                  "row while released: %s", stf_h5_last_error(h));
        stf_h5r *r = NULL; /* a reader between frames (this process: the file is closed) */
        CHECK(stf_h5r_open(path, &r, err, sizeof err) == 0, "open between frames: %s", err);
        if (r) {
            CHECK(stf_h5r_frames(r) == fr + 1, "frames %d between frames", stf_h5r_frames(r));
            /* the rows kept since frame fr's release are not there (no body before frame 1) */
            CHECK(stf_h5r_body_series(r, "ball", NULL, NULL, NULL, NULL, NULL, NULL) ==
                      (fr ? 2 * fr : -1), "body rows before frame %d", fr);
            stf_h5r_close(r);
        }
        /* another process opens the file and holds it while frame 2 is written */
        if (fr == 1) CHECK((holder = hold_open(path)) > 0, "the holder could not open the file");
    }
    int status = -1;
    CHECK(holder > 0 && waitpid(holder, &status, 0) == holder && WIFEXITED(status) &&
              WEXITSTATUS(status) == 0, "holder status %d", status);
    CHECK(stf_h5_close(h, err, sizeof err) == 0, "close: %s", err);
    stf_h5r *r = NULL;
    CHECK(stf_h5r_open(path, &r, err, sizeof err) == 0, "open: %s", err);
    if (r) {
        CHECK(stf_h5r_frames(r) == 3, "frames %d", stf_h5r_frames(r));
        double *t = NULL;
        CHECK(stf_h5r_body_series(r, "ball", &t, NULL, NULL, NULL, NULL, NULL) == 6, "body rows");
        for (int i = 0; t && i < 6; i++) CHECK_NEAR(t[i], i / 2 + 0.1 * (i % 2), 1e-12, "row time");
        free(t);
        stf_h5r_close(r);
    }
    for (int fr = 0; fr < 3; fr++) {
        double c[3];
        mesh_centre(path, fr, c);
        CHECK(fabs(c[0] - 1) < 1e-6 && fabs(c[1] - 2) < 1e-6 && fabs(c[2] - (3 - fr)) < 1e-6,
              "mesh %d centre %g %g %g", fr, c[0], c[1], c[2]);
    }
    CHECK(!has_object(path, "body_meshes/floor"), "a plane's mesh");
    CHECK(file_has(xpath, ":/body_meshes/ball/Step#2<"), "sidecar: no ball at frame 2");
    CHECK(file_has(xpath, ":/body_meshes/ball/triangles<"), "sidecar: no triangles");
    /* a resume after frame 2 drops frame 2's mesh (and keeps the others) */
    CHECK(stf_h5_open_resume(path, 2, 4, &h, err, sizeof err) == 0, "resume: %s", err);
    CHECK(stf_h5_close(h, err, sizeof err) == 0, "close resumed: %s", err);
    CHECK(has_object(path, "body_meshes/ball/Step#1"), "resume dropped frame 1's mesh");
    CHECK(!has_object(path, "body_meshes/ball/Step#2"), "resume kept frame 2's mesh");
    CHECK(file_has(xpath, ":/body_meshes/ball/Step#1<") && !file_has(xpath, ":/body_meshes/ball/Step#2<"),
          "resumed sidecar");
    remove(path);
    remove(xpath);
    remove(stem);
}

int main(void)
{
    char stem[64], path[80];
    temp_name(stem, sizeof stem, "out");
    snprintf(path, sizeof path, "%s.h5", stem);
    write_file(path);
    read_back(path);
    check_xdmf(stem);
    check_external(path);
    remove(path);
    remove(stem);
    check_killed();
    check_corrupt();
    check_shared();
    /* Every HDF5 object the module opened was closed (files included). */
    CHECK(H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_ALL) == 0, "open HDF5 ids: %ld",
          (long)H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_ALL));
    return test_result("test_h5io");
}
