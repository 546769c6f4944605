/* stf.h - shear-thickening fluid (STF) simulation: the public API of libstf.
 *
 * A particle fluid after Ozgen, Kallmann & Brown: Clavet-style viscoelastic SPH
 * (double density relaxation, viscosity impulses, plastic springs) whose springs gain a
 * history stiffness k_hist * |D^q x_i - D^q x_j| from a fractional derivative of the
 * particle velocities, plus the boundary treatment of the paper's section 3.3.
 *
 * Units are SI throughout (m, kg, s). The z axis points up (as in ODE scenes).
 *
 *   stf_fluid_def d = stf_default_fluid_def();
 *   d.effects = STF_EFFECT_GRAVITY | STF_EFFECT_PRESSURE;
 *   stf_fluid *f;
 *   if (stf_fluid_create(&d, &f, err, sizeof err) != 0) { puts(err); }
 *   stf_fluid_add_block(f, lo, hi, v0);
 *   stf_fluid_step(f, 1e-3);
 *   stf_fluid_destroy(f);
 */
#ifndef STF_H
#define STF_H

#include <stddef.h>
#include <stdint.h>

/* STF_API marks the library's public functions: the only symbols a shared libstf,
 * libstf_ode or libstf_io exports (the libraries are built with hidden visibility). */
#ifndef STF_API
#if defined(__GNUC__) || defined(__clang__)
#define STF_API __attribute__((visibility("default")))
#else
#define STF_API
#endif
#endif

