/* canvas.c - the raster of canvas.h: primitives, a 5x7 bitmap font and PNG output. */
#include "canvas.h"

#include <errno.h>
#include <math.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The index of pixel (x, y) of c, both inside it (x, y >= 0). */
static size_t pixel(const canvas *c, int x, int y) { return (size_t)y * (size_t)c->w + (size_t)x; }

canvas *canvas_new(int w, int h)
{
    if (w < 1 || h < 1 || (size_t)w * (size_t)h > ((size_t)1 << 28)) return NULL;
    canvas *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    c->w = w;
    c->h = h;
    c->rgb = calloc((size_t)w * (size_t)h * 3, sizeof *c->rgb);
    c->depth = malloc((size_t)w * (size_t)h * sizeof *c->depth);
    if (!c->rgb || !c->depth) {
        canvas_free(c);
        return NULL;
    }
    canvas_clear_depth(c);
    return c;
}

void canvas_free(canvas *c)
{
    if (!c) return;
    free(c->rgb);
    free(c->depth);
    free(c);
}

void canvas_fill(canvas *c, const float rgb[3])
{
    size_t n = (size_t)c->w * (size_t)c->h;
    for (size_t i = 0; i < n; i++) memcpy(c->rgb + 3 * i, rgb, 3 * sizeof(float));
}

void canvas_fill_gradient(canvas *c, const float top[3], const float bottom[3])
{
    for (int y = 0; y < c->h; y++) {
        float t = c->h > 1 ? (float)y / (float)(c->h - 1) : 0.f;
        float col[3];
        for (int k = 0; k < 3; k++) col[k] = top[k] + (bottom[k] - top[k]) * t;
        for (int x = 0; x < c->w; x++) memcpy(c->rgb + 3 * pixel(c, x, y), col, sizeof col);
    }
}

void canvas_clear_depth(canvas *c)
{
    size_t n = (size_t)c->w * (size_t)c->h;
    for (size_t i = 0; i < n; i++) c->depth[i] = INFINITY;
}

void canvas_blend(canvas *c, int x, int y, const float rgb[3], float a)
{
    if (x < 0 || y < 0 || x >= c->w || y >= c->h || !(a > 0)) return;
    if (a > 1) a = 1;
    float *p = c->rgb + 3 * pixel(c, x, y);
    for (int k = 0; k < 3; k++) p[k] += (rgb[k] - p[k]) * a;
}

static int clampi(int v, int lo, int hi) { return v < lo ? lo : v > hi ? hi : v; }

/* Coverage-based segment: each pixel near the segment gets 1 - (distance - w/2) clamped. */
static void segment(canvas *c, double x0, double y0, double z0, double x1, double y1, double z1,
                    const float rgb[3], double width, int depth_test, double bias)
{
    double hw = width / 2;
    int xa = clampi((int)floor(fmin(x0, x1) - hw - 1), 0, c->w - 1);
    int xb = clampi((int)ceil(fmax(x0, x1) + hw + 1), 0, c->w - 1);
    int ya = clampi((int)floor(fmin(y0, y1) - hw - 1), 0, c->h - 1);
    int yb = clampi((int)ceil(fmax(y0, y1) + hw + 1), 0, c->h - 1);
    if (fmax(x0, x1) + hw + 1 < 0 || fmin(x0, x1) - hw - 1 > c->w) return;
    if (fmax(y0, y1) + hw + 1 < 0 || fmin(y0, y1) - hw - 1 > c->h) return;
    double dx = x1 - x0, dy = y1 - y0, len2 = dx * dx + dy * dy;
    for (int y = ya; y <= yb; y++)
        for (int x = xa; x <= xb; x++) {
            double px = x + 0.5 - x0, py = y + 0.5 - y0;
            double t = len2 > 0 ? (px * dx + py * dy) / len2 : 0;
            t = t < 0 ? 0 : t > 1 ? 1 : t;
            double ex = px - t * dx, ey = py - t * dy;
            double d = sqrt(ex * ex + ey * ey);
            double a = hw + 0.5 - d;
            if (a <= 0) continue;
            if (depth_test) {
                double z = z0 + (z1 - z0) * t;
                if (z > c->depth[pixel(c, x, y)] + bias) continue;
            }
            canvas_blend(c, x, y, rgb, (float)(a > 1 ? 1 : a));
        }
}

