/* fluid.c - creation, particles, and the step of the paper's Algorithm 1. */
#include "fluid.h"

#include "cy.h"
#include "gauss_seidel.h"

#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

stf_fluid_def stf_default_fluid_def(void)
{
    stf_fluid_def d;
    memset(&d, 0, sizeof d);
    d.effects = STF_EFFECT_GRAVITY | STF_EFFECT_VISCOSITY | STF_EFFECT_PRESSURE |
                STF_EFFECT_SPRINGS | STF_EFFECT_HISTORY | STF_EFFECT_BOUNDARY_STICK;
    d.spacing = 0.01;
    d.density = 1270.0; /* cornstarch in water, about 57% starch by mass (grains of about 1.6 g/cm^3) */
    d.h = 0.0;
    d.gravity[2] = -9.81;
    d.sigma = 2.0;
    d.beta = 0.0;
    d.k = 1000.0;
    d.k_near = 200.0;
    d.rest_density = 0.0;
    d.k_min = 100.0;
    d.yield_ratio = 0.0;
    d.plasticity = 2.0;
    d.liquid_plasticity = -1; /* as plasticity */
    d.relaxation = STF_RELAX_JACOBI;
    d.iterations = 1;
    d.q = 0.5;
    d.d = 150;
    d.memory = 0.0;
    d.k_hist = 1000.0 * d.k_min; /* src/README.md, "Units": the paper's 10 k_min in its units */
    d.history_mode = STF_HISTORY_WINDOW;
    d.terms = 16;
    d.stick = 200.0;
    d.jitter = 0.2;
    d.model = STF_MODEL_CLAVET_STF;
    d.cy = (stf_cy_def){.mu0 = 1e-3, .mu_inf = 1e-3, .K = 1.0, .alpha = 2.0, .n = 1.0,
                        .eta = 0.01, .min_pressure_iterations = 2, .max_pressure_iterations = 100,
                        .viscosity_solver = STF_VISCOSITY_IMPLICIT, .cg_tolerance = 1e-4,
                        .max_cg_iterations = 200};
    return d;
}

stf_collider_def stf_default_collider_def(void)
{
    stf_collider_def c;
    memset(&c, 0, sizeof c);
    c.shape = STF_SHAPE_SPHERE;
    c.radius = 0.1;
    c.normal[2] = 1.0;
    c.wall = 0.02;
    c.friction = 0.2;
    return c;
}

void stf_set_threads(int n)
{
    if (n > 0) omp_set_num_threads(n);
}

#define FAIL(...)                                                                             \
    do {                                                                                      \
        snprintf(err, errlen, __VA_ARGS__);                                                   \
        return -1;                                                                            \
    } while (0)

/* stf_cy_check_def starts its message with the name of the field it refuses ("mu0: ..."): a
 * member of def->cy, or of def itself (effects, periodic, periodic_origin). */
static const char *cy_field(const char *msg)
{
    static const char *const fields[] = {
        "cy.mu0", "cy.mu_inf", "cy.K", "cy.alpha", "cy.n", "cy.eta",
        "cy.min_pressure_iterations", "cy.max_pressure_iterations", "cy.viscosity_solver",
        "cy.viscosity_form", "cy.cg_tolerance", "cy.max_cg_iterations", "cy.warm_start",
        "cy.relaxation", "cy.dt_max", "cy.cfl", "cy.pressure_solver", "cy.wall_pressure",
        "cy.pressure_gradient", "effects", "periodic", "periodic_origin", NULL};
    size_t n = strcspn(msg, ":");
    for (int i = 0; fields[i]; i++) {
        const char *name = strncmp(fields[i], "cy.", 3) ? fields[i] : fields[i] + 3;
        if (strlen(name) == n && !strncmp(name, msg, n)) return fields[i];
    }
    return "cy";
}

#define BAD(F, ...)                                                                                \
    do {                                                                                           \
        *field = (F);                                                                              \
        snprintf(err, errlen, __VA_ARGS__);                                                        \
        return -1;                                                                                 \
    } while (0)

