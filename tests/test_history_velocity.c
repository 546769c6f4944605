/* test_history_velocity.c - history.velocity: smoothed (src/fluid.c, stf_fluid_smoothed_velocity),
 * the velocity Eq. 3 remembers, on a simple cubic lattice whose answers are lattice sums:
 *
 *  linear field  v = (A z, B x, C y) + V0 in the bulk (a full neighbourhood) comes out
 *                unchanged to round-off: a uniform strain rate measures the same as with
 *                each particle's own velocity.
 *  checkerboard  the lattice's shortest wave, v = e (-1)^(i+j+k), is multiplied by
 *                S = sum_j (-1)^(|a|+|b|+|c|) w_j / sum_j w_j over the lattice neighbours
 *                (w = (1 - r/h)^2, the particle's own weight 1), computed here from the
 *                lattice itself; at h = 2 spacings |S| is about 0.1: the jitter of a resting
 *                relaxation is cut ten times.
 *  through a step  a pool at rest with history particle and smoothed: the smoothed pool's
 *                history stiffness stays lower (orderings between variants, the same
 *                lattice and seed).
 *
 * history.smoothing L > 0 (src/velocity_field.c, the field averaged over L on a lattice of
 * cell L), on the same lattice with L = 3 spacings (commensurate: every node of the bulk
 * gathers the same weights):
 *  uniform and linear fields come back unchanged in the bulk (particles 2 L from the block's
 *                faces), to round-off;
 *  checkerboard  is cut below 1% of its amplitude (the tent over 6 spacings cancels it);
 *  a shear step  v_x = U above a plane: the largest difference between neighbours one
 *                spacing apart across it falls as 1/L: doubling L divides it by 1.5 to 2.5
 *                (2 for a continuous filter; the exact factor depends on where the plane
 *                sits between the nodes), so the band in which the history sees the shear
 *                is L wide, not a spacing;
 *  threads       the result is bit-identical on 1 and 2 threads. */
#define _POSIX_C_SOURCE 200809L
#include "stf.h"
#include "fluid.h"
#include "test_util.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

static char err[512];

enum { N = 14 }; /* particles along each side */

static stf_fluid *lattice(double s, double eps)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.spacing = s;
    d.effects = STF_EFFECT_SPRINGS | STF_EFFECT_HISTORY;
    d.history_velocity = STF_HISTORY_SMOOTHED;
    stf_fluid *f = NULL;
    if (stf_fluid_create(&d, &f, err, sizeof err) != 0) {
        CHECK(0, "stf_fluid_create: %s", err);
        return NULL;
    }
    const double A = 0.7, B = -1.3, C = 0.4, V0[3] = {0.05, -0.02, 0.01};
    for (int k = 0; k < N; k++)
        for (int j = 0; j < N; j++)
            for (int i = 0; i < N; i++) {
                double x[3] = {i * s, j * s, k * s}, sg = ((i + j + k) & 1) ? -1.0 : 1.0;
                double v[3] = {V0[0] + A * x[2] + eps * sg, V0[1] + B * x[0], V0[2] + C * x[1]};
                stf_fluid_add_particle(f, x, v);
            }
    return f;
}

/* the particle at lattice site (i, j, k) is number (k N + j) N + i (added in that order) */
static int bulk(int idx, int reach)
{
    int i = idx % N, j = (idx / N) % N, k = idx / (N * N);
    return i >= reach && j >= reach && k >= reach && i < N - reach && j < N - reach && k < N - reach;
}