void canvas_line(canvas *c, double x0, double y0, double x1, double y1, const float rgb[3],
                 double width)
{
    if (!isfinite(x0) || !isfinite(y0) || !isfinite(x1) || !isfinite(y1)) return;
    segment(c, x0, y0, 0, x1, y1, 0, rgb, width, 0, 0);
}

void canvas_dashed_line(canvas *c, double x0, double y0, double x1, double y1,
                        const float rgb[3], double width, double dash, double gap)
{
    double dx = x1 - x0, dy = y1 - y0, len = sqrt(dx * dx + dy * dy);
    if (!(len > 0) || !(dash > 0) || gap < 0) return;
    for (double s = 0; s < len; s += dash + gap) {
        double e = fmin(s + dash, len);
        canvas_line(c, x0 + dx * s / len, y0 + dy * s / len, x0 + dx * e / len,
                    y0 + dy * e / len, rgb, width);
    }
}

void canvas_line_depth(canvas *c, double x0, double y0, double z0, double x1, double y1,
                       double z1, const float rgb[3], double width, double bias)
{
    if (!isfinite(x0) || !isfinite(y0) || !isfinite(x1) || !isfinite(y1)) return;
    segment(c, x0, y0, z0, x1, y1, z1, rgb, width, 1, bias);
}

void canvas_circle(canvas *c, double cx, double cy, double r, const float rgb[3])
{
    int xa = clampi((int)floor(cx - r - 1), 0, c->w - 1), xb = clampi((int)ceil(cx + r + 1), 0, c->w - 1);
    int ya = clampi((int)floor(cy - r - 1), 0, c->h - 1), yb = clampi((int)ceil(cy + r + 1), 0, c->h - 1);
    for (int y = ya; y <= yb; y++)
        for (int x = xa; x <= xb; x++) {
            double d = hypot(x + 0.5 - cx, y + 0.5 - cy);
            double a = r + 0.5 - d;
            if (a > 0) canvas_blend(c, x, y, rgb, (float)(a > 1 ? 1 : a));
        }
}

void canvas_rect(canvas *c, int x0, int y0, int x1, int y1, const float rgb[3])
{
    x0 = clampi(x0, 0, c->w);
    x1 = clampi(x1, 0, c->w);
    y0 = clampi(y0, 0, c->h);
    y1 = clampi(y1, 0, c->h);
    for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++) memcpy(c->rgb + 3 * pixel(c, x, y), rgb, 3 * sizeof(float));
}

/* The fixed light, in screen terms (x right, y up, z towards the viewer). */
static const double LX = -0.45, LY = 0.60, LZ = 0.66;