int stf_fluid_check_def(const stf_fluid_def *d, char *err, size_t errlen, const char **field)
{
    const char *unused;
    if (!field) field = &unused;
    *field = NULL;
    const unsigned all = STF_EFFECT_GRAVITY | STF_EFFECT_VISCOSITY | STF_EFFECT_PRESSURE |
                         STF_EFFECT_SPRINGS | STF_EFFECT_HISTORY | STF_EFFECT_BOUNDARY_STICK;
    if (d->effects & ~all) BAD("effects", "effects: unknown effect bits 0x%x", d->effects & ~all);
    if (d->model != STF_MODEL_CLAVET_STF && d->model != STF_MODEL_CARREAU_YASUDA)
        BAD("model", "model: must be clavet_stf or carreau_yasuda (got %d)", d->model);
    if (d->model == STF_MODEL_CARREAU_YASUDA) { /* caps on the counts (stf_cy_check_def: floors) */
        const stf_cy_def *c = &d->cy;
        if (c->min_pressure_iterations > 10000)
            BAD("cy.min_pressure_iterations",
                "min_pressure_iterations: must be <= 10000 (got %d)", c->min_pressure_iterations);
        if (c->max_pressure_iterations > 10000)
            BAD("cy.max_pressure_iterations",
                "max_pressure_iterations: must be <= 10000 (got %d)", c->max_pressure_iterations);
        if (c->max_cg_iterations > 100000)
            BAD("cy.max_cg_iterations", "max_cg_iterations: must be <= 100000 (got %d)",
                c->max_cg_iterations);
    }
    char cy_msg[256]; /* its own buffer: err may be short or NULL */
    if (d->model == STF_MODEL_CARREAU_YASUDA && stf_cy_check_def(d, cy_msg, sizeof cy_msg) != 0)
        BAD(cy_field(cy_msg), "%s", cy_msg);
    for (int a = 0; a < 3; a++)
        if (d->model != STF_MODEL_CARREAU_YASUDA && d->periodic[a] != 0)
            BAD("periodic", "periodic: only the carreau_yasuda model has periodic axes");
    if (!(d->spacing > 0 && d->spacing <= 1))
        BAD("spacing", "spacing: must be > 0 and <= 1 m (got %g)", d->spacing);
    if (!(d->density > 0 && isfinite(d->density)))
        BAD("density", "density: must be > 0 (got %g)", d->density);
    if (!(d->material_spacing >= 0 && isfinite(d->material_spacing) && d->material_spacing <= 1))
        BAD("material_spacing", "reference_spacing: must be in [0, 1] m (got %g)",
            d->material_spacing);
    if (d->material_spacing > 0 && d->reference_spacing > 0)
        BAD("reference_spacing",
            "reference_spacing: give the material's (fluid) or the history's, not both");
    if (d->material_spacing > 0 && d->h != 0)
        BAD("h", "h: must be 0 (2 spacings) with a reference_spacing: the material scales with "
                 "h / spacing fixed (got %g)", d->h);
    if (!(d->h == 0 || (d->h >= d->spacing && d->h <= 5 * d->spacing)))
        BAD("h", "h: must be 0 or in [spacing, 5*spacing] (got %g)", d->h);
    for (int a = 0; a < 3; a++)
        if (!isfinite(d->gravity[a])) BAD("gravity", "gravity: must be finite");
    if (!(d->sigma >= 0 && isfinite(d->sigma)))
        BAD("sigma", "sigma: must be >= 0 (got %g)", d->sigma);
    if (!(d->beta >= 0 && isfinite(d->beta))) BAD("beta", "beta: must be >= 0 (got %g)", d->beta);
    if (d->pressure_mode != STF_PRESSURE_RELAX && d->pressure_mode != STF_PRESSURE_PROJECTION)
        BAD("pressure_mode", "mode: must be relax or projection (got %d)", d->pressure_mode);
    if (d->pressure_mode == STF_PRESSURE_PROJECTION) {
        const stf_cy_def *c = &d->cy;
        if (d->model != STF_MODEL_CLAVET_STF)
            BAD("pressure_mode", "mode: projection is the clavet_stf model's choice (the "
                                 "carreau_yasuda model always projects)");
        if (!(c->eta > 0 && c->eta < 1)) BAD("pressure.eta", "eta: must be in (0,1) (got %g)", c->eta);
        if (!(c->min_pressure_iterations >= 1 && c->min_pressure_iterations <= 10000))
            BAD("pressure.min_iterations", "min_iterations: must be in [1, 10000] (got %d)",
                c->min_pressure_iterations);
        if (!(c->max_pressure_iterations >= c->min_pressure_iterations &&
              c->max_pressure_iterations <= 10000))
            BAD("pressure.max_iterations",
                "max_iterations: must be in [min_iterations, 10000] (got %d)",
                c->max_pressure_iterations);
        if (c->pressure_solver != STF_PRESSURE_JACOBI && c->pressure_solver != STF_PRESSURE_CG)
            BAD("pressure.solver", "solver: must be jacobi or cg (got %d)", c->pressure_solver);
        if (c->wall_pressure < STF_WALL_PRESSURE_OWN || c->wall_pressure > STF_WALL_PRESSURE_HYDROSTATIC)
            BAD("pressure.wall_pressure", "wall_pressure: must be own, mirror or hydrostatic (got %d)",
                c->wall_pressure);
        if (c->pressure_gradient < STF_PRESSURE_GRADIENT_SYMMETRIC ||
            c->pressure_gradient > STF_PRESSURE_GRADIENT_OFFSET)
            BAD("pressure.gradient", "gradient: must be symmetric, local_minimum or offset (got %d)",
                c->pressure_gradient);
        if (c->pressure_gradient != STF_PRESSURE_GRADIENT_SYMMETRIC &&
            c->pressure_solver != STF_PRESSURE_JACOBI)
            BAD("pressure.gradient", "gradient: %s needs solver jacobi (conjugate gradients need "
                                     "the symmetric form's symmetric matrix)",
                stf_pressure_gradient_name(c->pressure_gradient));
        if (!(c->cg_tolerance > 0 && c->cg_tolerance < 1))
            BAD("pressure.cg_tolerance", "cg_tolerance: must be in (0,1) (got %g)", c->cg_tolerance);
        if (!(c->max_cg_iterations >= 1 && c->max_cg_iterations <= 100000))
            BAD("pressure.max_cg_iterations", "max_cg_iterations: must be in [1, 100000] (got %d)",
                c->max_cg_iterations);
        if (!(c->warm_start >= 0 && c->warm_start <= 1))
            BAD("pressure.warm_start", "warm_start: must be in [0,1] (got %g)", c->warm_start);
        if (!(c->relaxation >= 0 && c->relaxation <= 1))
            BAD("pressure.relaxation", "relaxation: must be in (0,1], or 0 for 1 (got %g)",
                c->relaxation);
    }
    if ((d->effects & STF_EFFECT_PRESSURE) && d->pressure_mode == STF_PRESSURE_RELAX &&
        !(d->k > 0 && isfinite(d->k)))
        BAD("k", "k: must be > 0 (got %g)", d->k);
    if (!(d->k_near >= 0 && isfinite(d->k_near)))
        BAD("k_near", "k_near: must be >= 0 (got %g)", d->k_near);
    if (!(d->rest_density >= 0 && isfinite(d->rest_density)))
        BAD("rest_density", "rest_density: must be >= 0 (got %g)", d->rest_density);
    if (d->rest_packing != STF_REST_LATTICE && d->rest_packing != STF_REST_LIQUID)
        BAD("rest_packing", "rest: must be lattice or liquid (got %d)", d->rest_packing);
    if (d->relax_wall != STF_RELAX_WALL_MIRROR && d->relax_wall != STF_RELAX_WALL_GHOST)
        BAD("relax_wall", "wall: must be mirror or ghost (got %d)", d->relax_wall);
    if (d->relax_wall == STF_RELAX_WALL_GHOST &&
        (d->model != STF_MODEL_CLAVET_STF || d->pressure_mode != STF_PRESSURE_RELAX))
        BAD("relax_wall", "wall: ghost is a wall of the relaxation (mode relax of the "
                          "clavet_stf model)");
    if (d->rest_packing == STF_REST_LIQUID && d->rest_density > 0)
        BAD("rest_packing", "rest: liquid sets the rest density; give rest_density or rest, not "
                            "both");
    if (d->rest_packing == STF_REST_LIQUID &&
        (d->model != STF_MODEL_CLAVET_STF || d->pressure_mode != STF_PRESSURE_RELAX))
        BAD("rest_packing", "rest: liquid is the relaxation's rest density (mode relax of the "
                            "clavet_stf model)");
    if (d->rest_packing == STF_REST_LIQUID && d->tension)
        BAD("rest_packing", "rest: liquid is measured without tension (tension: false)");
    if (d->rest_packing == STF_REST_LIQUID && d->h > 0 &&
        fabs(d->h - 2 * d->spacing) > 1e-9 * d->spacing)
        BAD("rest_packing", "rest: liquid is measured at h = 2 spacings (got h = %g spacings)",
            d->h / d->spacing);
    if (!(d->k_min >= 0 && isfinite(d->k_min)))
        BAD("k_min", "k_min: must be >= 0 (got %g)", d->k_min);
    if (!(d->yield_ratio >= 0 && d->yield_ratio <= 1))
        BAD("yield_ratio", "yield_ratio: must be in [0,1] (got %g)", d->yield_ratio);
    if (!(d->plasticity >= 0 && isfinite(d->plasticity)))
        BAD("plasticity", "plasticity: must be >= 0 (got %g)", d->plasticity);
    if (!isfinite(d->liquid_plasticity))
        BAD("liquid_plasticity",
            "liquid_plasticity: must be finite, >= 0 (< 0: plasticity) (got %g)",
            d->liquid_plasticity);
    if (d->relaxation != STF_RELAX_JACOBI && d->relaxation != STF_RELAX_GAUSS_SEIDEL)
        BAD("relaxation", "relaxation: must be jacobi or gauss_seidel (got %d)", d->relaxation);
    if (!(d->spring_damping >= 0 && d->spring_damping <= 1))
        BAD("spring_damping", "damping: must be in [0, 1] s (got %g)", d->spring_damping);
    if (d->spring_damping > 0 && d->relaxation != STF_RELAX_GAUSS_SEIDEL)
        BAD("spring_damping", "damping: needs relaxation gauss_seidel");
    if (d->spring_passive != 0 && d->spring_passive != 1)
        BAD("spring_passive", "passive: must be true or false (got %d)", d->spring_passive);
    if (d->spring_passive && (d->effects & STF_EFFECT_SPRINGS) && !(d->effects & STF_EFFECT_HISTORY))
        BAD("spring_passive", "passive: needs effects.history (without it no spring stiffens)");
    if (!(d->iterations >= 1 && d->iterations <= 64))
        BAD("iterations", "iterations: must be in [1, 64] (got %d)", d->iterations);
    if (d->effects & STF_EFFECT_HISTORY) {
        if (!(d->effects & STF_EFFECT_SPRINGS)) BAD("effects", "history: needs the springs effect");
        if (!(d->q > 0 && d->q < 1)) BAD("q", "q: must be in (0,1) (got %g)", d->q);
        if (d->history_velocity != STF_HISTORY_PARTICLE &&
            d->history_velocity != STF_HISTORY_SMOOTHED)
            BAD("history_velocity", "history_velocity: must be particle or smoothed (got %d)",
                d->history_velocity);
        if (!(d->history_smoothing >= 0 && isfinite(d->history_smoothing)))
            BAD("history_smoothing", "smoothing: must be >= 0 m (got %g)", d->history_smoothing);
        if (d->history_smoothing > 0 && d->history_velocity != STF_HISTORY_SMOOTHED)
            BAD("history_smoothing", "smoothing: needs velocity smoothed");
        if (d->history_mode != STF_HISTORY_WINDOW && d->history_mode != STF_HISTORY_FULL &&
            d->history_mode != STF_HISTORY_SOE)
            BAD("history_mode", "history_mode: must be window, full or soe (got %d)",
                d->history_mode);
        if (d->history_mode == STF_HISTORY_SOE && !(d->terms >= 1 && d->terms <= 64))
            BAD("terms", "terms: must be in [1, 64] (got %d)", d->terms);
        if (d->memory <= 0 && !(d->d >= 1 && d->d <= 100000))
            BAD("d", "d: must be >= 1 and <= 100000 (got %d)", d->d);
        if (!(d->memory >= 0 && isfinite(d->memory)))
            BAD("memory", "memory: must be >= 0 (got %g)", d->memory);
        if (!(d->k_hist >= 0 && isfinite(d->k_hist)))
            BAD("k_hist", "k_hist: must be >= 0 (got %g)", d->k_hist);
        if (!(d->reference_spacing >= 0 && isfinite(d->reference_spacing)))
            BAD("reference_spacing", "reference_spacing: must be >= 0 (got %g)",
                d->reference_spacing);
        if (!(d->k_onset >= 0 && isfinite(d->k_onset)))
            BAD("k_onset", "k_onset: must be >= 0 (got %g)", d->k_onset);
    }
    if (!(d->jitter >= 0 && d->jitter <= 0.45))
        BAD("jitter", "jitter: must be in [0, 0.45] (got %g)", d->jitter);
    if (!(d->stick >= 0 && isfinite(d->stick)))
        BAD("stick", "stick: must be >= 0 (got %g)", d->stick);
    return 0;
}
#undef BAD

