/* scene.c - loading and checking YAML scene files (see scenes/README.md for the schema).
 *
 * The file is parsed into a libfyaml document, the --set/--unset overrides are applied to
 * that document, and the result is walked once to fill an stf_scene. Every error names the
 * place it came from: FILE:LINE:COL for text of the file, or the override that created the
 * offending node (such nodes carry the override's index as libfyaml node meta data).
 */
#define _POSIX_C_SOURCE 200809L
#include "body_mesh.h"
#include "metrics.h"
#include "stf_io.h"

#include <errno.h>
#include <libfyaml.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { SCENE_BAD = 2 };

typedef struct loader {
    const char *file; /* name used in messages */
    char material_file[1024]; /* the material file merged into the scene ("" without) */
    char *material_text;      /* its text and document, alive while the scene's nodes copied */
    struct fy_document *material_fyd; /* from it refer to them */
    char *err;
    size_t errlen;
    struct fy_document *fyd;
    const stf_override *ov;
    int nov;
    stf_scene *s;
} loader;

/* A mapping being read, with what "missing key" errors point at. */
typedef struct mapv {
    struct fy_node *node; /* the mapping, NULL when empty or null */
    struct fy_node *at;   /* its key node (or the item itself); NULL at top level */
    char path[128];       /* dotted path, "" at top level */
} mapv;

enum range { R_ANY, R_POS, R_NONNEG, R_UNIT, R_HALF_UNIT };

/* ------------------------------------------------------------------- locations, errors */

/* Position (1-based) of the first token of a node: scalars have one; collections use
 * their first descendant because libfyaml 0.7 exposes no start mark for them. */
static int node_mark(struct fy_node *n, int *line, int *col)
{
    if (!n) return 0;
    if (fy_node_is_scalar(n)) {
        struct fy_token *t = fy_node_get_scalar_token(n);
        const struct fy_mark *m = t ? fy_token_start_mark(t) : NULL;
        if (!m) return 0;
        *line = m->line + 1;
        *col = m->column + 1;
        return 1;
    }
    void *it = NULL;
    if (fy_node_is_sequence(n)) return node_mark(fy_node_sequence_iterate(n, &it), line, col);
    if (fy_node_is_mapping(n)) {
        struct fy_node_pair *p = fy_node_mapping_iterate(n, &it);
        return p ? node_mark(fy_node_pair_key(p), line, col) : 0;
    }
    return 0;
}

/* Node meta data: i + 1 for a node made by override i; MATERIAL_META for a node copied from
 * the material file (merge_material). */
#define MATERIAL_META (-1)

/* The override (index) that created n or one of its ancestors, or -1. */
static int node_override(struct fy_node *n)
{
    for (; n; n = fy_node_get_document_parent(n)) {
        intptr_t m = (intptr_t)fy_node_get_meta(n);
        if (m > 0) return (int)(m - 1);
        if (m == MATERIAL_META) return -1;
    }
    return -1;
}

/* 1 when n came from the material file (it or an ancestor was copied from there). */
static int node_from_material(struct fy_node *n)
{
    for (; n; n = fy_node_get_document_parent(n)) {
        intptr_t m = (intptr_t)fy_node_get_meta(n);
        if (m > 0) return 0;
        if (m == MATERIAL_META) return 1;
    }
    return 0;
}

static void mark_override(struct fy_node *n, int i)
{
    fy_node_set_meta(n, (void *)(intptr_t)(i + 1));
}

static void mark_material(struct fy_node *n)
{
    fy_node_set_meta(n, (void *)(intptr_t)MATERIAL_META);
}

static int override_fail(loader *L, int i, const char *key, const char *what)
{
    const stf_override *o = &L->ov[i];
    if (o->value)
        snprintf(L->err, L->errlen, "--set %s=%s: %s: %s", o->key, o->value, key, what);
    else
        snprintf(L->err, L->errlen, "--unset %s: %s: %s", o->key, key, what);
    return SCENE_BAD;
}

/* Reports an error at node `at` (or `alt` when `at` has no position). Returns SCENE_BAD. */
static int fail(loader *L, struct fy_node *at, struct fy_node *alt, const char *key,
                const char *fmt, ...) __attribute__((format(printf, 5, 6)));
static int fail(loader *L, struct fy_node *at, struct fy_node *alt, const char *key,
                const char *fmt, ...)
{
    char what[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    int o = node_override(at);
    if (o < 0) o = node_override(alt);
    if (o >= 0) return override_fail(L, o, key, what);
    int line = 1, col = 1;
    struct fy_node *where = at;
    if (!node_mark(at, &line, &col)) node_mark(where = alt, &line, &col);
    const char *file = node_from_material(where) ? L->material_file : L->file;
    snprintf(L->err, L->errlen, "%s:%d:%d: %s: %s", file, line, col, key, what);
    return SCENE_BAD;
}

static void join(char *out, size_t n, const char *path, const char *key)
{
    if (path[0])
        snprintf(out, n, "%s.%s", path, key);
    else
        snprintf(out, n, "%s", key);
}

static void join_index(char *out, size_t n, const char *path, int i)
{
    snprintf(out, n, "%s.%d", path, i);
}

static void list_words(char *out, size_t n, const char *const *words)
{
    out[0] = '\0';
    for (int i = 0; words[i]; i++) {
        size_t len = strlen(out);
        snprintf(out + len, n - len, "%s%s", i ? ", " : "", words[i]);
    }
}

/* ------------------------------------------------------------------------ node access */

static int is_null(struct fy_node *n)
{
    return !n || fy_node_is_null(n);
}

/* Copies a scalar's text into buf; 0 if n is not a scalar or too long. */
static int scalar_text(struct fy_node *n, char *buf, size_t size)
{
    if (!n || !fy_node_is_scalar(n)) return 0;
    size_t len = 0;
    const char *t = fy_node_get_scalar(n, &len);
    if (!t || len >= size) return 0;
    memcpy(buf, t, len);
    buf[len] = '\0';
    return 1;
}

/* Opens a mapping and rejects keys outside `allowed`. A null value is an empty mapping. */
static int open_map(loader *L, struct fy_node *n, struct fy_node *at, const char *path,
                    const char *const *allowed, mapv *m)
{
    m->node = is_null(n) ? NULL : n;
    m->at = at;
    snprintf(m->path, sizeof m->path, "%s", path);
    if (!m->node) return 0;
    if (!fy_node_is_mapping(n))
        return fail(L, n, at, path[0] ? path : "scene", "expected a mapping");
    void *it = NULL;
    struct fy_node_pair *p;
    while ((p = fy_node_mapping_iterate(n, &it))) {
        struct fy_node *k = fy_node_pair_key(p);
        char name[128], full[256], list[512];
        if (!scalar_text(k, name, sizeof name)) {
            return fail(L, k, at, path[0] ? path : "scene", "expected a plain key");
        }
        int ok = 0;
        for (int i = 0; allowed[i] && !ok; i++)
            ok = strcmp(allowed[i], name) == 0;
        if (!ok) {
            join(full, sizeof full, path, name);
            list_words(list, sizeof list, allowed);
            return fail(L, k, NULL, full, "unknown key (allowed: %s)", list);
        }
    }
    return 0;
}

/* The value of key in m; *keyn the key node (NULL when absent). */
static struct fy_node *lookup(const mapv *m, const char *key, struct fy_node **keyn)
{
    *keyn = NULL;
    if (!m->node) return NULL;
    struct fy_node_pair *p = fy_node_mapping_lookup_pair_by_string(m->node, key, FY_NT);
    if (!p) return NULL;
    *keyn = fy_node_pair_key(p);
    return fy_node_pair_value(p);
}

static int has(const mapv *m, const char *key)
{
    struct fy_node *k;
    lookup(m, key, &k);
    return k != NULL;
}

/* A missing required key: points at the parent's key, or at the --unset that removed it. */
static int missing(loader *L, const mapv *m, const char *key, const char *why)
{
    char full[256];
    join(full, sizeof full, m->path, key);
    for (int i = L->nov - 1; i >= 0; i--) {
        if (!L->ov[i].value && strcmp(L->ov[i].key, full) == 0)
            return override_fail(L, i, full, "required key is missing");
    }
    return fail(L, m->at, NULL, full, "required key is missing%s", why ? why : "");
}

static int range_ok(double v, int range, const char **msg)
{
    static const char *const msgs[] = {"", "must be > 0", "must be >= 0", "must be in [0,1]",
                                       "must be in [0,1)"};
    int ok = 1;
    switch (range) {
    case R_POS:
        ok = v > 0;
        break;
    case R_NONNEG:
        ok = v >= 0;
        break;
    case R_UNIT:
        ok = v >= 0 && v <= 1;
        break;
    case R_HALF_UNIT:
        ok = v >= 0 && v < 1;
        break;
    default:
        break;
    }
    *msg = msgs[range];
    return ok;
}

/* Parses a plain scalar as a number: 1 ok, 0 not a number, -1 not finite. */
static int scalar_number(struct fy_node *n, double *v)
{
    char buf[64], *end;
    if (is_null(n) || !fy_node_is_scalar(n) || fy_node_get_style(n) != FYNS_PLAIN) return 0;
    if (!scalar_text(n, buf, sizeof buf) || !buf[0]) return 0;
    const char *t = buf + (buf[0] == '+' || buf[0] == '-');
    if (t[0] == '.' && (t[1] == 'n' || t[1] == 'N' || t[1] == 'i' || t[1] == 'I')) return -1;
    errno = 0;
    *v = strtod(buf, &end);
    if (*end) return 0;
    return isfinite(*v) ? 1 : -1;
}

/* A number element at `path`: checks type, finiteness and range. */
static int number_at(loader *L, struct fy_node *n, struct fy_node *keyn, const char *path,
                     int range, double *out)
{
    const char *msg;
    int r = scalar_number(n, out);
    if (r == 0) return fail(L, n, keyn, path, "expected a number");
    if (r < 0) return fail(L, n, keyn, path, "must be a finite number (not .nan or .inf)");
    if (!range_ok(*out, range, &msg)) return fail(L, n, keyn, path, "%s", msg);
    return 0;
}

/* Optional number: 1 present, 0 absent, -1 error (message written). */
static int get_num(loader *L, const mapv *m, const char *key, int range, double *out)
{
    struct fy_node *k, *v = lookup(m, key, &k);
    char full[256];
    if (!k) return 0;
    join(full, sizeof full, m->path, key);
    return number_at(L, v, k, full, range, out) ? -1 : 1;
}

static int get_vec(loader *L, const mapv *m, const char *key, int range, int count, double *out)
{
    struct fy_node *k, *v = lookup(m, key, &k);
    char full[256], elem[272];
    if (!k) return 0;
    join(full, sizeof full, m->path, key);
    if (is_null(v) || !fy_node_is_sequence(v) || fy_node_sequence_item_count(v) != count) {
        fail(L, v, k, full, "expected a list of %d numbers", count);
        return -1;
    }
    for (int i = 0; i < count; i++) {
        join_index(elem, sizeof elem, full, i);
        if (number_at(L, fy_node_sequence_get_by_index(v, i), k, elem, range, &out[i])) return -1;
    }
    return 1;
}

static int get_int(loader *L, const mapv *m, const char *key, long lo, long hi, long *out)
{
    struct fy_node *k, *v = lookup(m, key, &k);
    char full[256], buf[64], *end;
    if (!k) return 0;
    join(full, sizeof full, m->path, key);
    int ok = !is_null(v) && fy_node_get_style(v) == FYNS_PLAIN && scalar_text(v, buf, sizeof buf);
    if (ok) {
        errno = 0;
        *out = strtol(buf, &end, 10);
        ok = buf[0] && !*end && errno == 0;
    }
    if (!ok) return fail(L, v, k, full, "expected an integer"), -1;
    if (*out < lo || *out > hi) return fail(L, v, k, full, "must be >= %ld and <= %ld", lo, hi), -1;
    return 1;
}

static int get_bool(loader *L, const mapv *m, const char *key, int *out)
{
    static const char *const yes[] = {"true", "True", "TRUE"}, *const no[] = {"false", "False",
                                                                              "FALSE"};
    struct fy_node *k, *v = lookup(m, key, &k);
    char full[256], buf[16];
    if (!k) return 0;
    join(full, sizeof full, m->path, key);
    if (!is_null(v) && fy_node_get_style(v) == FYNS_PLAIN && scalar_text(v, buf, sizeof buf)) {
        for (int i = 0; i < 3; i++) {
            if (!strcmp(buf, yes[i])) return *out = 1, 1;
            if (!strcmp(buf, no[i])) return *out = 0, 1;
        }
    }
    return fail(L, v, k, full, "expected true or false"), -1;
}

/* One of `names`: *out is the index. */
static int get_choice(loader *L, const mapv *m, const char *key, const char *const *names, int *out)
{
    struct fy_node *k, *v = lookup(m, key, &k);
    char full[256], buf[64], list[256];
    if (!k) return 0;
    join(full, sizeof full, m->path, key);
    if (scalar_text(v, buf, sizeof buf)) {
        for (int i = 0; names[i]; i++) {
            if (!strcmp(buf, names[i])) return *out = i, 1;
        }
    }
    list_words(list, sizeof list, names);
    return fail(L, v, k, full, "expected one of: %s", list), -1;
}

static int get_str(loader *L, const mapv *m, const char *key, char *out, size_t size)
{
    struct fy_node *k, *v = lookup(m, key, &k);
    char full[256];
    if (!k) return 0;
    join(full, sizeof full, m->path, key);
    if (is_null(v) || !fy_node_is_scalar(v)) return fail(L, v, k, full, "expected a string"), -1;
    if (!scalar_text(v, out, size))
        return fail(L, v, k, full, "must be at most %zu characters", size - 1), -1;
    return 1;
}

/* An int field of the fluid's def: any int here (its range is the def check's). */
static int get_count(loader *L, const mapv *m, const char *key, int *out)
{
    long v = *out;
    int r = get_int(L, m, key, INT_MIN, INT_MAX, &v);
    if (r > 0) *out = (int)v;
    return r;
}

/* Required variants: a missing key is an error. */
static int need_num(loader *L, const mapv *m, const char *key, int range, double *out)
{
    int r = get_num(L, m, key, range, out);
    if (r == 0) missing(L, m, key, NULL);
    return r == 1 ? 0 : SCENE_BAD;
}

static int need_vec(loader *L, const mapv *m, const char *key, int range, int count, double *out)
{
    int r = get_vec(L, m, key, range, count, out);
    if (r == 0) missing(L, m, key, NULL);
    return r == 1 ? 0 : SCENE_BAD;
}

/* Fails at the value of key `key` of m (which must be present), or at the key. */
static int fail_value(loader *L, const mapv *m, const char *key, const char *what)
{
    struct fy_node *k, *v = lookup(m, key, &k);
    char full[256];
    join(full, sizeof full, m->path, key);
    return fail(L, v, k, full, "%s", what);
}

/* Fails at key `key` of m (which must be present): the key itself is wrong here. */
static int fail_key(loader *L, const mapv *m, const char *key, const char *what)
{
    struct fy_node *k, *v = lookup(m, key, &k);
    char full[256];
    join(full, sizeof full, m->path, key);
    return fail(L, k, v, full, "%s", what);
}

static int normalise(double *v, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++)
        s += v[i] * v[i];
    if (!(s > 0)) return -1;
    s = sqrt(s);
    for (int i = 0; i < n; i++)
        v[i] /= s;
    return 0;
}

