/* render.c - `stf render OUT.h5`: PNG frames (and an mp4 if ffmpeg is around) or a montage
 * of chosen frames, drawn with a perspective camera: particles as shaded sphere splats,
 * rigid bodies as shaded solids, the container as a wireframe box, a time caption. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "cli.h"
#include "body_mesh.h"
#include "canvas.h"
#include "h5io.h"
#include "pictures.h"
#include "stf.h"

#define SS 2 /* supersampling factor of the 3-D part */
#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static const cli_usage USAGE = {
    "render",
    "usage: stf render OUT.h5 [-o DIR] [--frames all|N|A:B|a,b,...] [--every K] [--width W]\n"
    "                  [--height H] [--color speed|khist|none] [--max V] [--camera x,y,z]\n"
    "                  [--look x,y,z] [--montage FILE.png]\n",
    "Draws frames of a run's file (the particles, the bodies, the container) as PNG pictures,\n"
    "DIR/frame_0000.png ..., and DIR/movie.mp4 (30 frames/s) when ffmpeg is on the PATH.\n"
    "options:\n"
    "  -o DIR               the pictures' directory, made if missing (default: OUT_frames, OUT\n"
    "                       without .h5); frame_NNNN.png files after the new ones are removed\n"
    "  --frames SPEC        the file's frames, from 0: all (default), N, A:B (inclusive, either\n"
    "                       end may be left out) or a,b,c\n"
    "  --every K            every K-th frame of all or A:B (K >= 1, default 1)\n"
    "  --width W            picture width in pixels, 16 to 8192 (default 960, a montage's\n"
    "                       panels 480)\n"
    "  --height H           picture height in pixels, 16 to 8192 (default 720, montage 400)\n"
    "  --color MODE         particle colour: speed (m/s), khist (history stiffness) or none\n"
    "                       (default none: one colour)\n"
    "  --max V              the top of the colour scale, > 0, in the colour's unit (default:\n"
    "                       the 99th percentile over the frames drawn); needs --color\n"
    "  --camera x,y,z       the eye, m (default: from -y and a little +x, 35 degrees up, far\n"
    "                       enough to see the whole scene)\n"
    "  --look x,y,z         the point looked at, m (default: the centre of the scene's bounds)\n"
    "  --montage FILE.png   one picture of up to 16 frames, 4 a row, instead of DIR (default\n"
    "                       frames: 4 spread over the run)\n"
    "exit codes: 0 written, 2 bad input (bad option, unreadable file) or a write error\n"};

enum color_mode { COLOR_NONE, COLOR_SPEED, COLOR_KHIST };

/* ---------------------------------------------------------------- small vector helpers */

static void sub3(const double a[3], const double b[3], double o[3])
{
    for (int k = 0; k < 3; k++) o[k] = a[k] - b[k];
}
static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void cross3(const double a[3], const double b[3], double o[3])
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}
static int norm3(double a[3])
{
    double n = sqrt(dot3(a, a));
    if (!(n > 0)) return -1;
    for (int k = 0; k < 3; k++) a[k] /= n;
    return 0;
}
/* v rotated by the unit quaternion q = (w, x, y, z). */
static void qrot(const double q[4], const double v[3], double o[3])
{
    const double u[3] = {q[1], q[2], q[3]};
    double t[3], c[3];
    cross3(u, v, t);
    for (int k = 0; k < 3; k++) t[k] *= 2;
    cross3(u, t, c);
    for (int k = 0; k < 3; k++) o[k] = v[k] + q[0] * t[k] + c[k];
}

/* ---------------------------------------------------------------- camera */

typedef struct camera {
    double eye[3], fwd[3], right[3], up[3];
    double f;      /* focal length, pixels */
    double cx, cy; /* image centre, pixels */
} camera;

static int camera_aim(camera *cam, const double eye[3], const double look[3], int w, int h,
                      double fov_deg)
{
    memcpy(cam->eye, eye, sizeof cam->eye);
    sub3(look, eye, cam->fwd);
    if (norm3(cam->fwd) != 0) return -1;
    const double zup[3] = {0, 0, 1}, yup[3] = {0, 1, 0};
    cross3(cam->fwd, zup, cam->right);
    if (norm3(cam->right) != 0) { /* looking straight up or down */
        cross3(cam->fwd, yup, cam->right);
        if (norm3(cam->right) != 0) return -1;
    }
    cross3(cam->right, cam->fwd, cam->up);
    cam->f = (h / 2.0) / tan(fov_deg * M_PI / 360.0);
    cam->cx = w / 2.0;
    cam->cy = h / 2.0;
    return 0;
}

/* Screen position and depth of p; returns -1 if p is (nearly) behind the camera. */
static int project(const camera *cam, const double p[3], double *sx, double *sy, double *depth)
{
    double d[3];
    sub3(p, cam->eye, d);
    double z = dot3(d, cam->fwd);
    if (z < 1e-6) return -1;
    *sx = cam->cx + cam->f * dot3(d, cam->right) / z;
    *sy = cam->cy - cam->f * dot3(d, cam->up) / z;
    *depth = z;
    return 0;
}

/* ---------------------------------------------------------------- the file's content */

typedef struct body_view {
    char name[64];
    int shape;            /* enum stf_shape; sphere when the scene is unreadable */
    double radius, half_length, half[3];
    double *points;       /* convex hull points (body frame), owned */
    int npoints;
    int *tris, ntris;     /* hull faces (convex, box) */
    int n;                /* series length */
    double *time, *pos, *quat;
} body_view;

typedef struct scene_view {
    stf_h5r *r;
    const char *path;
    char name[64];
    double spacing;
    int has_container;
    double box_lo[3], box_hi[3]; /* container inner box up to the wall height */
    int nbodies;
    body_view *bodies;
} scene_view;

