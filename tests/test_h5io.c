/* test_h5io.c - the run output file: write frames, bodies, attributes and metrics, read
 * them back with the reader, check the XDMF sidecar, let h5dump and h5py open the file,
 * read a file left by a killed writer, and reject a file of random bytes. */
#define _POSIX_C_SOURCE 200809L
#include "h5io.h"
#include "test_util.h"

#include <hdf5.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
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
        CHECK(stf_h5_body_append(h, "ball", t, p, q, v, w, fo) == 0, "body row %d", row);
        if (row < 2) CHECK(stf_h5_body_append(h, "box", t, p, q, v, w, fo) == 0, "box row");
    }
    CHECK(stf_h5_body_append(h, "a/b", 0, frame_t, frame_t, frame_t, frame_t, frame_t) != 0,
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
    /* Every HDF5 object the module opened was closed (files included). */
    CHECK(H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_ALL) == 0, "open HDF5 ids: %ld",
          (long)H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_ALL));
    return test_result("test_h5io");
}