/* ------------------------------------------------------------------ the fluid's def check */

/* The scene key of each field of the fluid's def (stf_fluid_check_def names the field it
 * refuses: a member of stf_fluid_def); alt, when the field may be refused with its own key
 * absent (its default), is the key that made it wrong. */
static const struct def_key {
    const char *field, *key, *alt;
} def_keys[] = {
    {"effects", "effects", NULL},
    {"model", "fluid.model", NULL},
    {"spacing", "fluid.spacing", NULL},
    {"density", "fluid.density", NULL},
    {"jitter", "fluid.jitter", NULL},
    {"h", "fluid.h", NULL},
    {"material_spacing", "fluid.reference_spacing", NULL},
    {"relaxation", "fluid.relaxation", NULL},
    {"iterations", "fluid.iterations", NULL},
    {"gravity", "effects.gravity.g", NULL},
    {"sigma", "effects.viscosity.sigma", NULL},
    {"beta", "effects.viscosity.beta", NULL},
    {"k", "effects.pressure.k", NULL},
    {"k_near", "effects.pressure.k_near", NULL},
    {"rest_density", "effects.pressure.rest_density", NULL},
    {"rest_packing", "effects.pressure.rest", NULL},
    {"relax_wall", "effects.pressure.wall", NULL},
    {"pressure_mode", "effects.pressure.mode", NULL},
    {"pressure.eta", "effects.pressure.eta", "effects.pressure.mode"},
    {"pressure.min_iterations", "effects.pressure.min_iterations", "effects.pressure.mode"},
    {"pressure.max_iterations", "effects.pressure.max_iterations",
     "effects.pressure.min_iterations"},
    {"pressure.solver", "effects.pressure.solver", "effects.pressure.mode"},
    {"pressure.wall_pressure", "effects.pressure.wall_pressure", "effects.pressure.mode"},
    {"pressure.gradient", "effects.pressure.gradient", "effects.pressure.mode"},
    {"pressure.warm_start", "effects.pressure.warm_start", "effects.pressure.mode"},
    {"pressure.cg_tolerance", "effects.pressure.mode", NULL},
    {"pressure.max_cg_iterations", "effects.pressure.mode", NULL},
    {"pressure.relaxation", "effects.pressure.mode", NULL},
    {"k_min", "effects.springs.k_min", NULL},
    {"yield_ratio", "effects.springs.yield_ratio", NULL},
    {"plasticity", "effects.springs.plasticity", NULL},
    {"liquid_plasticity", "effects.springs.liquid_plasticity", NULL},
    {"spring_damping", "effects.springs.damping", NULL},
    {"spring_passive", "effects.springs.passive", NULL},
    {"q", "effects.history.q", NULL},
    {"d", "effects.history.d", NULL},
    {"memory", "effects.history.memory", NULL},
    {"k_hist", "effects.history.k_hist", NULL},
    {"reference_spacing", "effects.history.reference_spacing", NULL},
    {"k_onset", "effects.history.k_onset", NULL},
    {"history_mode", "effects.history.mode", NULL},
    {"history_velocity", "effects.history.velocity", NULL},
    {"history_smoothing", "effects.history.smoothing", NULL},
    {"terms", "effects.history.terms", NULL},
    {"stick", "effects.boundary_stick.stick", NULL},
    {"cy.mu0", "effects.carreau_yasuda.mu0", NULL},
    {"cy.mu_inf", "effects.carreau_yasuda.mu_inf", NULL},
    {"cy.K", "effects.carreau_yasuda.K", NULL},
    {"cy.alpha", "effects.carreau_yasuda.alpha", NULL},
    {"cy.n", "effects.carreau_yasuda.n", NULL},
    {"cy.eta", "effects.carreau_yasuda.eta", NULL},
    {"cy.min_pressure_iterations", "effects.carreau_yasuda.min_pressure_iterations", NULL},
    {"cy.max_pressure_iterations", "effects.carreau_yasuda.max_pressure_iterations",
     "effects.carreau_yasuda.min_pressure_iterations"},
    {"cy.viscosity_solver", "effects.carreau_yasuda.viscosity_solver", NULL},
    {"cy.viscosity_form", "effects.carreau_yasuda.viscosity_form", NULL},
    {"cy.pressure_solver", "effects.carreau_yasuda.pressure_solver", NULL},
    {"cy.wall_pressure", "effects.carreau_yasuda.wall_pressure", NULL},
    {"cy.pressure_gradient", "effects.carreau_yasuda.pressure_gradient", NULL},
    {"cy.cg_tolerance", "effects.carreau_yasuda.cg_tolerance", NULL},
    {"cy.max_cg_iterations", "effects.carreau_yasuda.max_cg_iterations", NULL},
    {"cy.cfl", "effects.carreau_yasuda.cfl", NULL},
    {"cy.dt_max", "effects.carreau_yasuda.dt_max", NULL},
    {"cy.warm_start", "effects.carreau_yasuda.warm_start", NULL},
    {"cy.relaxation", "effects.carreau_yasuda.relaxation", NULL},
    {"periodic", "container.periodic", NULL},
    {"periodic_origin", "container.position", NULL},
};

/* The value at a dotted key path of the document (overrides applied, material merged);
 * *keyn its key node. NULL (and *keyn NULL) when a key on the way is absent. */
static struct fy_node *node_at(loader *L, const char *path, struct fy_node **keyn)
{
    struct fy_node *cur = fy_document_root(L->fyd);
    char comp[128];
    *keyn = NULL;
    for (const char *p = path;; p += strcspn(p, ".") + 1) {
        size_t n = strcspn(p, ".");
        struct fy_node_pair *pair = NULL;
        if (n < sizeof comp && cur && fy_node_is_mapping(cur)) {
            memcpy(comp, p, n);
            comp[n] = '\0';
            pair = fy_node_mapping_lookup_pair_by_string(cur, comp, FY_NT);
        }
        if (!pair) return NULL;
        cur = fy_node_pair_value(pair);
        if (!p[n]) return *keyn = fy_node_pair_key(pair), cur;
    }
}

/* Checks the fluid's def read so far with stf_fluid_check_def, the one check of its ranges,
 * and reports a refused field at the node it came from: FILE:LINE:COL (the scene's or the
 * material's) or the --set that gave it, with its scene key and the check's message after
 * the field's name. Before the effects are read (effects_read 0) they count as none, and
 * their parameters still hold the defaults: only the fluid section's own keys are checked. */
static int check_fluid(loader *L, int effects_read)
{
    stf_fluid_def d = L->s->fluid;
    char msg[256];
    const char *field = NULL;
    if (!effects_read) d.effects = 0;
    if (stf_fluid_check_def(&d, msg, sizeof msg, &field) == 0) return 0;
    const struct def_key *dk = NULL;
    for (size_t i = 0; field && i < sizeof def_keys / sizeof def_keys[0] && !dk; i++)
        if (!strcmp(field, def_keys[i].field)) dk = &def_keys[i];
    if (!dk) return fail(L, NULL, NULL, "fluid", "%s", msg); /* a field no key sets */
    /* the message is "NAME: what is wrong" */
    const char *what = msg + strspn(msg, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                         "0123456789_");
    what = what[0] == ':' && what[1] == ' ' ? what + 2 : msg;
    struct fy_node *k, *v = node_at(L, dk->key, &k);
    if (!k && dk->alt) v = node_at(L, dk->alt, &k);
    if (!k) { /* the nearest section given, at its key */
        char up[128];
        snprintf(up, sizeof up, "%s", dk->key);
        for (char *dot; !k && (dot = strrchr(up, '.'));) {
            *dot = '\0';
            node_at(L, up, &k);
        }
        v = k;
    }
    return fail(L, v, k, dk->key, "%s", what);
}

/* ----------------------------------------------------------------------- the sections */

/* 1 when two blocks (boxes, or balls: radius > 0) share a volume deeper than 1 nm; touching
 * (to round-off) is not sharing. Not an error (the stability tests use it on purpose): the
 * first such pair is noted in blocks_note. */
static int blocks_overlap(const stf_block *a, const stf_block *b)
{
    if (a->radius > 0 && b->radius > 0) {
        double d2 = 0;
        for (int c = 0; c < 3; c++) d2 += (a->center[c] - b->center[c]) * (a->center[c] - b->center[c]);
        double r = a->radius + b->radius - 1e-9;
        return d2 < r * r;
    }
    if (a->radius > 0 || b->radius > 0) { /* a ball and a box: the box's point nearest the centre */
        const stf_block *ball = a->radius > 0 ? a : b, *box = a->radius > 0 ? b : a;
        double d2 = 0;
        for (int c = 0; c < 3; c++) {
            double q = ball->center[c] < box->lo[c] ? box->lo[c]
                       : ball->center[c] > box->hi[c] ? box->hi[c] : ball->center[c];
            d2 += (ball->center[c] - q) * (ball->center[c] - q);
        }
        double r = ball->radius - 1e-9;
        return d2 < r * r;
    }
    for (int c = 0; c < 3; c++)
        if (!(a->lo[c] < b->hi[c] - 1e-9 && b->lo[c] < a->hi[c] - 1e-9)) return 0;
    return 1;
}

