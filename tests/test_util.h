/* test_util.h - a tiny assertion harness: CHECK records a failure and goes on; the test's
 * main returns test_result(). */
#ifndef STF_TEST_UTIL_H
#define STF_TEST_UTIL_H
#include <math.h>
#include <stdio.h>

static int test_failures;

#define CHECK(cond, ...)                                                                      \
    do {                                                                                      \
        if (!(cond)) {                                                                        \
            fprintf(stderr, "%s:%d: CHECK(%s) failed: ", __FILE__, __LINE__, #cond);          \
            fprintf(stderr, __VA_ARGS__);                                                     \
            fputc('\n', stderr);                                                              \
            test_failures++;                                                                  \
        }                                                                                     \
    } while (0)

#define CHECK_NEAR(a, b, tol, what)                                                           \
    CHECK(fabs((double)(a) - (double)(b)) <= (tol), "%s: %.17g vs %.17g (tol %.3g)", what,    \
          (double)(a), (double)(b), (double)(tol))

/* xorshift64*: the next number of the stream *state, uniform in [-1, 1). */
static inline double test_urand(unsigned long long *state)
{
    *state ^= *state >> 12;
    *state ^= *state << 25;
    *state ^= *state >> 27;
    unsigned long long r = *state * 2685821657736338717ull;
    return (double)(r >> 11) / 9007199254740992.0 * 2.0 - 1.0;
}

static inline int test_result(const char *name)
{
    if (test_failures) fprintf(stderr, "%s: %d check(s) failed\n", name, test_failures);
    else printf("%s: ok\n", name);
    return test_failures ? 1 : 0;
}
#endif
