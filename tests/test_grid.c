/* test_grid.c - the neighbour search against brute force: every pair closer than h and no
 * other, through Verlet reuse and rebuilds, in compressed clusters and across periodic
 * seams; the lists do not depend on the thread count nor on the AVX2 path. */
#include "grid.h"
#include "test_util.h"

#include <omp.h>
#include <stdio.h>
#include <sys/resource.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static uint32_t rng = 12345u;
static double uniform(void)
{
    rng = rng * 1664525u + 1013904223u;
    return (rng >> 8) / 16777216.0;
}

/* Nearest-image difference along an axis of period p (p = 0: not periodic). */
static double image(double d, double p) { return p > 0 ? d - p * floor(d / p + 0.5) : d; }

/* Brute force: does every row hold exactly the particles closer than h, each once? Returns
 * the number of wrong rows. */
static int wrong_rows(const stf_grid *g, const double *x, int n, double h, const double period[3])
{
    int bad = 0;
    char *seen = calloc((size_t)n, 1);
    for (int i = 0; i < n; i++) {
        const int32_t *row = grid_row(g, i);
        int ok = 1, expect = 0;
        memset(seen, 0, (size_t)n);
        for (int k = 0; k < g->count[i]; k++) {
            int j = row[k];
            if (j < 0 || j >= n || j == i || seen[j]) ok = 0;
            else seen[j] = 1;
        }
        for (int j = 0; j < n; j++) {
            if (j == i) continue;
            double r2 = 0;
            for (int a = 0; a < 3; a++) {
                double d = image(x[3 * j + a] - x[3 * i + a], period[a]);
                r2 += d * d;
            }
            if (r2 < h * h) {
                expect++;
                if (!seen[j]) ok = 0;
            }
        }
        if (expect != g->count[i]) ok = 0;
        if (!ok && bad++ < 3)
            fprintf(stderr, "particle %d: %d neighbours listed, %d closer than h\n", i,
                    g->count[i], expect);
    }
    free(seen);
    return bad;
}

/* n particles: a loose cloud over a box with negative corners, plus a dense clump (more
 * candidates than any fixed row would hold) and a few coincident pairs. */
static double *cloud(int n, double h)
{
    double *x = malloc((size_t)n * 3 * sizeof *x);
    for (int i = 0; i < n; i++) {
        int clump = i % 5 == 0;
        for (int a = 0; a < 3; a++)
            x[3 * i + a] = clump ? 0.1 + 0.6 * h * uniform() : -0.4 + 0.9 * uniform();
    }
    for (int i = 1; i < n; i += 97) memcpy(x + 3 * i, x + 3 * (i - 1), 3 * sizeof *x);
    return x;
}

static int lists_equal(const stf_grid *a, const stf_grid *b, int n)
{
    for (int i = 0; i < n; i++) {
        if (a->count[i] != b->count[i]) return 0;
        if (memcmp(grid_row(a, i), grid_row(b, i), (size_t)a->count[i] * sizeof(int32_t)))
            return 0;
    }
    return 1;
}