static int parse_blocks(loader *L, const mapv *fluid)
{
    static const char *const keys[] = {"min", "max", "center", "radius", "velocity", NULL};
    struct fy_node *k, *v = lookup(fluid, "blocks", &k);
    char path[64];
    if (!k) return missing(L, fluid, "blocks", NULL);
    if (is_null(v) || !fy_node_is_sequence(v) || fy_node_sequence_item_count(v) < 1)
        return fail(L, v, k, "fluid.blocks", "expected a list of at least 1 block");
    int n = fy_node_sequence_item_count(v);
    L->s->blocks = calloc((size_t)n, sizeof *L->s->blocks);
    if (!L->s->blocks) return fail(L, NULL, NULL, "fluid.blocks", "out of memory");
    for (int i = 0; i < n; i++) {
        struct fy_node *item = fy_node_sequence_get_by_index(v, i);
        stf_block *b = &L->s->blocks[i];
        mapv bm;
        snprintf(path, sizeof path, "fluid.blocks.%d", i);
        if (is_null(item)) return fail(L, item, k, path, "expected a mapping");
        if (open_map(L, item, item, path, keys, &bm)) return SCENE_BAD;
        if (get_vec(L, &bm, "velocity", R_ANY, 3, b->velocity) < 0) return SCENE_BAD;
        int r = get_num(L, &bm, "radius", R_POS, &b->radius);
        if (r < 0) return SCENE_BAD;
        if (r > 0) { /* a ball: centre and radius; lo, hi its bounding box */
            if (has(&bm, "min")) return fail_key(L, &bm, "min", "not allowed with radius (a ball)");
            if (has(&bm, "max")) return fail_key(L, &bm, "max", "not allowed with radius (a ball)");
            if (need_vec(L, &bm, "center", R_ANY, 3, b->center)) return SCENE_BAD;
            for (int c = 0; c < 3; c++) {
                b->lo[c] = b->center[c] - b->radius;
                b->hi[c] = b->center[c] + b->radius;
            }
        } else {
            if (has(&bm, "center"))
                return fail_key(L, &bm, "center", "only allowed with radius (a ball)");
            if (need_vec(L, &bm, "min", R_ANY, 3, b->lo) || need_vec(L, &bm, "max", R_ANY, 3, b->hi))
                return SCENE_BAD;
            for (int c = 0; c < 3; c++) {
                if (!(b->lo[c] < b->hi[c]))
                    return fail_value(L, &bm, "max", "must be > min in every component");
            }
        }
        b->line = b->col = 1;
        node_mark(item, &b->line, &b->col);
        for (int j = 0; j < i && !L->s->blocks_note[0]; j++)
            if (blocks_overlap(b, &L->s->blocks[j]))
                snprintf(L->s->blocks_note, sizeof L->s->blocks_note,
                         "%s:%d:%d: %s overlaps fluid.blocks.%d: the particles they share sit on "
                         "each other (twice the density there)", L->file, b->line, b->col, path, j);
        L->s->nblocks = i + 1;
    }
    return 0;
}

static int parse_fluid(loader *L, const mapv *top)
{
    static const char *const keys[] = {"model", "spacing", "density", "h", "jitter", "blocks",
                                       "relaxation", "iterations", "reference_spacing",
                                       "settle", NULL};
    static const char *const relaxations[] = {"jacobi", "gauss_seidel", NULL};
    static const char *const models[] = {"clavet_stf", "carreau_yasuda", NULL};
    stf_fluid_def *f = &L->s->fluid;
    struct fy_node *k, *v = lookup(top, "fluid", &k);
    mapv m;
    int model;
    if (!k) return missing(L, top, "fluid", NULL);
    if (open_map(L, v, k, "fluid", keys, &m)) return SCENE_BAD;
    if (get_choice(L, &m, "model", models, &model) < 0) return SCENE_BAD;
    if (has(&m, "model"))
        f->model = model ? STF_MODEL_CARREAU_YASUDA : STF_MODEL_CLAVET_STF;
    /* the def's fields are numbers here; their ranges are the def check's (check_fluid) */
    if (need_num(L, &m, "spacing", R_ANY, &f->spacing)) return SCENE_BAD;
    if (get_num(L, &m, "density", R_ANY, &f->density) < 0 ||
        get_num(L, &m, "h", R_ANY, &f->h) < 0 ||
        get_num(L, &m, "reference_spacing", R_ANY, &f->material_spacing) < 0 ||
        get_num(L, &m, "jitter", R_ANY, &f->jitter) < 0)
        return SCENE_BAD;
    int relax;
    if (get_choice(L, &m, "relaxation", relaxations, &relax) < 0) return SCENE_BAD;
    if (has(&m, "relaxation")) f->relaxation = relax ? STF_RELAX_GAUSS_SEIDEL : STF_RELAX_JACOBI;
    if (get_count(L, &m, "iterations", &f->iterations) < 0) return SCENE_BAD;
    /* the fluid's own keys are checked before its blocks and the effects are read */
    if (check_fluid(L, 0)) return SCENE_BAD;
    if (get_num(L, &m, "settle", R_NONNEG, &L->s->settle) < 0) return SCENE_BAD;
    if (L->s->settle > 10) return fail_value(L, &m, "settle", "must be in [0, 10] s");
    if (!(L->s->settle / L->s->dt < STF_MAX_STEPS + 0.5)) {
        char why[160];
        snprintf(why, sizeof why, "%g s is %.3g steps of dt = %g s, more than %ld, the most a "
                 "run takes", L->s->settle, L->s->settle / L->s->dt, L->s->dt, STF_MAX_STEPS);
        return fail_value(L, &m, "settle", why);
    }
    return parse_blocks(L, &m);
}

static int parse_history(loader *L, const mapv *h)
{
    static const char *const modes[] = {"window", "full", "soe", NULL};
    static const char *const velocities[] = {"particle", "smoothed", NULL}; /* enum order */
    int vel = 0;
    stf_fluid_def *f = &L->s->fluid;
    int mode = 0, rd, rm;
    if (get_num(L, h, "q", R_ANY, &f->q) < 0) return SCENE_BAD;
    if ((rd = get_count(L, h, "d", &f->d)) < 0) return SCENE_BAD;
    if ((rm = get_num(L, h, "memory", R_ANY, &f->memory)) < 0) return SCENE_BAD;
    if (rd && rm) return fail_key(L, h, "memory", "give either d or memory, not both");
    /* memory 0 is the def's "no memory: d is the window": a scene says that by giving d */
    if (rm && !(f->memory > 0)) return fail_value(L, h, "memory", "must be > 0 (or give d)");
    if (rd) f->memory = 0; /* memory > 0 would override d */
    if (get_num(L, h, "k_hist", R_ANY, &f->k_hist) < 0 ||
        get_num(L, h, "reference_spacing", R_ANY, &f->reference_spacing) < 0 ||
        get_num(L, h, "k_onset", R_ANY, &f->k_onset) < 0 ||
        get_num(L, h, "smoothing", R_ANY, &f->history_smoothing) < 0)
        return SCENE_BAD;
    if (get_choice(L, h, "mode", modes, &mode) < 0) return SCENE_BAD;
    if (has(h, "mode")) f->history_mode = mode; /* the order of enum stf_history_mode */
    if (get_choice(L, h, "velocity", velocities, &vel) < 0) return SCENE_BAD;
    if (has(h, "velocity")) f->history_velocity = vel;
    int rt = get_count(L, h, "terms", &f->terms);
    if (rt < 0) return SCENE_BAD;
    if (rt && f->history_mode != STF_HISTORY_SOE)
        return fail_key(L, h, "terms", "only with mode: soe");
    double steps = rm ? f->memory / L->s->dt : 1; /* the window is d = round(memory / dt) */
    if (f->history_mode == STF_HISTORY_WINDOW && !(steps >= 0.5 && steps < 100000.5)) {
        char what[160];
        snprintf(what, sizeof what, "must be in [0.5 dt, 100000.5 dt] = [%g, %g] s (d = "
                 "round(memory / dt) steps, 1 .. 100000)", 0.5 * L->s->dt, 100000.5 * L->s->dt);
        return fail_value(L, h, "memory", what);
    }
    return 0;
}

/* The projection's choices, shared by effects.carreau_yasuda and effects.pressure (mode
 * projection): the names in the order of their enums (stf.h), so the index is the value. */
static const char *const psolvers[] = STF_PRESSURE_SOLVER_NAMES;
static const char *const walls[] = STF_WALL_PRESSURE_NAMES;
static const char *const gradients[] = STF_PRESSURE_GRADIENT_NAMES;

/* effects.carreau_yasuda: the second paper's model (needs fluid.model: carreau_yasuda). */
static int parse_carreau_yasuda(loader *L, const mapv *p)
{
    static const char *const solvers[] = {"implicit", "explicit", NULL};
    static const char *const forms[] = {"morris", "central", NULL};
    stf_cy_def *c = &L->s->fluid.cy;
    if (get_num(L, p, "mu0", R_ANY, &c->mu0) < 0 ||
        get_num(L, p, "mu_inf", R_ANY, &c->mu_inf) < 0 || get_num(L, p, "K", R_ANY, &c->K) < 0 ||
        get_num(L, p, "alpha", R_ANY, &c->alpha) < 0 || get_num(L, p, "n", R_ANY, &c->n) < 0 ||
        get_num(L, p, "eta", R_ANY, &c->eta) < 0 ||
        get_num(L, p, "cg_tolerance", R_ANY, &c->cg_tolerance) < 0 ||
        get_num(L, p, "cfl", R_ANY, &c->cfl) < 0 ||
        get_num(L, p, "dt_max", R_ANY, &c->dt_max) < 0 ||
        get_num(L, p, "warm_start", R_ANY, &c->warm_start) < 0 ||
        get_num(L, p, "relaxation", R_ANY, &c->relaxation) < 0 ||
        get_count(L, p, "min_pressure_iterations", &c->min_pressure_iterations) < 0 ||
        get_count(L, p, "max_pressure_iterations", &c->max_pressure_iterations) < 0 ||
        get_count(L, p, "max_cg_iterations", &c->max_cg_iterations) < 0)
        return SCENE_BAD;
    if (get_choice(L, p, "viscosity_solver", solvers, &c->viscosity_solver) < 0 ||
        get_choice(L, p, "pressure_solver", psolvers, &c->pressure_solver) < 0 ||
        get_choice(L, p, "wall_pressure", walls, &c->wall_pressure) < 0 ||
        get_choice(L, p, "pressure_gradient", gradients, &c->pressure_gradient) < 0 ||
        get_choice(L, p, "viscosity_form", forms, &c->viscosity_form) < 0)
        return SCENE_BAD;
    return 0;
}

/* effects.pressure: Clavet's double density relaxation (mode relax, the paper's) or the
 * projection (mode projection, ours); each mode's keys are refused with the other, so that
 * nothing given is silently unused. */