void canvas_sphere(canvas *c, double cx, double cy, double r, double z, double rz,
                   const float rgb[3])
{
    if (!(r > 0) || !isfinite(cx) || !isfinite(cy) || !isfinite(z)) return;
    if (cx + r < 0 || cy + r < 0 || cx - r > c->w || cy - r > c->h) return;
    double ln = sqrt(LX * LX + LY * LY + LZ * LZ);
    double lx = LX / ln, ly = LY / ln, lz = LZ / ln;
    /* half vector of the light and the view direction (0,0,1) */
    double hx = lx, hy = ly, hz = lz + 1, hn = sqrt(hx * hx + hy * hy + hz * hz);
    hx /= hn, hy /= hn, hz /= hn;
    int xa = clampi((int)floor(cx - r), 0, c->w - 1), xb = clampi((int)ceil(cx + r), 0, c->w - 1);
    int ya = clampi((int)floor(cy - r), 0, c->h - 1), yb = clampi((int)ceil(cy + r), 0, c->h - 1);
    for (int y = ya; y <= yb; y++)
        for (int x = xa; x <= xb; x++) {
            double nx = (x + 0.5 - cx) / r, ny = -(y + 0.5 - cy) / r;
            double q = nx * nx + ny * ny;
            /* edge coverage over the last pixel of radius */
            double cov = (1 - sqrt(q)) * r + 0.5;
            if (cov <= 0) continue;
            if (q > 1) q = 1;
            double nz = sqrt(1 - q);
            double d = z - rz * nz;
            size_t i = pixel(c, x, y);
            if (d >= c->depth[i]) continue;
            double ndl = nx * lx + ny * ly + nz * lz;
            if (ndl < 0) ndl = 0;
            double ndh = nx * hx + ny * hy + nz * hz;
            double spec = ndh > 0 ? 0.35 * pow(ndh, 40) : 0;
            double shade = 0.28 + 0.72 * ndl;
            float col[3];
            for (int k = 0; k < 3; k++) col[k] = (float)(rgb[k] * shade + spec);
            if (cov >= 1) {
                memcpy(c->rgb + 3 * i, col, sizeof col);
                c->depth[i] = (float)d;
            } else {
                canvas_blend(c, x, y, col, (float)cov);
                if (cov > 0.5) c->depth[i] = (float)d;
            }
        }
}

void canvas_triangle(canvas *c, const double p0[3], const double p1[3], const double p2[3],
                     const float rgb[3])
{
    double area = (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p2[0] - p0[0]) * (p1[1] - p0[1]);
    if (!(fabs(area) > 1e-12)) return;
    int xa = clampi((int)floor(fmin(p0[0], fmin(p1[0], p2[0]))), 0, c->w - 1);
    int xb = clampi((int)ceil(fmax(p0[0], fmax(p1[0], p2[0]))), 0, c->w - 1);
    int ya = clampi((int)floor(fmin(p0[1], fmin(p1[1], p2[1]))), 0, c->h - 1);
    int yb = clampi((int)ceil(fmax(p0[1], fmax(p1[1], p2[1]))), 0, c->h - 1);
    for (int y = ya; y <= yb; y++)
        for (int x = xa; x <= xb; x++) {
            double px = x + 0.5, py = y + 0.5;
            double w0 = ((p1[0] - px) * (p2[1] - py) - (p2[0] - px) * (p1[1] - py)) / area;
            double w1 = ((p2[0] - px) * (p0[1] - py) - (p0[0] - px) * (p2[1] - py)) / area;
            double w2 = 1 - w0 - w1;
            if (w0 < 0 || w1 < 0 || w2 < 0) continue;
            double z = w0 * p0[2] + w1 * p1[2] + w2 * p2[2];
            size_t i = pixel(c, x, y);
            if (z >= c->depth[i]) continue;
            c->depth[i] = (float)z;
            memcpy(c->rgb + 3 * i, rgb, 3 * sizeof(float));
        }
}

/* ---- font: 5x7 glyphs (lower-case descenders use two more rows) ---- */

typedef struct glyph {
    char ch;
    unsigned char rows[9]; /* top to bottom (rows 7, 8: descenders); bit 4 = left column */
} glyph;