static void scene_view_free(scene_view *v)
{
    for (int i = 0; i < v->nbodies; i++) {
        body_view *b = &v->bodies[i];
        free(b->points);
        free(b->tris);
        free(b->time);
        free(b->pos);
        free(b->quat);
    }
    free(v->bodies);
    if (v->r) stf_h5r_close(v->r);
}

/* The hull faces of a box's corners or a convex body's points: the triangles of the body's
 * mesh (src/io/body_mesh.c, the one the XDMF sidecar holds), whose vertices are the points in
 * their order, so the faces index b->points. */
static void hull_faces(body_view *b)
{
    stf_collider_def d = stf_default_collider_def();
    d.shape = STF_SHAPE_CONVEX;
    d.points = b->points;
    d.npoints = b->npoints;
    stf_mesh m;
    if (stf_mesh_build(&d, &m) != 0) return;
    int *t = malloc(3 * (size_t)m.nt * sizeof *t);
    if (t) {
        for (int i = 0; i < 3 * m.nt; i++) t[i] = m.t[i];
        b->tris = t;
        b->ntris = m.nt;
    }
    stf_mesh_free(&m);
}

static int load_view(const char *path, scene_view *v, char *err, size_t errlen)
{
    memset(v, 0, sizeof *v);
    v->path = path;
    if (stf_h5r_open(path, &v->r, err, errlen) != 0) return -1;
    if (stf_h5r_frames(v->r) < 1) {
        snprintf(err, errlen, "%s: the file has no frames", path);
        return -1;
    }
    if (stf_h5r_attr_double(v->r, "spacing", &v->spacing) != 0 || !(v->spacing > 0)) {
        snprintf(err, errlen, "%s: no valid 'spacing' attribute", path);
        return -1;
    }
    double c[6];
    const char *names[6] = {"container_x0", "container_y0", "container_z0",
                            "container_x1", "container_y1", "container_z1"};
    v->has_container = 1;
    for (int i = 0; i < 6; i++)
        if (stf_h5r_attr_double(v->r, names[i], &c[i]) != 0 || !isfinite(c[i])) v->has_container = 0;
    if (v->has_container) {
        for (int k = 0; k < 3; k++) {
            v->box_lo[k] = c[k];
            v->box_hi[k] = c[3 + k];
        }
        v->box_hi[2] = c[2] + (c[5] - c[2]) / 2; /* z1 is twice the wall height */
    }

    /* body shapes from the scene text (if it loads); else spheres of the half height */
    stf_scene *sc = NULL;
    char *text = stf_h5r_attr_string(v->r, "scene");
    char serr[512];
    if (text && stf_scene_load_string("scene", text, NULL, 0, &sc, serr, sizeof serr) != 0) sc = NULL;
    free(text);
    if (sc) snprintf(v->name, sizeof v->name, "%s", sc->name);

    int nb = stf_h5r_body_count(v->r);
    v->bodies = calloc(nb > 0 ? (size_t)nb : 1, sizeof *v->bodies);
    if (!v->bodies) {
        if (sc) stf_scene_free(sc);
        snprintf(err, errlen, "out of memory");
        return -1;
    }
    for (int i = 0; i < nb; i++) {
        const char *name = stf_h5r_body_name(v->r, i);
        body_view *b = &v->bodies[v->nbodies];
        if (!name) continue;
        snprintf(b->name, sizeof b->name, "%s", name);
        b->n = stf_h5r_body_series(v->r, name, &b->time, &b->pos, &b->quat, NULL, NULL, NULL);
        if (b->n <= 0) {
            free(b->time);
            free(b->pos);
            free(b->quat);
            memset(b, 0, sizeof *b);
            continue;
        }
        v->nbodies++;
        char key[128];
        double hh = v->spacing;
        snprintf(key, sizeof key, "body.%s.half_height", name);
        stf_h5r_attr_double(v->r, key, &hh);
        b->shape = STF_SHAPE_SPHERE;
        b->radius = hh;
        const stf_body_def *def = NULL;
        for (int k = 0; sc && k < sc->nbodies; k++)
            if (!strcmp(sc->bodies[k].name, name)) def = &sc->bodies[k];
        if (!def) continue;
        const stf_collider_def *s = &def->shape;
        b->shape = s->shape;
        b->radius = s->radius;
        b->half_length = s->half_length;
        memcpy(b->half, s->half, sizeof b->half);
        if (s->shape == STF_SHAPE_BOX) {
            b->npoints = 8;
            b->points = malloc(24 * sizeof *b->points);
            for (int m = 0; b->points && m < 8; m++)
                for (int k = 0; k < 3; k++) b->points[3 * m + k] = (m >> k & 1) ? s->half[k] : -s->half[k];
            if (!b->points) b->npoints = 0;
        } else if (s->shape == STF_SHAPE_CONVEX && s->points && s->npoints > 0) {
            b->points = malloc(3 * (size_t)s->npoints * sizeof *b->points);
            if (b->points) {
                memcpy(b->points, s->points, 3 * (size_t)s->npoints * sizeof *b->points);
                b->npoints = s->npoints;
            }
        }
        if (b->npoints) hull_faces(b);
        if (s->shape == STF_SHAPE_CYLINDER) { /* flat ends: the mesh (rings of 32), not spheres */
            stf_mesh m;
            if (stf_mesh_build(s, &m) == 0) {
                b->points = malloc(3 * (size_t)m.nv * sizeof *b->points);
                b->tris = malloc(3 * (size_t)m.nt * sizeof *b->tris);
                if (b->points && b->tris) {
                    memcpy(b->points, m.v, 3 * (size_t)m.nv * sizeof *b->points);
                    for (int e = 0; e < 3 * m.nt; e++) b->tris[e] = m.t[e];
                    b->npoints = m.nv;
                    b->ntris = m.nt;
                } else {
                    free(b->points);
                    free(b->tris);
                    b->points = NULL;
                    b->tris = NULL;
                }
                stf_mesh_free(&m);
            }
        }
    }
    if (sc) stf_scene_free(sc);
    if (!v->name[0]) {
        const char *base = strrchr(path, '/');
        snprintf(v->name, sizeof v->name, "%s", base ? base + 1 : path);
    }
    return 0;
}