static int parse_pressure(loader *L, const mapv *p)
{
    stf_fluid_def *f = &L->s->fluid;
    stf_cy_def *c = &f->cy;
    static const char *const modes[] = {"relax", "projection", NULL}; /* enum order */
    static const char *const relax_only[] = {"k", "k_near", "rest_density", "rest", "tension",
                                             "wall", NULL};
    static const char *const relax_walls[] = {"mirror", "ghost", NULL}; /* enum order */
    static const char *const packings[] = {"lattice", "liquid", NULL}; /* enum order */
    static const char *const projection_only[] = {"eta", "solver", "wall_pressure", "gradient",
                                                  "min_iterations", "max_iterations",
                                                  "warm_start", NULL};
    if (get_choice(L, p, "mode", modes, &f->pressure_mode) < 0) return SCENE_BAD;
    const char *const *other = f->pressure_mode == STF_PRESSURE_PROJECTION ? relax_only
                                                                           : projection_only;
    for (int k = 0; other[k]; k++)
        if (has(p, other[k]))
            return fail_key(L, p, other[k],
                            f->pressure_mode == STF_PRESSURE_PROJECTION
                                ? "a key of mode relax (this pressure is mode: projection)"
                                : "a key of mode: projection (this pressure is mode relax)");
    if (get_num(L, p, "k", R_ANY, &f->k) < 0 || get_num(L, p, "k_near", R_ANY, &f->k_near) < 0 ||
        get_bool(L, p, "tension", &f->tension) < 0 ||
        get_num(L, p, "rest_density", R_ANY, &f->rest_density) < 0 ||
        get_choice(L, p, "rest", packings, &f->rest_packing) < 0 ||
        get_choice(L, p, "wall", relax_walls, &f->relax_wall) < 0 ||
        get_num(L, p, "eta", R_ANY, &c->eta) < 0 ||
        get_num(L, p, "warm_start", R_ANY, &c->warm_start) < 0 ||
        get_count(L, p, "min_iterations", &c->min_pressure_iterations) < 0 ||
        get_count(L, p, "max_iterations", &c->max_pressure_iterations) < 0 ||
        get_choice(L, p, "solver", psolvers, &c->pressure_solver) < 0 ||
        get_choice(L, p, "wall_pressure", walls, &c->wall_pressure) < 0 ||
        get_choice(L, p, "gradient", gradients, &c->pressure_gradient) < 0)
        return SCENE_BAD;
    return 0;
}

/* Reads the params of one effect; e is its index in the effect table. */
static int parse_effect_params(loader *L, int e, const mapv *p)
{
    stf_fluid_def *f = &L->s->fluid;
    switch (e) {
    case 0:
        return get_vec(L, p, "g", R_ANY, 3, f->gravity) < 0 ? SCENE_BAD : 0;
    case 1:
        if (get_num(L, p, "sigma", R_ANY, &f->sigma) < 0) return SCENE_BAD;
        return get_num(L, p, "beta", R_ANY, &f->beta) < 0 ? SCENE_BAD : 0;
    case 2:
        return parse_pressure(L, p);
    case 3: {
        if (get_num(L, p, "k_min", R_ANY, &f->k_min) < 0) return SCENE_BAD;
        if (get_num(L, p, "yield_ratio", R_ANY, &f->yield_ratio) < 0) return SCENE_BAD;
        if (get_num(L, p, "damping", R_ANY, &f->spring_damping) < 0) return SCENE_BAD;
        if (get_bool(L, p, "passive", &f->spring_passive) < 0) return SCENE_BAD;
        int r = get_num(L, p, "liquid_plasticity", R_ANY, &f->liquid_plasticity);
        if (r < 0) return SCENE_BAD;
        /* < 0 is the def's "as plasticity": a scene says that by leaving the key out */
        if (r && f->liquid_plasticity < 0)
            return fail_value(L, p, "liquid_plasticity", "must be >= 0 (without it: plasticity)");
        return get_num(L, p, "plasticity", R_ANY, &f->plasticity) < 0 ? SCENE_BAD : 0;
    }
    case 4:
        return parse_history(L, p);
    case 6:
        return parse_carreau_yasuda(L, p);
    default:
        return get_num(L, p, "stick", R_ANY, &f->stick) < 0 ? SCENE_BAD : 0;
    }
}

static const char *const gravity_keys[] = {"g", NULL};
static const char *const viscosity_keys[] = {"sigma", "beta", NULL};
static const char *const pressure_keys[] = {"k", "k_near", "rest_density", "rest", "tension", "wall", "mode",
                                            "eta", "solver", "wall_pressure", "gradient", "min_iterations",
                                            "max_iterations", "warm_start", NULL};
static const char *const springs_keys[] = {"k_min", "yield_ratio", "plasticity", "liquid_plasticity", "damping", "passive", NULL};
static const char *const history_keys[] = {"q", "d", "memory", "k_hist", "mode", "reference_spacing", "terms", "k_onset", "velocity", "smoothing", NULL};
static const char *const stick_keys[] = {"stick", NULL};
static const char *const cy_keys[] = {"mu0", "mu_inf", "K", "alpha", "n", "eta",
                                      "min_pressure_iterations", "max_pressure_iterations",
                                      "viscosity_solver", "cg_tolerance", "max_cg_iterations",
                                      "cfl", "dt_max", "warm_start", "relaxation", "viscosity_form",
                                      "pressure_solver", "wall_pressure", "pressure_gradient", NULL};

static int parse_effects(loader *L, const mapv *top)
{
    static const char *const names[] = {"gravity", "viscosity",      "pressure",
                                        "springs", "history",        "boundary_stick",
                                        "carreau_yasuda", NULL};
    /* carreau_yasuda holds the parameters of fluid.model carreau_yasuda: no effect bit */
    static const unsigned bits[] = {STF_EFFECT_GRAVITY,  STF_EFFECT_VISCOSITY,
                                    STF_EFFECT_PRESSURE, STF_EFFECT_SPRINGS,
                                    STF_EFFECT_HISTORY,  STF_EFFECT_BOUNDARY_STICK, 0};
    static const char *const *const params[] = {gravity_keys, viscosity_keys, pressure_keys,
                                                springs_keys, history_keys,   stick_keys,
                                                cy_keys};
    struct fy_node *k, *v = lookup(top, "effects", &k);
    mapv m, p;
    char path[64];
    if (!k) return missing(L, top, "effects", NULL);
    if (open_map(L, v, k, "effects", names, &m)) return SCENE_BAD;
    L->s->fluid.effects = 0;
    for (int e = 0; names[e]; e++) {
        struct fy_node *ek, *ev = lookup(&m, names[e], &ek);
        if (!ek) continue;
        L->s->fluid.effects |= bits[e];
        snprintf(path, sizeof path, "effects.%s", names[e]);
        if (open_map(L, ev, ek, path, params[e], &p) || parse_effect_params(L, e, &p))
            return SCENE_BAD;
    }
    if (has(&m, "history") && !has(&m, "springs"))
        return fail_key(L, &m, "history", "needs effects.springs");
    /* a projection (the Carreau-Yasuda model's, or the Clavet fluid's pressure.mode
       projection) turns a jittered lattice's density errors into velocity (h (rho - rho0) /
       (rho0 dt) in one step): its blocks start on the lattice unless fluid.jitter is given */
    struct fy_node *jk;
    node_at(L, "fluid.jitter", &jk);
    if (stf_def_projects(&L->s->fluid) && !jk) L->s->fluid.jitter = 0;
    int cy = L->s->fluid.model == STF_MODEL_CARREAU_YASUDA;
    if (has(&m, "carreau_yasuda") && !cy)
        return fail_key(L, &m, "carreau_yasuda", "needs fluid.model: carreau_yasuda");
    for (int e = 1; cy && e < 6; e++) {
        if (has(&m, names[e]))
            return fail_key(L, &m, names[e],
                            "not part of fluid.model carreau_yasuda (allowed: gravity, carreau_yasuda)");
    }
    return 0;
}

static const char *const motion_names[] = {"dynamic", "kinematic", "static", NULL};

static void default_vibration(stf_vibration *v)
{
    *v = (stf_vibration){.axis = {0, 0, 1}, .frequency = 50, .jitter_period = 0.5, .seed = 1};
}

/* Reads m.vibration if present; allowed only for kinematic motion. */
static int parse_vibration(loader *L, const mapv *m, int motion, stf_vibration *vib)
{
    static const char *const keys[] = {"axis",          "amplitude", "frequency", "jitter",
                                       "jitter_period", "seed",      NULL};
    struct fy_node *k, *v = lookup(m, "vibration", &k);
    char path[160];
    mapv vm;
    long seed;
    default_vibration(vib);
    if (!k) return 0;
    if (motion != STF_MOTION_KINEMATIC)
        return fail_key(L, m, "vibration", "only allowed with motion: kinematic");
    join(path, sizeof path, m->path, "vibration");
    if (open_map(L, v, k, path, keys, &vm)) return SCENE_BAD;
    int r = get_vec(L, &vm, "axis", R_ANY, 3, vib->axis);
    if (r < 0) return SCENE_BAD;
    if (r && normalise(vib->axis, 3)) return fail_value(L, &vm, "axis", "must be non-zero");
    if (get_num(L, &vm, "amplitude", R_NONNEG, &vib->amplitude) < 0 ||
        get_num(L, &vm, "frequency", R_POS, &vib->frequency) < 0 ||
        get_num(L, &vm, "jitter", R_HALF_UNIT, &vib->jitter) < 0 ||
        get_num(L, &vm, "jitter_period", R_POS, &vib->jitter_period) < 0)
        return SCENE_BAD;
    if ((r = get_int(L, &vm, "seed", 0, (long)UINT_MAX < LONG_MAX ? (long)UINT_MAX : LONG_MAX,
                     &seed)) < 0)
        return SCENE_BAD;
    if (r) vib->seed = (unsigned)seed;
    return 0;
}

/* container.periodic: a list of horizontal axes (x, y) along which the fluid wraps, with the
 * container's inner box as the period; only for the carreau_yasuda model and a static
 * container (ode_glue moves the walls across such an axis out of the fluid's reach). */
static int parse_periodic(loader *L, const mapv *m, stf_container_def *c)
{
    static const char *const axes[] = {"x", "y", NULL};
    struct fy_node *k, *v = lookup(m, "periodic", &k);
    char full[160], elem[176], buf[16];
    if (!k) return 0;
    join(full, sizeof full, m->path, "periodic");
    if (is_null(v) || !fy_node_is_sequence(v))
        return fail(L, v, k, full, "expected a list of axes (allowed: x, y)");
    stf_fluid_def *f = &L->s->fluid;
    int n = fy_node_sequence_item_count(v), on[2] = {0, 0};
    for (int i = 0; i < n; i++) {
        struct fy_node *item = fy_node_sequence_get_by_index(v, i);
        join_index(elem, sizeof elem, full, i);
        int a = -1;
        if (scalar_text(item, buf, sizeof buf))
            for (int j = 0; axes[j]; j++)
                if (!strcmp(buf, axes[j])) a = j;
        if (a < 0)
            return fail(L, item, k, elem,
                        "expected an axis (allowed: x, y; z is bounded by the floor)");
        if (on[a]) return fail(L, item, k, elem, "axis %s given twice", axes[a]);
        on[a] = 1;
    }
    if (n == 0) return 0;
    if (f->model != STF_MODEL_CARREAU_YASUDA)
        return fail_key(L, m, "periodic", "only with fluid.model: carreau_yasuda (the "
                                          "clavet_stf model has no periodic axes)");
    if (c->motion != STF_MOTION_STATIC)
        return fail_key(L, m, "periodic", "only with a static container (motion: static)");
    double h = f->h > 0 ? f->h : 2 * f->spacing;
    for (int a = 0; a < 2; a++) {
        if (!on[a]) continue;
        if (c->size[a] < 3 * h) {
            char what[160];
            snprintf(what, sizeof what,
                     "the period along %s (container.size.%d = %g m) must be >= 3 h = %g m",
                     axes[a], a, c->size[a], 3 * h);
            return fail_value(L, m, "periodic", what);
        }
        f->periodic[a] = c->size[a];
        f->periodic_origin[a] = c->position[a] - c->size[a] / 2;
    }
    return 0;
}

/* Coulomb friction of particle contacts unless a solid sets it: 0.2 for the Clavet fluid;
 * 0 for the Carreau-Yasuda model, whose walls are no-slip through its viscosity
 * (src/cy_walls.c): a friction per contact on top of that is a drag that grows as the step
 * shrinks (tests/settling_scene.py: -15.5% against Stokes' law at dt 2 ms, -18.8% at 1 ms,
 * against -5.0% and -8.9% without). The fluid is parsed first. */
static double default_friction(const loader *L)
{
    return L->s->fluid.model == STF_MODEL_CARREAU_YASUDA ? 0.0 : 0.2;
}

