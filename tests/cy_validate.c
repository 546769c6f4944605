/* cy_validate.c - physics validation of the Carreau-Yasuda model (src/cy*.c).
 *
 *   cy_validate hydrostatic   pressure at depth vs rho g h; mean density error below eta
 *   cy_validate poiseuille    plane Poiseuille flow (periodic channel, body force) for a
 *                             Newtonian, a shear-thinning and a shear-thickening fluid, against
 *                             the profile from eta(g) g = G |y| solved across the channel
 *   cy_validate floating      a box floating in water (ODE body): draft vs Archimedes
 *   cy_validate stability     dt = 3e-4 s: the explicit viscosity blows up (detected, with
 *                             a message naming the step), the implicit one stays bounded
 *   cy_validate dambreak      a 2:1 dam break against Martin & Moyce (1952)
 * A last argument `central` runs the case with viscosity_form central (default morris).
 * Each prints its measured figures and returns non-zero when a check fails. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "stf_ode.h"
#include "stf_sim.h"
#include "test_util.h"

static stf_fluid_def cy_def(double spacing)
{
    stf_fluid_def d = stf_default_fluid_def();
    d.model = STF_MODEL_CARREAU_YASUDA;
    d.effects = STF_EFFECT_GRAVITY;
    d.spacing = spacing;
    d.density = 1000;
    d.jitter = 0;
    return d;
}

/* The viscous operator of every case (the last argument `central`, else morris). */
static int g_form = STF_VISCOSITY_MORRIS;