/* Body pose at time t: position interpolated, orientation normalised-lerped. */
static void body_pose(const body_view *b, double t, double pos[3], double q[4])
{
    int lo = 0, hi = b->n - 1;
    if (t <= b->time[0]) hi = 0;
    else if (t >= b->time[b->n - 1]) lo = hi;
    else {
        while (hi - lo > 1) {
            int mid = (lo + hi) / 2;
            if (b->time[mid] <= t) lo = mid;
            else hi = mid;
        }
    }
    double a = 0;
    if (hi != lo && b->time[hi] > b->time[lo]) a = (t - b->time[lo]) / (b->time[hi] - b->time[lo]);
    for (int k = 0; k < 3; k++) pos[k] = b->pos[3 * lo + k] * (1 - a) + b->pos[3 * hi + k] * a;
    double s = dot3(b->quat + 4 * lo + 1, b->quat + 4 * hi + 1) + b->quat[4 * lo] * b->quat[4 * hi];
    double sign = s < 0 ? -1 : 1, n = 0;
    for (int k = 0; k < 4; k++) {
        q[k] = b->quat[4 * lo + k] * (1 - a) + sign * b->quat[4 * hi + k] * a;
        n += q[k] * q[k];
    }
    n = sqrt(n);
    if (!(n > 0)) {
        q[0] = 1, q[1] = q[2] = q[3] = 0;
    } else
        for (int k = 0; k < 4; k++) q[k] /= n;
}

/* ---------------------------------------------------------------- colours */

static void ramp(double t, float out[3])
{
    /* dark blue, blue, cyan, yellow, red */
    static const float stops[5][3] = {{0.10f, 0.15f, 0.55f}, {0.15f, 0.45f, 0.95f},
                                      {0.20f, 0.85f, 0.85f}, {0.98f, 0.85f, 0.20f},
                                      {0.90f, 0.18f, 0.12f}};
    if (!(t > 0)) t = 0;
    if (t > 1) t = 1;
    double s = t * 4;
    int i = (int)s;
    if (i > 3) i = 3;
    double f = s - i;
    for (int k = 0; k < 3; k++) out[k] = (float)(stops[i][k] * (1 - f) + stops[i + 1][k] * f);
}

static const float FLUID_RGB[3] = {0.25f, 0.50f, 0.88f};
static const float BODY_RGB[3] = {0.55f, 0.08f, 0.08f};
static const float TEXT_RGB[3] = {0.08f, 0.08f, 0.10f};
static const float WHITE[3] = {1, 1, 1};

/* ---------------------------------------------------------------- drawing */

typedef struct render_opts {
    int width, height;
    int color;
    double vmax; /* colour scale, > 0 */
    const char *cbar_label;
} render_opts;

static void draw_segment3(canvas *c, const camera *cam, const double a[3], const double b[3],
                          const float rgb[3], double width, double bias)
{
    /* subdivided so the depth along the edge is right under perspective */
    const int N = 24;
    double prev[3] = {0, 0, 0}, ps[3] = {0, 0, 0};
    int have = 0;
    for (int i = 0; i <= N; i++) {
        double p[3];
        for (int k = 0; k < 3; k++) p[k] = a[k] + (b[k] - a[k]) * i / N;
        int ok = project(cam, p, &ps[0], &ps[1], &ps[2]) == 0;
        if (ok && have)
            canvas_line_depth(c, prev[0], prev[1], prev[2], ps[0], ps[1], ps[2], rgb, width, bias);
        have = ok;
        memcpy(prev, ps, sizeof prev);
    }
}

static void draw_container(canvas *c, const camera *cam, const scene_view *v, int floor_pass)
{
    const double *lo = v->box_lo, *hi = v->box_hi;
    double corner[8][3];
    for (int m = 0; m < 8; m++)
        for (int k = 0; k < 3; k++) corner[m][k] = (m >> k & 1) ? hi[k] : lo[k];
    if (floor_pass) {
        /* the floor as a light quad (depth is cleared afterwards: it is background) */
        double q[4][3];
        int idx[4] = {0, 1, 3, 2};
        for (int i = 0; i < 4; i++)
            if (project(cam, corner[idx[i]], &q[i][0], &q[i][1], &q[i][2]) != 0) return;
        const float floor_rgb[3] = {0.80f, 0.80f, 0.78f};
        canvas_triangle(c, q[0], q[1], q[2], floor_rgb);
        canvas_triangle(c, q[0], q[2], q[3], floor_rgb);
        canvas_clear_depth(c);
        return;
    }
    const float edge_rgb[3] = {0.25f, 0.27f, 0.30f};
    for (int m = 0; m < 8; m++)
        for (int k = 0; k < 3; k++) {
            int n = m | (1 << k);
            if (n == m) continue;
            draw_segment3(c, cam, corner[m], corner[n], edge_rgb, 1.6 * SS, v->spacing * 0.5);
        }
}

/* A world-space light for flat faces (from above, front, left). */
static void face_color(const double n[3], const float base[3], float out[3])
{
    double l[3] = {-0.35, -0.5, 0.8};
    norm3(l);
    double d = dot3(n, l);
    if (d < 0) d = 0;
    for (int k = 0; k < 3; k++) out[k] = (float)(base[k] * (0.35 + 0.65 * d));
}