static int parse_container(loader *L, const mapv *top)
{
    static const char *const keys[] = {"size",   "wall", "position",  "friction", "stick",
                                       "motion", "mass", "vibration", "periodic", NULL};
    stf_container_def *c = &L->s->container;
    struct fy_node *k, *v = lookup(top, "container", &k);
    mapv m;
    if (!k) return 0;
    *c = (stf_container_def){
        .present = 1, .wall = 0.02, .friction = default_friction(L), .stick = 1,
        .motion = STF_MOTION_STATIC};
    if (open_map(L, v, k, "container", keys, &m)) return SCENE_BAD;
    if (need_vec(L, &m, "size", R_POS, 3, c->size)) return SCENE_BAD;
    if (get_num(L, &m, "wall", R_POS, &c->wall) < 0 ||
        get_vec(L, &m, "position", R_ANY, 3, c->position) < 0 ||
        get_num(L, &m, "friction", R_UNIT, &c->friction) < 0 ||
        get_bool(L, &m, "stick", &c->stick) < 0 ||
        get_choice(L, &m, "motion", motion_names, &c->motion) < 0)
        return SCENE_BAD;
    int r = get_num(L, &m, "mass", R_POS, &c->mass);
    if (r < 0) return SCENE_BAD;
    if (c->motion == STF_MOTION_DYNAMIC && !r) return missing(L, &m, "mass", " (motion: dynamic)");
    if (c->motion != STF_MOTION_DYNAMIC && r)
        return fail_key(L, &m, "mass", "only allowed with motion: dynamic");
    if (parse_periodic(L, &m, c)) return SCENE_BAD;
    return parse_vibration(L, &m, c->motion, &c->vibration);
}

/* The container's inner box: lo, hi (m); z from the floor to the walls' top. */
static void container_inside(const stf_container_def *c, double lo[3], double hi[3])
{
    for (int a = 0; a < 2; a++) {
        lo[a] = c->position[a] - c->size[a] / 2;
        hi[a] = c->position[a] + c->size[a] / 2;
    }
    lo[2] = c->position[2];
    hi[2] = c->position[2] + c->size[2];
}

/* Every block must start inside the container's inner box. */
static int check_blocks_inside(loader *L)
{
    const stf_container_def *c = &L->s->container;
    if (!c->present) return 0;
    double lo[3], hi[3];
    container_inside(c, lo, hi);
    for (int i = 0; i < L->s->nblocks; i++) {
        const stf_block *b = &L->s->blocks[i];
        int in = 1;
        for (int a = 0; a < 3; a++)
            in = in && b->lo[a] >= lo[a] && b->hi[a] <= hi[a];
        if (in) continue;
        struct fy_node *fluid =
            fy_node_mapping_lookup_by_string(fy_document_root(L->fyd), "fluid", FY_NT);
        struct fy_node *blocks = fy_node_mapping_lookup_by_string(fluid, "blocks", FY_NT);
        char path[64];
        struct fy_node *item = fy_node_sequence_get_by_index(blocks, i);
        /* an override that moved a corner is named instead of the block's place */
        struct fy_node *corner = fy_node_mapping_lookup_by_string(item, "min", FY_NT);
        if (node_override(corner) < 0) corner = fy_node_mapping_lookup_by_string(item, "max", FY_NT);
        snprintf(path, sizeof path, "fluid.blocks.%d", i);
        return fail(L, item, corner, path, "lies outside the container");
    }
    return 0;
}

/* ---------------------------------------------------------------------------- bodies */

static const char *const shape_names[] = {"sphere", "box", "capsule", "cylinder", "convex", NULL};
static const int shape_ids[] = {STF_SHAPE_SPHERE, STF_SHAPE_BOX, STF_SHAPE_CAPSULE,
                                STF_SHAPE_CYLINDER, STF_SHAPE_CONVEX};
/* Geometry keys of each shape, in shape_names order. */
static const char *const radius_keys[] = {"radius", NULL};
static const char *const box_keys[] = {"size", NULL};
static const char *const round_keys[] = {"radius", "length", NULL};
static const char *const convex_keys[] = {"points", NULL};
static const char *const *const shape_keys[] = {radius_keys, box_keys, round_keys, round_keys,
                                                convex_keys};

/* Names become HDF5 group names and file names: letters, digits, '_' and those of `extra`. */
static int valid_name_ext(const char *s, const char *extra)
{
    if (!s[0]) return 0;
    for (; *s; s++) {
        char ch = *s;
        int ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') ||
                 ch == '_' || strchr(extra, ch);
        if (!ok) return 0;
    }
    return 1;
}

static int valid_name(const char *s) { return valid_name_ext(s, ""); }

/* Appends the convex points of m.points to scene->points; *first is the index of the first. */
static int parse_points(loader *L, const mapv *m, int *first, int *count)
{
    struct fy_node *k, *v = lookup(m, "points", &k);
    char path[160], elem[176];
    join(path, sizeof path, m->path, "points");
    if (is_null(v) || !fy_node_is_sequence(v) || fy_node_sequence_item_count(v) < 4)
        return fail(L, v, k, path, "expected a list of at least 4 points [x, y, z]");
    int n = fy_node_sequence_item_count(v), have = 0;
    for (int i = 0; i < L->s->nbodies; i++)
        have += L->s->bodies[i].shape.npoints;
    double *p = realloc(L->s->points, sizeof *p * 3 * (size_t)(have + n));
    if (!p) return fail(L, NULL, NULL, path, "out of memory");
    L->s->points = p;
    for (int i = 0; i < n; i++) {
        struct fy_node *pt = fy_node_sequence_get_by_index(v, i);
        join_index(elem, sizeof elem, path, i);
        if (is_null(pt) || !fy_node_is_sequence(pt) || fy_node_sequence_item_count(pt) != 3)
            return fail(L, pt, k, elem, "expected a list of 3 numbers");
        for (int c = 0; c < 3; c++) {
            char sub[192];
            join_index(sub, sizeof sub, elem, c);
            if (number_at(L, fy_node_sequence_get_by_index(pt, c), k, sub, R_ANY,
                          &p[3 * (have + i) + c]))
                return SCENE_BAD;
        }
    }
    *first = have;
    *count = n;
    return 0;
}

static int parse_shape(loader *L, const mapv *m, int si, stf_body_def *b, int *first)
{
    static const char *const geometry[] = {"radius", "size", "length", "points", NULL};
    const char *const *own = shape_keys[si];
    char list[64];
    for (int g = 0; geometry[g]; g++) {
        int mine = 0;
        for (int i = 0; own[i]; i++)
            mine = mine || !strcmp(own[i], geometry[g]);
        if (mine && !has(m, geometry[g])) return missing(L, m, geometry[g], NULL);
        if (!mine && has(m, geometry[g])) {
            char what[160];
            list_words(list, sizeof list, own);
            snprintf(what, sizeof what, "not a key of shape %s (allowed: %s)", shape_names[si],
                     list);
            return fail_key(L, m, geometry[g], what);
        }
    }
    double size[3];
    if (get_num(L, m, "radius", R_POS, &b->shape.radius) < 0) return SCENE_BAD;
    if (get_num(L, m, "length", R_POS, &b->shape.half_length) < 0) return SCENE_BAD;
    b->shape.half_length /= 2;
    int r = get_vec(L, m, "size", R_POS, 3, size);
    if (r < 0) return SCENE_BAD;
    for (int c = 0; r && c < 3; c++)
        b->shape.half[c] = size[c] / 2;
    if (shape_ids[si] == STF_SHAPE_CONVEX) return parse_points(L, m, first, &b->shape.npoints);
    return 0;
}

static int parse_mass(loader *L, const mapv *m, stf_body_def *b)
{
    int rm = get_num(L, m, "mass", R_POS, &b->mass);
    if (rm < 0) return SCENE_BAD;
    int rd = get_num(L, m, "density", R_POS, &b->density);
    if (rd < 0) return SCENE_BAD;
    if (rm && rd) return fail_key(L, m, "density", "give either mass or density, not both");
    if (b->motion == STF_MOTION_DYNAMIC && !rm && !rd)
        return missing(L, m, "mass", " (a dynamic body needs mass or density)");
    if (b->motion != STF_MOTION_DYNAMIC && (rm || rd)) /* it would be ignored */
        return fail_key(L, m, rm ? "mass" : "density",
                        "only for motion: dynamic (a static or kinematic body's motion is given, "
                        "not computed from forces)");
    return 0;
}

static int parse_body(loader *L, struct fy_node *item, int i, int *first)
{
    static const char *const keys[] = {
        "name",   "shape",    "radius",   "size",      "length",   "points",
        "mass",   "density",  "position", "rotation",  "velocity", "angular_velocity",
        "motion", "friction", "stick",    "vibration", NULL};
    stf_body_def *b = &L->s->bodies[i];
    char path[64];
    mapv m;
    int si;
    snprintf(path, sizeof path, "bodies.%d", i);
    if (is_null(item)) return fail(L, item, NULL, path, "expected a mapping");
    if (open_map(L, item, item, path, keys, &m)) return SCENE_BAD;
    b->shape = stf_default_collider_def();
    b->shape.friction = default_friction(L);
    b->shape.stick = 0;
    b->quaternion[0] = 1;
    b->line = b->col = 1;
    node_mark(item, &b->line, &b->col);
    int r = get_str(L, &m, "name", b->name, sizeof b->name);
    if (r <= 0) return r < 0 ? SCENE_BAD : missing(L, &m, "name", NULL);
    if (!valid_name(b->name))
        return fail_value(L, &m, "name", "must be non-empty and use only [A-Za-z0-9_]");
    if (!strcmp(b->name, "fluid")) /* expect: fluid.KEY names the fluid's metrics */
        return fail_value(L, &m, "name", "'fluid' is reserved (expect: fluid.KEY is a fluid metric)");
    for (int j = 0; j < i; j++) {
        if (strcmp(L->s->bodies[j].name, b->name)) continue;
        char what[160];
        snprintf(what, sizeof what, "duplicate body name '%s' (first at line %d)", b->name,
                 L->s->bodies[j].line);
        return fail_value(L, &m, "name", what);
    }
    if ((r = get_choice(L, &m, "shape", shape_names, &si)) <= 0)
        return r < 0 ? SCENE_BAD : missing(L, &m, "shape", NULL);
    b->shape.shape = shape_ids[si];
    if (parse_shape(L, &m, si, b, first)) return SCENE_BAD;
    if (get_choice(L, &m, "motion", motion_names, &b->motion) < 0) return SCENE_BAD;
    if (parse_mass(L, &m, b)) return SCENE_BAD;
    if (get_vec(L, &m, "position", R_ANY, 3, b->position) < 0 ||
        (r = get_vec(L, &m, "rotation", R_ANY, 4, b->quaternion)) < 0 ||
        get_vec(L, &m, "velocity", R_ANY, 3, b->velocity) < 0 ||
        get_vec(L, &m, "angular_velocity", R_ANY, 3, b->angular_velocity) < 0 ||
        get_num(L, &m, "friction", R_UNIT, &b->shape.friction) < 0 ||
        get_bool(L, &m, "stick", &b->shape.stick) < 0)
        return SCENE_BAD;
    if (r && normalise(b->quaternion, 4)) return fail_value(L, &m, "rotation", "must be non-zero");
    static const char *const moving[] = {"velocity", "angular_velocity"};
    for (int j = 0; j < 2 && b->motion == STF_MOTION_STATIC; j++) /* it would move with it */
        if (has(&m, moving[j]))
            return fail_key(L, &m, moving[j], "not with motion: static (a moving body is kinematic)");
    return parse_vibration(L, &m, b->motion, &b->vibration);
}