/* The rest density that makes the initial cubic lattice an equilibrium.
 *
 * Near-pressure is always repulsive, so with rho0 equal to the lattice's kernel density the
 * fluid swells until its pressure is negative enough to balance it (about 10% in height for
 * the defaults). Choosing rho0 = rho_lat + (k_near/k) * rho_near_lat * S2/S1, with S1, S2 the
 * sums of (1-q) and (1-q)^2 weighted by |cos| to the neighbours, cancels the two pressures
 * along any lattice axis, so a block starts at rest at its physical density. */
static double lattice_rest_density(double spacing, double h, double k, double k_near,
                                   double *rest_near)
{
    int m = (int)ceil(h / spacing);
    double rho = 0, rho_near = 0, s1 = 0, s2 = 0;
    for (int a = -m; a <= m; a++)
        for (int b = -m; b <= m; b++)
            for (int c = -m; c <= m; c++) {
                double r = spacing * sqrt((double)(a * a + b * b + c * c));
                if (r <= 0 || r >= h) continue;
                double w = 1 - r / h, cosz = fabs(c * spacing / r);
                rho += w * w;
                rho_near += w * w * w;
                s1 += w * cosz;
                s2 += w * w * cosz;
            }
    *rest_near = rho_near;
    return k > 0 ? rho + (k_near / k) * rho_near * s2 / s1 : rho;
}

int stf_fluid_create(const stf_fluid_def *def, stf_fluid **out, char *err, size_t errlen)
{
    *out = NULL;
    if (stf_fluid_check_def(def, err, errlen, NULL) != 0) return -1;
    stf_fluid *f = calloc(1, sizeof *f);
    if (!f) FAIL("out of memory");
    f->def = *def;
    if (def->material_spacing > 0) { /* the same continuum material (stf.h) */
        double r = def->material_spacing / def->spacing;
        f->def.k *= r;
        f->def.k_near *= r;
        f->def.sigma *= r * r;
        f->def.beta *= r;
        f->def.k_min *= r * r;
        f->def.k_onset *= r * r;
        f->def.k_hist *= r * r * r;
    }
    f->h = def->h > 0 ? def->h : 2.0 * def->spacing;
    /* The contacts act inside the distance at which the walls' pressure holds the fluid.
       Clavet's mirror holds it at half a spacing from a body; contacts there too stop every
       particle the pressure brings, and carry that pressure as one-sided contacts: a body
       held in water felt 1.18, 1.06 and 1.02 rho V g at 1.5, 2 and 3 spacings of radius
       (1.12, 1.05, 1.015 with them at 0.3 spacings; tests/README.md, "Buoyancy by
       radius"). At the container the contacts stay at half a spacing: there they quiet the
       pool (at 0.3 its wall layers sink to them and the still pool's motion grows two to
       three times; scenes/README.md, the bowling ball). cy.c sets the Carreau-Yasuda walls'. */
    f->contact = 0.5 * def->spacing;
    f->contact_body = 0.3 * def->spacing;
    f->mass = def->density * def->spacing * def->spacing * def->spacing;
    /* With tension the rest density balances near-pressure on the lattice (see above);
       without, both pressures start from zero on the lattice. */
    double rest_near;
    f->rest_density = lattice_rest_density(def->spacing, f->h, def->tension ? def->k : 0,
                                           def->k_near, &rest_near);
    f->rest_near = def->tension ? 0 : rest_near;
    f->lattice = def->spacing;
    if (def->rest_packing == STF_REST_LIQUID) {
        /* The liquid's kernel sum at the fluid's number density; the blocks are laid on the
           lattice whose kernel sum it is (a little wider), so a block starts at rest, without
           the stored pressure of a lattice denser than the liquid (a dropped ball then
           breathes and rebounds without any history), and settles into the liquid's packing
           at the fluid's density. The lattice's sum falls with its spacing: bisection. */
        f->rest_density *= STF_LIQUID_PACKING;
        double lo = def->spacing, hi = 1.1 * def->spacing, dummy;
        for (int it = 0; it < 60; it++) {
            double mid = 0.5 * (lo + hi);
            if (lattice_rest_density(mid, f->h, 0, 0, &dummy) > f->rest_density) lo = mid;
            else hi = mid;
        }
        f->lattice = 0.5 * (lo + hi);
    }
    if (def->rest_density > 0) f->rest_density = def->rest_density;
    f->reorder_interval = 16;
    stf_pressure_wall_table(f);
    if (def->model == STF_MODEL_CLAVET_STF && def->relaxation == STF_RELAX_GAUSS_SEIDEL &&
        (def->effects & STF_EFFECT_SPRINGS) &&
        !(f->gs = calloc(1, sizeof *f->gs))) {
        free(f);
        FAIL("out of memory");
    }
    if ((def->model == STF_MODEL_CARREAU_YASUDA || projects(f)) && stf_cy_create(f) != 0) {
        free(f);
        FAIL("out of memory");
    }
    *out = f;
    return 0;
}

