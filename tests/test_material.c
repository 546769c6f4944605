/* test_material.c - a scene's `material:` (src/io/scene.c, merge_material), on real files in a
 * temporary directory:
 *  - the material's fluid keys and the parameters of the effects the scene names fill the
 *    scene; the scene's own keys win; an effect the scene does not name stays off;
 *  - d and memory are one key: a scene's d wins over the material's memory;
 *  - a bad key or value in the material is reported at the material file's line (also a
 *    value the fluid's def check refuses, of the fluid section or of an effect);
 *  - a missing material file is reported at the scene's `material` key;
 *  - the stored scene text holds the merged scene without the `material` key and loads (with
 *    no material file around) to the same fluid.
 *  - the shipped cornstarch material at its reference spacing and at 1.5x: the stiffnesses
 *    scale as the continuum similarity says (k_min and k_onset as s^-2, k_hist as s^-3, k as
 *    1/s, sigma as s^-2).
 */
#define _POSIX_C_SOURCE 200809L
#include "stf_io.h"
#include "test_util.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char dir[] = "/tmp/stf_test_materialXXXXXX";

static void put(const char *name, const char *text)
{
    char path[256];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    CHECK(f != NULL, "cannot write %s", path);
    if (!f) return;
    fputs(text, f);
    fclose(f);
}

static const char *material =
    "name: clay\n"
    "fluid:\n"
    "  density: 1500\n"
    "  relaxation: gauss_seidel\n"
    "effects:\n"
    "  viscosity: {sigma: 7.0}\n"
    "  springs: {k_min: 300, plasticity: 1.5}\n"
    "  history: {q: 0.4, memory: 2.0, k_hist: 5e5}\n";

static const char *scene_head =
    "duration: 0.1\n"
    "material: clay\n"
    "fluid:\n"
    "  spacing: 0.02\n"
    "  blocks: [{min: [0, 0, 0], max: [0.1, 0.1, 0.1]}]\n";

static int load(const char *name, stf_scene **s, char *err, size_t errlen)
{
    char path[256];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    return stf_scene_load(path, NULL, 0, s, err, errlen);
}

static void test_merge(void)
{
    char text[1024], err[512];
    snprintf(text, sizeof text, "%s%s", scene_head,
             "effects:\n  viscosity: {}\n  springs: {k_min: 50}\n  history: {d: 40}\n");
    put("merge.yaml", text);
    stf_scene *s = NULL;
    int rc = load("merge.yaml", &s, err, sizeof err);
    CHECK(rc == 0, "merge.yaml: %s", err);
    if (rc) return;
    const stf_fluid_def *f = &s->fluid;
    CHECK(f->density == 1500, "density %g from the material", f->density);
    CHECK(f->relaxation == STF_RELAX_GAUSS_SEIDEL, "relaxation from the material");
    CHECK(f->sigma == 7.0, "sigma %g from the material's viscosity", f->sigma);
    CHECK(f->k_min == 50, "k_min %g: the scene's own wins", f->k_min);
    CHECK(f->plasticity == 1.5, "plasticity %g from the material", f->plasticity);
    CHECK(f->q == 0.4 && f->k_hist == 5e5, "history q %g, k_hist %g from the material", f->q, f->k_hist);
    CHECK(f->d == 40 && f->memory == 0, "d %d, memory %g: the scene's d wins over the material's memory",
          f->d, f->memory);
    CHECK(!(f->effects & STF_EFFECT_PRESSURE) && !(f->effects & STF_EFFECT_BOUNDARY_STICK),
          "effects 0x%x: only those the scene names", f->effects);
    CHECK(s->text && !strstr(s->text, "material"), "stored text still names the material:\n%s", s->text);
    /* the stored text alone (no material file) gives the same fluid */
    stf_scene *again = NULL;
    rc = stf_scene_load_string("/nonexistent/stored.yaml", s->text, NULL, 0, &again, err, sizeof err);
    CHECK(rc == 0, "stored text: %s", err);
    if (!rc) {
        const stf_fluid_def *g = &again->fluid;
        CHECK(g->density == f->density && g->sigma == f->sigma && g->k_min == f->k_min &&
                  g->k_hist == f->k_hist && g->d == f->d && g->effects == f->effects &&
                  g->relaxation == f->relaxation,
              "the stored scene loads to another fluid");
        stf_scene_free(again);
    }
    stf_scene_free(s);
}