static int parse_bodies(loader *L, const mapv *top)
{
    struct fy_node *k, *v = lookup(top, "bodies", &k);
    if (!k || is_null(v)) return 0;
    if (!fy_node_is_sequence(v)) return fail(L, v, k, "bodies", "expected a list of bodies");
    int n = fy_node_sequence_item_count(v);
    if (n > STF_METRICS_MAX_BODIES) { /* the report and expect would miss the others */
        char path[64], what[96];
        snprintf(path, sizeof path, "bodies.%d", STF_METRICS_MAX_BODIES);
        snprintf(what, sizeof what, "at most %d bodies (the run metrics hold that many)",
                 STF_METRICS_MAX_BODIES);
        return fail(L, fy_node_sequence_get_by_index(v, STF_METRICS_MAX_BODIES), k, path, "%s", what);
    }
    int *first = calloc((size_t)n + 1, sizeof *first);
    L->s->bodies = calloc((size_t)n + 1, sizeof *L->s->bodies);
    if (!first || !L->s->bodies) {
        free(first);
        return fail(L, NULL, NULL, "bodies", "out of memory");
    }
    int rc = 0;
    for (int i = 0; i < n && !rc; i++) {
        rc = parse_body(L, fy_node_sequence_get_by_index(v, i), i, &first[i]);
        L->s->nbodies = i + 1;
    }
    /* Only now: parse_points reallocs the storage, which moves it. */
    for (int i = 0; i < L->s->nbodies; i++) {
        stf_collider_def *sh = &L->s->bodies[i].shape;
        sh->points = sh->npoints ? L->s->points + 3 * first[i] : NULL;
    }
    free(first);
    return rc;
}

/* ---------------------------------------------------------------------------- expect */

static const char *const top_metrics[] = {"time_end", "surface_height", NULL};
#define body_metrics stf_body_metric_names
#define fluid_metrics stf_fluid_metric_names

static int in_list(const char *s, const char *const *list)
{
    for (int i = 0; list[i]; i++) {
        if (!strcmp(s, list[i])) return 1;
    }
    return 0;
}

/* Checks an expect key; returns an error text or NULL. */
static const char *expect_key_error(const stf_scene *s, const char *key)
{
    const char *dot = strchr(key, '.');
    if (!dot) {
        if (in_list(key, top_metrics)) return NULL;
        if (!in_list(key, body_metrics)) return "unknown metric";
        return s->nbodies ? NULL : "a body metric needs at least one body";
    }
    size_t plen = (size_t)(dot - key);
    if (plen == 5 && !strncmp(key, "fluid", 5))
        return in_list(dot + 1, fluid_metrics) ? NULL : "unknown fluid metric";
    for (int i = 0; i < s->nbodies; i++) {
        if (strlen(s->bodies[i].name) == plen && !strncmp(key, s->bodies[i].name, plen))
            return in_list(dot + 1, body_metrics) ? NULL : "unknown body metric";
    }
    return "the prefix names no body (nor fluid)";
}

/* "OP NUMBER" or a plain number (==). */
static int parse_condition(struct fy_node *v, stf_expectation *e)
{
    static const char *const ops[] = {"<=", ">=", "==", "<", ">", NULL};
    char buf[96], *t = buf, *end;
    if (scalar_number(v, &e->value) == 1) return strcpy(e->op, "=="), 0;
    if (is_null(v) || !scalar_text(v, buf, sizeof buf)) return -1;
    while (*t == ' ')
        t++;
    int i = 0;
    while (ops[i] && strncmp(t, ops[i], strlen(ops[i])))
        i++;
    if (!ops[i]) return -1;
    strcpy(e->op, ops[i]);
    t += strlen(ops[i]);
    e->value = strtod(t, &end);
    while (*end == ' ')
        end++;
    return end == t || *end || !isfinite(e->value) ? -1 : 0;
}

/* Half extents of a body along the world axes (m), from its shape and rotation; the bounding
 * sphere for a convex hull. */
static void body_extent(const stf_body_def *b, double e[3])
{
    double R[9];
    stf_quat_matrix(b->quaternion, R);
    const stf_collider_def *d = &b->shape;
    for (int a = 0; a < 3; a++) {
        double ax = fabs(R[3 * a + 2]); /* the local z axis: capsules' and cylinders' */
        switch (d->shape) {
        case STF_SHAPE_SPHERE: e[a] = d->radius; break;
        case STF_SHAPE_BOX:
            e[a] = fabs(R[3 * a]) * d->half[0] + fabs(R[3 * a + 1]) * d->half[1] + ax * d->half[2];
            break;
        case STF_SHAPE_CAPSULE: e[a] = ax * d->half_length + d->radius; break;
        case STF_SHAPE_CYLINDER:
            e[a] = ax * d->half_length + d->radius * sqrt(fmax(0.0, 1 - ax * ax));
            break;
        default: {
            double inr, bound;
            e[a] = stf_collider_extent(d, &inr, &bound) == 0 ? bound : 0.0;
        }
        }
    }
}

/* A dynamic body must start clear of the container's walls and floor: one that overlaps
 * them is thrown out by the collision stage, and one outside falls for ever. Above the walls'
 * top (a ball thrown in from above) it may reach past their line while it clears their top
 * edge (by its bounding radius). Static and kinematic bodies (a ramp set into the floor) are
 * not checked. */
static int check_bodies_inside(loader *L)
{
    const stf_container_def *c = &L->s->container;
    if (!c->present || L->s->fluid.periodic[0] > 0 || L->s->fluid.periodic[1] > 0) return 0;
    double lo[3], hi[3];
    container_inside(c, lo, hi);
    for (int i = 0; i < L->s->nbodies; i++) {
        const stf_body_def *b = &L->s->bodies[i];
        if (b->motion != STF_MOTION_DYNAMIC) continue; /* a fixed ramp may sit in the floor */
        double e[3];
        body_extent(b, e);
        const double *p = b->position;
        double r = fmax(e[0], fmax(e[1], e[2]));  /* for the distance to a wall's top edge */
        double dz = p[2] > hi[2] ? p[2] - hi[2] : 0.0; /* above the walls' top */
        int inside = p[0] > lo[0] && p[0] < hi[0] && p[1] > lo[1] && p[1] < hi[1];
        const char *why = NULL;
        if (!inside) why = "lies outside the container";
        else if (p[2] - e[2] < lo[2]) why = "reaches under the container's floor";
        else
            for (int a = 0; a < 2 && !why; a++) {
                /* the nearer wall of the pair; above the top, the distance to its edge */
                double gap = fmin(p[a] - lo[a], hi[a] - p[a]);
                if (dz > 0 ? hypot(gap, dz) < r : gap < e[a]) why = "overlaps the container's walls";
            }
        if (!why) continue;
        struct fy_node *bodies =
            fy_node_mapping_lookup_by_string(fy_document_root(L->fyd), "bodies", FY_NT);
        struct fy_node *item = fy_node_sequence_get_by_index(bodies, i);
        struct fy_node *pos = fy_node_mapping_lookup_by_string(item, "position", FY_NT);
        char path[64], what[512];
        snprintf(path, sizeof path, "bodies.%d.position", i);
        snprintf(what, sizeof what,
                 "the body '%s' %s (its extent %.3g, %.3g, %.3g m about [%.3g, %.3g, %.3g]; "
                 "the container's inside x %.3g..%.3g, y %.3g..%.3g, z from %.3g)",
                 b->name, why, e[0], e[1], e[2], p[0], p[1], p[2], lo[0], hi[0], lo[1], hi[1], lo[2]);
        return fail(L, pos ? pos : item, item, path, "%s", what);
    }
    return 0;
}

static int parse_expect(loader *L, const mapv *top)
{
    struct fy_node *k, *v = lookup(top, "expect", &k);
    char list[512], path[160];
    if (!k || is_null(v)) return 0;
    if (!fy_node_is_mapping(v)) return fail(L, v, k, "expect", "expected a mapping");
    int n = fy_node_mapping_item_count(v);
    L->s->expect = calloc((size_t)n + 1, sizeof *L->s->expect);
    if (!L->s->expect) return fail(L, NULL, NULL, "expect", "out of memory");
    for (int i = 0; i < n; i++) {
        struct fy_node_pair *p = fy_node_mapping_get_by_index(v, i);
        struct fy_node *ek = fy_node_pair_key(p), *ev = fy_node_pair_value(p);
        stf_expectation *e = &L->s->expect[i];
        if (!scalar_text(ek, e->key, sizeof e->key))
            return fail(L, ek, k, "expect", "expected a metric name");
        snprintf(path, sizeof path, "expect.%s", e->key);
        const char *bad = expect_key_error(L->s, e->key);
        if (bad) {
            list_words(list, sizeof list, top_metrics);
            return fail(L, ek, NULL, path, "%s (allowed: %s, [BODY.]%s, fluid.%s ...)", bad, list,
                        body_metrics[0], fluid_metrics[0]);
        }
        if (parse_condition(ev, e))
            return fail(L, ev, ek, path,
                        "expected \"OP NUMBER\" with OP one of <, <=, >, >=, == (or a number)");
        e->line = e->col = 1;
        node_mark(ek, &e->line, &e->col);
        L->s->nexpect = i + 1;
    }
    return 0;
}

/* ------------------------------------------------------------------------- top level */

static void file_stem(const char *path, char *out, size_t n)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const char *dot = strrchr(base, '.');
    size_t len = dot && dot != base ? (size_t)(dot - base) : strlen(base);
    if (len >= n) len = n - 1;
    memcpy(out, base, len);
    out[len] = '\0';
}

long stf_run_steps(double duration, double dt, char *err, size_t errlen)
{
    char dummy[8];
    if (!err || !errlen) err = dummy, errlen = sizeof dummy;
    if (!(duration > 0) || !isfinite(duration) || !(dt > 0) || !isfinite(dt)) {
        snprintf(err, errlen, "a duration of %g s at dt = %g s: both must be finite numbers > 0",
                 duration, dt);
        return -1;
    }
    double n = duration / dt;
    if (n < 0.5) {
        snprintf(err, errlen, "%g s is %.3g steps of dt = %g s, 0 once rounded (a run takes at "
                 "least 1 step: %g s or more)", duration, n, dt, dt / 2);
        return -1;
    }
    if (!(n < STF_MAX_STEPS + 0.5)) {
        snprintf(err, errlen, "%g s is %.3g steps of dt = %g s, more than %ld, the most a run "
                 "takes (at most %g s at this dt)", duration, n, dt, STF_MAX_STEPS,
                 (double)STF_MAX_STEPS * dt);
        return -1;
    }
    return lround(n);
}

/* 1 when key of m was given by an override (--set), not by the file. */
static int set_here(const mapv *m, const char *key)
{
    struct fy_node *k, *v = lookup(m, key, &k);
    return k && (node_override(k) >= 0 || node_override(v) >= 0);
}

static int parse_scene(loader *L)
{
    static const char *const keys[] = {
        "name",      "duration", "dt", "frame_rate", "bounce_min_rise", "material", "fluid",
        "effects",   "container", "dt_control", "bodies", "expect", NULL};
    static const char *const dt_controls[] = {"adaptive", "fixed", NULL};
    stf_scene *s = L->s;
    mapv top;
    if (open_map(L, fy_document_root(L->fyd), NULL, "", keys, &top)) return SCENE_BAD;
    file_stem(s->path, s->name, sizeof s->name);
    s->dt = 0.001;
    s->frame_rate = 60;
    int named = get_str(L, &top, "name", s->name, sizeof s->name);
    if (named < 0) return SCENE_BAD;
    if (named > 0 && !valid_name_ext(s->name, "-."))
        return fail_value(L, &top, "name", "must be non-empty and use only [A-Za-z0-9_.-]");
    if (need_num(L, &top, "duration", R_POS, &s->duration)) return SCENE_BAD;
    if (get_num(L, &top, "dt", R_POS, &s->dt) < 0) return SCENE_BAD;
    if (s->dt > 0.1) return fail_value(L, &top, "dt", "must be > 0 and <= 0.1");
    if (get_choice(L, &top, "dt_control", dt_controls, &s->dt_fixed) < 0) return SCENE_BAD;
    if (get_num(L, &top, "frame_rate", R_POS, &s->frame_rate) < 0 ||
        get_num(L, &top, "bounce_min_rise", R_NONNEG, &s->bounce_min_rise) < 0)
        return SCENE_BAD;
    if (s->frame_rate * s->dt > 1 + 1e-9) { /* a frame is written after a step at most */
        char what[128];
        int rate = has(&top, "frame_rate");
        snprintf(what, sizeof what, "must be <= 1/%s = %g (one frame per step at most)",
                 rate ? "dt" : "frame_rate", rate ? 1 / s->dt : 1 / s->frame_rate);
        return fail_value(L, &top, rate ? "frame_rate" : "dt", what);
    }
    /* the run's step count and its steps between frames must be counts it can take (a
       duration of 1e300 s overflowed the count and ran 0 steps) */
    char why[256];
    if (stf_run_steps(s->duration, s->dt, why, sizeof why) < 0)
        return fail_value(L, &top, set_here(&top, "dt") && !set_here(&top, "duration")
                                       ? "dt" : "duration", why);
    if (!(1 / (s->frame_rate * s->dt) < STF_MAX_STEPS + 0.5)) {
        int rate = has(&top, "frame_rate");
        snprintf(why, sizeof why, "a frame every %.3g steps of dt = %g s (1 / (frame_rate dt)): "
                 "more than %ld, the most a run takes (frame_rate must be >= %g)",
                 1 / (s->frame_rate * s->dt), s->dt, STF_MAX_STEPS, 1 / (STF_MAX_STEPS * s->dt));
        return fail_value(L, &top, rate ? "frame_rate" : "dt", why);
    }
    s->fluid = stf_default_fluid_def();
    if (parse_fluid(L, &top) || parse_effects(L, &top) || check_fluid(L, 1) ||
        parse_container(L, &top) || check_blocks_inside(L) || parse_bodies(L, &top) ||
        check_bodies_inside(L) ||
        parse_expect(L, &top))
        return SCENE_BAD;
    if (s->nbodies > 0 && (s->fluid.periodic[0] > 0 || s->fluid.periodic[1] > 0))
        return fail_key(L, &top, "bodies",
                        "not with container.periodic (bodies do not wrap across the seams)");
    return 0;
}

