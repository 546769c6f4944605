/* test_scene_limits.c - inputs the fuzzer found, and their kin: the scene loader bounds the
 * work a file can ask for and refuses each with exit code 2 and FILE:LINE:COL, quickly.
 * (An alarm turns a hang into a failure instead of a stuck test.) */
#define _POSIX_C_SOURCE 200809L
#include "stf_io.h"
#include "test_util.h"

#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static void on_alarm(int sig)
{
    (void)sig;
    static const char msg[] = "test_scene_limits: FAIL: an input took more than 20 s\n";
    ssize_t w = write(2, msg, sizeof msg - 1);
    (void)w;
    _exit(1);
}

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Loads text; expects rc and (for rc 2) every needle in the message; at most 1 s. */
static void expect(const char *what, const char *text, const stf_override *ov, int nov, int rc,
                   const char *needle1, const char *needle2)
{
    char err[1024] = "";
    stf_scene *s = NULL;
    double t0 = now();
    int got = stf_scene_load_string("f.yaml", text, ov, nov, &s, err, sizeof err);
    double secs = now() - t0;
    CHECK(got == rc, "%s: rc %d, want %d (%s)", what, got, rc, err);
    CHECK(secs < 1.0, "%s: took %.2f s", what, secs);
    if (needle1) CHECK(strstr(err, needle1), "%s: message '%s' lacks '%s'", what, err, needle1);
    if (needle2) CHECK(strstr(err, needle2), "%s: message '%s' lacks '%s'", what, err, needle2);
    stf_scene_free(s);
}

#define SCENE_HEAD                                                                            \
    "duration: 0.1\n"                                                                         \
    "fluid:\n"                                                                                \
    "  spacing: 0.01\n"

static void test_utf8(void)
{
    /* libfyaml 0.7.12 loops forever on '%' followed by a byte that starts no UTF-8 sequence
       (the fuzzer's first timeout); every invalid sequence is refused before parsing. */
    expect("%\\xff", "%\xff\xff\xff", NULL, 0, 2, "f.yaml:1:2: scene: not UTF-8", "0xff");
    expect("%\\x80", "%\x80", NULL, 0, 2, "f.yaml:1:2:", "not UTF-8");
    expect("truncated", "a: 1\nb: \xc3", NULL, 0, 2, "f.yaml:2:4:", "not UTF-8");
    expect("surrogate", "a: \xed\xa0\x80", NULL, 0, 2, "f.yaml:1:4:", "not UTF-8");
    expect("overlong", "a: \xc0\xaf", NULL, 0, 2, "f.yaml:1:4:", "not UTF-8");
    expect("above U+10FFFF", "a: \xf4\x90\x80\x80", NULL, 0, 2, "f.yaml:1:4:", "not UTF-8");
    /* valid multi-byte text passes the check (and fails later, on the schema) */
    expect("valid UTF-8", "# caf\xc3\xa9\xe2\x82\xac\xf0\x9f\x98\x80\nname: cafe\n", NULL, 0, 2,
           "duration", NULL);
    stf_override ov = {"name", "x\xff"};
    expect("override", SCENE_HEAD "  blocks: [{min: [0, 0, 0], max: [0.1, 0.1, 0.1]}]\n"
                                  "effects: {}\n",
           &ov, 1, 2, "--set name=", "UTF-8");
}

static void test_aliases(void)
{
    /* "billion laughs": 9 lines that resolve to 10^9 nodes (3.3 GB and minutes in libfyaml) */
    char laughs[2048] = "a0: &a0 [x, x, x, x, x, x, x, x, x, x]\n";
    for (int i = 1; i < 9; i++) {
        char line[256];
        int n = snprintf(line, sizeof line, "a%d: &a%d [", i, i);
        for (int k = 0; k < 10; k++)
            n += snprintf(line + n, sizeof line - (size_t)n, "%s*a%d", k ? ", " : "", i - 1);
        snprintf(line + n, sizeof line - (size_t)n, "]\n");
        strcat(laughs, line);
    }
    expect("billion laughs", laughs, NULL, 0, 2, "f.yaml:", "aliases expand to more than");
    expect("recursive alias", "a: &a [*a]\n", NULL, 0, 2, "f.yaml:1:", "aliases expand");
    expect("recursive merge", "duration: 0.1\nfluid: &f\n  spacing: 0.01\n  blocks: [{<<: *f, min: [0,0,0], max: [1,1,1]}]\n",
           NULL, 0, 2, "f.yaml:", "aliases expand");
    expect("undefined alias", "a: *nope\n", NULL, 0, 2, "f.yaml:1:", "alias");
    /* a sensible use of aliases still works */
    stf_scene *s = NULL;
    char err[512];
    int rc = stf_scene_load_string("f.yaml",
                                   SCENE_HEAD "  blocks:\n"
                                              "    - &b {min: [0, 0, 0], max: [0.1, 0.1, 0.1]}\n"
                                              "    - *b\n"
                                              "effects: {}\n",
                                   NULL, 0, &s, err, sizeof err);
    CHECK(rc == 0 && s && s->nblocks == 2 && s->blocks[1].hi[2] == 0.1, "alias block: %s", err);
    stf_scene_free(s);
}