static void draw_body(canvas *c, const camera *cam, const body_view *b, double t, double spacing)
{
    double pos[3], q[4];
    body_pose(b, t, pos, q);
    if (b->ntris > 0) {
        for (int f = 0; f < b->ntris; f++) {
            double w[3][3], s[3][3];
            int ok = 1;
            for (int i = 0; i < 3; i++) {
                qrot(q, b->points + 3 * b->tris[3 * f + i], w[i]);
                for (int k = 0; k < 3; k++) w[i][k] += pos[k];
                ok &= project(cam, w[i], &s[i][0], &s[i][1], &s[i][2]) == 0;
            }
            if (!ok) continue;
            double e1[3], e2[3], n[3];
            sub3(w[1], w[0], e1);
            sub3(w[2], w[0], e2);
            cross3(e1, e2, n);
            if (norm3(n) != 0) continue;
            float col[3];
            face_color(n, BODY_RGB, col);
            canvas_triangle(c, s[0], s[1], s[2], col);
        }
        if (b->shape == STF_SHAPE_BOX) { /* dark edges */
            const float edge[3] = {0.2f, 0.03f, 0.03f};
            for (int m = 0; m < 8; m++)
                for (int k = 0; k < 3; k++) {
                    int n = m | (1 << k);
                    if (n == m) continue;
                    double a[3], bb[3];
                    qrot(q, b->points + 3 * m, a);
                    qrot(q, b->points + 3 * n, bb);
                    for (int j = 0; j < 3; j++) a[j] += pos[j], bb[j] += pos[j];
                    draw_segment3(c, cam, a, bb, edge, 1.2 * SS, spacing * 0.2);
                }
        }
        return;
    }
    /* sphere; a capsule as a chain of spheres along the local z axis (a cylinder is a mesh) */
    double len = b->shape == STF_SHAPE_CAPSULE || b->shape == STF_SHAPE_CYLINDER ? b->half_length : 0;
    double r = b->radius > 0 ? b->radius : spacing;
    int steps = len > 0 ? (int)ceil(2 * len / (r * 0.25)) : 0;
    for (int i = 0; i <= steps; i++) {
        double local[3] = {0, 0, steps ? -len + 2 * len * i / steps : 0}, p[3];
        qrot(q, local, p);
        for (int k = 0; k < 3; k++) p[k] += pos[k];
        double sx, sy, d;
        if (project(cam, p, &sx, &sy, &d) != 0) continue;
        canvas_sphere(c, sx, sy, cam->f * r / d, d, r, BODY_RGB);
    }
    /* a marker on a sphere's surface shows its rotation */
    if (b->shape == STF_SHAPE_SPHERE && len == 0) {
        const float mark[3] = {0.95f, 0.85f, 0.80f};
        for (int i = 0; i < 3; i++) {
            double local[3] = {0, 0, 0}, p[3];
            local[i] = r * 0.999;
            qrot(q, local, p);
            for (int k = 0; k < 3; k++) p[k] += pos[k];
            double sx, sy, d;
            if (project(cam, p, &sx, &sy, &d) != 0) continue;
            canvas_sphere(c, sx, sy, cam->f * r * 0.12 / d, d - r * 0.02, r * 0.12, mark);
        }
    }
}

static void format_time(double t, char *buf, size_t n)
{
    snprintf(buf, n, "t = %.3f s", t);
}

/* A horizontal colour bar with 0 and vmax at the bottom right. */
static void draw_colorbar(canvas *c, const render_opts *o, int scale)
{
    int bw = c->w / 4 < 220 ? c->w / 4 : 220, bh = 10 * scale / 2 + 4;
    int x0 = c->w - bw - 14 * scale / 2 - 8, y0 = c->h - bh - 22 * scale / 2 - 14;
    const float frame[3] = {0.2f, 0.2f, 0.2f};
    canvas_rect(c, x0 - 1, y0 - 1, x0 + bw + 1, y0 + bh + 1, frame);
    for (int x = 0; x < bw; x++) {
        float col[3];
        ramp((double)x / (bw - 1), col);
        canvas_rect(c, x0 + x, y0, x0 + x + 1, y0 + bh, col);
    }
    char hi[32];
    snprintf(hi, sizeof hi, "%.3g", o->vmax);
    int ty = y0 + bh + 4;
    canvas_text_halo(c, x0, ty, "0", TEXT_RGB, WHITE, scale);
    canvas_text_halo(c, x0 + bw - canvas_text_width(hi, scale), ty, hi, TEXT_RGB, WHITE, scale);
    int lw = canvas_text_width(o->cbar_label, scale);
    canvas_text_halo(c, x0 + bw / 2 - lw / 2, y0 - canvas_text_height(scale) - 5, o->cbar_label,
                     TEXT_RGB, WHITE, scale);
}