static void test_verlet(void)
{
    const int n = 3000;
    const double h = 0.06, none[3] = {0, 0, 0};
    double *x = cloud(n, h);
    stf_grid g = {0};
    CHECK(stf_grid_build(&g, x, n, h) == 0, "build");
    CHECK(wrong_rows(&g, x, n, h, none) == 0, "first build");
    int most = 0;
    for (int i = 0; i < n; i++) most = g.count[i] > most ? g.count[i] : most;
    CHECK(most > 96, "the clump should outgrow a 96-slot row (most %d)", most);
    /* small random moves: the candidates are reused while the two largest moves stay inside
       the skin, and rebuilt after; the rows are right either way */
    long rebuilds0 = g.rebuilds;
    int reused = 0;
    for (int step = 0; step < 12; step++) {
        for (int k = 0; k < 3 * n; k++) x[k] += 0.004 * h * (uniform() - 0.5);
        x[3 * (step * 131 % n)] += 0.3 * h * (step % 4 == 3); /* now and then one jumps */
        int due = stf_grid_due(&g, x, n, h);
        reused += !due;
        CHECK(stf_grid_build(&g, x, n, h) == 0, "build");
        CHECK(wrong_rows(&g, x, n, h, none) == 0, "step %d (due %d)", step, due);
    }
    CHECK(reused > 0, "the candidates were never reused");
    CHECK(g.rebuilds > rebuilds0, "a particle jumped a third of h: no rebuild");
    /* carried along as a whole (here 3 h in steps of h/10) the lists stay valid: no rebuild */
    long rebuilds1 = g.rebuilds;
    for (int step = 0; step < 30; step++) {
        for (int i = 0; i < n; i++) x[3 * i] += 0.1 * h, x[3 * i + 2] -= 0.05 * h;
        CHECK(stf_grid_build(&g, x, n, h) == 0, "build");
    }
    CHECK(g.rebuilds == rebuilds1, "a uniform translation rebuilt the lists %ld times",
          g.rebuilds - rebuilds1);
    CHECK(wrong_rows(&g, x, n, h, none) == 0, "after the translation");
    /* a shear of more than the skin across h: due, and the rows right */
    int due = 0;
    for (int step = 0; step < 10 && !due; step++) {
        for (int i = 0; i < n; i++) x[3 * i] += 0.2 * x[3 * i + 1];
        due = stf_grid_due(&g, x, n, h);
        CHECK(stf_grid_build(&g, x, n, h) == 0, "build");
        CHECK(wrong_rows(&g, x, n, h, none) == 0, "shear step %d", step);
    }
    CHECK(due, "a shear of 20%% a step never asked for a rebuild");
    /* a slip along a plane between two layers of cells: everything above it jumps 0.6 h
       along it, each cell moving as a whole */
    for (int i = 0; i < n; i++) x[3 * i] += 0.6 * h * (floor(x[3 * i + 1] * (1.0 / g.cell)) >= 1);
    CHECK(stf_grid_due(&g, x, n, h), "a slip of 0.6 h did not ask for a rebuild");
    CHECK(stf_grid_build(&g, x, n, h) == 0, "build");
    CHECK(wrong_rows(&g, x, n, h, none) == 0, "after the slip");
    stf_grid_free(&g);
    free(x);
}

/* Two particles in neighbouring cells, each moving as a whole: the relative move across the
 * cells is what counts. */
static void test_two_cells(void)
{
    const double h = 0.1, none[3] = {0, 0, 0}; /* default skin: candidates within 0.125 */
    double x[6] = {0.0, 0.12, 0.06, 0.126, 0.13, 0.06};
    stf_grid g = {0};
    CHECK(stf_grid_build(&g, x, 2, h) == 0, "build");
    CHECK(g.ccount[0] == 0, "0.1264 apart: not candidates");
    x[3] -= 0.03; /* now 0.0965 apart: neighbours, after a relative move of 0.3 h */
    CHECK(stf_grid_due(&g, x, 2, h), "a relative move of 0.3 h across two cells: not due");
    CHECK(stf_grid_build(&g, x, 2, h) == 0, "build");
    CHECK(wrong_rows(&g, x, 2, h, none) == 0, "two cells");
    stf_grid_free(&g);
}

static void test_threads_and_paths(void)
{
    const int n = 4000;
    const double h = 0.05;
    double *x = cloud(n, h);
    stf_grid one = {0}, two = {0}, plain = {0};
    plain.plain = 1;
    int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    CHECK(stf_grid_build(&one, x, n, h) == 0, "build");
    CHECK(stf_grid_build(&plain, x, n, h) == 0, "build");
    omp_set_num_threads(2);
    CHECK(stf_grid_build(&two, x, n, h) == 0, "build");
    omp_set_num_threads(threads);
    CHECK(lists_equal(&one, &two, n), "1 and 2 threads give different lists");
    CHECK(lists_equal(&one, &plain, n), "the AVX2 and plain searches give different lists");
    /* a checkpoint's restore from the reference positions gives the same lists */
    stf_grid back = {0};
    CHECK(stf_grid_restore(&back, one.xref, n, h, one.skin_used) == 0, "restore");
    CHECK(stf_grid_build(&back, x, n, h) == 0, "build");
    CHECK(lists_equal(&one, &back, n), "restored lists differ");
    stf_grid_free(&one);
    stf_grid_free(&two);
    stf_grid_free(&plain);
    stf_grid_free(&back);
    free(x);
}