static const glyph FONT[] = {
    {'0', {0x0e, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0e, 0x00, 0x00}},
    {'1', {0x04, 0x0c, 0x04, 0x04, 0x04, 0x04, 0x0e, 0x00, 0x00}},
    {'2', {0x0e, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1f, 0x00, 0x00}},
    {'3', {0x1f, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0e, 0x00, 0x00}},
    {'4', {0x02, 0x06, 0x0a, 0x12, 0x1f, 0x02, 0x02, 0x00, 0x00}},
    {'5', {0x1f, 0x10, 0x1e, 0x01, 0x01, 0x11, 0x0e, 0x00, 0x00}},
    {'6', {0x06, 0x08, 0x10, 0x1e, 0x11, 0x11, 0x0e, 0x00, 0x00}},
    {'7', {0x1f, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08, 0x00, 0x00}},
    {'8', {0x0e, 0x11, 0x11, 0x0e, 0x11, 0x11, 0x0e, 0x00, 0x00}},
    {'9', {0x0e, 0x11, 0x11, 0x0f, 0x01, 0x02, 0x0c, 0x00, 0x00}},
    {'A', {0x0e, 0x11, 0x11, 0x1f, 0x11, 0x11, 0x11, 0x00, 0x00}},
    {'B', {0x1e, 0x11, 0x11, 0x1e, 0x11, 0x11, 0x1e, 0x00, 0x00}},
    {'C', {0x0e, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0e, 0x00, 0x00}},
    {'D', {0x1c, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1c, 0x00, 0x00}},
    {'E', {0x1f, 0x10, 0x10, 0x1e, 0x10, 0x10, 0x1f, 0x00, 0x00}},
    {'F', {0x1f, 0x10, 0x10, 0x1e, 0x10, 0x10, 0x10, 0x00, 0x00}},
    {'G', {0x0e, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0f, 0x00, 0x00}},
    {'H', {0x11, 0x11, 0x11, 0x1f, 0x11, 0x11, 0x11, 0x00, 0x00}},
    {'I', {0x0e, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0e, 0x00, 0x00}},
    {'J', {0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0c, 0x00, 0x00}},
    {'K', {0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11, 0x00, 0x00}},
    {'L', {0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1f, 0x00, 0x00}},
    {'M', {0x11, 0x1b, 0x15, 0x15, 0x11, 0x11, 0x11, 0x00, 0x00}},
    {'N', {0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11, 0x00, 0x00}},
    {'O', {0x0e, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e, 0x00, 0x00}},
    {'P', {0x1e, 0x11, 0x11, 0x1e, 0x10, 0x10, 0x10, 0x00, 0x00}},
    {'Q', {0x0e, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0d, 0x00, 0x00}},
    {'R', {0x1e, 0x11, 0x11, 0x1e, 0x14, 0x12, 0x11, 0x00, 0x00}},
    {'S', {0x0f, 0x10, 0x10, 0x0e, 0x01, 0x01, 0x1e, 0x00, 0x00}},
    {'T', {0x1f, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04, 0x00, 0x00}},
    {'U', {0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e, 0x00, 0x00}},
    {'V', {0x11, 0x11, 0x11, 0x11, 0x11, 0x0a, 0x04, 0x00, 0x00}},
    {'W', {0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0a, 0x00, 0x00}},
    {'X', {0x11, 0x11, 0x0a, 0x04, 0x0a, 0x11, 0x11, 0x00, 0x00}},
    {'Y', {0x11, 0x11, 0x0a, 0x04, 0x04, 0x04, 0x04, 0x00, 0x00}},
    {'Z', {0x1f, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1f, 0x00, 0x00}},
    {'a', {0x00, 0x00, 0x0e, 0x01, 0x0f, 0x11, 0x0f, 0x00, 0x00}},
    {'b', {0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x1e, 0x00, 0x00}},
    {'c', {0x00, 0x00, 0x0e, 0x10, 0x10, 0x11, 0x0e, 0x00, 0x00}},
    {'d', {0x01, 0x01, 0x0d, 0x13, 0x11, 0x11, 0x0f, 0x00, 0x00}},
    {'e', {0x00, 0x00, 0x0e, 0x11, 0x1f, 0x10, 0x0e, 0x00, 0x00}},
    {'f', {0x06, 0x09, 0x08, 0x1c, 0x08, 0x08, 0x08, 0x00, 0x00}},
    {'g', {0x00, 0x00, 0x0f, 0x11, 0x11, 0x11, 0x0f, 0x01, 0x0e}},
    {'h', {0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x11, 0x00, 0x00}},
    {'i', {0x04, 0x00, 0x0c, 0x04, 0x04, 0x04, 0x0e, 0x00, 0x00}},
    {'j', {0x02, 0x00, 0x06, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0c}},
    {'k', {0x10, 0x10, 0x12, 0x14, 0x18, 0x14, 0x12, 0x00, 0x00}},
    {'l', {0x0c, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0e, 0x00, 0x00}},
    {'m', {0x00, 0x00, 0x1a, 0x15, 0x15, 0x11, 0x11, 0x00, 0x00}},
    {'n', {0x00, 0x00, 0x16, 0x19, 0x11, 0x11, 0x11, 0x00, 0x00}},
    {'o', {0x00, 0x00, 0x0e, 0x11, 0x11, 0x11, 0x0e, 0x00, 0x00}},
    {'p', {0x00, 0x00, 0x1e, 0x11, 0x11, 0x11, 0x1e, 0x10, 0x10}},
    {'q', {0x00, 0x00, 0x0f, 0x11, 0x11, 0x11, 0x0f, 0x01, 0x01}},
    {'r', {0x00, 0x00, 0x16, 0x19, 0x10, 0x10, 0x10, 0x00, 0x00}},
    {'s', {0x00, 0x00, 0x0e, 0x10, 0x0e, 0x01, 0x1e, 0x00, 0x00}},
    {'t', {0x08, 0x08, 0x1c, 0x08, 0x08, 0x09, 0x06, 0x00, 0x00}},
    {'u', {0x00, 0x00, 0x11, 0x11, 0x11, 0x13, 0x0d, 0x00, 0x00}},
    {'v', {0x00, 0x00, 0x11, 0x11, 0x11, 0x0a, 0x04, 0x00, 0x00}},
    {'w', {0x00, 0x00, 0x11, 0x11, 0x15, 0x15, 0x0a, 0x00, 0x00}},
    {'x', {0x00, 0x00, 0x11, 0x0a, 0x04, 0x0a, 0x11, 0x00, 0x00}},
    {'y', {0x00, 0x00, 0x11, 0x11, 0x11, 0x11, 0x0f, 0x01, 0x0e}},
    {'z', {0x00, 0x00, 0x1f, 0x02, 0x04, 0x08, 0x1f, 0x00, 0x00}},
    {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0c, 0x0c, 0x00, 0x00}},
    {'-', {0x00, 0x00, 0x00, 0x0e, 0x00, 0x00, 0x00, 0x00, 0x00}},
    {'+', {0x00, 0x04, 0x04, 0x1f, 0x04, 0x04, 0x00, 0x00, 0x00}},
    {':', {0x00, 0x0c, 0x0c, 0x00, 0x0c, 0x0c, 0x00, 0x00, 0x00}},
    {'/', {0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00, 0x00, 0x00}},
    {'=', {0x00, 0x00, 0x1f, 0x00, 0x1f, 0x00, 0x00, 0x00, 0x00}},
    {'(', {0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02, 0x00, 0x00}},
    {')', {0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08, 0x00, 0x00}},
    {',', {0x00, 0x00, 0x00, 0x00, 0x0c, 0x04, 0x08, 0x00, 0x00}},
    {'_', {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1f, 0x00, 0x00}},
    {'%', {0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03, 0x00, 0x00}},
    {'\'', {0x04, 0x04, 0x08, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}},
    {'?', {0x0e, 0x11, 0x01, 0x02, 0x04, 0x00, 0x04, 0x00, 0x00}},
};