void stf_fluid_destroy(stf_fluid *f)
{
    if (!f) return;
    free(f->x);
    free(f->v);
    free(f->xprev);
    free(f->dx);
    free(f->dproj);
    free(f->hit);
    free(f->id);
    free(f->rho);
    free(f->rho_near);
    free(f->khist_mean);
    free(f->Dprev);
    free(f->field_w);
    free(f->field_v);
    stf_grid_free(&f->grid);
    if (f->gs) stf_gs_free(f->gs);
    free(f->gs);
    stf_cy_free(f);
    if (f->springs.n_alloc) stf_springs_free(&f->springs);
    if (f->hist.n_alloc) stf_history_free(&f->hist);
    for (int k = 0; k < f->ncolliders; k++) stf_collider_free(&f->colliders[k]);
    free(f->colliders);
    free(f);
}

static int grow(void **p, size_t elem, int cap)
{
    void *q = realloc(*p, elem * (size_t)cap);
    if (!q) return -1;
    *p = q;
    return 0;
}

/* Makes room for n particles in every array the enabled effects need. */
static int reserve(stf_fluid *f, int n)
{
    if (n <= f->cap) return 0;
    int cap = n > 2 * f->cap ? n : 2 * f->cap;
    if (grow((void **)&f->x, 3 * sizeof(double), cap) || grow((void **)&f->v, 3 * sizeof(double), cap) ||
        grow((void **)&f->xprev, 3 * sizeof(double), cap) ||
        grow((void **)&f->dx, 3 * sizeof(double), cap) ||
        grow((void **)&f->dproj, 3 * sizeof(double), cap) || grow((void **)&f->hit, 1, cap) ||
        grow((void **)&f->id, sizeof(int32_t), cap))
        return -1;
    if (has(f, STF_EFFECT_PRESSURE) &&
        (grow((void **)&f->rho, sizeof(double), cap) || grow((void **)&f->rho_near, sizeof(double), cap)))
        return -1;
    if (has(f, STF_EFFECT_SPRINGS)) {
        if (f->springs.n_alloc == 0 ? stf_springs_init(&f->springs, cap) : stf_springs_resize(&f->springs, cap))
            return -1;
    }
    if (has(f, STF_EFFECT_HISTORY)) {
        if (grow((void **)&f->khist_mean, sizeof(float), cap)) return -1;
        if (f->def.spring_passive && grow((void **)&f->Dprev, 3 * sizeof(double), cap)) return -1;
        if (f->hist.n_alloc == 0 && f->hist.w == NULL) {
            /* the window is fixed at the first step, when dt is known */
        } else if (stf_history_resize(&f->hist, cap)) {
            return -1;
        }
    }
    f->cap = cap;
    return 0;
}

int stf_fluid_add_particle(stf_fluid *f, const double x[3], const double v[3])
{
    if (reserve(f, f->n + 1) != 0) return -1;
    int i = f->n++;
    for (int a = 0; a < 3; a++) {
        f->x[3 * i + a] = x[a];
        f->v[3 * i + a] = v[a];
        f->xprev[3 * i + a] = x[a];
    }
    f->id[i] = f->next_id++;
    if (f->khist_mean) f->khist_mean[i] = 0;
    if (f->Dprev) memset(f->Dprev + 3 * (size_t)i, 0, 3 * sizeof *f->Dprev);
    if (f->springs.n_alloc) f->springs.count[i] = 0, f->springs.complete[i] = 0;
    return i;
}

/* A deterministic offset of up to amp in each axis, from the particle id: a perfect cubic
 * lattice at rest is a crystal with a shear modulus that a liquid does not have. */
static void lattice_jitter(double amp, uint32_t id, double x[3])
{
    if (amp <= 0) return;
    uint32_t h = id * 2654435761u + 12345u;
    for (int a = 0; a < 3; a++) {
        h ^= h >> 15;
        h *= 2246822519u;
        h ^= h >> 13;
        x[a] += amp * (2.0 * (h & 0xffffff) / 16777216.0 - 1.0);
    }
}

int stf_fluid_add_block(stf_fluid *f, const double lo[3], const double hi[3], const double v[3])
{
    double s = f->lattice, off[3] = {0, 0, 0};
    long cnt[3];
    for (int a = 0; a < 3; a++) cnt[a] = hi[a] > lo[a] ? (long)floor((hi[a] - lo[a]) / s + 1e-9) : 0;
    /* rest: liquid: the wider lattice, centred, rounded up only where its overhang is at most a
       quarter site (an eighth on each side: the outer sites stay 3/8 of a site inside the block,
       wider than the jitter; at half a site a jittered particle started in the floor's band, and
       the 1.5 cm bowling pool blew up in its first steps) */
    if (f->def.rest_packing == STF_REST_LIQUID)
        for (int a = 0; a < 3; a++) {
            cnt[a] = hi[a] > lo[a] ? (long)floor((hi[a] - lo[a]) / s + 0.25) : 0;
            off[a] = 0.5 * ((hi[a] - lo[a]) - (double)cnt[a] * s);
        }
    if (cnt[0] * cnt[1] * cnt[2] > 100000000L) return -1;
    if (reserve(f, f->n + (int)(cnt[0] * cnt[1] * cnt[2])) != 0) return -1;
    int added = 0;
    /* Lattice sites at cell centres, so a block of size L holds L/s layers. */
    for (long c = 0; c < cnt[2]; c++)
        for (long b = 0; b < cnt[1]; b++)
            for (long a = 0; a < cnt[0]; a++) {
                double x[3] = {lo[0] + off[0] + ((double)a + 0.5) * s,
                                lo[1] + off[1] + ((double)b + 0.5) * s,
                                lo[2] + off[2] + ((double)c + 0.5) * s};
                lattice_jitter(f->def.jitter * f->def.spacing, (uint32_t)f->next_id, x);
                if (stf_fluid_add_particle(f, x, v) < 0) return -1;
                added++;
            }
    return added;
}