static void test_sort(void)
{
    const int n = 2500;
    const double h = 0.05, none[3] = {0, 0, 0};
    double *x = cloud(n, h), *y = malloc((size_t)n * 3 * sizeof *y);
    stf_grid g = {0};
    CHECK(stf_grid_sort(&g, x, n, h) == 0, "sort");
    char *hit = calloc((size_t)n, 1);
    int perm_ok = 1;
    for (int i = 0; i < n; i++) {
        int o = g.order[i];
        if (o < 0 || o >= n || hit[o]) perm_ok = 0;
        else hit[o] = 1;
        memcpy(y + 3 * i, x + 3 * o, 3 * sizeof *y);
    }
    CHECK(perm_ok, "grid_sort's order is not a permutation");
    CHECK(stf_grid_build(&g, y, n, h) == 0, "build");
    CHECK(wrong_rows(&g, y, n, h, none) == 0, "sorted particles");
    free(hit);
    free(y);
    free(x);
    stf_grid_free(&g);
}

static void test_periodic(void)
{
    const int n = 1500;
    const double h = 0.07;
    double period[3] = {0.5, 0.3, 0};
    double *x = malloc((size_t)n * 3 * sizeof *x);
    for (int i = 0; i < n; i++) {
        x[3 * i] = -0.2 + period[0] * uniform();
        x[3 * i + 1] = 0.1 + period[1] * uniform();
        x[3 * i + 2] = 0.25 * uniform();
    }
    stf_grid g = {0};
    memcpy(g.period, period, sizeof period);
    g.origin[0] = -0.2;
    g.origin[1] = 0.1;
    CHECK(stf_grid_build(&g, x, n, h) == 0, "build");
    CHECK(wrong_rows(&g, x, n, h, period) == 0, "periodic");
    stf_grid_free(&g);
    free(x);
}

/* No particles (an empty fluid, or every particle removed): a fresh grid builds, and
 * grows to particles after. */
static void test_empty(void)
{
    const double h = 0.1, none[3] = {0, 0, 0};
    stf_grid g = {0};
    CHECK(stf_grid_build(&g, NULL, 0, h) == 0, "build of no particles");
    CHECK(stf_grid_due(&g, NULL, 0, h) == 0, "no particles, nothing moved: due");
    CHECK(stf_grid_build(&g, NULL, 0, h) == 0, "second build of no particles");
    double x[6] = {0.0, 0.0, 0.0, 0.05, 0.0, 0.0};
    CHECK(stf_grid_build(&g, x, 2, h) == 0, "build");
    CHECK(wrong_rows(&g, x, 2, h, none) == 0, "two particles after none");
    stf_grid_free(&g);
}

/* A restore that runs out of memory (the address space capped with setrlimit: a real
 * allocation failure) into a grid in use: it reports -1, and the next build must not reuse
 * the half-overwritten candidate lists as if they were still those of the last rebuild. Not
 * under ASan (its shadow memory does not fit under the cap). */
static void test_restore_out_of_memory(void)
{
#if !defined(__SANITIZE_ADDRESS__)
    const int n = 4000;
    const double h = 0.05, none[3] = {0, 0, 0};
    double *x = cloud(n, h), *dense = malloc((size_t)n * 3 * sizeof *dense);
    for (int i = 0; i < n; i++) dense[3 * i] = dense[3 * i + 1] = dense[3 * i + 2] = 0.3;
    stf_grid g = {0};
    CHECK(stf_grid_build(&g, x, n, h) == 0, "build");
    long pages = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (f && fscanf(f, "%ld", &pages) == 1) {
        struct rlimit old, cap;
        getrlimit(RLIMIT_AS, &old);
        cap = old;
        cap.rlim_cur = (rlim_t)pages * 4096 + (32u << 20); /* n^2 candidates need 64 MB */
        if (cap.rlim_cur < old.rlim_cur && setrlimit(RLIMIT_AS, &cap) == 0) {
            int rc = stf_grid_restore(&g, dense, n, h, 0.25);
            setrlimit(RLIMIT_AS, &old);
            CHECK(rc == -1, "restoring 16 M candidates under a 32 MB cap succeeded");
            CHECK(stf_grid_build(&g, x, n, h) == 0, "build after the failed restore");
            CHECK(wrong_rows(&g, x, n, h, none) == 0, "rows after a failed restore");
        }
    }
    if (f) fclose(f);
    stf_grid_free(&g);
    free(dense);
    free(x);
#endif
}