static void test_lattice(void)
{
    double s = 0.01, eps = 1e-3;
    for (int pass = 0; pass < 2; pass++) {
        double e = pass ? eps : 0.0;
        stf_fluid *f = lattice(s, e);
        if (!f) return;
        int n = stf_fluid_count(f);
        CHECK(stf_grid_build(&f->grid, f->x, n, f->h) == 0, "grid_build");
        double *out = malloc(3 * (size_t)n * sizeof *out);
        stf_fluid_smoothed_velocity(f, out);
        /* the checkerboard factor from the lattice: the sites within h of a site */
        int m = (int)(f->h / s) + 1;
        double sw = 0, ssw = 0;
        for (int a = -m; a <= m; a++)
            for (int b = -m; b <= m; b++)
                for (int c = -m; c <= m; c++) {
                    double q = s * sqrt((double)(a * a + b * b + c * c)) / f->h;
                    if (q >= 1) continue;
                    double w = (1 - q) * (1 - q);
                    sw += w;
                    ssw += ((abs(a) + abs(b) + abs(c)) & 1) ? -w : w;
                }
        double S = ssw / sw, worst = 0, worst_lin = 0;
        int reach = m; /* a full neighbourhood */
        for (int p = 0; p < n; p++) {
            if (!bulk(p, reach)) continue;
            const double *x = f->x + 3 * p, *v = f->v + 3 * p;
            int i = p % N, j = (p / N) % N, k = p / (N * N);
            double sg = ((i + j + k) & 1) ? -1.0 : 1.0;
            /* the linear part as given, the checkerboard scaled by S */
            double want[3] = {v[0] - e * sg + S * e * sg, v[1], v[2]};
            (void)x;
            for (int a = 0; a < 3; a++) {
                double d = fabs(out[3 * p + a] - want[a]);
                if (pass) worst = fmax(worst, d);
                else worst_lin = fmax(worst_lin, d);
            }
        }
        if (!pass)
            CHECK(worst_lin <= 1e-14, "a linear field through the smoothing: off by %.3g m/s", worst_lin);
        else {
            CHECK(worst <= 1e-14, "checkerboard: off the lattice factor S = %.6f by %.3g m/s", S, worst);
            CHECK(fabs(S) < 0.2, "checkerboard factor S = %.4f: the shortest wave is not damped", S);
        }
        free(out);
        stf_fluid_destroy(f);
    }
}

/* A jittered block settling under gravity with every Clavet effect and stiff history: the
 * mean history stiffness of its particles after 0.4 s, history.velocity as given. */
static double resting_khist(int velocity)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.spacing = 0.02;
    d.relaxation = STF_RELAX_GAUSS_SEIDEL;
    d.history_velocity = velocity;
    d.memory = 0.2;
    d.k_hist = 4.0e7;
    d.k_onset = 5.0e5;
    d.jitter = 0.05;
    stf_fluid *f = NULL;
    if (stf_fluid_create(&d, &f, err, sizeof err) != 0) {
        CHECK(0, "stf_fluid_create: %s", err);
        return NAN;
    }
    stf_collider_def box = stf_default_collider_def();
    box.shape = STF_SHAPE_CONTAINER;
    box.half[0] = 0.15, box.half[1] = 0.15, box.half[2] = 0.3;
    box.wall = 0.03;
    if (stf_fluid_add_collider(f, &box, err, sizeof err) < 0) CHECK(0, "container: %s", err);
    double lo[3] = {-0.14, -0.14, 0.0}, hi[3] = {0.14, 0.14, 0.16}, v0[3] = {0, 0, 0};
    stf_fluid_add_block(f, lo, hi, v0);
    int n = stf_fluid_count(f);
    double mean = 0;
    for (int s = 0; s < 400; s++) {
        if (stf_fluid_step(f, 1e-3) != 0) {
            CHECK(0, "velocity %d, step %d: %s", velocity, s, stf_fluid_failure(f));
            break;
        }
    }
    float *k = malloc((size_t)n * sizeof *k);
    stf_fluid_get_history_stiffness(f, k);
    for (int i = 0; i < n; i++) mean += k[i];
    free(k);
    stf_fluid_destroy(f);
    return mean / n;
}

/* The lattice of lattice() with velocity kind: 0 uniform V0, 1 linear, 2 checkerboard of 1e-3,
 * 3 a shear step v_x = 0.1 m/s above the plane z = 6.5 spacings. */
static stf_fluid *field_lattice(double s, double L, int kind)
{
    stf_fluid *f = lattice(s, 0.0);
    if (!f) return NULL;
    f->def.history_smoothing = L;
    int n = stf_fluid_count(f);
    for (int p = 0; p < n; p++) {
        int i = p % N, j = (p / N) % N, k = p / (N * N);
        double *v = f->v + 3 * p, sg = ((i + j + k) & 1) ? -1.0 : 1.0;
        if (kind == 0) v[0] = 0.05, v[1] = -0.02, v[2] = 0.01;
        if (kind == 2) v[0] = 1e-3 * sg, v[1] = v[2] = 0;
        if (kind == 3) v[0] = k > 6 ? 0.1 : 0.0, v[1] = v[2] = 0;
    }
    return f;
}