static void expect_error(const char *scene_file, const char *want)
{
    char err[512] = "";
    stf_scene *s = NULL;
    int rc = load(scene_file, &s, err, sizeof err);
    CHECK(rc == 2, "%s: want exit 2, got %d", scene_file, rc);
    CHECK(strstr(err, want) != NULL, "%s: '%s' not in '%s'", scene_file, want, err);
    stf_scene_free(s);
}

static void test_errors(void)
{
    char text[1024], want[512];
    put("materials/bad.yaml", "fluid:\n  density: 1500\neffects:\n  springs: {k_min: -3}\n");
    snprintf(text, sizeof text, "duration: 0.1\nmaterial: bad\nfluid:\n  spacing: 0.02\n"
                                "  blocks: [{min: [0, 0, 0], max: [0.1, 0.1, 0.1]}]\n"
                                "effects:\n  springs: {}\n");
    put("bad_value.yaml", text);
    snprintf(want, sizeof want, "%s/materials/bad.yaml:4:20: effects.springs.k_min: must be >= 0", dir);
    expect_error("bad_value.yaml", want);
    put("materials/badkey.yaml", "fluid:\n  spacing: 0.01\n");
    snprintf(text, sizeof text, "duration: 0.1\nmaterial: badkey\nfluid:\n  spacing: 0.02\n"
                                "  blocks: [{min: [0, 0, 0], max: [0.1, 0.1, 0.1]}]\neffects: {}\n");
    put("bad_key.yaml", text);
    snprintf(want, sizeof want, "%s/materials/badkey.yaml:2:3: fluid.spacing: unknown key", dir);
    expect_error("bad_key.yaml", want);
    snprintf(text, sizeof text, "duration: 0.1\nmaterial: nothere\nfluid:\n  spacing: 0.02\n"
                                "  blocks: [{min: [0, 0, 0], max: [0.1, 0.1, 0.1]}]\neffects: {}\n");
    put("missing.yaml", text);
    snprintf(want, sizeof want, "%s/missing.yaml:2:11: material: cannot read %s/materials/nothere.yaml",
             dir, dir);
    expect_error("missing.yaml", want);
    /* the def check's refusals of the material's values name the material file, of the
       fluid section and of an effect; one against the scene's own key names the scene */
    put("materials/thin.yaml", "fluid:\n  density: 0\n");
    snprintf(text, sizeof text,
             "duration: 0.1\nmaterial: thin\nfluid:\n  spacing: 0.02\n"
             "  blocks: [{min: [0, 0, 0], max: [0.1, 0.1, 0.1]}]\neffects: {}\n");
    put("bad_density.yaml", text);
    snprintf(want, sizeof want, "%s/materials/thin.yaml:2:12: fluid.density: must be > 0 (got 0)",
             dir);
    expect_error("bad_density.yaml", want);
    put("materials/onset.yaml", "fluid:\n  reference_spacing: 0.02\neffects:\n"
                                "  history: {q: 0.5, k_onset: -2}\n");
    snprintf(text, sizeof text,
             "duration: 0.1\nmaterial: onset\nfluid:\n  spacing: 0.02\n"
             "  blocks: [{min: [0, 0, 0], max: [0.1, 0.1, 0.1]}]\n"
             "effects:\n  springs: {}\n  history: {d: 10}\n");
    put("bad_onset.yaml", text);
    snprintf(want, sizeof want,
             "%s/materials/onset.yaml:4:30: effects.history.k_onset: must be >= 0 (got -2)", dir);
    expect_error("bad_onset.yaml", want);
    snprintf(text, sizeof text,
             "duration: 0.1\nmaterial: onset\nfluid:\n  spacing: 0.02\n"
             "  blocks: [{min: [0, 0, 0], max: [0.1, 0.1, 0.1]}]\n"
             "effects:\n  springs: {}\n"
             "  history: {k_onset: 0, reference_spacing: 0.01}\n");
    put("both_spacings.yaml", text);
    snprintf(want, sizeof want,
             "%s/both_spacings.yaml:8:44: effects.history.reference_spacing: give the "
             "material's (fluid) or the history's, not both",
             dir);
    expect_error("both_spacings.yaml", want);
}