/* The rows of g, copied (row i at i * cap). */
static int32_t *copy_rows(const stf_grid *g, int n, int cap, int *count)
{
    int32_t *rows = malloc((size_t)n * (size_t)cap * sizeof *rows);
    for (int i = 0; i < n; i++) {
        count[i] = g->count[i] < cap ? g->count[i] : cap;
        memcpy(rows + (size_t)i * (size_t)cap, grid_row(g, i), (size_t)count[i] * sizeof *rows);
    }
    return rows;
}

/* gained[i] (set by the filter) must say whether row i holds a particle the previous row
 * (old, ocount) did not; after a rebuild every row counts as gained. Returns the wrong ones. */
static int wrong_gained(const stf_grid *g, int n, const int32_t *old, const int *ocount, int cap,
                        int rebuilt)
{
    int bad = 0;
    for (int i = 0; i < n; i++) {
        int new_one = 0;
        const int32_t *row = grid_row(g, i);
        for (int k = 0; k < g->count[i] && !new_one; k++) {
            int found = 0;
            for (int m = 0; m < ocount[i] && !found; m++)
                found = old[(size_t)i * (size_t)cap + (size_t)m] == row[k];
            new_one = !found;
        }
        int want = rebuilt || new_one;
        if (g->gained[i] != want && bad++ < 3)
            fprintf(stderr, "particle %d: gained %d, want %d (rebuilt %d)\n", i, g->gained[i], want,
                    rebuilt);
    }
    return bad;
}

/* The filters' "gained a neighbour" flags (springs.c skips its search for new springs on
 * them) against the rows themselves, through small moves that bring neighbours in and out,
 * candidate reuse and rebuilds, for the AVX2 and the plain filter; one particle's candidates
 * span more than one 64-bit word of flags (the clump). */
static void test_gained(void)
{
    const int n = 3000, cap = n; /* rows copied whole */
    const double h = 0.06;
    for (int plain = 0; plain <= 1; plain++) {
        rng = 777u;
        double *x = cloud(n, h);
        stf_grid g = {0};
        g.plain = plain;
        CHECK(stf_grid_build(&g, x, n, h) == 0, "build");
        int *ocount = malloc((size_t)n * sizeof *ocount), reused = 0, some_kept = 0;
        for (int step = 0; step < 16; step++) {
            int32_t *old = copy_rows(&g, n, cap, ocount);
            for (int k = 0; k < 3 * n; k++) x[k] += 0.01 * h * (uniform() - 0.5);
            long r0 = g.rebuilds;
            CHECK(stf_grid_build(&g, x, n, h) == 0, "build");
            int rebuilt = g.rebuilds != r0;
            reused += !rebuilt;
            for (int i = 0; i < n && !rebuilt; i++) some_kept += !g.gained[i];
            CHECK(wrong_gained(&g, n, old, ocount, cap, rebuilt) == 0, "%s filter, step %d",
                  plain ? "plain" : "AVX2", step);
            free(old);
        }
        CHECK(reused > 0 && some_kept > 0, "no step reused the candidates with a row unchanged");
        free(ocount);
        stf_grid_free(&g);
        free(x);
    }
}

int main(void)
{
    test_empty();
    test_verlet();
    test_two_cells();
    test_threads_and_paths();
    test_gained();
    test_sort();
    test_periodic();
    test_restore_out_of_memory();
    return test_result("test_grid");
}