/* Renders frame fr into a new width x height canvas. */
static canvas *render_frame(const scene_view *v, const camera *cam_ss, const render_opts *o, int fr,
                            int text_scale, char *err, size_t errlen)
{
    int n = stf_h5r_frame_count(v->r, fr);
    double t = stf_h5r_frame_time(v->r, fr);
    double *x = n > 0 ? malloc(3 * (size_t)n * sizeof *x) : NULL;
    double *vel = n > 0 ? malloc(3 * (size_t)n * sizeof *vel) : NULL;
    float *kh = n > 0 && o->color == COLOR_KHIST ? malloc((size_t)n * sizeof *kh) : NULL;
    canvas *big = canvas_new(o->width * SS, o->height * SS);
    canvas *out = NULL;
    if (n < 0 || !big || (n > 0 && (!x || !vel || (o->color == COLOR_KHIST && !kh)))) {
        snprintf(err, errlen, "%s: frame %d: out of memory or bad frame", v->path, fr);
        goto done;
    }
    if (n > 0 && stf_h5r_read_frame(v->r, fr, x, vel) != 0) {
        snprintf(err, errlen, "%s: cannot read frame %d", v->path, fr);
        goto done;
    }
    if (kh && stf_h5r_read_khist(v->r, fr, kh) != 0) {
        snprintf(err, errlen, "%s: frame %d has no khist dataset (--color khist needs one)", v->path, fr);
        goto done;
    }
    const float top[3] = {0.93f, 0.95f, 0.98f}, bottom[3] = {0.99f, 0.99f, 0.99f};
    canvas_fill_gradient(big, top, bottom);
    if (v->has_container) draw_container(big, cam_ss, v, 1);

    double rad = v->spacing / 2;
    for (int i = 0; i < n; i++) {
        double sx, sy, d;
        if (!isfinite(x[3 * i]) || !isfinite(x[3 * i + 1]) || !isfinite(x[3 * i + 2])) continue;
        if (project(cam_ss, x + 3 * i, &sx, &sy, &d) != 0) continue;
        float col[3];
        if (o->color == COLOR_SPEED) ramp(sqrt(dot3(vel + 3 * i, vel + 3 * i)) / o->vmax, col);
        else if (o->color == COLOR_KHIST) ramp(kh[i] / o->vmax, col);
        else memcpy(col, FLUID_RGB, sizeof col);
        canvas_sphere(big, sx, sy, cam_ss->f * rad / d, d, rad, col);
    }
    for (int b = 0; b < v->nbodies; b++) draw_body(big, cam_ss, &v->bodies[b], t, v->spacing);
    if (v->has_container) draw_container(big, cam_ss, v, 0);

    out = canvas_downsample(big, SS);
    if (!out) {
        snprintf(err, errlen, "out of memory");
        goto done;
    }
    char cap[64];
    format_time(t, cap, sizeof cap);
    int m = 6 * text_scale;
    canvas_text_halo(out, m, m, cap, TEXT_RGB, WHITE, text_scale);
    if (text_scale >= 2) {
        int s1 = text_scale - 1 > 1 ? text_scale - 1 : 1;
        char info[96];
        snprintf(info, sizeof info, "%s  frame %d", v->name, fr);
        canvas_text_halo(out, out->w - m - canvas_text_width(info, s1), m, info, TEXT_RGB, WHITE, s1);
    }
    if (o->color != COLOR_NONE) draw_colorbar(out, o, text_scale > 1 ? text_scale - 1 : 1);
done:
    canvas_free(big);
    free(x);
    free(vel);
    free(kh);
    return out;
}

/* ---------------------------------------------------------------- options */

static int parse_vec3(const char *s, double out[3])
{
    char *end;
    for (int k = 0; k < 3; k++) {
        out[k] = strtod(s, &end);
        if (end == s || !isfinite(out[k])) return -1;
        s = end;
        if (k < 2) {
            if (*s != ',') return -1;
            s++;
        }
    }
    return *s ? -1 : 0;
}

static int parse_int(const char *s, int *out, int lo)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (end == s || *end || errno || v < lo || v > 100000) return -1;
    *out = (int)v;
    return 0;
}

/* --frames: "all", "N", "A:B" (inclusive, either end may be empty), "a,b,c". Fills a list
 * of frame indices (malloc'ed). Returns count, or -1 with err. */