static const glyph *find_glyph(char ch)
{
    size_t n = sizeof FONT / sizeof FONT[0];
    for (size_t i = 0; i < n; i++)
        if (FONT[i].ch == ch) return &FONT[i];
    return &FONT[n - 1]; /* '?' */
}

int canvas_text_width(const char *s, int scale)
{
    int n = (int)strlen(s);
    return n > 0 ? (6 * n - 1) * scale : 0;
}

int canvas_text_height(int scale) { return 7 * scale; }

void canvas_text(canvas *c, int x, int y, const char *s, const float rgb[3], int scale)
{
    if (scale < 1) scale = 1;
    for (; *s; s++, x += 6 * scale) {
        if (*s == ' ') continue;
        const glyph *g = find_glyph(*s);
        for (int r = 0; r < 9; r++)
            for (int col = 0; col < 5; col++)
                if (g->rows[r] & (0x10 >> col))
                    canvas_rect(c, x + col * scale, y + r * scale, x + (col + 1) * scale,
                                y + (r + 1) * scale, rgb);
    }
}

void canvas_text_halo(canvas *c, int x, int y, const char *s, const float rgb[3],
                      const float halo[3], int scale)
{
    if (scale < 1) scale = 1;
    int d = scale > 1 ? scale / 2 + 0 : 1;
    for (int oy = -1; oy <= 1; oy++)
        for (int ox = -1; ox <= 1; ox++)
            if (ox || oy) canvas_text(c, x + ox * d, y + oy * d, s, halo, scale);
    canvas_text(c, x, y, s, rgb, scale);
}