static void test_nesting(void)
{
    static char deep[9000];
    memset(deep, '[', 4000);
    memset(deep + 4000, ']', 4000);
    expect("deep flow", deep, NULL, 0, 2, "f.yaml:1:", "depth");
    char *map = calloc(1, 8000), *p = map;
    for (int i = 0; i < 1300; i++)
        p += sprintf(p, "{a: ");
    memset(p, '}', 1300);
    expect("deep mapping", map, NULL, 0, 2, "f.yaml:1:", "depth");
    free(map);
}

/* A run's step counts: round(duration / dt) in 1 .. STF_MAX_STEPS (1e300 s overflowed the
 * count and ran 0 steps), the steps between frames and fluid.settle's steps at most that. */
static void test_steps(void)
{
#define STEPS_SCENE(top, fluid)                                                               \
    top "fluid:\n  spacing: 0.01\n" fluid                                                     \
        "  blocks: [{min: [0, 0, 0], max: [0.1, 0.1, 0.1]}]\neffects: {}\n"
    expect("1e9 steps", STEPS_SCENE("duration: 1000000\n", ""), NULL, 0, 0, NULL, NULL);
    expect("1e300 s", STEPS_SCENE("duration: 1e300\n", ""), NULL, 0, 2, "f.yaml:1:11: duration: ",
           "more than 1000000000");
    expect("1e9 + 1 steps", STEPS_SCENE("duration: 1000000.001\n", ""), NULL, 0, 2,
           "f.yaml:1:11: duration: ", "more than 1000000000");
    expect("0 steps", STEPS_SCENE("duration: 0.0004\n", ""), NULL, 0, 2, "f.yaml:1:11: duration: ",
           "0 once rounded");
    expect("tiny dt", STEPS_SCENE("duration: 1\ndt: 1e-300\n", ""), NULL, 0, 2,
           "f.yaml:1:11: duration: ", "1e+300 steps");
    stf_override dt = {"dt", "1e-300"}, dur = {"duration", "1e300"};
    expect("--set dt", STEPS_SCENE("duration: 1\n", ""), &dt, 1, 2, "--set dt=1e-300: dt: ",
           "more than");
    expect("--set duration", STEPS_SCENE("duration: 1\n", ""), &dur, 1, 2,
           "--set duration=1e300: duration: ", "more than");
    expect("frame_rate", STEPS_SCENE("duration: 1\nframe_rate: 1e-12\n", ""), NULL, 0, 2,
           "f.yaml:2:13: frame_rate: ", "a frame every");
    expect("settle", STEPS_SCENE("duration: 0.1\ndt: 1e-9\n", "  settle: 10\n"), NULL, 0, 2,
           "f.yaml:5:11: fluid.settle: ", "more than");
#undef STEPS_SCENE
    char err[256];
    CHECK(stf_run_steps(2.0, 0.001, err, sizeof err) == 2000, "2 s at 1 ms: %s", err);
    CHECK(stf_run_steps(1e300, 0.001, err, sizeof err) == -1 && strstr(err, "more than"),
          "1e300 s: %s", err);
    CHECK(stf_run_steps(INFINITY, 0.001, err, sizeof err) == -1 && strstr(err, "finite"),
          "inf s: %s", err);
    CHECK(stf_run_steps(1, 0, NULL, 0) == -1, "dt 0");
}

int main(void)
{
    signal(SIGALRM, on_alarm);
    alarm(20);
    test_utf8();
    test_aliases();
    test_nesting();
    test_steps();
    return test_result("test_scene_limits");
}