static int select_frames(const char *spec, int nframes, int every, int **out, char *err, size_t errlen)
{
    int *list = malloc((size_t)nframes * sizeof *list + sizeof *list);
    int n = 0;
    if (!list) return -1;
    if (!strcmp(spec, "all") || strchr(spec, ':')) {
        int a = 0, b = nframes - 1;
        if (strcmp(spec, "all")) {
            const char *colon = strchr(spec, ':');
            char left[32] = "", right[32] = "";
            size_t ll = (size_t)(colon - spec);
            if (ll >= sizeof left || strlen(colon + 1) >= sizeof right) goto bad;
            memcpy(left, spec, ll);
            snprintf(right, sizeof right, "%s", colon + 1);
            if (left[0] && parse_int(left, &a, 0) != 0) goto bad;
            if (right[0] && parse_int(right, &b, 0) != 0) goto bad;
            if (b > nframes - 1) { /* an explicit end past the file is refused, not cut */
                snprintf(err, errlen, "--frames %s: frame %d out of range (the file has %d frames, "
                         "0..%d; 'A:' runs to the end)", spec, b, nframes, nframes - 1);
                free(list);
                return -1;
            }
            if (a > b) {
                snprintf(err, errlen, "--frames %s: no frames in that range (the file has %d frames, 0..%d)",
                         spec, nframes, nframes - 1);
                free(list);
                return -1;
            }
        }
        for (int i = a; i <= b; i += every) list[n++] = i;
    } else {
        const char *s = spec;
        while (*s) {
            char *end;
            errno = 0;
            long v = strtol(s, &end, 10);
            if (end == s || errno || v < 0) goto bad;
            if (v >= nframes) {
                snprintf(err, errlen, "--frames: frame %ld out of range (the file has %d frames, 0..%d)", v,
                         nframes, nframes - 1);
                free(list);
                return -1;
            }
            if (n < nframes) list[n++] = (int)v;
            s = end;
            if (*s == ',') s++;
            else if (*s) goto bad;
        }
        if (n == 0) goto bad;
    }
    *out = list;
    return n;
bad:
    snprintf(err, errlen, "--frames '%s': expected all, N, A:B or a,b,c", spec);
    free(list);
    return -1;
}

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* The 99th percentile of speed or khist over the chosen frames (sampled). */
static int color_scale(const scene_view *v, const int *frames, int nf, int mode, double *vmax,
                       char *err, size_t errlen)
{
    size_t total = 0;
    for (int i = 0; i < nf; i++) {
        int n = stf_h5r_frame_count(v->r, frames[i]);
        if (n > 0) total += (size_t)n;
    }
    size_t stride = total / 2000000 + 1, cnt = 0;
    float *vals = malloc((total / stride + 1 + (size_t)nf) * sizeof *vals);
    if (!vals) {
        snprintf(err, errlen, "out of memory");
        return -1;
    }
    for (int i = 0; i < nf; i++) {
        int n = stf_h5r_frame_count(v->r, frames[i]);
        if (n <= 0) continue;
        double *vel = mode == COLOR_SPEED ? malloc(3 * (size_t)n * sizeof *vel) : NULL;
        float *k = mode == COLOR_KHIST ? malloc((size_t)n * sizeof *k) : NULL;
        int rc = 0;
        if (mode == COLOR_SPEED) rc = vel ? stf_h5r_read_frame(v->r, frames[i], NULL, vel) : -1;
        else rc = k ? stf_h5r_read_khist(v->r, frames[i], k) : -1;
        if (rc != 0) {
            snprintf(err, errlen, mode == COLOR_KHIST ? "%s: frame %d has no khist dataset (--color khist needs one)"
                                                      : "%s: cannot read frame %d",
                     v->path, frames[i]);
            free(vel);
            free(k);
            free(vals);
            return -1;
        }
        for (int j = 0; j < n; j += (int)stride) {
            double s = mode == COLOR_SPEED ? sqrt(dot3(vel + 3 * j, vel + 3 * j)) : k[j];
            if (isfinite(s)) vals[cnt++] = (float)s;
        }
        free(vel);
        free(k);
    }
    double p = 0;
    if (cnt > 0) {
        qsort(vals, cnt, sizeof *vals, cmp_float);
        p = vals[(size_t)floor(0.99 * (double)(cnt - 1))];
    }
    free(vals);
    if (mode == COLOR_KHIST && !(p > 0)) /* said, not silently drawn in one colour */
        fprintf(stderr, "stf render: note: the history stiffness is 0 in the chosen frames (a run "
                        "without effects.history, or the Carreau-Yasuda model): one colour\n");
    *vmax = p > 0 ? p : 1;
    return 0;
}

/* Bounding box of the scene to frame: container (to the wall height), fluid of the first
 * frame, bodies at their first sample. */
static void scene_bounds(const scene_view *v, double lo[3], double hi[3])
{
    for (int k = 0; k < 3; k++) lo[k] = INFINITY, hi[k] = -INFINITY;
    if (v->has_container)
        for (int k = 0; k < 3; k++) lo[k] = v->box_lo[k], hi[k] = v->box_hi[k];
    int n = stf_h5r_frame_count(v->r, 0);
    double *x = n > 0 ? malloc(3 * (size_t)n * sizeof *x) : NULL;
    if (x && stf_h5r_read_frame(v->r, 0, x, NULL) == 0)
        for (int i = 0; i < n; i++)
            for (int k = 0; k < 3; k++)
                if (isfinite(x[3 * i + k])) {
                    lo[k] = fmin(lo[k], x[3 * i + k] - v->spacing / 2);
                    hi[k] = fmax(hi[k], x[3 * i + k] + v->spacing / 2);
                }
    free(x);
    for (int b = 0; b < v->nbodies; b++) {
        const body_view *bv = &v->bodies[b];
        double r = fmax(bv->radius + bv->half_length, fmax(bv->half[0], fmax(bv->half[1], bv->half[2])));
        for (int i = 0; i < bv->npoints; i++) r = fmax(r, sqrt(dot3(bv->points + 3 * i, bv->points + 3 * i)));
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], bv->pos[k] - r);
            hi[k] = fmax(hi[k], bv->pos[k] + r);
        }
    }
    for (int k = 0; k < 3; k++)
        if (!(lo[k] <= hi[k])) lo[k] = -0.1, hi[k] = 0.1;
}

#define FOV 30.0

/* Camera from the front (-y), a little from the side (+x), 35 degrees above, far enough
 * that the box fits into 88% of the picture; or the user's --camera / --look. */
static int make_camera(const scene_view *v, const double *eye_opt, const double *look_opt, int w,
                       int h, camera *cam)
{
    double lo[3], hi[3], centre[3];
    scene_bounds(v, lo, hi);
    for (int k = 0; k < 3; k++) centre[k] = (lo[k] + hi[k]) / 2;
    const double *look = look_opt ? look_opt : centre;
    if (eye_opt) return camera_aim(cam, eye_opt, look, w, h, FOV);
    double el = 35 * M_PI / 180, az = -68 * M_PI / 180;
    double dir[3] = {cos(el) * cos(az), cos(el) * sin(az), sin(el)};
    double size = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                       (hi[2] - lo[2]) * (hi[2] - lo[2]));
    double dist = size * 0.6;
    for (int it = 0; it < 400; it++, dist *= 1.03) {
        double eye[3];
        for (int k = 0; k < 3; k++) eye[k] = look[k] + dir[k] * dist;
        if (camera_aim(cam, eye, look, w, h, FOV) != 0) return -1;
        int fits = 1;
        for (int m = 0; m < 8 && fits; m++) {
            double p[3] = {(m & 1) ? hi[0] : lo[0], (m & 2) ? hi[1] : lo[1], (m & 4) ? hi[2] : lo[2]};
            double sx, sy, d;
            if (project(cam, p, &sx, &sy, &d) != 0 || fabs(sx - cam->cx) > 0.88 * w / 2 ||
                fabs(sy - cam->cy) > 0.84 * h / 2)
                fits = 0;
        }
        if (fits) return 0;
    }
    return 0;
}