int stf_fluid_add_ball(stf_fluid *f, const double c[3], double r, const double v[3])
{
    double s = f->lattice;
    if (!(r > 0)) return 0;
    long m = (long)floor(r / s);
    if (m > 250) return -1; /* (2m+1)^3 > 10^8 sites */
    long side = 2 * m + 1;
    if (reserve(f, f->n + (int)(side * side * side)) != 0) return -1;
    int added = 0;
    /* Sites c + (a, b, k) s: the lattice is symmetric about the centre. */
    for (long k = -m; k <= m; k++)
        for (long b = -m; b <= m; b++)
            for (long a = -m; a <= m; a++) {
                if ((double)(a * a + b * b + k * k) * s * s >= r * r) continue;
                double x[3] = {c[0] + (double)a * s, c[1] + (double)b * s, c[2] + (double)k * s};
                lattice_jitter(f->def.jitter * f->def.spacing, (uint32_t)f->next_id, x);
                if (stf_fluid_add_particle(f, x, v) < 0) return -1;
                added++;
            }
    return added;
}

int stf_fluid_add_collider(stf_fluid *f, const stf_collider_def *def, char *err, size_t errlen)
{
    if (f->ncolliders == f->collider_cap) {
        int cap = f->collider_cap ? 2 * f->collider_cap : 4;
        if (grow((void **)&f->colliders, sizeof(collider), cap)) FAIL("out of memory");
        f->collider_cap = cap;
    }
    collider *c = &f->colliders[f->ncolliders];
    if (stf_collider_init(c, def, err, errlen) != 0) return -1;
    c->two_sided = def->shape == STF_SHAPE_CONTAINER && stf_wall_two_sided(def->wall, f->def.spacing);
    return f->ncolliders++;
}

void stf_fluid_set_collider_state(stf_fluid *f, int id, const double pos[3], const double rot[9],
                                  const double vel[3], const double angvel[3])
{
    collider *c = &f->colliders[id];
    memcpy(c->pos, pos, sizeof c->pos);
    if (rot) memcpy(c->rot, rot, sizeof c->rot);
    if (vel) memcpy(c->vel, vel, sizeof c->vel);
    if (angvel) memcpy(c->angvel, angvel, sizeof c->angvel);
}

double stf_fluid_collider_distance(const stf_fluid *f, int id, const double x[3])
{
    double n[3];
    return stf_collider_sdf(&f->colliders[id], x, n);
}

void stf_fluid_collider_impulse(const stf_fluid *f, int id, double impulse[3], double moment[3])
{
    const collider *c = &f->colliders[id];
    memcpy(impulse, c->impulse, sizeof c->impulse);
    memcpy(moment, c->moment, sizeof c->moment);
}

void stf_fluid_collider_impulse_parts(const stf_fluid *f, int id, double parts[STF_PARTS][3])
{
    memcpy(parts, f->colliders[id].part, sizeof f->colliders[id].part);
}

void stf_fluid_collider_shift(const stf_fluid *f, int id, double shift[3])
{
    memcpy(shift, f->colliders[id].shift, sizeof f->colliders[id].shift);
}

/* the particles within band outside any of the colliders ids */
static int in_band(const stf_fluid *f, const int *ids, int nids, const double *x, double band)
{
    double nrm[3];
    for (int k = 0; k < nids; k++) {
        const collider *c = &f->colliders[ids[k]];
        if (stf_collider_near(c, x, band) && stf_collider_sdf(c, x, nrm) < band) return 1;
    }
    return 0;
}

int stf_fluid_collider_band(const stf_fluid *f, const int *ids, int nids, double band,
                            const double origin[3], double sum[3], double sum2[6])
{
    int count = 0;
    for (int a = 0; a < 3; a++) sum[a] = 0;
    for (int a = 0; a < 6; a++) sum2[a] = 0;
    /* serial, in particle order: the sums do not depend on the thread count */
    for (int i = 0; i < f->n; i++) {
        const double *x = f->x + 3 * i;
        if (!in_band(f, ids, nids, x, band)) continue;
        double r[3] = {x[0] - origin[0], x[1] - origin[1], x[2] - origin[2]};
        count++;
        for (int a = 0; a < 3; a++) sum[a] += r[a];
        sum2[0] += r[0] * r[0], sum2[1] += r[1] * r[1], sum2[2] += r[2] * r[2];
        sum2[3] += r[0] * r[1], sum2[4] += r[0] * r[2], sum2[5] += r[1] * r[2];
    }
    return count;
}

void stf_fluid_collider_band_push(stf_fluid *f, const int *ids, int nids, double band,
                                  const double origin[3], const double dv[3], const double w[3])
{
    int n = f->n;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        const double *x = f->x + 3 * i;
        if (!in_band(f, ids, nids, x, band)) continue;
        double r[3] = {x[0] - origin[0], x[1] - origin[1], x[2] - origin[2]};
        double *v = f->v + 3 * i;
        v[0] += dv[0] + w[1] * r[2] - w[2] * r[1];
        v[1] += dv[1] + w[2] * r[0] - w[0] * r[2];
        v[2] += dv[2] + w[0] * r[1] - w[1] * r[0];
    }
}

int stf_fluid_remove_inside(stf_fluid *f, int id)
{
    /* Particles closer than half a spacing would be thrown out on the first step. */
    double margin = 0.5 * f->def.spacing;
    int m = 0;
    int32_t *perm = malloc((size_t)(f->n > 0 ? f->n : 1) * sizeof *perm);
    if (!perm) return -1;
    for (int i = 0; i < f->n; i++) {
        double nrm[3];
        if (stf_collider_sdf(&f->colliders[id], f->x + 3 * i, nrm) >= margin) perm[m++] = i;
    }
    int removed = f->n - m;
    if (removed) {
        f->n = m; /* keep the first m of perm; springs to the others are dropped */
        if (stf_fluid_permute(f, perm) != 0) removed = -1;
    }
    free(perm);
    return removed;
}

/* ------------------------------------------------------------------ permutation */

static void permute_vec3(double *a, double *tmp, const int32_t *perm, int n)
{
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++)
        for (int c = 0; c < 3; c++) tmp[3 * i + c] = a[3 * perm[i] + c];
    memcpy(a, tmp, (size_t)n * 3 * sizeof *a);
}

int stf_fluid_permute(stf_fluid *f, const int32_t *perm)
{
    int n = f->n;
    int32_t *inv = malloc((size_t)f->cap * sizeof *inv);
    int32_t *ids = malloc((size_t)f->cap * sizeof *ids);
    if (!inv || !ids) {
        free(inv);
        free(ids);
        return -1;
    }
    permute_vec3(f->x, f->dx, perm, n);
    permute_vec3(f->v, f->dx, perm, n);
    permute_vec3(f->xprev, f->dx, perm, n);
    for (int i = 0; i < f->cap; i++) inv[i] = -1;
    for (int i = 0; i < n; i++) {
        ids[i] = f->id[perm[i]];
        inv[perm[i]] = i;
    }
    memcpy(f->id, ids, (size_t)n * sizeof *ids);
    if (f->khist_mean) {
        float *k = (float *)ids;
        for (int i = 0; i < n; i++) k[i] = f->khist_mean[perm[i]];
        memcpy(f->khist_mean, k, (size_t)n * sizeof *k);
    }
    if (f->Dprev && f->Dprev_ok) {
        double *t = malloc(3 * (size_t)n * sizeof *t + 1);
        if (!t) return -1;
        for (int i = 0; i < n; i++)
            for (int a = 0; a < 3; a++) t[3 * i + a] = f->Dprev[3 * (size_t)perm[i] + (size_t)a];
        memcpy(f->Dprev, t, 3 * (size_t)n * sizeof *t);
        free(t);
    }
    if (f->springs.n_alloc) stf_springs_permute(&f->springs, perm, inv, n);
    grid_invalidate(&f->grid); /* its candidate lists hold the old indices */
    int rc = f->hist.n_alloc ? stf_history_permute(&f->hist, perm, n) : 0;
    free(inv);
    free(ids);
    return rc;
}