/* --------------------------------------------------------------------------- overrides */

/* Index component of a path into a sequence: -1 if not a number. */
static int path_index(const char *comp)
{
    char *end;
    if (!comp[0] || comp[0] == '-' || comp[0] == '+') return -1;
    long i = strtol(comp, &end, 10);
    return *end || i > INT_MAX ? -1 : (int)i;
}

static struct fy_node *new_mapping_at(loader *L, struct fy_node_pair *p, struct fy_node *map,
                                      const char *comp, int oi)
{
    struct fy_node *m = fy_node_create_mapping(L->fyd);
    if (!m) return NULL;
    mark_override(m, oi);
    if (p) {
        fy_node_pair_set_value(p, m);
        return m;
    }
    struct fy_node *k = fy_node_create_scalar_copy(L->fyd, comp, FY_NT);
    if (!k) return fy_node_free(m), NULL;
    mark_override(k, oi);
    if (fy_node_mapping_append(map, k, m)) {
        fy_node_free(k);
        fy_node_free(m);
        return NULL;
    }
    return m;
}

/* Walks (creating mappings when setting) to the parent of the last path component. */
static int walk_to_parent(loader *L, int oi, char **comps, int n, struct fy_node **out)
{
    const stf_override *o = &L->ov[oi];
    struct fy_node *cur = fy_document_root(L->fyd);
    if (is_null(cur)) {
        if (!o->value) return override_fail(L, oi, o->key, "no such key");
        cur = fy_node_create_mapping(L->fyd);
        if (!cur || fy_document_set_root(L->fyd, cur))
            return override_fail(L, oi, o->key, "out of memory");
    }
    for (int i = 0; i < n - 1; i++) {
        struct fy_node *next = NULL;
        struct fy_node_pair *p = NULL;
        if (fy_node_is_mapping(cur)) {
            p = fy_node_mapping_lookup_pair_by_string(cur, comps[i], FY_NT);
            next = p ? fy_node_pair_value(p) : NULL;
            if ((!p || is_null(next)) && o->value) next = new_mapping_at(L, p, cur, comps[i], oi);
        } else if (fy_node_is_sequence(cur)) {
            int idx = path_index(comps[i]);
            if (idx >= 0) next = fy_node_sequence_get_by_index(cur, idx);
        }
        if (is_null(next) || fy_node_is_scalar(next))
            return override_fail(L, oi, o->key, "no such key");
        cur = next;
    }
    *out = cur;
    return 0;
}

static long utf8_invalid_at(const char *text);

/* An override's value as a node of the document; NULL when it is not valid UTF-8 YAML. An
 * alias in it would name an anchor of the file; it is refused later as not a value. */
static struct fy_node *build_value(loader *L, const char *text)
{
    if (utf8_invalid_at(text) >= 0) return NULL;
    return fy_node_build_from_string(L->fyd, text[0] ? text : "~", FY_NT);
}

static int set_last(loader *L, int oi, struct fy_node *parent, const char *comp)
{
    const stf_override *o = &L->ov[oi];
    struct fy_node *v = build_value(L, o->value);
    if (!v) return override_fail(L, oi, o->key, "cannot parse the value as UTF-8 YAML");
    mark_override(v, oi);
    if (fy_node_is_mapping(parent)) {
        /* d and memory are the history's one window, in steps or seconds: setting one
           replaces the other (a scene's memory, or its material's) */
        const char *other = !strcmp(comp, "d") ? "memory" : !strcmp(comp, "memory") ? "d" : NULL;
        char *dot = strrchr(o->key, '.');
        struct fy_node_pair *twin =
            other && dot && dot - o->key == 15 && !strncmp(o->key, "effects.history", 15)
                ? fy_node_mapping_lookup_pair_by_string(parent, other, FY_NT)
                : NULL;
        if (twin) fy_node_free(fy_node_mapping_remove_by_key(parent, fy_node_pair_key(twin)));
        struct fy_node_pair *p = fy_node_mapping_lookup_pair_by_string(parent, comp, FY_NT);
        if (p) return fy_node_pair_set_value(p, v) ? override_fail(L, oi, o->key, "cannot set") : 0;
        struct fy_node *k = fy_node_create_scalar_copy(L->fyd, comp, FY_NT);
        if (k) mark_override(k, oi);
        if (k && !fy_node_mapping_append(parent, k, v)) return 0;
        fy_node_free(k);
        fy_node_free(v);
        return override_fail(L, oi, o->key, "cannot set");
    }
    int idx = path_index(comp), count = fy_node_sequence_item_count(parent);
    if (idx < 0 || idx > count) {
        fy_node_free(v);
        return override_fail(L, oi, o->key, "no such list item");
    }
    if (idx == count)
        return fy_node_sequence_append(parent, v) ? override_fail(L, oi, o->key, "cannot set") : 0;
    struct fy_node *old = fy_node_sequence_get_by_index(parent, idx);
    fy_node_sequence_insert_after(parent, old, v);
    fy_node_free(fy_node_sequence_remove(parent, old));
    return 0;
}

static int unset_last(loader *L, int oi, struct fy_node *parent, const char *comp)
{
    const stf_override *o = &L->ov[oi];
    if (fy_node_is_mapping(parent)) {
        struct fy_node_pair *p = fy_node_mapping_lookup_pair_by_string(parent, comp, FY_NT);
        if (!p) return override_fail(L, oi, o->key, "no such key");
        /* fy_node_mapping_remove() would leak the pair; this frees pair and key. */
        fy_node_free(fy_node_mapping_remove_by_key(parent, fy_node_pair_key(p)));
        return 0;
    }
    int idx = path_index(comp);
    struct fy_node *item = idx >= 0 ? fy_node_sequence_get_by_index(parent, idx) : NULL;
    if (!item) return override_fail(L, oi, o->key, "no such list item");
    fy_node_free(fy_node_sequence_remove(parent, item));
    return 0;
}

static int apply_override(loader *L, int oi)
{
    const stf_override *o = &L->ov[oi];
    char buf[256], *comps[32];
    int n = 0;
    if (!o->key || snprintf(buf, sizeof buf, "%s", o->key) >= (int)sizeof buf)
        return override_fail(L, oi, o->key ? o->key : "", "key too long");
    for (char *t = buf, *dot; n < 32; t = dot + 1) {
        comps[n++] = t;
        if (!(dot = strchr(t, '.'))) break;
        *dot = '\0';
    }
    for (int i = 0; i < n; i++) {
        if (!comps[i][0]) return override_fail(L, oi, o->key, "empty component in the key");
    }
    if (n > 2 && !strcmp(comps[0], "expect")) { /* expect keys hold dots: fluid.escaped */
        for (int i = 2; i < n; i++) comps[i][-1] = '.';
        n = 2;
    }
    struct fy_node *parent = NULL;
    if (walk_to_parent(L, oi, comps, n, &parent)) return SCENE_BAD;
    return o->value ? set_last(L, oi, parent, comps[n - 1])
                    : unset_last(L, oi, parent, comps[n - 1]);
}

/* ------------------------------------------------------------------------------ loading */

static void ignore_diag(struct fy_diag *diag, void *user, const char *buf, size_t len)
{
    (void)diag, (void)user, (void)buf, (void)len;
}

/* Bounds on the work a scene file can ask of the parser. libfyaml expands aliases in
 * place, so a few lines of nested aliases ("billion laughs") would become gigabytes; and
 * libfyaml 0.7.12 loops forever on some invalid UTF-8 (a '%' followed by a byte >= 0x80
 * that starts no valid sequence). Both are refused before libfyaml sees them. */
enum { MAX_EXPANDED_NODES = 100000, MAX_ALIAS_DEPTH = 64 };

/* Offset of the first byte of text that is not valid UTF-8 (RFC 3629: no overlong forms,
 * no surrogates, nothing above U+10FFFF), or -1 when all of it is. */
static long utf8_invalid_at(const char *text)
{
    const unsigned char *s = (const unsigned char *)text;
    for (long i = 0; s[i];) {
        unsigned c = s[i];
        int len = c < 0x80 ? 1 : c >= 0xc2 && c <= 0xdf ? 2 : c >= 0xe0 && c <= 0xef ? 3
                                                        : c >= 0xf0 && c <= 0xf4 ? 4 : 0;
        if (!len) return i;
        for (int k = 1; k < len; k++) {
            if ((s[i + k] & 0xc0) != 0x80) return i;
        }
        if ((c == 0xe0 && s[i + 1] < 0xa0) || (c == 0xed && s[i + 1] >= 0xa0) ||
            (c == 0xf0 && s[i + 1] < 0x90) || (c == 0xf4 && s[i + 1] >= 0x90))
            return i;
        i += len;
    }
    return -1;
}

/* Writes "FILE:LINE:COL: scene: not UTF-8 text" for the invalid byte at offset at. */
static int fail_utf8(loader *L, const char *text, long at)
{
    int line = 1, col = 1;
    for (long i = 0; i < at; i++) {
        if (text[i] == '\n') line++, col = 1;
        else if (((unsigned char)text[i] & 0xc0) != 0x80) col++;
    }
    snprintf(L->err, L->errlen, "%s:%d:%d: scene: not UTF-8 text (byte 0x%02x)", L->file, line,
             col, (unsigned char)text[at]);
    return SCENE_BAD;
}

/* Counts the nodes of n with its aliases expanded, down to *budget (an alias naming an
 * anchor defined more than once counts every definition). Returns -1 when the budget runs
 * out or aliases nest deeper than MAX_ALIAS_DEPTH (a recursive alias does both), and
 * *bad is the alias where it happened. */
static int count_expanded(struct fy_document *fyd, struct fy_node *n, int depth, long *budget,
                          struct fy_node **bad)
{
    if (!n) return 0;
    if (--*budget < 0) return -1;
    void *it = NULL;
    if (fy_node_is_alias(n)) {
        size_t len = 0;
        const char *name = fy_node_get_scalar(n, &len);
        if (depth >= MAX_ALIAS_DEPTH) return *bad = n, -1;
        struct fy_anchor *a;
        while ((a = fy_document_anchor_iterate(fyd, &it))) {
            size_t alen = 0;
            const char *aname = fy_anchor_get_text(a, &alen);
            if (!name || !aname || alen != len || memcmp(name, aname, len)) continue;
            if (count_expanded(fyd, fy_anchor_node(a), depth + 1, budget, bad))
                return *bad = *bad ? *bad : n, -1;
        }
        return 0;
    }
    if (fy_node_is_sequence(n)) {
        struct fy_node *c;
        while ((c = fy_node_sequence_iterate(n, &it)))
            if (count_expanded(fyd, c, depth, budget, bad)) return -1;
    } else if (fy_node_is_mapping(n)) {
        struct fy_node_pair *p;
        while ((p = fy_node_mapping_iterate(n, &it))) {
            if (count_expanded(fyd, fy_node_pair_key(p), depth, budget, bad) ||
                count_expanded(fyd, fy_node_pair_value(p), depth, budget, bad))
                return -1;
        }
    }
    return 0;
}