/* ---------------------------------------------------------------- ffmpeg */

static int on_path(const char *prog)
{
    const char *path = getenv("PATH");
    if (!path) return 0;
    char buf[4096];
    while (*path) {
        const char *colon = strchr(path, ':');
        size_t len = colon ? (size_t)(colon - path) : strlen(path);
        if (len > 0 && len + strlen(prog) + 2 < sizeof buf) {
            memcpy(buf, path, len);
            buf[len] = '/';
            strcpy(buf + len + 1, prog);
            if (access(buf, X_OK) == 0) return 1;
        }
        path += len;
        if (*path == ':') path++;
    }
    return 0;
}

static int make_movie(const char *dir)
{
    size_t len = strlen(dir) + 32;
    char *in = malloc(len), *out = malloc(len);
    if (!in || !out) {
        free(in);
        free(out);
        return -1;
    }
    snprintf(in, len, "%s/frame_%%04d.png", dir);
    snprintf(out, len, "%s/movie.mp4", dir);
    pid_t pid = fork();
    if (pid == 0) {
        char *args[] = {"ffmpeg", "-y", "-loglevel", "error", "-framerate", "30", "-i", in,
                        "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-pix_fmt", "yuv420p", out, NULL};
        execvp("ffmpeg", args);
        _exit(127);
    }
    int status = 0, rc = -1;
    if (pid > 0 && waitpid(pid, &status, 0) == pid && WIFEXITED(status) && WEXITSTATUS(status) == 0) rc = 0;
    if (rc == 0) printf("stf render: wrote %s\n", out);
    free(in);
    free(out);
    return rc;
}

static int mkdirs(const char *dir)
{
    char buf[4096];
    if (strlen(dir) >= sizeof buf) return -1;
    strcpy(buf, dir);
    for (char *p = buf + 1; *p; p++)
        if (*p == '/') {
            *p = 0;
            if (mkdir(buf, 0777) != 0 && errno != EEXIST) return -1;
            *p = '/';
        }
    if (mkdir(buf, 0777) != 0 && errno != EEXIST) return -1;
    struct stat st;
    return stat(buf, &st) == 0 && S_ISDIR(st.st_mode) ? 0 : -1;
}

/* ---------------------------------------------------------------- the command */