/* The shipped material at its reference spacing (2 cm) and at 3 cm. */
static void test_scaling(void)
{
    const char *scenes = getenv("STF_SCENES");
    if (!scenes) scenes = "scenes";
    char text[2048], path[512], err[512];
    double sp[2] = {0.02, 0.03};
    stf_fluid *fl[2] = {NULL, NULL};
    for (int k = 0; k < 2; k++) {
        snprintf(text, sizeof text,
                 "duration: 0.1\nmaterial: cornstarch\nfluid:\n  spacing: %g\n"
                 "  blocks: [{min: [0, 0, 0], max: [0.1, 0.1, 0.1]}]\n"
                 "effects:\n  viscosity: {}\n  pressure: {}\n  springs: {}\n  history: {}\n",
                 sp[k]);
        snprintf(path, sizeof path, "%s/scale.yaml", scenes);
        stf_scene *s = NULL;
        int rc = stf_scene_load_string(path, text, NULL, 0, &s, err, sizeof err);
        CHECK(rc == 0, "cornstarch at %g m: %s", sp[k], err);
        if (rc) return;
        rc = stf_fluid_create(&s->fluid, &fl[k], err, sizeof err);
        CHECK(rc == 0, "create: %s", err);
        stf_scene_free(s);
        if (rc) return;
    }
    stf_fluid_def da, db;
    stf_fluid_get_def(fl[0], &da);
    stf_fluid_get_def(fl[1], &db);
    const stf_fluid_def *a = &da, *b = &db;
    double r = 0.02 / 0.03;
    CHECK(a->material_spacing == 0.02, "the material is given at 2 cm (got %g)", a->material_spacing);
    CHECK_NEAR(b->k_min / a->k_min, r * r, 1e-12, "k_min as s^-2");
    CHECK_NEAR(b->k_onset / a->k_onset, r * r, 1e-12, "k_onset as s^-2");
    CHECK_NEAR(b->k_hist / a->k_hist, r * r * r, 1e-12, "k_hist as s^-3");
    CHECK_NEAR(b->k / a->k, r, 1e-12, "k as 1/s");
    CHECK_NEAR(b->k_near / a->k_near, r, 1e-12, "k_near as 1/s");
    CHECK_NEAR(b->sigma / a->sigma, r * r, 1e-12, "sigma as s^-2");
    CHECK(b->plasticity == a->plasticity && b->stick == a->stick && b->q == a->q,
          "rates and q do not scale");
    stf_fluid_destroy(fl[0]);
    stf_fluid_destroy(fl[1]);
}

int main(void)
{
    if (!mkdtemp(dir)) return 1;
    char sub[300];
    snprintf(sub, sizeof sub, "%s/materials", dir);
    mkdir(sub, 0700);
    put("materials/clay.yaml", material);
    test_merge();
    test_errors();
    test_scaling();
    const char *files[] = {"materials/clay.yaml", "materials/bad.yaml", "materials/badkey.yaml",
                           "merge.yaml", "bad_value.yaml", "bad_key.yaml", "missing.yaml"};
    for (size_t i = 0; i < sizeof files / sizeof *files; i++) {
        char p[400];
        snprintf(p, sizeof p, "%s/%s", dir, files[i]);
        unlink(p);
    }
    rmdir(sub);
    rmdir(dir);
    return test_result("test_material");
}