/* --------------------------------------------------------------------- the step */

/* A particle is bad when its state is not finite, or when it would cross ten interaction
 * radii in one step: no stable run does that (the relaxation reaches a few neighbours per
 * step), so it is a blow-up caught before it turns into NaN. */
static int first_bad(const stf_fluid *f, double vmax)
{
    int n = f->n, bad = n;
    const double *x = f->x, *v = f->v, *xp = f->xprev;
    double v2max = vmax * vmax, d2max = v2max * (f->dt_now * f->dt_now);
    /* Comparisons that are false for NaN: a non-finite velocity fails the first, a
       non-finite position the second (xprev was checked a stage earlier, so it is finite).
       No branch and no division: this runs after every stage. */
#pragma omp parallel for schedule(static) reduction(min : bad)
    for (int i = 0; i < n; i++) {
        double v2 = v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2];
        double dx = x[3 * i] - xp[3 * i], dy = x[3 * i + 1] - xp[3 * i + 1],
               dz = x[3 * i + 2] - xp[3 * i + 2];
        double d2 = dx * dx + dy * dy + dz * dz;
        int ok = (v2 <= v2max) & (d2 <= d2max);
        bad = ok || bad < i ? bad : i;
    }
    return bad < n ? bad : -1;
}

int stf_fluid_check(stf_fluid *f, const char *effect)
{
    double vmax = 10.0 * f->h / f->dt_now;
    int i = first_bad(f, vmax);
    if (i < 0) return 0;
    const double *v = f->v + 3 * i, *x = f->x + 3 * i, *xp = f->xprev + 3 * i;
    double speed = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) +
                   sqrt((x[0] - xp[0]) * (x[0] - xp[0]) + (x[1] - xp[1]) * (x[1] - xp[1]) +
                        (x[2] - xp[2]) * (x[2] - xp[2]));
    snprintf(f->failure, sizeof f->failure,
             "step %ld (t = %.6g s): particle %d (id %d) %s after effect '%s'", f->steps + 1,
             f->time, i, f->id[i],
             isfinite(speed) && isfinite(f->x[3 * i]) && isfinite(f->x[3 * i + 1]) &&
                     isfinite(f->x[3 * i + 2])
                 ? "blew up (moves more than 10 h in a step)"
                 : "has a non-finite position or velocity",
             effect);
    return -1;
}

static int start_history(stf_fluid *f, double dt)
{
    if (f->def.history_mode == STF_HISTORY_SOE)
        return stf_history_soe_init(&f->hist, f->def.q, f->def.terms, f->cap > 0 ? f->cap : 1);
    int window = 0;
    if (f->def.history_mode == STF_HISTORY_WINDOW)
        window = f->def.memory > 0 ? (int)lround(f->def.memory / dt) : f->def.d;
    if (window < 1 && f->def.history_mode == STF_HISTORY_WINDOW) window = 1;
    return stf_history_init(&f->hist, f->def.q, window, f->cap > 0 ? f->cap : 1);
}

void stf_fluid_smoothed_velocity(const stf_fluid *f, double *out)
{
    int n = f->n;
    const double *x = f->x, *v = f->v;
    double inv_h = 1.0 / f->h;
#pragma omp parallel for schedule(dynamic, 256)
    for (int i = 0; i < n; i++) {
        const int32_t *nb = grid_row(&f->grid, i);
        double w0 = 1.0, sx = v[3 * i], sy = v[3 * i + 1], sz = v[3 * i + 2];
        for (int k = 0; k < f->grid.count[i]; k++) {
            int j = nb[k];
            double rx = x[3 * j] - x[3 * i], ry = x[3 * j + 1] - x[3 * i + 1], rz = x[3 * j + 2] - x[3 * i + 2];
            double q = sqrt(rx * rx + ry * ry + rz * rz) * inv_h;
            if (q >= 1.0) continue;
            double w = (1.0 - q) * (1.0 - q);
            w0 += w;
            sx += w * v[3 * j], sy += w * v[3 * j + 1], sz += w * v[3 * j + 2];
        }
        out[3 * i] = sx / w0, out[3 * i + 1] = sy / w0, out[3 * i + 2] = sz / w0;
    }
}

static int reorder_by_cell(stf_fluid *f)
{
    /* The grid's bucket order keeps each cell's particles together in memory. */
    stf_cy_follow_order(f, f->grid.order); /* the projection's warm start (none: no-op) */
    return stf_fluid_permute(f, f->grid.order);
}

static void gravity_apply(stf_fluid *f, double dt)
{
    const double *g = f->def.gravity;
    int n = f->n;
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) f->v[3 * i + a] += dt * g[a];
}

#define TIMED(stage, call)                                                                    \
    do {                                                                                      \
        double t0_ = omp_get_wtime();                                                         \
        call;                                                                                 \
        f->stage_seconds[stage] += omp_get_wtime() - t0_;                                     \
    } while (0)