int cli_render(int argc, char **argv)
{
    if (cli_help_asked(argc, argv)) return cli_help(&USAGE);
    const char *in = NULL, *dir_opt = NULL, *frames_opt = NULL, *montage = NULL;
    int every = 1, width = 0, height = 0, color = COLOR_NONE, have_eye = 0, have_look = 0, every_given = 0;
    double vmax_opt = 0, eye[3], look[3];
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        int has_val = i + 1 < argc;
        const char *val = has_val ? argv[i + 1] : NULL;
        int bad = 0;
        if (a[0] != '-') {
            if (in) return cli_usage_error(&USAGE, "unexpected argument '%s'", a);
            in = a;
            continue;
        } else if (!has_val) {
            static const char *const valued[] = {"-o", "--frames", "--montage", "--every", "--width",
                                                 "--height", "--camera", "--look", "--max", "--color",
                                                 NULL};
            return cli_missing_value(&USAGE, a, valued);
        } else if (!strcmp(a, "-o")) dir_opt = val;
        else if (!strcmp(a, "--frames")) frames_opt = val;
        else if (!strcmp(a, "--montage")) montage = val;
        else if (!strcmp(a, "--every")) bad = parse_int(val, &every, 1), every_given = 1;
        else if (!strcmp(a, "--width")) bad = parse_int(val, &width, 16);
        else if (!strcmp(a, "--height")) bad = parse_int(val, &height, 16);
        else if (!strcmp(a, "--camera")) bad = parse_vec3(val, eye), have_eye = 1;
        else if (!strcmp(a, "--look")) bad = parse_vec3(val, look), have_look = 1;
        else if (!strcmp(a, "--max")) {
            char *end;
            vmax_opt = strtod(val, &end);
            bad = end == val || *end || !(vmax_opt > 0) || !isfinite(vmax_opt);
        } else if (!strcmp(a, "--color")) {
            if (!strcmp(val, "speed")) color = COLOR_SPEED;
            else if (!strcmp(val, "khist")) color = COLOR_KHIST;
            else if (!strcmp(val, "none")) color = COLOR_NONE;
            else bad = 1;
        } else {
            return cli_usage_error(&USAGE, "unknown option '%s'", a);
        }
        if (bad) return cli_usage_error(&USAGE, "bad value '%s' for %s", val, a);
        i++;
    }
    if (!in) return cli_usage_error(&USAGE, "no output file given");
    if ((width > 8192 || height > 8192)) {
        fprintf(stderr, "stf render: --width/--height at most 8192\n");
        return 2;
    }
    if (montage && dir_opt) { /* one picture or a directory of frames, not both */
        fprintf(stderr, "stf render: -o DIR writes frames and --montage FILE.png one picture: "
                        "give one of them\n");
        return 2;
    }
    if (vmax_opt > 0 && color == COLOR_NONE) {
        fprintf(stderr, "stf render: --max is the top of the colour scale: give --color speed or khist\n");
        return 2;
    }
    if (every_given && frames_opt && strcmp(frames_opt, "all") && !strchr(frames_opt, ':')) {
        fprintf(stderr, "stf render: --every applies to --frames all or A:B, not to '%s'\n", frames_opt);
        return 2;
    }

    char err[1024];
    scene_view v;
    if (load_view(in, &v, err, sizeof err) != 0) {
        fprintf(stderr, "stf render: %s\n", err);
        scene_view_free(&v);
        return 2;
    }
    int rc = 2, *frames = NULL, nsel = 0;
    char *dir = NULL;
    int nframes = stf_h5r_frames(v.r);
    const char *spec = frames_opt ? frames_opt : "all";
    nsel = select_frames(spec, nframes, every, &frames, err, sizeof err);
    if (nsel < 0) {
        fprintf(stderr, "stf render: %s\n", err);
        goto out;
    }
    if (montage && !frames_opt && !every_given && nsel > 4) { /* four frames spread over the run */
        for (int i = 0; i < 4; i++) frames[i] = (int)lround((double)i * (nframes - 1) / 3);
        nsel = 4;
    }
    if (montage && nsel > 16) {
        fprintf(stderr, "stf render: --montage takes at most 16 frames (got %d)\n", nsel);
        goto out;
    }

    render_opts o = {0};
    o.width = width ? width : montage ? 480 : 960;
    o.height = height ? height : montage ? 400 : 720;
    o.color = color;
    o.cbar_label = color == COLOR_SPEED ? "speed (m/s)" : "k_hist";
    if (color != COLOR_NONE) {
        if (vmax_opt > 0) o.vmax = vmax_opt;
        else if (color_scale(&v, frames, nsel, color, &o.vmax, err, sizeof err) != 0) {
            fprintf(stderr, "stf render: %s\n", err);
            goto out;
        }
    }
    camera cam;
    if (make_camera(&v, have_eye ? eye : NULL, have_look ? look : NULL, o.width * SS, o.height * SS,
                    &cam) != 0) {
        fprintf(stderr, "stf render: --camera and --look must differ\n");
        goto out;
    }
    int text_scale = o.width >= 640 ? 3 : 2;

    if (montage) {
        int cols = nsel < 4 ? nsel : 4, rows = (nsel + cols - 1) / cols, gap = 6;
        canvas *m = canvas_new(cols * o.width + (cols + 1) * gap, rows * o.height + (rows + 1) * gap);
        if (!m) {
            fprintf(stderr, "stf render: out of memory\n");
            goto out;
        }
        canvas_fill(m, WHITE);
        for (int i = 0; i < nsel; i++) {
            canvas *p = render_frame(&v, &cam, &o, frames[i], 2, err, sizeof err);
            if (!p) {
                fprintf(stderr, "stf render: %s\n", err);
                canvas_free(m);
                goto out;
            }
            canvas_blit(m, p, gap + (i % cols) * (o.width + gap), gap + (i / cols) * (o.height + gap));
            canvas_free(p);
        }
        if (canvas_write_png(m, montage, err, sizeof err) != 0) {
            fprintf(stderr, "stf render: %s\n", err);
            canvas_free(m);
            goto out;
        }
        canvas_free(m);
        printf("stf render: wrote %s (%d frames)\n", montage, nsel);
        rc = 0;
        goto out;
    }

    if (dir_opt) dir = strdup(dir_opt);
    else {
        size_t len = strlen(in);
        dir = malloc(len + 8);
        if (dir) {
            strcpy(dir, in);
            if (len > 3 && !strcmp(dir + len - 3, ".h5")) dir[len - 3] = 0;
            strcat(dir, "_frames");
        }
    }
    if (!dir || mkdirs(dir) != 0) {
        fprintf(stderr, "stf render: cannot create directory %s: %s\n", dir ? dir : "?", strerror(errno));
        goto out;
    }
    /* Every frame goes to frame_NNNN.png.part first and is renamed once all are drawn: a
     * frame that cannot be read leaves the frames already in DIR as they were. */
    size_t plen = strlen(dir) + 32;
    char *png = malloc(plen), *part = malloc(plen);
    int written = 0;
    if (!png || !part) fprintf(stderr, "stf render: out of memory\n");
    for (; png && part && written < nsel; written++) {
        canvas *p = render_frame(&v, &cam, &o, frames[written], text_scale, err, sizeof err);
        snprintf(part, plen, "%s/frame_%04d.png.part", dir, written);
        unlink(part);
        if (!p || canvas_write_png(p, part, err, sizeof err) != 0) {
            fprintf(stderr, "stf render: %s\n", err);
            canvas_free(p);
            unlink(part);
            break;
        }
        canvas_free(p);
    }
    for (int i = 0; i < written; i++) {
        snprintf(part, plen, "%s/frame_%04d.png.part", dir, i);
        snprintf(png, plen, "%s/frame_%04d.png", dir, i);
        if (written < nsel) unlink(part);
        else if (rename(part, png) != 0) {
            fprintf(stderr, "stf render: %s: %s\n", png, strerror(errno));
            written = -1;
            break;
        }
    }
    /* the rest of a longer earlier render's sequence would continue this one's (and its movie) */
    for (int i = nsel; written == nsel && i <= 9999; i++) {
        snprintf(png, plen, "%s/frame_%04d.png", dir, i);
        if (unlink(png) != 0) break;
    }
    free(png);
    free(part);
    if (written != nsel) goto out;
    printf("stf render: wrote %d frames to %s/frame_0000.png .. frame_%04d.png (file frames %d..%d)\n",
           nsel, dir, nsel - 1, frames[0], frames[nsel - 1]);
    if (on_path("ffmpeg")) {
        if (make_movie(dir) != 0) fprintf(stderr, "stf render: ffmpeg failed; the frames are kept\n");
    } else {
        printf("stf render: ffmpeg not found on PATH, no movie written\n");
    }
    rc = 0;
out:
    free(dir);
    free(frames);
    scene_view_free(&v);
    return rc;
}