canvas *canvas_downsample(const canvas *src, int f)
{
    if (f < 1 || src->w % f || src->h % f) return NULL;
    canvas *d = canvas_new(src->w / f, src->h / f);
    if (!d) return NULL;
    float inv = 1.f / (float)(f * f);
    for (int y = 0; y < d->h; y++)
        for (int x = 0; x < d->w; x++) {
            float acc[3] = {0, 0, 0};
            float zmin = INFINITY;
            for (int j = 0; j < f; j++)
                for (int i = 0; i < f; i++) {
                    size_t s = pixel(src, x * f + i, y * f + j);
                    for (int k = 0; k < 3; k++) acc[k] += src->rgb[3 * s + (size_t)k];
                    if (src->depth[s] < zmin) zmin = src->depth[s];
                }
            size_t o = pixel(d, x, y);
            for (int k = 0; k < 3; k++) d->rgb[3 * o + (size_t)k] = acc[k] * inv;
            d->depth[o] = zmin;
        }
    return d;
}

void canvas_blit(canvas *dst, const canvas *src, int x, int y)
{
    for (int j = 0; j < src->h; j++) {
        int ty = y + j;
        if (ty < 0 || ty >= dst->h) continue;
        for (int i = 0; i < src->w; i++) {
            int tx = x + i;
            if (tx < 0 || tx >= dst->w) continue;
            memcpy(dst->rgb + 3 * pixel(dst, tx, ty), src->rgb + 3 * pixel(src, i, j),
                   3 * sizeof(float));
        }
    }
}

/* ---- PNG ---- */

/* 1 if path is an existing file with content that is not a PNG: a picture must not replace
 * a run, a scene or anything else given by mistake as the output. */
int canvas_holds_other_data(const char *path)
{
    FILE *fp = fopen(path, "rb");
    if (!fp) return 0;
    unsigned char sig[8];
    size_t n = fread(sig, 1, sizeof sig, fp);
    fclose(fp);
    return n > 0 && (n < sizeof sig || png_sig_cmp(sig, 0, sizeof sig) != 0);
}