static void test_field(void)
{
    double s = 0.01, L = 3 * s;
    int reach = 6; /* 2 L */
    for (int kind = 0; kind < 3; kind++) {
        stf_fluid *f = field_lattice(s, L, kind);
        if (!f) return;
        int n = stf_fluid_count(f);
        double *out = malloc(3 * (size_t)n * sizeof *out), worst = 0;
        CHECK(stf_fluid_field_velocity(f, out) == 0, "field velocity failed");
        for (int p = 0; p < n; p++) {
            if (!bulk(p, reach)) continue;
            for (int a = 0; a < 3; a++)
                worst = fmax(worst, fabs(out[3 * p + a] - (kind == 2 ? 0.0 : f->v[3 * p + a])));
        }
        if (kind < 2)
            CHECK(worst <= 1e-15, "%s field through smoothing %g m: off by %.3g m/s",
                  kind ? "a linear" : "a uniform", L, worst);
        else
            CHECK(worst <= 1e-5, "checkerboard of 1e-3 m/s through smoothing %g m: %.3g m/s left",
                  L, worst);
        free(out);
        stf_fluid_destroy(f);
    }
    /* the shear step: the largest neighbour difference across the plane in the bulk */
    double jump[2];
    for (int c = 0; c < 2; c++) {
        stf_fluid *f = field_lattice(s, (c + 1) * L, 3);
        if (!f) return;
        int n = stf_fluid_count(f);
        double *out = malloc(3 * (size_t)n * sizeof *out);
        CHECK(stf_fluid_field_velocity(f, out) == 0, "field velocity failed");
        jump[c] = 0;
        for (int p = 0; p + N * N < n; p++) {
            int i = p % N, j = (p / N) % N;
            if (i < 3 || j < 3 || i >= N - 3 || j >= N - 3) continue;
            jump[c] = fmax(jump[c], fabs(out[3 * (p + N * N)] - out[3 * p]));
        }
        free(out);
        stf_fluid_destroy(f);
    }
    printf("shear step of 0.1 m/s: largest neighbour difference %.4g m/s at L = %g m, %.4g at %g m\n",
           jump[0], L, jump[1], 2 * L);
    CHECK(jump[0] < 0.1 * 0.5, "smoothing %g m leaves a jump of %.3g m/s of 0.1", L, jump[0]);
    CHECK(jump[0] / jump[1] > 1.5 && jump[0] / jump[1] < 2.5, "the band does not widen with L: %.4g / %.4g",
          jump[0], jump[1]);
    /* one thread and two: the same bits */
    stf_fluid *f = field_lattice(s, L, 1);
    if (!f) return;
    int n = stf_fluid_count(f);
    double *a = malloc(3 * (size_t)n * sizeof *a), *b = malloc(3 * (size_t)n * sizeof *b);
    int nt = omp_get_max_threads();
    omp_set_num_threads(1);
    CHECK(stf_fluid_field_velocity(f, a) == 0, "field velocity failed");
    omp_set_num_threads(2);
    CHECK(stf_fluid_field_velocity(f, b) == 0, "field velocity failed");
    omp_set_num_threads(nt);
    CHECK(memcmp(a, b, 3 * (size_t)n * sizeof *a) == 0, "1 and 2 threads differ");
    free(a);
    free(b);
    stf_fluid_destroy(f);
}

int main(void)
{
    test_lattice();
    test_field();
    double kp = resting_khist(STF_HISTORY_PARTICLE), ks = resting_khist(STF_HISTORY_SMOOTHED);
    printf("resting pool, mean history stiffness above the onset after 0.4 s: particle %.4g, "
           "smoothed %.4g 1/s^2\n", kp, ks);
    CHECK(ks < kp, "smoothed %.4g 1/s^2 is not below particle %.4g", ks, kp);
    return test_result("test_history_velocity");
}