/* Writes the first error libfyaml collected in diag, as FILE:LINE:COL: YAML ...: msg. */
static void diag_error(loader *L, struct fy_diag *diag, const char *what)
{
    void *it = NULL;
    struct fy_diag_error *e = fy_diag_errors_iterate(diag, &it);
    if (e)
        snprintf(L->err, L->errlen, "%s:%d:%d: %s: %s", L->file, e->line, e->column, what,
                 e->msg);
    else
        snprintf(L->err, L->errlen, "%s: %s", L->file, what);
}

/* Parses text, then resolves its aliases if they expand to a bounded document. On an error
 * writes FILE:LINE:COL (libfyaml's collected errors, or the alias) and returns NULL. */
static struct fy_document *parse_text(loader *L, const char *text)
{
    long bad_at = utf8_invalid_at(text);
    if (bad_at >= 0) return fail_utf8(L, text, bad_at), NULL;
    struct fy_diag_cfg dc;
    fy_diag_cfg_default(&dc);
    dc.fp = NULL;
    dc.output_fn = ignore_diag;
    dc.level = FYET_ERROR;
    struct fy_diag *diag = fy_diag_create(&dc);
    if (!diag) {
        snprintf(L->err, L->errlen, "%s: out of memory", L->file);
        return NULL;
    }
    fy_diag_set_collect_errors(diag, true);
    struct fy_parse_cfg cfg = {.flags = FYPCF_QUIET, .diag = diag};
    struct fy_document *fyd = fy_document_build_from_string(&cfg, text, FY_NT);
    if (!fyd) diag_error(L, diag, "YAML syntax error");
    long budget = MAX_EXPANDED_NODES;
    struct fy_node *bad = NULL;
    if (fyd && count_expanded(fyd, fy_document_root(fyd), 0, &budget, &bad)) {
        int line = 1, col = 1;
        node_mark(bad, &line, &col);
        snprintf(L->err, L->errlen,
                 "%s:%d:%d: scene: aliases expand to more than %d nodes or nest deeper than %d "
                 "(recursive alias?)", L->file, line, col, MAX_EXPANDED_NODES, MAX_ALIAS_DEPTH);
        fy_document_destroy(fyd);
        fyd = NULL;
    }
    if (fyd && fy_document_resolve(fyd) != 0) {
        diag_error(L, diag, "YAML alias error");
        fy_document_destroy(fyd);
        fyd = NULL;
    }
    /* Errors collected later (override values built in this document) would leak. */
    fy_diag_set_collect_errors(diag, false);
    fy_diag_destroy(diag); /* the document keeps its own reference */
    return fyd;
}

/* Copies every key of the mapping `from` (material document) that `into` (scene document)
 * lacks, marking the copies as the material's. */
static int fill_missing(loader *L, struct fy_node *into, struct fy_node *from)
{
    void *it = NULL;
    struct fy_node_pair *p;
    while ((p = fy_node_mapping_iterate(from, &it))) {
        char name[128];
        if (!scalar_text(fy_node_pair_key(p), name, sizeof name))
            return fail(L, fy_node_pair_key(p), NULL, "material", "expected a plain key");
        if (fy_node_mapping_lookup_pair_by_string(into, name, FY_NT)) continue; /* the scene's */
        /* one of two ways to give the same thing: the scene's way wins */
        static const char *const alike[][2] = {{"d", "memory"}, {"memory", "d"}};
        int taken = 0;
        for (int a = 0; a < 2; a++)
            taken |= !strcmp(name, alike[a][0]) &&
                     fy_node_mapping_lookup_pair_by_string(into, alike[a][1], FY_NT) != NULL;
        if (taken) continue;
        struct fy_node *k = fy_node_copy(L->fyd, fy_node_pair_key(p));
        struct fy_node *v = fy_node_copy(L->fyd, fy_node_pair_value(p));
        if (!k || !v || fy_node_mapping_append(into, k, v) != 0) {
            snprintf(L->err, L->errlen, "%s: out of memory", L->file);
            return SCENE_BAD;
        }
        mark_material(k);
        mark_material(v);
    }
    return 0;
}

/* The material's file: NAME alone is materials/NAME.yaml beside the scene file; a name
 * with a '/' or ending in .yaml is a path relative to the scene file's directory. */
static void material_path(const loader *L, const char *name, char *out, size_t n)
{
    const char *slash = strrchr(L->file, '/');
    int dir = slash ? (int)(slash - L->file + 1) : 0;
    size_t len = strlen(name);
    int is_path = strchr(name, '/') || (len > 5 && !strcmp(name + len - 5, ".yaml"));
    if (name[0] == '/') snprintf(out, n, "%s", name);
    else if (is_path) snprintf(out, n, "%.*s%s", dir, L->file, name);
    else snprintf(out, n, "%.*smaterials/%s.yaml", dir, L->file, name);
}

static char *read_file(const char *path);

/* The scene's `material: NAME`: the material file's fluid keys fill the scene's fluid
 * mapping, and its parameters of each effect the scene names fill that effect's mapping
 * (an effect the scene does not name stays off); the scene's own keys win. The key is then
 * removed, so the scene text stored in an output file holds the whole material. */
static int merge_material(loader *L)
{
    struct fy_node *root = fy_document_root(L->fyd);
    if (!root || !fy_node_is_mapping(root)) return 0;
    struct fy_node_pair *mp = fy_node_mapping_lookup_pair_by_string(root, "material", FY_NT);
    if (!mp) return 0;
    char name[512];
    struct fy_node *mk = fy_node_pair_key(mp), *mv = fy_node_pair_value(mp);
    if (!scalar_text(mv, name, sizeof name) || !name[0] || fy_node_is_null(mv))
        return fail(L, mv, mk, "material", "expected a material name (e.g. cornstarch) or a path");
    material_path(L, name, L->material_file, sizeof L->material_file);
    char *text = read_file(L->material_file);
    if (!text)
        return fail(L, mv, mk, "material", "cannot read %s: %s", L->material_file, strerror(errno));
    const char *scene_file = L->file;
    L->file = L->material_file; /* syntax errors name the material file */
    struct fy_document *mat = parse_text(L, text);
    L->file = scene_file;
    L->material_text = text;
    L->material_fyd = mat;
    if (!mat) return SCENE_BAD;
    static const char *const top_keys[] = {"name", "fluid", "effects", NULL};
    static const char *const fluid_keys[] = {"model", "density", "h", "jitter", "relaxation",
                                             "iterations", "reference_spacing", NULL};
    int rc = 0;
    mapv top, fl, ef;
    const char *saved = L->file;
    L->file = L->material_file; /* keys of the material document name its file */
    rc = open_map(L, fy_document_root(mat), NULL, "", top_keys, &top);
    struct fy_node *k, *v;
    if (!rc && (v = lookup(&top, "fluid", &k)))
        rc = open_map(L, v, k, "fluid", fluid_keys, &fl);
    L->file = saved;
    if (!rc && fl.node) {
        struct fy_node *sf = fy_node_mapping_lookup_by_string(root, "fluid", FY_NT);
        if (sf && fy_node_is_mapping(sf)) rc = fill_missing(L, sf, fl.node);
    }
    if (!rc && (v = lookup(&top, "effects", &k)) && !is_null(v)) {
        L->file = L->material_file;
        if (!fy_node_is_mapping(v)) rc = fail(L, v, k, "effects", "expected a mapping");
        L->file = saved;
        ef.node = rc ? NULL : v;
        struct fy_node *se = fy_node_mapping_lookup_by_string(root, "effects", FY_NT);
        void *it = NULL;
        struct fy_node_pair *p;
        while (!rc && ef.node && se && fy_node_is_mapping(se) && (p = fy_node_mapping_iterate(se, &it))) {
            char en[64];
            if (!scalar_text(fy_node_pair_key(p), en, sizeof en)) continue;
            struct fy_node *me = fy_node_mapping_lookup_by_string(ef.node, en, FY_NT);
            if (!me || !fy_node_is_mapping(me)) continue;
            struct fy_node *val = fy_node_pair_value(p);
            if (is_null(val)) { /* `history:` or `history: {}` with nothing of its own */
                val = fy_node_create_mapping(L->fyd);
                if (!val || fy_node_pair_set_value(p, val) != 0) {
                    rc = SCENE_BAD;
                    break;
                }
            }
            if (fy_node_is_mapping(val)) rc = fill_missing(L, val, me);
        }
    }
    if (!rc) /* the stored text holds the material itself; this frees pair and key */
        fy_node_free(fy_node_mapping_remove_by_key(root, mk));
    return rc;
}

static int load(loader *L, const char *text)
{
    stf_scene *s = L->s;
    L->fyd = parse_text(L, text);
    if (!L->fyd) return SCENE_BAD;
    /* --set material=NAME / --unset material choose the material before it is merged;
       every other override then applies over the merged scene */
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1 && merge_material(L)) return SCENE_BAD;
        for (int i = 0; i < L->nov; i++) {
            int material = L->ov[i].key && !strcmp(L->ov[i].key, "material");
            if (material == (pass == 0) && apply_override(L, i)) return SCENE_BAD;
        }
    }
    int rc = parse_scene(L);
    if (rc) return rc;
    /* Emitted only once the scene is valid: libfyaml 0.7.12's emitter leaks on some scalars
     * a valid scene cannot hold (found by the fuzzer: a long run of quotes). */
    s->text = fy_emit_document_to_string(L->fyd, FYECF_MODE_BLOCK | FYECF_WIDTH_INF);
    if (!s->text) s->text = calloc(1, 1);
    return 0;
}

int stf_scene_load_string(const char *name, const char *text, const stf_override *ov, int nov,
                          stf_scene **out, char *err, size_t errlen)
{
    char dummy[8];
    stf_scene *s = calloc(1, sizeof *s);
    loader L = {.file = name ? name : "<string>",
                .err = err ? err : dummy,
                .errlen = err ? errlen : sizeof dummy,
                .ov = ov,
                .nov = ov ? nov : 0,
                .s = s};
    *out = NULL;
    if (L.errlen) L.err[0] = '\0';
    if (!s) return snprintf(L.err, L.errlen, "%s: out of memory", L.file), SCENE_BAD;
    snprintf(s->path, sizeof s->path, "%s", L.file);
    int rc = load(&L, text ? text : "");
    if (L.fyd) fy_document_destroy(L.fyd);
    if (L.material_fyd) fy_document_destroy(L.material_fyd);
    free(L.material_text);
    if (rc) {
        stf_scene_free(s);
        return rc;
    }
    *out = s;
    return 0;
}

static char *read_file(const char *path)
{
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    size_t cap = 4096, len = 0;
    char *buf = malloc(cap);
    while (buf) {
        size_t want = cap - len - 1, got = fread(buf + len, 1, want, fp);
        len += got;
        if (got < want) {
            if (ferror(fp)) break;
            buf[len] = '\0';
            fclose(fp);
            return buf;
        }
        char *bigger = realloc(buf, cap *= 2);
        if (!bigger) break;
        buf = bigger;
    }
    int saved = errno;
    free(buf);
    fclose(fp);
    errno = saved ? saved : ENOMEM;
    return NULL;
}

int stf_scene_load(const char *path, const stf_override *ov, int nov, stf_scene **out, char *err,
                   size_t errlen)
{
    errno = 0;
    char *text = read_file(path);
    if (!text) {
        *out = NULL;
        if (err && errlen) snprintf(err, errlen, "%s: cannot read: %s", path, strerror(errno));
        return SCENE_BAD;
    }
    int rc = stf_scene_load_string(path, text, ov, nov, out, err, errlen);
    free(text);
    return rc;
}

void stf_scene_free(stf_scene *s)
{
    if (!s) return;
    free(s->blocks);
    free(s->bodies);
    free(s->expect);
    free(s->points);
    free(s->text);
    free(s);
}