#ifdef __cplusplus
extern "C" {
#endif

#define STF_VERSION "0.1.0"

/* Effects: stages of the step. An effect not named is not run and allocates nothing. */
enum stf_effect {
    STF_EFFECT_GRAVITY = 1u << 0,        /* constant body acceleration */
    STF_EFFECT_VISCOSITY = 1u << 1,      /* Clavet's pairwise viscosity impulses */
    STF_EFFECT_PRESSURE = 1u << 2,       /* double density relaxation */
    STF_EFFECT_SPRINGS = 1u << 3,        /* plastic springs (Clavet) */
    STF_EFFECT_HISTORY = 1u << 4,        /* history stiffness on the springs (Eq. 2-6) */
    STF_EFFECT_BOUNDARY_STICK = 1u << 5, /* section 3.3 tangential damping at walls */
};

/* How the fractional derivative's history is kept. */
enum stf_history_mode {
    STF_HISTORY_WINDOW = 0, /* exact Eq. 3 over the last d steps (12 n d bytes) */
    STF_HISTORY_FULL = 1,   /* exact Eq. 3 over every past step (memory grows with steps) */
    STF_HISTORY_SOE = 2,    /* Eq. 3 over every past step, weights fitted by `terms`
                               exponentials: O(terms) time and memory per particle */
};

/* Which velocity the fractional derivative (Eq. 3) remembers (scene key history.velocity). */
enum stf_history_velocity {
    STF_HISTORY_PARTICLE = 0, /* each particle's own velocity, as the paper writes Eq. 3 */
    STF_HISTORY_SMOOTHED = 1, /* ours: the velocity field at the particle, the Shepard average
                                 of its neighbours' velocities with the density kernel
                                 (1 - r/h)^2. A linear flow is kept, so a strain rate
                                 measures the same; the grid-scale jitter of a relaxation at
                                 rest (a few cm/s at 1 ms) is averaged out, so a resting pool
                                 does not keep itself jammed (src/fluid.c) */
};

/* Fluid models (stf_fluid_def.model, scene key fluid.model). */
enum stf_model {
    STF_MODEL_CLAVET_STF = 0,     /* Clavet SPH + history springs (first paper) */
    STF_MODEL_CARREAU_YASUDA = 1, /* Carreau-Yasuda SPH with pressure projection (second paper) */
};

/* The Clavet model's pressure stage (stf_fluid_def.pressure_mode, scene key
 * effects.pressure.mode). */
enum stf_pressure_mode {
    STF_PRESSURE_RELAX = 0,      /* Clavet's double density relaxation (Alg. 2), one Jacobi pass
                                    with stiffnesses k and k_near: the paper's */
    STF_PRESSURE_PROJECTION = 1, /* ours: the second paper's pressure projection (Algorithm 1,
                                    with the solver, tolerance and walls of def.cy) on the
                                    velocities the other effects predict: the fluid held at its
                                    rest density to eta (src/cy.c, stf_cy_pressure_stage) */
};

/* The Clavet relaxation's rest density when none is given (stf_fluid_def.rest_packing, scene
 * key effects.pressure.rest). The kernel sum is a proxy for mass per volume, and it depends on
 * the packing: a settled liquid's disordered packing has a lower kernel sum than the cubic
 * lattice at the same number density, so a fluid held at the lattice's kernel sum is denser
 * than its density by 2-2.6% (src/README.md, "The rest density of the liquid"). */
enum stf_rest_packing {
    STF_REST_LATTICE = 0, /* the cubic lattice's kernel sum: a lattice block starts at rest */
    STF_REST_LIQUID = 1,  /* ours: the lattice's times STF_LIQUID_PACKING, the settled liquid's
                             at the same number density, so the fluid is at its density */
};

/* The walls of Clavet's relaxation (stf_fluid_def.relax_wall, scene key effects.pressure.wall).
 * A particle near a solid misses the neighbours the solid takes the place of; each collider
 * counts as a half-space of lattice sites, within h of the particle (src/pressure.c). */
enum stf_relax_wall {
    STF_RELAX_WALL_MIRROR = 0, /* ours: sites fixed half a spacing and more inside the solid,
                                  carrying the particle's pressure plus the hydrostatic
                                  difference; twice the push the particle's own density gives,
                                  so not the gradient of an energy: each pass of a particle
                                  at a wall can do net work on it (a pool's particle-scale
                                  motion is kept up by it) */
    STF_RELAX_WALL_GHOST = 1,  /* ours: the sites are the mirror image of the particle's own
                                  lattice (2d + l s from it, the particle itself the first):
                                  the wall enters through the particle's density only, and its
                                  push, of the same strength, is the gradient of Clavet's energy
                                  (src/README.md, "The relaxation's walls") */
};

/* The kernel sum of the settled liquid over the cubic lattice's at the same number density, for
 * Clavet's kernel (1 - r/h)^2 at h = 2 spacings (measured: src/README.md, "The rest density of
 * the liquid"). */
#define STF_LIQUID_PACKING 0.975

/* The Carreau-Yasuda model's pressure projection (cy_pressure.c). */
enum stf_pressure_solver {
    STF_PRESSURE_JACOBI = 0, /* Algorithm 1: Jacobi with Eq. 21's k_i, each iteration's k_i >= 0 */
    STF_PRESSURE_CG = 1,     /* ours: the same equations solved by conjugate gradients to eta,
                                the pressure >= 0 in total (it may fall where the fluid expands) */
};

/* The walls' part in the Carreau-Yasuda projection (cy_walls.c). */
enum stf_wall_pressure {
    STF_WALL_PRESSURE_OWN = 0,    /* a wall pushes with the particle's own k_i once (the
                                     boundary particles of the paper carry no pressure) */
    STF_WALL_PRESSURE_MIRROR = 1, /* ours: the wall's lattice carries the particle's pressure
                                     and sees its approach as a mirror: twice the wall term */
    STF_WALL_PRESSURE_HYDROSTATIC = 2, /* ours: the mirror, its lattice carrying the particle's
                                          pressure plus the hydrostatic difference rho0 g.(x_b -
                                          x_i), as the relaxation's mirror does */
};

/* The particles' pressure force in the Carreau-Yasuda projection (cy_pressure.c). */
enum stf_pressure_gradient {
    STF_PRESSURE_GRADIENT_SYMMETRIC = 0,     /* the paper's: sum_j m (k_i/rho_i + k_j/rho_j) grad W */
    STF_PRESSURE_GRADIENT_LOCAL_MINIMUM = 1, /* ours: sum_j m (k_j/rho_j - min) grad W, the
                                                pressures offset by their neighbourhood's least
                                                (Koshizuka and Oka 1996): a uniform pressure
                                                pushes no particle (jacobi only) */
    STF_PRESSURE_GRADIENT_OFFSET = 2,        /* ours: the same at the walls too, and a sphere's or
                                                a box's pressure force from the fluid's pressure
                                                on its surface (cy_walls.c; jacobi only) */
};

enum stf_viscosity_solver {
    STF_VISCOSITY_IMPLICIT = 0, /* backward Euler, conjugate gradients (Algorithm 2) */
    STF_VISCOSITY_EXPLICIT = 1, /* forward Euler (for comparison; limited by dt ~ h^2/nu) */
};

/* The SPH viscous operator of the Carreau-Yasuda model (both approximate nu lap(u) for a
 * divergence-free flow of uniform viscosity). */
enum stf_viscosity_form {
    STF_VISCOSITY_MORRIS = 0,  /* Morris et al. (1997): pair forces along u_i - u_j */
    STF_VISCOSITY_CENTRAL = 1, /* Monaghan's 2 (d + 2) form: pair forces along x_i - x_j,
                                  conserving angular momentum (zero for rigid motion) */
};

/* Carreau-Yasuda SPH (second paper): cubic spline kernel of support h, per-particle
 * stiffness pressure projection (Eq. 11-21), viscosity nu(g) = nu_inf + (nu0 - nu_inf)
 * (1 + (K g)^a)^((n-1)/a) (Eq. 3) on the shear rate g = sqrt(D:D / 2), D = grad v + grad v^T. */
typedef struct stf_cy_def {
    double mu0;            /* zero-shear kinematic viscosity, m^2/s (>= 0; the paper's mu_0) */
    double mu_inf;         /* infinite-shear kinematic viscosity, m^2/s (>= 0) */
    double K;              /* time constant, s (>= 0): where the shear dependence sets in */
    double alpha;          /* transition smoothness a, dimensionless (> 0) */
    double n;              /* power index: 1 Newtonian, < 1 shear thinning, > 1 thickening (> 0) */
    double eta;            /* pressure projection: mean density error tolerance, fraction (> 0) */
    int min_pressure_iterations; /* 1 .. 10000; the paper uses 2 */
    int max_pressure_iterations; /* min .. 10000; reached means "not converged" in the stats */
    int viscosity_solver;  /* enum stf_viscosity_solver */
    double cg_tolerance;   /* implicit viscosity: stop at |residual| <= tol |rhs| (> 0) */
    int max_cg_iterations; /* 1 .. 100000 */
    double cfl;            /* 0: one step of the given dt; in (0,1): CFL-adaptive substeps of
                              length dt_sub = min(dt, cfl h / v_max), v_max the largest particle
                              speed at the substep's start, dimensionless (Courant number) */
    double dt_max;         /* s, >= 0: with cfl, the longest substep (0: the step's dt); a
                              coupled step longer than the CFL substep then splits into
                              nearly equal substeps instead of, e.g., two halves */
    double warm_start;     /* [0,1]: the pressure projection starts from this fraction of the
                              last step's pressure (0: from zero, the paper's); the iterations
                              then only add pressure, dimensionless */
    double relaxation;     /* (0,1]: each Jacobi iteration applies this fraction of the k_i of
                              Eq. 21 (0 means 1, the paper's), dimensionless */
    int viscosity_form;    /* enum stf_viscosity_form (default morris) */
    int pressure_solver;   /* enum stf_pressure_solver (default jacobi) */
    int wall_pressure;     /* enum stf_wall_pressure (default own) */
    int pressure_gradient; /* enum stf_pressure_gradient (default symmetric) */
} stf_cy_def;

/* What the Carreau-Yasuda solver did in the last step (zeros for the Clavet model). */
typedef struct stf_solver_stats {
    int pressure_iterations;  /* pressure projection iterations */
    double density_error;     /* mean (rho* - rho0)/rho0 over particles (compression only)
                                 after the last iteration, fraction */
    int viscosity_iterations; /* conjugate gradient iterations (0 explicit) */
    double viscosity_residual;/* final |residual| / |rhs| of the viscosity solve */
    double max_viscosity;     /* largest kinematic viscosity of a particle, m^2/s */
    double min_viscosity;     /* smallest, m^2/s */
    /* over the substeps of the last stf_fluid_step (one without cfl) */
    int substeps;             /* substeps taken */
    double dt_min, dt_max;    /* shortest and longest substep, s */
    double cfl_number;        /* largest v_max dt_sub / h of a substep, dimensionless */
    long pressure_iterations_total; /* summed over the substeps */
    double density_error_sum; /* final mean density error summed over the substeps, fraction */
    double density_error_max; /* largest of them, fraction */
    int pressure_iterations_max;    /* most iterations of a substep */
    long viscosity_iterations_total; /* CG iterations summed over the substeps */
    int viscosity_iterations_max;   /* most CG iterations of a substep */
} stf_solver_stats;

/* How the springs (Alg. 3 with Eq. 6) are applied (src/gauss_seidel.c):
 * JACOBI: every spring's displacement from the same positions, saturated so that no spring
 * does more than become rigid within the step (springs.c); GAUSS_SEIDEL: as compliant
 * constraints one after the other, as Clavet's algorithm does, stable at any stiffness. */
enum stf_relaxation { STF_RELAX_JACOBI = 0, STF_RELAX_GAUSS_SEIDEL = 1 };

typedef struct stf_fluid_def {
    unsigned effects;      /* bit set of enum stf_effect */
    double spacing;        /* initial particle spacing, m (> 0, <= 1) */
    double density;        /* physical density, kg/m^3; particle mass = density*spacing^3 */
    double jitter;         /* random offset of block particles from the lattice, in spacings,
                              [0, 0.45]: breaks the crystal a cubic lattice would be */
    double h;              /* interaction radius, m: 0 (2*spacing), or in [spacing, 5*spacing]
                              (0 with material_spacing) */
    double material_spacing; /* m (0 .. 1; scene key fluid.reference_spacing): if > 0, the
                              parameters below describe the material at this spacing, and a
                              fluid at another spacing s takes the same continuum material
                              (h/s fixed): with r = material_spacing / s, the spring stiffnesses
                              k_min and k_onset scale by r^2 (modulus = rho k s^2 times a
                              lattice sum), k_hist by r^3 (and neighbours' relative velocities
                              for a flow scale by 1/r), the pressure stiffnesses k and k_near by
                              r (bulk modulus = rho k s times a lattice sum), sigma by r^2
                              (kinematic viscosity = sigma s^2 times a lattice sum) and beta by
                              r; rates (plasticity, stick) and ratios stay. 0: as given */
    double gravity[3];     /* gravity acceleration, m/s^2 */
    /* viscosity (Clavet Alg. 5): velocity impulse dt*(1-r/h)*(sigma*u + beta*u^2) per pair,
       u the inward radial relative speed (m/s) */
    double sigma;          /* linear viscosity, 1/s (>= 0) */
    double beta;           /* quadratic viscosity, 1/m (>= 0) */
    /* double density relaxation (Clavet Alg. 2) */
    double k;              /* pressure stiffness, m/s^2 (> 0) */
    double k_near;         /* near-pressure stiffness, m/s^2 (>= 0) */
    double rest_density;   /* rest kernel density (sum of (1-r/h)^2), dimensionless;
                              0 means the value of the initial cubic lattice */
    int rest_packing;      /* enum stf_rest_packing (default lattice): the packing whose kernel
                              sum is the rest density when rest_density is 0 */
    int relax_wall;        /* enum stf_relax_wall (default mirror): the relaxation's walls */
    int tension;           /* 1: Clavet's pressure as written, negative below rest density
                              (cohesion, surface tension); 0: pressure and near-pressure only
                              push, both measured from the rest lattice (no tension) */
    int pressure_mode;     /* enum stf_pressure_mode (default relax). projection: k, k_near,
                              rest_density and tension are not used; cy.eta, cy.pressure_solver,
                              cy.wall_pressure, cy.min/max_pressure_iterations, cy.max_cg_iterations
                              and cy.cg_tolerance are */
    /* springs (Clavet Alg. 3-4) */
    double k_min;          /* spring stiffness, 1/s^2 (>= 0) */
    double yield_ratio;    /* tolerated deformation / rest length, dimensionless (>= 0) */
    double plasticity;     /* rest-length creep rate alpha, 1/s (>= 0) */
    double liquid_plasticity; /* 1/s (>= 0; < 0: plasticity): ours, the creep rate of a spring
                              whose history stiffness is below the onset (every spring without
                              history). A liquid's springs keep almost no shape; a spring that
                              stiffens then freezes the shape it has, instead of snapping back
                              to a rest length its liquid past left behind, which put the
                              resting jammed pool in a self-sustained jitter (src/springs.c) */
    int relaxation;        /* enum stf_relaxation: how the springs' displacements are applied */
    double spring_damping; /* s (>= 0; scene key springs.damping): gauss_seidel only, a
                              dashpot beside each spring with the relaxation time tau
                              (Kelvin-Voigt; src/gauss_seidel.c). 0: none */
    int iterations;        /* gauss_seidel: sweeps over the spring constraints per step, 1..64 */
    int spring_passive;    /* 0/1 (scene key springs.passive; ours, default 0; needs history):
                              a spring whose history stiffness rose since the last step has its
                              rest length moved towards its length, so that its elastic energy
                              k (r - L)^2 / 2 does not rise with the stiffness (src/springs.c).
                              Eq. 6 as written stiffens a compressed spring and gives back more
                              than it took: a steel ball at 8 m/s onto 6 cm of the cornstarch
                              over a floor leaves at 8.33 m/s (2.36 m/s passive) */
    /* history (Eq. 3-6): k = k_min + k_hist * dt^(1-q)/Gamma(3-q) * |sum a (v_i - v_j)| */
    double q;              /* fractional order, in (0,1) */
    int d;                 /* history window, steps (1 .. 100000); ignored if memory > 0 */
    double memory;         /* history window, s (> 0 overrides d: d = round(memory/dt)) */
    double k_hist;         /* history stiffness gain, 1/s^2 per m/s^q (>= 0) */
    double reference_spacing; /* m (>= 0): if > 0, k_hist is the gain at this spacing and is
                              scaled by reference_spacing/spacing. Neighbours' relative
                              velocities shrink with the spacing for the same flow, so Eq. 6
                              with a fixed k_hist softens as the resolution grows; 0: Eq. 6 as
                              written */
    double k_onset;        /* 1/s^2 (>= 0): onset of thickening. A spring's history stiffness
                              kh below k_onset is slow creep or lattice noise and stiffens
                              nothing; above it only the excess counts:
                              k = k_min + max(0, kh - k_onset). 0: Eq. 6 as written */
    int history_mode;      /* enum stf_history_mode */
    int history_velocity;  /* enum stf_history_velocity (default particle: Eq. 3 as written) */
    double history_smoothing; /* m (>= 0; scene key history.smoothing; ours): with velocity
                              smoothed, > 0 averages the velocity field over this length (a
                              lattice of this cell, trilinear spread and gather:
                              src/velocity_field.c) instead of over the kernel's neighbours,
                              so the band in which jammed fluid shears, and the speed at which
                              a body creeps through it, do not shrink with the spacing.
                              0: the kernel's neighbours */
    int terms;             /* soe mode: number of exponentials K, 1..64 (default 16) */
    /* boundary treatment (section 3.3) */
    double stick;          /* 1/s: tangential velocity at a wall decays at the rate
                              stick * kh / (k_min + kh), kh = mean history stiffness (>= 0) */
    /* the fluid model: Clavet/STF (the fields above) or Carreau-Yasuda (cy below, src/cy.c);
       the Carreau-Yasuda model runs gravity and its own solver, and no other effect */
    int model;             /* enum stf_model */
    stf_cy_def cy;         /* Carreau-Yasuda parameters (model STF_MODEL_CARREAU_YASUDA) */
    /* periodic domain (Carreau-Yasuda model only; scene key container.periodic): along
       axis a with periodic[a] > 0 (m, >= 3 h), positions wrap into [periodic_origin[a],
       periodic_origin[a] + periodic[a]) and neighbours are found across the seam; solids
       (a container's walls) across that axis must stay out of the fluid's reach */
    double periodic[3];
    double periodic_origin[3];
} stf_fluid_def;

/* 1 when the fluid's pressure is a projection, and stf_fluid_solver_stats reports it: the
 * Carreau-Yasuda model's, or the Clavet model's pressure effect with pressure_mode
 * projection (stf_fluid_check_def refuses that mode with the Carreau-Yasuda model). */
static inline int stf_def_projects(const stf_fluid_def *d)
{
    return d->model == STF_MODEL_CARREAU_YASUDA ||
           ((d->effects & STF_EFFECT_PRESSURE) && d->pressure_mode == STF_PRESSURE_PROJECTION);
}

/* Defaults: a cornstarch-like viscoelastic fluid at 1 cm spacing with every effect on. */
STF_API stf_fluid_def stf_default_fluid_def(void);

/* Shapes a particle collides with. Distances are signed: > 0 outside the solid. */
enum stf_shape {
    STF_SHAPE_PLANE = 0,     /* half-space n.x < offset is solid (n in body frame) */
    STF_SHAPE_SPHERE = 1,    /* radius */
    STF_SHAPE_BOX = 2,       /* half extents */
    STF_SHAPE_CAPSULE = 3,   /* radius, half length along local z */
    STF_SHAPE_CYLINDER = 4,  /* radius, half length along local z */
    STF_SHAPE_CONTAINER = 5, /* open-top box: inner half extents; the inside is free */
    STF_SHAPE_CONVEX = 6,    /* convex hull of points (libccd GJK + EPA) */
};

typedef struct stf_collider_def {
    int shape;              /* enum stf_shape */
    double radius;          /* m: sphere, capsule, cylinder */
    double half_length;     /* m: capsule and cylinder half length along local z */
    double half[3];         /* m: box half extents; container inner half extents */
    double wall;            /* m: container wall thickness (>= 0, for drawing and ODE) */
    double normal[3];       /* plane normal (unit), body frame */
    double offset;          /* m: plane offset along normal */
    const double *points;   /* convex: 3*npoints coordinates in the body frame, m */
    int npoints;            /* convex: number of points (>= 4) */
    double friction;        /* Coulomb friction coefficient of particle contacts, [0,1] */
    int stick;              /* 1: section 3.3 boundary treatment applies at this surface */
} stf_collider_def;

STF_API stf_collider_def stf_default_collider_def(void);
/* Whether a container's walls and floor of thickness wall (m) are solid from both sides for a
 * fluid of this spacing (m): when they are at least a spacing thick. A particle in such a wall
 * leaves by the nearest face, inner or outer; a thinner wall cannot tell the sides apart (a
 * particle squeezed into it by a body may be past its mid-plane), so it sends every particle
 * in it back into the container, and its outside is free. */
static inline int stf_wall_two_sided(double wall, double spacing) { return wall >= spacing; }

/* The scene keys' names of enum stf_pressure_solver, stf_wall_pressure and
 * stf_pressure_gradient, each in its enum's order (NULL-terminated: the scene parser's lists
 * of choices), and the name of a value (what the run's parameters and messages print; "?"
 * outside the list). */
#define STF_PRESSURE_SOLVER_NAMES {"jacobi", "cg", NULL}
#define STF_WALL_PRESSURE_NAMES {"own", "mirror", "hydrostatic", NULL}
#define STF_PRESSURE_GRADIENT_NAMES {"symmetric", "local_minimum", "offset", NULL}
static inline const char *stf_name_in_list(const char *const *names, int count, int v)
{
    return v >= 0 && v < count ? names[v] : "?";
}
static inline const char *stf_pressure_solver_name(int s)
{
    static const char *const names[] = STF_PRESSURE_SOLVER_NAMES;
    return stf_name_in_list(names, (int)(sizeof names / sizeof *names) - 1, s);
}
static inline const char *stf_wall_pressure_name(int w)
{
    static const char *const names[] = STF_WALL_PRESSURE_NAMES;
    return stf_name_in_list(names, (int)(sizeof names / sizeof *names) - 1, w);
}
static inline const char *stf_pressure_gradient_name(int g)
{
    static const char *const names[] = STF_PRESSURE_GRADIENT_NAMES;
    return stf_name_in_list(names, (int)(sizeof names / sizeof *names) - 1, g);
}
/* A bounded shape's size about its body origin: the radius of the largest sphere inside it
 * (m; 0 for a convex hull that does not hold the origin) and of the smallest sphere holding
 * it (m). Returns 0; -1 for planes and containers (unbounded) or an invalid def. */
STF_API int stf_collider_extent(const stf_collider_def *def, double *inradius, double *bound);
/* A bounded shape's volume (m^3) and the volume of the band of width band (m) outside its
 * surface, counted on a grid of 64^3 cells over its bounding cube (within 0.25% for a sphere,
 * a box and a capsule whose band is 8 cells thick: tests/test_colliders.c). Returns 0; -1 as stf_collider_extent, or band <= 0. */
STF_API int stf_collider_volumes(const stf_collider_def *def, double band, double *vol, double *vol_band);

typedef struct stf_fluid stf_fluid;

/* Checks every field of def (the one check of its ranges: stf_fluid_create calls it, and so
 * does the scene loader, which reports a refused field at the scene key it came from).
 * Returns 0 when def is valid (*field is then NULL); -1 when not, with "NAME: what is wrong"
 * in err (NAME the field's scene key, e.g. "k_onset: must be >= 0 (got -1)", "damping: needs
 * relaxation gauss_seidel") and in *field the member of stf_fluid_def that is wrong, spelt as
 * in C: "spacing", "spring_damping", "material_spacing", "gravity", "cy.mu0" (a static
 * string). Of two fields that contradict each other, *field is the one the message names.
 * err may be NULL with errlen 0; field may be NULL. */
STF_API int stf_fluid_check_def(const stf_fluid_def *def, char *err, size_t errlen, const char **field);
/* Creates a fluid from def; checks every field (stf_fluid_check_def). Returns 0, or -1 with a
 * message in err. */
STF_API int stf_fluid_create(const stf_fluid_def *def, stf_fluid **out, char *err, size_t errlen);
STF_API void stf_fluid_destroy(stf_fluid *f);

/* Fills the box [lo,hi] (m) with particles on a cubic lattice at the fluid's spacing,
 * moving with velocity v (m/s). Returns the number of particles added. */
STF_API int stf_fluid_add_block(stf_fluid *f, const double lo[3], const double hi[3], const double v[3]);
/* Fills a ball of radius r (m) around c (m) with particles on a cubic lattice through c
 * (the lattice sites closer than r to c), moving with velocity v (m/s). Returns the number
 * of particles added, or -1 (out of memory, or more than 10^8 sites). */
STF_API int stf_fluid_add_ball(stf_fluid *f, const double c[3], double r, const double v[3]);
/* Adds one particle. Returns its index. */
STF_API int stf_fluid_add_particle(stf_fluid *f, const double x[3], const double v[3]);

/* Colliders: solids the particles cannot enter. Returns an id >= 0, or -1 with err. */
STF_API int stf_fluid_add_collider(stf_fluid *f, const stf_collider_def *def, char *err, size_t errlen);
/* How many colliders the fluid has (the ids are 0 .. count - 1). */
STF_API int stf_fluid_collider_count(const stf_fluid *f);
/* Sets a collider's pose (position m, rotation 3x3 row-major body->world) and its velocity
 * (linear m/s at the position, angular rad/s). */
STF_API void stf_fluid_set_collider_state(stf_fluid *f, int id, const double pos[3], const double rot[9],
                                  const double vel[3], const double angvel[3]);
/* Removes the particles whose centres lie inside collider id (set-up of overlapping bodies).
 * Returns how many were removed, or -1 when out of memory. */
STF_API int stf_fluid_remove_inside(stf_fluid *f, int id);
/* The impulse (N s) the fluid gave collider id during the last step, and its moment about
 * the collider position (N m s). */
STF_API void stf_fluid_collider_impulse(const stf_fluid *f, int id, double impulse[3], double moment[3]);
/* Which stage gave the impulse above: the pressure (Clavet's relaxation or a projection, the
 * walls' push), the viscosity (the Carreau-Yasuda walls' no-slip), the collision stage's
 * contacts, and section 3.3's stick. Their sum is the impulse. */
enum { STF_PART_PRESSURE, STF_PART_VISCOSITY, STF_PART_CONTACT, STF_PART_STICK, STF_PARTS };
/* The impulse of the last step by part (N s, parts[STF_PART_...]). */
STF_API void stf_fluid_collider_impulse_parts(const stf_fluid *f, int id, double parts[STF_PARTS][3]);
/* The overlap removal's mass-weighted displacement (kg m) during the last step: the sum of
 * m delta over the particles collider id pushed out of itself by delta without changing
 * their velocity. A dynamic body of mass M moves by -shift / M to keep the centre of mass
 * of fluid and body where it was (stf_ode does); the moment above then keeps the angular
 * momentum, taking the particles' velocities relative to the collider's velocity. */
STF_API void stf_fluid_collider_shift(const stf_fluid *f, int id, double shift[3]);
/* The particles within band (m) outside the surface of any of the nids colliders ids (the
 * geoms of one body; each particle counted once): their number, the sum of their positions
 * relative to origin (m) and of the products of those (xx yy zz xy xz yz, m^2), summed in
 * particle order. */
STF_API int stf_fluid_collider_band(const stf_fluid *f, const int *ids, int nids, double band,
                                    const double origin[3], double sum[3], double sum2[6]);
/* Changes the velocity of each of those particles at x by dv + w × (x - origin) (m/s). */
STF_API void stf_fluid_collider_band_push(stf_fluid *f, const int *ids, int nids, double band,
                                          const double origin[3], const double dv[3],
                                          const double w[3]);
/* Signed distance (m) from x to the collider's surface (> 0 outside). */
STF_API double stf_fluid_collider_distance(const stf_fluid *f, int id, const double x[3]);

/* Advances the fluid by dt seconds (one substep of the paper's Algorithm 1).
 * Returns 0, or -1 on a numerical failure (see stf_fluid_failure). */
STF_API int stf_fluid_step(stf_fluid *f, double dt);
/* After a failed step: what failed ("NaN in position after effect 'pressure', particle 12"). */
STF_API const char *stf_fluid_failure(const stf_fluid *f);

/* Number of OpenMP threads used (0 = OpenMP default). Results do not depend on it. */
STF_API void stf_set_threads(int n);

/* State, copied out (arrays of 3*n doubles). */
STF_API int stf_fluid_count(const stf_fluid *f);
STF_API double stf_fluid_particle_mass(const stf_fluid *f);
STF_API double stf_fluid_time(const stf_fluid *f);
STF_API long stf_fluid_steps(const stf_fluid *f);
STF_API void stf_fluid_get_positions(const stf_fluid *f, double *x);
STF_API void stf_fluid_get_velocities(const stf_fluid *f, double *v);
/* Multiplies every particle's velocity by factor (the settling before t = 0, stf_ode_settle). */
STF_API void stf_fluid_scale_velocities(stf_fluid *f, double factor);
/* Sets collider id's velocity and angular velocity to zero (its pose stays). */
STF_API void stf_fluid_hold_collider(stf_fluid *f, int id);
/* Sets the fluid's time and step count back to 0 (after the settling). */
STF_API void stf_fluid_reset_clock(stf_fluid *f);
/* Forgets the history (Eq. 3's past velocities and every spring's history stiffness): the
 * fluid's past starts now, as for a fluid long at rest. After the settling, whose start-up
 * motion is not the material's past. The window starts again at the next step. */
STF_API void stf_fluid_forget_history(stf_fluid *f);
/* Per particle: mean history stiffness of its springs (1/s^2), 0 without history. */
STF_API void stf_fluid_get_history_stiffness(const stf_fluid *f, float *k);
/* Per particle: persistent id (index at creation). */
STF_API void stf_fluid_get_ids(const stf_fluid *f, int32_t *id);
/* Number of springs (0 without the springs effect). */
STF_API long stf_fluid_spring_count(const stf_fluid *f);
/* Bytes allocated for an effect's own storage (0 when the effect is off). */
STF_API size_t stf_fluid_effect_bytes(const stf_fluid *f, unsigned effect);
/* Seconds spent in an effect's stage since creation (wall clock). */
STF_API double stf_fluid_effect_seconds(const stf_fluid *f, unsigned effect);
/* The effective history window in steps (0 without history). */
STF_API int stf_fluid_history_steps(const stf_fluid *f);
/* The effective parameters (the def with every default and derived value filled in: h,
 * particle mass, rest densities, history window), as YAML "key: value  # unit" lines.
 * Returns the length written (like snprintf). */
STF_API int stf_fluid_describe(const stf_fluid *f, char *buf, size_t len);
/* The Carreau-Yasuda solver's statistics of the last step. */
STF_API void stf_fluid_solver_stats(const stf_fluid *f, stf_solver_stats *st);
/* Adds to acc the statistics part of the substeps that follow acc's (one substep's, or a
 * whole step's): substeps and the *_total and *_sum fields summed, the *_max fields,
 * cfl_number and dt_max the largest, dt_min the smallest; the per-substep fields (those
 * above substeps) become part's, the last substep's. An acc with substeps 0 is empty: it
 * becomes part. */
STF_API void stf_solver_stats_merge(stf_solver_stats *acc, const stf_solver_stats *part);
/* Per particle: pressure (Pa) of the last step's projection; zeros for the Clavet model. */
STF_API void stf_fluid_get_pressures(const stf_fluid *f, double *p);
/* The Carreau-Yasuda viscosity (Eq. 3) at shear rate g (1/s), m^2/s. */
STF_API double stf_cy_viscosity(const stf_cy_def *cy, double g);
/* The rest density rho0 (kg/m^3) of the Carreau-Yasuda model: the kernel sum of the cubic
 * lattice at the fluid's spacing times the particle mass (close to def.density). */
STF_API double stf_fluid_cy_rest_density(const stf_fluid *f);
/* Steps in which the springs saturated: some particle's spring gains dt^2 k (1 - L/h)
 * summed to more than 1 and were scaled down so the step cannot overshoot (springs.c). The
 * history stiffness beyond that is rigid within a step. 0 without springs. */
STF_API long stf_fluid_saturated_steps(const stf_fluid *f);

/* Largest particle speed, m/s (0 without particles). */
STF_API double stf_fluid_max_speed(const stf_fluid *f);
/* The last step's largest sum over a particle's springs of dt^2 k (1 - L/h) (before any
 * saturation; dimensionless, 0 without springs): the spring network's stiffness number, which
 * limits the Jacobi step; 0 with relaxation gauss_seidel, stable at any gain. */
STF_API double stf_fluid_spring_gain(const stf_fluid *f);
/* The Clavet pressure's own stiffness in the last step, 1/s^2: the largest (P + 2 P_near) / h
 * over the particles, P and P_near the pressures of the double density relaxation (m/s^2).
 * A pair's push dt^2 (P (1 - q) + P_near (1 - q)^2) changes with its distance by dt^2 (P +
 * 2 P_near (1 - q)) / h besides the density's own change (k/h): under an impact's compression
 * that term grows past k/h. 0 without the pressure effect, in projection mode, or before the
 * first step. */
STF_API double stf_fluid_pressure_stiffness(const stf_fluid *f);
/* The length of the last step, s (0 before the first). */
STF_API double stf_fluid_last_dt(const stf_fluid *f);
/* The definition the fluid was created with, as given (h 0 means 2 spacings). */
STF_API void stf_fluid_get_def(const stf_fluid *f, stf_fluid_def *def);

/* FNV-1a hash of positions and velocities, for determinism tests. */
STF_API uint64_t stf_fluid_hash(const stf_fluid *f);

/* History weights (Eq. 3). For n >= 1 (steps since the start of history) and p in [0,n]:
 * the weight a_{p,n}. Exposed for tests and the history analysis. */
STF_API double stf_history_weight(double q, long p, long n);

#ifdef __cplusplus
}
#endif
#endif