static stf_fluid *make(const stf_fluid_def *def)
{
    char err[256];
    stf_fluid *f;
    stf_fluid_def d[1] = {*def};
    d->cy.viscosity_form = g_form;
    if (stf_fluid_create(d, &f, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        exit(2);
    }
    return f;
}

static __attribute__((unused)) int add_container(stf_fluid *f, double hx, double hy, double hz)
{
    stf_collider_def c = stf_default_collider_def();
    c.shape = STF_SHAPE_CONTAINER;
    c.half[0] = hx, c.half[1] = hy, c.half[2] = hz;
    c.wall = 0.02;
    c.friction = 0;
    char err[256];
    int id = stf_fluid_add_collider(f, &c, err, sizeof err);
    double pos[3] = {0, 0, 0}, rot[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, z[3] = {0, 0, 0};
    stf_fluid_set_collider_state(f, id, pos, rot, z, z);
    return id;
}

/* ------------------------------------------------------------------- hydrostatic */

/* A 0.4 m layer of a viscous liquid (nu = 0.05 m^2/s, so it settles within the run) on a
 * floor, periodic sideways (a laterally infinite layer: side walls would carry part of the
 * weight by viscous friction while the layer settles). After 1 s the pressure, averaged
 * over the last 0.3 s in depth bins of two spacings, must be rho0 g depth within 6% of
 * rho0 g H, and the mean density error of every step after the first 0.1 s below eta. */
static int hydrostatic(void)
{
    const double s = 0.02, H = 0.4, g = 9.81, L = 0.2, dt = 1e-3;
    stf_fluid_def d = cy_def(s);
    d.cy.mu0 = d.cy.mu_inf = 0.05;
    d.periodic[0] = d.periodic[1] = L;
    d.periodic_origin[0] = d.periodic_origin[1] = -L / 2;
    stf_fluid *f = make(&d);
    stf_collider_def c = stf_default_collider_def();
    c.shape = STF_SHAPE_PLANE; /* the floor z = 0 */
    c.friction = 0;
    char err[256];
    int id = stf_fluid_add_collider(f, &c, err, sizeof err);
    double pos[3] = {0, 0, 0}, rot[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, z[3] = {0, 0, 0};
    stf_fluid_set_collider_state(f, id, pos, rot, z, z);
    stf_fluid_add_block(f, (double[3]){-L / 2, -L / 2, 0}, (double[3]){L / 2, L / 2, H}, z);
    int n = stf_fluid_count(f), steps = 1000, avg_from = 700;
    enum { NB = 10 };
    double psum[NB] = {0}, zsum[NB] = {0}, cnt[NB] = {0}, worst_err = 0, sum_iter = 0,
           top_sum = 0, floor_force = 0;
    double *x = malloc((size_t)n * 3 * sizeof *x), *v = malloc((size_t)n * 3 * sizeof *v),
           *p = malloc((size_t)n * sizeof *p);
    double rho0 = stf_fluid_cy_rest_density(f), vmax = 0;
    for (int k = 0; k < steps; k++) {
        if (stf_fluid_step(f, dt) != 0) {
            fprintf(stderr, "%s\n", stf_fluid_failure(f));
            return 1;
        }
        stf_solver_stats st;
        stf_fluid_solver_stats(f, &st);
        if (k >= 100 && st.density_error > worst_err) worst_err = st.density_error;
        sum_iter += st.pressure_iterations;
        if (k < avg_from) continue;
        stf_fluid_get_positions(f, x);
        stf_fluid_get_pressures(f, p);
        double top = -1e9;
        for (int i = 0; i < n; i++) top = x[3 * i + 2] > top ? x[3 * i + 2] : top;
        top_sum += top;
        for (int i = 0; i < n; i++) {
            int b = (int)(x[3 * i + 2] / (2 * s));
            if (b < 0 || b >= NB) continue;
            psum[b] += p[i], zsum[b] += x[3 * i + 2], cnt[b]++;
        }
        double J[3], M[3];
        stf_fluid_collider_impulse(f, id, J, M);
        floor_force -= J[2] / dt;
    }
    stf_fluid_get_velocities(f, v);
    for (int i = 0; i < n; i++) {
        double sp = sqrt(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
        vmax = sp > vmax ? sp : vmax;
    }
    int navg = steps - avg_from;
    /* the free surface: half a spacing above the top particle */
    double surface = top_sum / navg + 0.5 * s, worst = 0;
    double weight = n * stf_fluid_particle_mass(f) * g, fl = floor_force / navg;
    printf("hydrostatic: %d particles, rho0 %.2f kg/m^3, surface %.4f m (initial %.4f), final max "
           "speed %.3g m/s, mean pressure iterations %.2f, worst mean density error %.4f%% "
           "(eta %.0f%%), floor force / weight %.4f\n",
           n, rho0, surface, H, vmax, sum_iter / steps, 100 * worst_err, 100 * d.cy.eta, fl / weight);
    printf("  depth (m)   p measured (Pa)   rho0 g depth (Pa)\n");
    for (int b = 0; b < NB; b++) {
        if (!cnt[b]) continue;
        double depth = surface - zsum[b] / cnt[b], expect = rho0 * g * depth, got = psum[b] / cnt[b];
        if (depth < 3 * s) continue; /* the top layers: no full neighbourhood */
        double rel = fabs(got - expect) / (rho0 * g * H);
        worst = rel > worst ? rel : worst;
        printf("  %8.3f   %12.1f   %12.1f\n", depth, got, expect);
    }
    printf("  worst |p - rho0 g depth| / (rho0 g H) = %.3f (tolerance 0.06)\n", worst);
    CHECK(worst < 0.06, "pressure off hydrostatic by %.3f of rho g H", worst);
    CHECK(worst_err < d.cy.eta, "mean density error %.4f above eta", worst_err);
    CHECK(fabs(fl / weight - 1) < 0.02, "the floor carries %.4f of the weight", fl / weight);
    free(x), free(v), free(p);
    stf_fluid_destroy(f);
    return test_result("cy_validate hydrostatic");
}

/* --------------------------------------------------------------------- poiseuille */

/* The steady profile between plates at z = 0 and z = Hc driven by a body force G along x:
 * the shear stress at distance y from the mid-plane is G y (per unit density), so the shear
 * rate solves nu(g) g = G |y| (bisection; nu(g) g grows with g for every n > 0), and
 * u(y) = integral of g from |y| to Hc/2. Tabulated on m + 1 points, y = Hc/2 * k/m. */
static void reference_profile(const stf_cy_def *cy, double G, double Hc, int m, double *u)
{
    double *gam = malloc((size_t)(m + 1) * sizeof *gam);
    for (int k = 0; k <= m; k++) {
        double tau = G * Hc / 2 * k / m, lo = 0, hi = 1;
        while (stf_cy_viscosity(cy, hi) * hi < tau) hi *= 2;
        for (int it = 0; it < 200; it++) {
            double mid = 0.5 * (lo + hi);
            if (stf_cy_viscosity(cy, mid) * mid < tau) lo = mid;
            else hi = mid;
        }
        gam[k] = 0.5 * (lo + hi);
    }
    u[m] = 0; /* at the wall */
    for (int k = m - 1; k >= 0; k--) u[k] = u[k + 1] + 0.5 * (gam[k] + gam[k + 1]) * Hc / 2 / m;
    free(gam);
}

static double profile_at(const double *u, int m, double Hc, double z)
{
    double y = fabs(z - Hc / 2) / (Hc / 2) * m;
    int k = (int)y;
    if (k >= m) return u[m];
    return u[k] + (y - k) * (u[k + 1] - u[k]);
}

static int poiseuille_case(const char *name, stf_cy_def cy, double G, double tol, double shape_tol)
{
    const double s = 0.02, Hc = 0.2, Lx = 0.16, Ly = 0.12, dt = 1e-3, T = 1.0;
    stf_fluid_def d = cy_def(s);
    d.cy = cy;
    d.gravity[0] = G, d.gravity[1] = 0, d.gravity[2] = 0; /* the driving body force */
    d.periodic[0] = Lx, d.periodic[1] = Ly;
    stf_fluid *f = make(&d);
    double rot[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, zero[3] = {0, 0, 0};
    for (int w = 0; w < 2; w++) { /* floor z > 0 free; ceiling z < Hc free */
        stf_collider_def c = stf_default_collider_def();
        c.shape = STF_SHAPE_PLANE;
        c.friction = 0;
        c.normal[2] = w ? -1 : 1;
        c.offset = w ? -Hc : 0;
        char err[256];
        int id = stf_fluid_add_collider(f, &c, err, sizeof err);
        stf_fluid_set_collider_state(f, id, zero, rot, zero, zero);
    }
    stf_fluid_add_block(f, (double[3]){0, 0, 0}, (double[3]){Lx, Ly, Hc}, zero);
    int n = stf_fluid_count(f), steps = (int)lround(T / dt), avg_from = steps - 200;
    enum { NL = 10, M = 2000 };
    double usum[NL] = {0}, zsum[NL] = {0}, cnt[NL] = {0}, cg = 0, res = 0;
    double *x = malloc((size_t)n * 3 * sizeof *x), *v = malloc((size_t)n * 3 * sizeof *v);
    for (int k = 0; k < steps; k++) {
        if (stf_fluid_step(f, dt) != 0) {
            fprintf(stderr, "%s: %s\n", name, stf_fluid_failure(f));
            return 1;
        }
        stf_solver_stats st;
        stf_fluid_solver_stats(f, &st);
        cg += st.viscosity_iterations;
        res = st.viscosity_residual > res ? st.viscosity_residual : res;
        if (k < avg_from) continue;
        stf_fluid_get_positions(f, x);
        stf_fluid_get_velocities(f, v);
        for (int i = 0; i < n; i++) {
            int b = (int)(x[3 * i + 2] / Hc * NL);
            if (b < 0 || b >= NL) continue;
            usum[b] += v[3 * i], zsum[b] += x[3 * i + 2], cnt[b]++;
        }
    }
    double u[M + 1];
    reference_profile(&cy, G, Hc, M, u);
    double worst = 0, shape = 0, ucen = 0, zc[NL], uc[NL];
    for (int b = 0; b < NL; b++) {
        zc[b] = cnt[b] ? zsum[b] / cnt[b] : 0;
        uc[b] = cnt[b] ? usum[b] / cnt[b] : 0;
        ucen = uc[b] > ucen ? uc[b] : ucen;
    }
    printf("poiseuille %s: n = %g, %d particles, %.1f CG iterations per step (tolerance %g, "
           "worst final residual %.2g)\n   z (m)    u (m/s)   reference (m/s)\n",
           name, cy.n, n, cg / steps, cy.cg_tolerance, res);
    for (int b = 0; b < NL; b++) {
        if (!cnt[b]) continue;
        double z = zsum[b] / cnt[b], got = usum[b] / cnt[b], ref = profile_at(u, M, Hc, z);
        double e = fabs(got - ref) / u[0];
        worst = e > worst ? e : worst;
        /* the shape: both profiles scaled to their own largest value */
        double es = fabs(got / ucen - ref / profile_at(u, M, Hc, zc[NL / 2]));
        shape = es > shape ? es : shape;
        (void)uc;
        printf("  %6.3f   %8.5f   %8.5f\n", z, got, ref);
    }
    printf("  worst |u - u_ref| / u_ref(centre) = %.3f (tolerance %.2f); shape (each scaled to its "
           "largest value) off by %.3f (tolerance %.2f)\n", worst, tol, shape, shape_tol);
    CHECK(worst < tol, "%s: profile off by %.3f of the centre velocity", name, worst);
    CHECK(shape < shape_tol, "%s: profile shape off by %.3f", name, shape);
    free(x), free(v);
    stf_fluid_destroy(f);
    return 0;
}

/* Newtonian (n = 1), shear thinning (n = 0.5) and shear thickening (n = 1.5) fluids, all
 * through Eq. 3 with K = 10 s (K g >> 1 at the walls: power-law behaviour). */
static int poiseuille(void)
{
    stf_cy_def base = stf_default_fluid_def().cy;
    stf_cy_def newton = base, thin = base, thick = base;
    newton.mu0 = newton.mu_inf = 0.1, newton.n = 1;
    thin.mu0 = 1.0, thin.mu_inf = 0, thin.K = 10, thin.alpha = 2, thin.n = 0.5;
    thick.mu0 = 0.05, thick.mu_inf = 0, thick.K = 10, thick.alpha = 2, thick.n = 1.5;
    int rc = poiseuille_case("newtonian", newton, 2.0, 0.05, 0.03);
    rc |= poiseuille_case("shear-thinning", thin, 2.0, 0.15, 0.05);
    rc |= poiseuille_case("shear-thickening", thick, 2.0, 0.08, 0.05);
    return rc ? rc : test_result("cy_validate poiseuille");
}

/* ----------------------------------------------------------------------- floating */

/* A box of half the water's density in a pool, coupled through ode_glue (an ODE body; the
 * fluid's wall impulses are its only support). After settling (viscous liquid, nu = 0.01
 * m^2/s, so it comes to rest within the run) its draft must be Archimedes' H rho_b/rho_f
 * within half a particle spacing. The draft is measured from the fluid volume: level =
 * (N s^3 + draft A_box) / A_pool (the pool keeps its rest density to eta). */
static int floating(void)
{
    const double s = 0.02, L = 0.32, depth = 0.14, H = 0.1, side = 0.16, dt = 1e-3;
    stf_fluid_def d = cy_def(s);
    d.cy.mu0 = d.cy.mu_inf = 0.01;
    stf_fluid *f = make(&d);
    dInitODE2(0);
    dWorldID w = dWorldCreate();
    dSpaceID sp = dHashSpaceCreate(0);
    dWorldSetGravity(w, 0, 0, d.gravity[2]);
    stf_fluid_add_block(f, (double[3]){-L / 2, -L / 2, 0}, (double[3]){L / 2, L / 2, depth},
                        (double[3]){0, 0, 0});
    stf_ode *c = stf_ode_create(w, sp, f);
    char err[256];
    CHECK(stf_ode_attach_container(c, 0, (double[3]){0, 0, 0}, (double[3]){L, L, 3 * depth}, 0.02,
                                   NULL, err, sizeof err) == 0, "%s", err);
    const double rho_f = d.density, rho_b = 0.5 * rho_f;
    dBodyID box = dBodyCreate(w);
    dMass m;
    dMassSetBoxTotal(&m, rho_b * side * side * H, side, side, H);
    dBodySetMass(box, &m);
    dBodySetPosition(box, 0, 0, depth + H / 2 + 0.005);
    dGeomSetBody(dCreateBox(sp, side, side, H), box);
    CHECK(stf_ode_attach_body(c, box, NULL, err, sizeof err) == 0, "%s", err);
    stf_ode_remove_overlaps(c);
    double zsum = 0, vmax = 0;
    int zn = 0;
    for (int k = 0; k < 2000; k++) {
        if (stf_ode_step(c, dt) != 0) {
            fprintf(stderr, "step %d: %s\n", k, stf_fluid_failure(f));
            return 1;
        }
        if (k >= 1500) {
            zsum += dBodyGetPosition(box)[2], zn++;
            double vz = fabs(dBodyGetLinearVel(box)[2]);
            vmax = vz > vmax ? vz : vmax;
        }
    }
    double zmean = zsum / zn, bottom = zmean - H / 2, A = L * L;
    double vol = stf_fluid_count(f) * s * s * s;
    double draft = (vol / A - bottom) / (1 - side * side / A), want = rho_b / rho_f * H;
    printf("floating box (CY, via ode_glue): %d particles, draft %.4f m, Archimedes %.4f m, "
           "error %.2f spacings (tolerance 0.5), largest |vz| over the last 0.5 s %.3g m/s\n",
           stf_fluid_count(f), draft, want, (draft - want) / s, vmax);
    CHECK(fabs(draft - want) < 0.5 * s, "draft %g m, Archimedes gives %g m", draft, want);
    CHECK(vmax < 0.05, "the box is not at rest: %g m/s", vmax);
    stf_ode_destroy(c);
    stf_fluid_destroy(f);
    dSpaceDestroy(sp);
    dWorldDestroy(w);
    dCloseODE();
    return test_result("cy_validate floating");
}

/* ---------------------------------------------------------------------- stability */

/* The paper's Fig. 4c/4d at test resolution: a column of a viscous shear-thickening fluid
 * (nu0 = 0.2 m^2/s, nu_inf = 0, K = 1 s, alpha = 2, n = 1.5: shear thickening) falls into a box, dt =
 * 3e-4 s. Explicit viscosity is unstable there (nu dt / (h/2)^2 >= 0.15, growing with the shear, above
 * forward Euler's ~0.1): the run must stop with a failure naming the explicit viscosity.
 * The implicit solve must run to the end with every speed below the free-fall speed from
 * the column's top (sqrt(2 g H) ~ 2.7 m/s here, x1.5). */
static int run_column(int solver, double dt, double T, char *why, size_t len, double *vmax_out)
{
    const double s = 0.02;
    stf_fluid_def d = cy_def(s);
    d.cy.mu0 = 0.2, d.cy.mu_inf = 0, d.cy.K = 1.0, d.cy.alpha = 2, d.cy.n = 1.5;
    d.cy.viscosity_solver = solver;
    stf_fluid *f = make(&d);
    add_container(f, 0.15, 0.15, 0.3);
    stf_fluid_add_block(f, (double[3]){-0.15, -0.15, 0}, (double[3]){-0.03, -0.03, 0.36},
                        (double[3]){0, 0, 0});
    int n = stf_fluid_count(f), steps = (int)lround(T / dt), rc = 0;
    double *v = malloc((size_t)n * 3 * sizeof *v), vmax = 0;
    why[0] = 0;
    for (int k = 0; k < steps && rc == 0; k++) {
        if (stf_fluid_step(f, dt) != 0) {
            snprintf(why, len, "%s", stf_fluid_failure(f));
            rc = -1;
            break;
        }
        stf_fluid_get_velocities(f, v);
        for (int i = 0; i < n; i++) {
            double sp = sqrt(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
            vmax = sp > vmax ? sp : vmax;
        }
    }
    *vmax_out = vmax;
    free(v);
    stf_fluid_destroy(f);
    return rc;
}

static int stability(void)
{
    char why[512];
    double vmax;
    int rc = run_column(STF_VISCOSITY_EXPLICIT, 3e-4, 0.5, why, sizeof why, &vmax);
    printf("stability: explicit, dt = 3e-4 s: %s\n", rc ? why : "ran to the end (unexpected)");
    CHECK(rc != 0, "the explicit viscosity did not blow up at dt = 3e-4 s (max speed %g)", vmax);
    CHECK(strstr(why, "viscosity (explicit)") != NULL, "failure does not name the explicit viscosity: %s", why);
    rc = run_column(STF_VISCOSITY_IMPLICIT, 3e-4, 0.5, why, sizeof why, &vmax);
    printf("stability: implicit, dt = 3e-4 s: %s, largest speed %.3f m/s (bound %.2f)\n",
           rc ? why : "ran to the end", vmax, 1.5 * sqrt(2 * 9.81 * 0.36));
    CHECK(rc == 0, "implicit failed: %s", why);
    CHECK(vmax < 1.5 * sqrt(2 * 9.81 * 0.36), "implicit speed %g m/s", vmax);
    return test_result("cy_validate stability");
}

/* ---------------------------------------------------------------------- dam break */

/* Martin & Moyce (1952), Phil. Trans. R. Soc. A 244, plate 1, the 2:1 column (n^2 = 2):
 * surge front Z = x/a against T = t sqrt(2 g / a), a the column's width, as tabulated in
 * the SPH/MPS literature (e.g. Koshizuka & Oka 1996). Plausibility: the front speed of the
 * last points, dZ/dT = 1.3, is v = 1.3 sqrt(2 g a) ~ 1.9 sqrt(g a), close to the 2 sqrt(g a)
 * of shallow-water theory with friction; Ritter's frictionless 2 sqrt(g 2a) would be 2. */
static const double mm_T[] = {0.41, 0.84, 1.19, 1.43, 1.63, 1.83, 1.98, 2.20, 2.32, 2.51, 2.65, 2.83};
static const double mm_Z[] = {1.11, 1.22, 1.44, 1.67, 1.89, 2.11, 2.33, 2.56, 2.78, 3.00, 3.22, 3.44};

/* Water (nu = 1e-6 m^2/s) column a x 2a on a floor against the wall x = 0, quasi-2D
 * (periodic in y, 6 particles deep), released at t = 0. The front: the largest x of a
 * particle within 3 spacings of the floor, plus half a spacing. */
static int dambreak(void)
{
    const double a = 0.1, s = 0.01, g = 9.81, dt = 5e-4, Ly = 0.06;
    stf_fluid_def d = cy_def(s);
    d.cy.mu0 = d.cy.mu_inf = 1e-6;
    d.periodic[1] = Ly;
    stf_fluid *f = make(&d);
    double rot[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, zero[3] = {0, 0, 0};
    char err[256];
    for (int w = 0; w < 2; w++) { /* the floor, and the back wall x = 0 */
        stf_collider_def c = stf_default_collider_def();
        c.shape = STF_SHAPE_PLANE;
        c.friction = 0;
        c.normal[0] = w ? 1 : 0, c.normal[1] = 0, c.normal[2] = w ? 0 : 1;
        int id = stf_fluid_add_collider(f, &c, err, sizeof err);
        stf_fluid_set_collider_state(f, id, zero, rot, zero, zero);
    }
    stf_fluid_add_block(f, (double[3]){0, 0, 0}, (double[3]){a, Ly, 2 * a}, zero);
    int n = stf_fluid_count(f), next = 0, nmm = (int)(sizeof mm_T / sizeof *mm_T);
    double *x = malloc((size_t)n * 3 * sizeof *x), worst = 0, tscale = sqrt(2 * g / a), Zs[16];
    printf("dam break (Martin & Moyce 1952, 2:1 column, a = %.2f m, %d particles, dt = %g s):\n"
           "     T     Z measured   Z Martin-Moyce\n", a, n, dt);
    for (int k = 1; next < nmm; k++) {
        if (stf_fluid_step(f, dt) != 0) {
            fprintf(stderr, "%s\n", stf_fluid_failure(f));
            return 1;
        }
        double T = k * dt * tscale;
        if (T + 1e-9 < mm_T[next]) continue;
        stf_fluid_get_positions(f, x);
        double front = 0;
        for (int i = 0; i < n; i++)
            if (x[3 * i + 2] < 3 * s && x[3 * i] > front) front = x[3 * i];
        double Z = (front + 0.5 * s) / a, e = fabs(Z - mm_Z[next]);
        worst = e > worst ? e : worst;
        printf("  %5.2f   %6.3f       %5.2f\n", T, Z, mm_Z[next]);
        Zs[next++] = Z;
    }
    /* the front speed once the surge is established (T from 1.83 to 2.83) */
    double speed = (Zs[nmm - 1] - Zs[5]) / (mm_T[nmm - 1] - mm_T[5]);
    double mm_speed = (mm_Z[nmm - 1] - mm_Z[5]) / (mm_T[nmm - 1] - mm_T[5]);
    printf("  worst |Z - Z_MM| = %.3f (tolerance 0.35 = 3.5 cm at a = 0.1 m); front speed dZ/dT "
           "for T in [1.83, 2.83] %.3f, Martin & Moyce %.3f (tolerance 15%%)\n", worst, speed, mm_speed);
    /* SPH fronts lead the measured one during the acceleration (T < 1.5), as widely reported
       for this experiment (the gate's opening delayed the release); the offset then stays. */
    CHECK(worst < 0.35, "surge front off Martin & Moyce by %.3f a", worst);
    CHECK(fabs(speed / mm_speed - 1) < 0.15, "front speed %.3f vs %.3f", speed, mm_speed);
    free(x);
    stf_fluid_destroy(f);
    return test_result("cy_validate dambreak");
}

/* scenes/dam_break_3d.yaml (the SPlisHSPlasH benchmark) at a coarse spacing (0.072 m: 13^3 = 2197
 * particles), dt = 0.01 s and cfl = 0.2 so the CFL condition binds in the surge. Holds: every
 * substep's Courant number v_max dt_sub / h is at most cfl (the solver's own figure, and v_max
 * from the velocities before each coupled step times its longest substep), the CFL condition did
 * cut steps, the mean density error over the substeps is at most eta, no particle leaves, and the
 * front advances as a dam break (Martin & Moyce: x/a = 2.1 at t sqrt(2g/a) = 1.83, here t = 0.4 s;
 * the test takes between 1.5 and 2.6). */
static int dam3d(const char *path)
{
    const double T = 0.4, sp = 0.072, cfl = 0.2, g = 9.81;
    stf_override ov[] = {{"fluid.spacing", "0.072"}, {"dt", "0.01"},
                         {"effects.carreau_yasuda.cfl", "0.2"},
                         {"effects.carreau_yasuda.viscosity_form",
                          g_form == STF_VISCOSITY_CENTRAL ? "central" : "morris"}};
    char err[1024];
    stf_scene *sc;
    if (stf_scene_load(path, ov, 4, &sc, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        return 1;
    }
    stf_sim *sim;
    if (stf_sim_create(sc, &sim, err, sizeof err) != 0) {
        fprintf(stderr, "%s\n", err);
        return 1;
    }
    stf_fluid *f = sim->fluid;
    int n = stf_fluid_count(f);
    double *x = malloc(3 * (size_t)n * sizeof *x), *v = malloc(3 * (size_t)n * sizeof *v);
    double h = 2 * sp, x0 = -1e30, a, err_sum = 0, err_max = 0, cn_max = 0, cn_own = 0;
    long substeps = 0, cut = 0;
    stf_fluid_get_positions(f, x);
    double lo = 1e30;
    for (int i = 0; i < n; i++) x0 = fmax(x0, x[3 * i]), lo = fmin(lo, x[3 * i]);
    a = x0 - lo + sp; /* the column's width */
    int steps = (int)lround(T / sc->dt), rc = 0;
    for (int s = 0; s < steps && rc == 0; s++) {
        stf_fluid_get_velocities(f, v);
        double vmax = 0;
        for (int i = 0; i < n; i++)
            vmax = fmax(vmax, sqrt(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]));
        double dt_first = sc->dt / ceil(fmax(1.0, vmax * sc->dt / (cfl * h)) - 1e-12);
        rc = stf_sim_step(sim);
        stf_solver_stats st;
        stf_fluid_solver_stats(f, &st);
        cn_own = fmax(cn_own, st.cfl_number);
        /* the first substep, recomputed here from the velocities before the step */
        cn_max = fmax(cn_max, vmax * fmin(dt_first, st.dt_max) / h);
        CHECK(st.dt_max <= sc->dt * (1 + 1e-12) && st.dt_min > 0, "substep lengths %g %g", st.dt_min, st.dt_max);
        substeps += st.substeps;
        cut += st.substeps > 1;
        err_sum += st.density_error_sum;
        err_max = fmax(err_max, st.density_error_max);
    }
    CHECK(rc == 0, "the run failed: %s", stf_fluid_failure(f));
    stf_fluid_get_positions(f, x);
    double front = -1e30;
    for (int i = 0; i < n; i++) front = fmax(front, x[3 * i]);
    double Z = (front - lo + sp / 2) / a, Tn = T * sqrt(2 * g / a);
    printf("dam3d: %d particles, %ld substeps in %d steps (%ld cut by the CFL condition), "
           "largest Courant number %.3f (solver) %.3f (from the velocities), cfl %.2f\n"
           "dam3d: mean density error %.3f%% (largest %.3f%%, eta %.1f%%); front x/a = %.2f at "
           "T = %.2f (Martin & Moyce 2.11 at 1.83)\n",
           n, substeps, steps, cut, cn_own, cn_max, cfl, 100 * err_sum / (double)substeps,
           100 * err_max, 100 * sc->fluid.cy.eta, Z, Tn);
    CHECK(cn_own <= cfl * (1 + 1e-12), "solver Courant number %g > cfl %g", cn_own, cfl);
    CHECK(cn_max <= cfl * (1 + 1e-9), "Courant number from the velocities %g > cfl %g", cn_max, cfl);
    CHECK(cut > 0, "the CFL condition never cut a step: the test would not test it");
    CHECK(err_sum / (double)substeps <= sc->fluid.cy.eta, "mean density error %g > eta", err_sum / (double)substeps);
    CHECK(Z >= 1.5 && Z <= 2.6, "front x/a = %g at T = %g", Z, Tn);
    double top = sc->container.size[2];
    int escaped = 0;
    for (int i = 0; i < n; i++)
        escaped += fabs(x[3 * i]) > sc->container.size[0] / 2 || fabs(x[3 * i + 1]) > sc->container.size[1] / 2 ||
                   x[3 * i + 2] < 0 || x[3 * i + 2] > top;
    CHECK(escaped == 0, "%d particles left the tank", escaped);
    free(x);
    free(v);
    stf_sim_destroy(sim);
    stf_scene_free(sc);
    return test_result("cy_dam3d");
}

int main(int argc, char **argv)
{
    if (argc > 2 && !strcmp(argv[argc - 1], "central")) g_form = STF_VISCOSITY_CENTRAL, argc--;
    const char *what = argc > 1 ? argv[1] : "";
    if (!strcmp(what, "hydrostatic")) return hydrostatic();
    if (!strcmp(what, "poiseuille")) return poiseuille();
    if (!strcmp(what, "floating")) return floating();
    if (!strcmp(what, "stability")) return stability();
    if (!strcmp(what, "dambreak")) return dambreak();
    if (!strcmp(what, "dam3d") && argc > 2) return dam3d(argv[2]);
    fprintf(stderr, "usage: cy_validate hydrostatic|poiseuille|floating|stability|dambreak|dam3d SCENE"
                    " [central]\n");
    return 2;
}