int stf_fluid_step(stf_fluid *f, double dt)
{
    if (f->failure[0]) return -1;
    int n = f->n;
    f->dt_now = dt;
    for (int k = 0; k < f->ncolliders; k++) {
        memset(f->colliders[k].impulse, 0, sizeof f->colliders[k].impulse);
        memset(f->colliders[k].moment, 0, sizeof f->colliders[k].moment);
        memset(f->colliders[k].shift, 0, sizeof f->colliders[k].shift);
        memset(f->colliders[k].part, 0, sizeof f->colliders[k].part);
    }
    if (f->def.model == STF_MODEL_CARREAU_YASUDA) return stf_cy_step(f, dt);
    if (has(f, STF_EFFECT_HISTORY) && f->hist.w == NULL && start_history(f, dt) != 0) goto oom;
    TIMED(STAGE_GRID, {
        /* Particles are re-sorted by cell (memory locality) when the neighbour candidates
           are rebuilt anyway, at most every reorder_interval steps: particles that stay put
           stay in order and keep their candidate lists. */
        if (stf_grid_due(&f->grid, f->x, n, f->h) && f->steps >= f->next_reorder) {
            if (stf_grid_sort(&f->grid, f->x, n, f->h) != 0 || reorder_by_cell(f) != 0) goto oom;
            f->next_reorder = f->steps + f->reorder_interval;
        }
        if (stf_grid_build_checked(&f->grid, f->x, n, f->h) != 0) goto oom; /* moves checked once */
    });
    if (has(f, STF_EFFECT_HISTORY) && f->def.k_hist > 0) { /* k_hist = 0: D is never read */
        TIMED(STAGE_HISTORY, {
            const double *vh = f->v;
            if (f->def.history_velocity == STF_HISTORY_SMOOTHED) {
                int rc = 0;
                if (f->def.history_smoothing > 0) rc = stf_fluid_field_velocity(f, f->dx);
                else stf_fluid_smoothed_velocity(f, f->dx);
                if (rc == -1) return -1;
                if (rc != 0) goto oom;
                vh = f->dx;
            }
            if (stf_history_push(&f->hist, vh, n) != 0) goto oom;
            stf_history_derivative(&f->hist, n);
            if (f->Dprev && !f->Dprev_ok) { /* the first step: no stiffness before it */
                memcpy(f->Dprev, f->hist.D, 3 * (size_t)n * sizeof *f->Dprev);
                f->Dprev_ok = 1;
            }
        });
    }
    if (has(f, STF_EFFECT_GRAVITY)) {
        TIMED(STAGE_GRAVITY, gravity_apply(f, dt));
    }
    if (has(f, STF_EFFECT_VISCOSITY)) {
        TIMED(STAGE_VISCOSITY, stf_viscosity_apply(f, dt));
        if (stf_fluid_check(f, "viscosity")) return -1;
    }
#pragma omp parallel for schedule(static)
    for (int i = 0; i < 3 * n; i++) {
        f->xprev[i] = f->x[i];
        f->x[i] += dt * f->v[i];
    }
    if (has(f, STF_EFFECT_SPRINGS)) {
        int rc = 0;
        TIMED(STAGE_SPRINGS, rc = stf_springs_step(f, dt));
        if (rc != 0) goto oom;
        if (f->Dprev_ok) /* springs.passive: this step's D is the next step's "before" */
            memcpy(f->Dprev, f->hist.D, 3 * (size_t)n * sizeof *f->Dprev);
        if (stf_fluid_check(f, has(f, STF_EFFECT_HISTORY) ? "history springs" : "springs")) return -1;
    }
    if (has(f, STF_EFFECT_PRESSURE)) {
        int rc = 0;
        if (projects(f)) TIMED(STAGE_PRESSURE, rc = stf_cy_pressure_stage(f, dt));
        else TIMED(STAGE_PRESSURE, stf_pressure_relax(f, dt));
        if (rc != 0) goto oom;
        if (stf_fluid_check(f, projects(f) ? "pressure (projection)" : "pressure")) return -1;
    }
    TIMED(STAGE_COLLIDE, stf_collide_all(f, dt));
#pragma omp parallel for schedule(static)
    for (int i = 0; i < 3 * n; i++) f->v[i] = (f->x[i] - f->xprev[i]) / dt;
    if (stf_fluid_check(f, "collisions")) return -1;
    if (has(f, STF_EFFECT_BOUNDARY_STICK)) {
        TIMED(STAGE_BOUNDARY, stf_boundary_stick(f, dt));
        if (stf_fluid_check(f, "boundary_stick")) return -1;
    }
    f->time += dt;
    f->steps++;
    return 0;
oom:
    snprintf(f->failure, sizeof f->failure, "step %ld (t = %.6g s): out of memory", f->steps + 1,
             f->time);
    return -1;
}

const char *stf_fluid_failure(const stf_fluid *f) { return f->failure; }

/* ------------------------------------------------------------------ read access */

int stf_fluid_count(const stf_fluid *f) { return f->n; }
int stf_fluid_collider_count(const stf_fluid *f) { return f->ncolliders; }
double stf_fluid_particle_mass(const stf_fluid *f) { return f->mass; }
double stf_fluid_time(const stf_fluid *f) { return f->time; }
long stf_fluid_steps(const stf_fluid *f) { return f->steps; }
void stf_fluid_get_positions(const stf_fluid *f, double *x) { memcpy(x, f->x, (size_t)f->n * 3 * sizeof *x); }
void stf_fluid_get_velocities(const stf_fluid *f, double *v) { memcpy(v, f->v, (size_t)f->n * 3 * sizeof *v); }
void stf_fluid_scale_velocities(stf_fluid *f, double factor)
{
    for (int i = 0; i < 3 * f->n; i++) f->v[i] *= factor;
}

void stf_fluid_hold_collider(stf_fluid *f, int id)
{
    memset(f->colliders[id].vel, 0, sizeof f->colliders[id].vel);
    memset(f->colliders[id].angvel, 0, sizeof f->colliders[id].angvel);
}

void stf_fluid_reset_clock(stf_fluid *f)
{
    f->time = 0;
    f->steps = 0;
    f->next_reorder = 0;
}

void stf_fluid_forget_history(stf_fluid *f)
{
    if (f->hist.n_alloc || f->hist.w) stf_history_free(&f->hist); /* re-made at the next step */
    f->Dprev_ok = 0;
    if (f->khist_mean) memset(f->khist_mean, 0, (size_t)f->cap * sizeof *f->khist_mean);
}

void stf_fluid_get_ids(const stf_fluid *f, int32_t *id) { memcpy(id, f->id, (size_t)f->n * sizeof *id); }

void stf_fluid_get_history_stiffness(const stf_fluid *f, float *k)
{
    if (f->khist_mean) memcpy(k, f->khist_mean, (size_t)f->n * sizeof *k);
    else memset(k, 0, (size_t)f->n * sizeof *k);
}

long stf_fluid_spring_count(const stf_fluid *f)
{
    return f->springs.n_alloc ? stf_springs_total(&f->springs, f->n) : 0;
}

double stf_fluid_max_speed(const stf_fluid *f)
{
    double m2 = 0;
    int n = f->n;
#pragma omp parallel for schedule(static) reduction(max : m2)
    for (int i = 0; i < n; i++) {
        const double *v = f->v + 3 * i;
        double s2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
        if (s2 > m2) m2 = s2;
    }
    return sqrt(m2);
}

double stf_fluid_spring_gain(const stf_fluid *f)
{
    /* compliant constraints (gauss_seidel.c) are stable at any gain: nothing limits the step */
    return f->springs.n_alloc && !f->gs ? f->springs.max_gain : 0;
}
double stf_fluid_last_dt(const stf_fluid *f) { return f->dt_now; }

double stf_fluid_pressure_stiffness(const stf_fluid *f)
{
    if (!has(f, STF_EFFECT_PRESSURE) || projects(f) || !f->rho || f->steps == 0) return 0;
    double m = 0;
    int n = f->n;
#pragma omp parallel for schedule(static) reduction(max : m)
    for (int i = 0; i < n; i++) {
        double p = f->rho[i] + 2.0 * f->rho_near[i]; /* pressures (stf_pressure_relax) */
        if (p > m) m = p;
    }
    return m / f->h;
}

void stf_fluid_get_def(const stf_fluid *f, stf_fluid_def *def) { *def = f->def; }

long stf_fluid_saturated_steps(const stf_fluid *f)
{
    return f->springs.n_alloc ? f->springs.saturated_steps : 0;
}

int stf_fluid_history_steps(const stf_fluid *f)
{
    if (!has(f, STF_EFFECT_HISTORY)) return 0;
    if (f->hist.w) return f->hist.window > 0 ? f->hist.window : (int)f->hist.pushed;
    return f->def.d;
}

size_t stf_fluid_effect_bytes(const stf_fluid *f, unsigned effect)
{
    switch (effect) {
    case STF_EFFECT_PRESSURE: return f->rho ? 2 * (size_t)f->cap * sizeof(double) : 0;
    case STF_EFFECT_SPRINGS: return f->springs.n_alloc ? stf_springs_bytes(&f->springs) : 0;
    case STF_EFFECT_HISTORY:
        return (f->hist.n_alloc ? stf_history_bytes(&f->hist) : 0) +
               (f->khist_mean ? (size_t)f->cap * sizeof(float) : 0);
    default: return 0; /* gravity, viscosity and boundary_stick keep no storage */
    }
}