int canvas_write_png(const canvas *c, const char *path, char *err, size_t errlen)
{
    if (canvas_holds_other_data(path)) {
        snprintf(err, errlen, "%s: exists and is not a PNG; not overwritten (choose another name)", path);
        return -1;
    }
    size_t nbuf = (size_t)c->w * (size_t)c->h * 3;
    unsigned char *buf = malloc(nbuf);
    png_bytep *rows = malloc((size_t)c->h * sizeof *rows);
    if (!buf || !rows) {
        free(buf);
        free(rows);
        snprintf(err, errlen, "%s: out of memory", path);
        return -1;
    }
    for (size_t i = 0; i < nbuf; i++) {
        float v = c->rgb[i];
        v = v != v ? 0.f : v < 0 ? 0.f : v > 1 ? 1.f : v;
        buf[i] = (unsigned char)lrintf(v * 255.f);
    }
    for (int y = 0; y < c->h; y++) rows[y] = buf + (size_t)y * (size_t)c->w * 3;

    FILE *fp = fopen(path, "wb");
    if (!fp) {
        snprintf(err, errlen, "%s: %s", path, strerror(errno));
        free(buf);
        free(rows);
        return -1;
    }
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    int rc = -1;
    if (!png || !info) {
        snprintf(err, errlen, "%s: cannot initialise libpng", path);
    } else if (setjmp(png_jmpbuf(png))) {
        snprintf(err, errlen, "%s: libpng write error", path);
    } else {
        png_init_io(png, fp);
        png_set_IHDR(png, info, (png_uint_32)c->w, (png_uint_32)c->h, 8, PNG_COLOR_TYPE_RGB,
                     PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
        png_set_compression_level(png, 6);
        png_write_info(png, info);
        png_write_image(png, rows);
        png_write_end(png, NULL);
        rc = 0;
    }
    png_destroy_write_struct(png ? &png : NULL, info ? &info : NULL);
    if (fclose(fp) != 0 && rc == 0) {
        snprintf(err, errlen, "%s: %s", path, strerror(errno));
        rc = -1;
    }
    if (rc != 0) remove(path);
    free(buf);
    free(rows);
    return rc;
}

double canvas_nice_step(double range, int want)
{
    double raw = range / want, e = pow(10, floor(log10(raw))), m = raw / e;
    return (m < 1.5 ? 1 : m < 3.5 ? 2 : m < 7.5 ? 5 : 10) * e;
}

int canvas_tick_decimals(double step)
{
    int d = (int)ceil(-log10(step) - 1e-9);
    return d < 0 ? 0 : d > 6 ? 6 : d;
}

void canvas_axes_draw(canvas *c, const canvas_axes *a, int xwant, int ywant, int xnumbers, int ts)
{
    static const float ink[3] = {0.10f, 0.10f, 0.12f}, grid[3] = {0.88f, 0.89f, 0.91f};
    double us = canvas_nice_step(a->u1 - a->u0, xwant), vs = canvas_nice_step(a->v1 - a->v0, ywant);
    int ud = canvas_tick_decimals(us), vd = canvas_tick_decimals(vs);
    char buf[48];
    for (double v = ceil(a->v0 / vs - 1e-9) * vs; v <= a->v1 + vs * 1e-6; v += vs) {
        double y = canvas_axes_y(a, v);
        canvas_line(c, a->x0, y, a->x1, y, grid, 1);
        canvas_line(c, a->x0 - 5, y, a->x0, y, ink, 1.5);
        snprintf(buf, sizeof buf, "%.*f", vd, fabs(v) < vs * 1e-6 ? 0.0 : v);
        canvas_text(c, a->x0 - 12 - canvas_text_width(buf, ts), (int)lround(y) - 7, buf, ink, ts);
    }
    for (double u = ceil(a->u0 / us - 1e-9) * us; u <= a->u1 + us * 1e-6; u += us) {
        double x = canvas_axes_x(a, u);
        canvas_line(c, x, a->y0, x, a->y1, grid, 1);
        canvas_line(c, x, a->y1, x, a->y1 + 5, ink, 1.5);
        if (!xnumbers) continue;
        snprintf(buf, sizeof buf, "%.*f", ud, fabs(u) < us * 1e-6 ? 0.0 : u);
        canvas_text(c, (int)lround(x) - canvas_text_width(buf, ts) / 2, a->y1 + 13, buf, ink, ts);
    }
    canvas_line(c, a->x0, a->y0, a->x1, a->y0, ink, 1.5);
    canvas_line(c, a->x0, a->y1, a->x1, a->y1, ink, 1.5);
    canvas_line(c, a->x0, a->y0, a->x0, a->y1, ink, 1.5);
    canvas_line(c, a->x1, a->y0, a->x1, a->y1, ink, 1.5);
}

void canvas_nice_range(double *lo, double *hi, int keep_zero)
{
    if (!(*hi > *lo)) {
        double m = fabs(*lo) > 0 ? fabs(*lo) * 0.1 : 0.1;
        *lo -= m;
        *hi += m;
    }
    double pad = (*hi - *lo) * 0.05;
    double step = canvas_nice_step(*hi - *lo + 2 * pad, 5);
    if (keep_zero && *lo == 0) pad = 0;
    *lo = floor((*lo - pad) / step) * step;
    *hi = ceil((*hi + pad) / step) * step;
}