double stf_fluid_effect_seconds(const stf_fluid *f, unsigned effect)
{
    switch (effect) {
    case STF_EFFECT_GRAVITY: return f->stage_seconds[STAGE_GRAVITY];
    case STF_EFFECT_VISCOSITY: return f->stage_seconds[STAGE_VISCOSITY];
    case STF_EFFECT_PRESSURE: return f->stage_seconds[STAGE_PRESSURE];
    case STF_EFFECT_SPRINGS: return f->stage_seconds[STAGE_SPRINGS];
    case STF_EFFECT_HISTORY: return f->stage_seconds[STAGE_HISTORY];
    case STF_EFFECT_BOUNDARY_STICK: return f->stage_seconds[STAGE_BOUNDARY];
    default: return 0;
    }
}

int stf_fluid_describe(const stf_fluid *f, char *buf, size_t len)
{
    const stf_fluid_def *d = &f->def;
    if (d->model == STF_MODEL_CARREAU_YASUDA) {
        int k = snprintf(buf, len,
                         "effects: [%s]\nspacing: %.9g  # m\nh: %.9g  # m\ndensity: %.9g  # kg/m^3\n"
                         "particle_mass: %.9g  # kg\njitter: %.9g  # spacings\n"
                         "gravity: [%.9g, %.9g, %.9g]  # m/s^2\n",
                         has(f, STF_EFFECT_GRAVITY) ? "gravity" : "", d->spacing, f->h, d->density,
                         f->mass, d->jitter, d->gravity[0], d->gravity[1], d->gravity[2]);
        size_t used = k > 0 && (size_t)k < len ? (size_t)k : len;
        return k + stf_cy_describe(f, buf + used, len - used);
    }
    static const char *const names[] = {"gravity", "viscosity", "pressure", "springs", "history",
                                        "boundary_stick"};
    char effects[128] = "";
    for (int k = 0; k < 6; k++)
        if (d->effects & (1u << k)) {
            strcat(effects, effects[0] ? ", " : "");
            strcat(effects, names[k]);
        }
    int w = snprintf(
        buf, len,
        "effects: [%s]\nspacing: %.9g  # m\nmaterial_spacing: %.9g  # m (the material's; the "
        "stiffnesses below are scaled to spacing)\nh: %.9g  # m\ndensity: %.9g  # kg/m^3\n"
        "particle_mass: %.9g  # kg\njitter: %.9g  # spacings\ngravity: [%.9g, %.9g, %.9g]  # m/s^2\n"
        "sigma: %.9g  # 1/s\nbeta: %.9g  # 1/m\nk: %.9g  # m/s^2\nk_near: %.9g  # m/s^2\n"
        "tension: %s\nrest: %s\nwall: %s\nrest_density: %.9g  # kernel sum\nrest_near_density: %.9g  # kernel sum\n"
        "k_min: %.9g  # 1/s^2\nyield_ratio: %.9g\nplasticity: %.9g  # 1/s\nliquid_plasticity: %.9g  # 1/s\n"
        "relaxation: %s\niterations: %d\nspring_damping: %.9g  # s\nspring_passive: %s\nq: %.9g\n"
        "history_mode: %s\nhistory_velocity: %s\nhistory_smoothing: %.9g  # m (0: the kernel's neighbours)\nhistory_steps: %d  # at the first step (with memory: memory / dt)\n"
        "memory: %.9g  # s (0: history_steps as given)\nk_hist: %.9g  # 1/s^2 per m/s^q\n"
        "reference_spacing: %.9g  # m\nk_onset: %.9g  # 1/s^2\n"
        "stick: %.9g  # 1/s\n",
        effects, d->spacing, d->material_spacing, f->h, d->density, f->mass, d->jitter, d->gravity[0], d->gravity[1],
        d->gravity[2], d->sigma, d->beta, d->k, d->k_near, d->tension ? "true" : "false",
        d->rest_packing == STF_REST_LIQUID ? "liquid" : "lattice",
        d->relax_wall == STF_RELAX_WALL_GHOST ? "ghost" : "mirror", f->rest_density, f->rest_near, d->k_min, d->yield_ratio, d->plasticity,
        d->liquid_plasticity >= 0 ? d->liquid_plasticity : d->plasticity,
        d->relaxation == STF_RELAX_GAUSS_SEIDEL ? "gauss_seidel" : "jacobi", d->iterations,
        d->spring_damping, d->spring_passive ? "true" : "false", d->q,
        d->history_mode == STF_HISTORY_FULL  ? "full"
        : d->history_mode == STF_HISTORY_SOE ? "soe"
                                             : "window",
        d->history_velocity == STF_HISTORY_SMOOTHED ? "smoothed" : "particle", d->history_smoothing,
        stf_fluid_history_steps(f), d->memory,
        d->k_hist, d->reference_spacing, d->k_onset, d->stick);
    if (projects(f) && w >= 0 && (size_t)w < len)
        w += snprintf(buf + w, len - (size_t)w,
                      "pressure_mode: projection  # k, k_near, rest_density unused\n"
                      "pressure_eta: %.9g\npressure_solver: %s\npressure_wall_pressure: %s\n"
                      "pressure_gradient: %s\n"
                      "pressure_iterations: [%d, %d]\npressure_warm_start: %.9g\n"
                      "projection_rest_density: %.9g  # kg/m^3, the cubic spline's lattice sum\n",
                      d->cy.eta, stf_pressure_solver_name(d->cy.pressure_solver),
                      stf_wall_pressure_name(d->cy.wall_pressure),
                      stf_pressure_gradient_name(d->cy.pressure_gradient),
                      d->cy.min_pressure_iterations, d->cy.max_pressure_iterations,
                      d->cy.warm_start, stf_fluid_cy_rest_density(f));
    if (d->history_mode == STF_HISTORY_SOE && w >= 0 && (size_t)w < len)
        w += snprintf(buf + w, len - (size_t)w, "history_terms: %d  # exponentials\n", d->terms);
    return w;
}

uint64_t stf_fluid_hash(const stf_fluid *f)
{
    /* In id order, so the periodic re-sorting of particles does not change the hash. */
    uint64_t h = 1469598103934665603ull;
    int32_t *where = malloc((size_t)(f->next_id > 0 ? f->next_id : 1) * sizeof *where);
    if (!where) return 0;
    for (int k = 0; k < f->next_id; k++) where[k] = -1;
    for (int i = 0; i < f->n; i++) where[f->id[i]] = i;
    for (int k = 0; k < f->next_id; k++) {
        if (where[k] < 0) continue;
        const unsigned char *p = (const unsigned char *)(f->x + 3 * where[k]);
        for (size_t b = 0; b < 3 * sizeof(double); b++) h = (h ^ p[b]) * 1099511628211ull;
        p = (const unsigned char *)(f->v + 3 * where[k]);
        for (size_t b = 0; b < 3 * sizeof(double); b++) h = (h ^ p[b]) * 1099511628211ull;
    }
    free(where);
    return h;
}
