/* test_sim.c - a scene made real (ode_glue/stf_sim.c): what the output says of a body over a
 * step that adaptive control split into substeps, and the sizes of the shapes it splits by. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "stf_sim.h"
#include "test_util.h"
#include "sim_util.h"

/* A ball thrown down into a fluid block (no container, so no ODE contacts): the only forces on
 * it are gravity and the fluid's, so over each step m (v1 - v0) = (m g + F) dt, with F the
 * fluid force the output reports for the step. The impact splits steps into substeps whose
 * fluid forces differ; the last substep's force alone breaks the balance. */
static void test_fluid_force_is_step_mean(void)
{
    static const char *const scene =
        "name: throw\n"
        "duration: 1\n"
        "dt: 0.002\n"
        "fluid:\n"
        "  spacing: 0.01\n"
        "  blocks:\n"
        "    - {min: [-0.05, -0.05, 0.0], max: [0.05, 0.05, 0.04]}\n"
        "effects:\n"
        "  gravity: {}\n"
        "  pressure: {}\n"
        "bodies:\n"
        "  - {name: ball, shape: sphere, radius: 0.02, density: 3000, position: [0, 0, 0.07],\n"
        "     velocity: [0, 0, -6]}\n";
    stf_scene *sc;
    stf_sim *s = load_sim("throw.yaml", scene, &sc);
    if (!s) return;
    dMass mass;
    dBodyGetMass(s->bodies[0], &mass);
    const double m = mass.mass, dt = sc->dt, *g = sc->fluid.gravity;
    int split_with_force = 0;
    double worst = 0, scale = 0;
    for (int step = 0; step < 15; step++) {
        double p[3], q[4], v0[3], v1[3], w[3], f[3];
        stf_sim_body_state(s, 0, p, q, v0, w, f);
        long before = s->substeps;
        CHECK(stf_sim_step(s) == 0, "step %d", step);
        stf_sim_body_state(s, 0, p, q, v1, w, f);
        double fn = sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
        if (s->substeps - before > 1 && fn > 0) split_with_force++;
        for (int a = 0; a < 3; a++) {
            double err = fabs(m * (v1[a] - v0[a]) - (m * g[a] + f[a]) * dt);
            if (err > worst) worst = err;
        }
        if (fn * dt > scale) scale = fn * dt;
    }
    printf("fluid force: %d split steps with a fluid force; worst |m dv - (m g + F) dt| = %.3g N s "
           "(largest F dt %.3g N s), %ld substeps in 15 steps\n",
           split_with_force, worst, scale, s->substeps);
    CHECK(split_with_force >= 2, "the impact must split steps while the fluid pushes the ball");
    CHECK(scale > 0.01 * m * 6, "the fluid must stop the ball noticeably (F dt %.3g)", scale);
    CHECK(worst <= 1e-9 * scale, "the reported force is not the step's mean: %.3g N s", worst);
    stf_sim_destroy(s);
    stf_scene_free(sc);
}

/* The shapes' sizes the substep control uses: exact for the primitives, and for a convex
 * hull the depth of its centre (before, a hull counted as 0 thick and 0 wide). */
static void test_extents(void)
{
    stf_collider_def d = stf_default_collider_def();
    double in, out;
    d.shape = STF_SHAPE_SPHERE, d.radius = 0.1;
    CHECK(stf_collider_extent(&d, &in, &out) == 0 && in == 0.1 && out == 0.1, "sphere %g %g", in, out);
    d = stf_default_collider_def();
    d.shape = STF_SHAPE_BOX, d.half[0] = 0.1, d.half[1] = 0.2, d.half[2] = 0.2;
    CHECK(stf_collider_extent(&d, &in, &out) == 0, "box");
    CHECK_NEAR(in, 0.1, 0, "box inradius");
    CHECK_NEAR(out, 0.3, 1e-15, "box bound");
    d = stf_default_collider_def();
    d.shape = STF_SHAPE_CAPSULE, d.radius = 0.1, d.half_length = 0.3;
    CHECK(stf_collider_extent(&d, &in, &out) == 0, "capsule");
    CHECK_NEAR(in, 0.1, 0, "capsule inradius");
    CHECK_NEAR(out, 0.4, 1e-15, "capsule bound");
    d.shape = STF_SHAPE_CYLINDER;
    CHECK(stf_collider_extent(&d, &in, &out) == 0, "cylinder");
    CHECK_NEAR(in, 0.1, 0, "cylinder inradius");
    CHECK_NEAR(out, sqrt(0.1), 1e-15, "cylinder bound");
    /* the box [-0.1,0.1] x [-0.2,0.2] x [-0.2,0.2] as a hull of its 8 corners */
    double pts[24];
    for (int k = 0; k < 8; k++) {
        pts[3 * k] = (k & 1) ? 0.1 : -0.1;
        pts[3 * k + 1] = (k & 2) ? 0.2 : -0.2;
        pts[3 * k + 2] = (k & 4) ? 0.2 : -0.2;
    }
    d = stf_default_collider_def();
    d.shape = STF_SHAPE_CONVEX, d.points = pts, d.npoints = 8;
    CHECK(stf_collider_extent(&d, &in, &out) == 0, "convex");
    CHECK_NEAR(in, 0.1, 1e-9, "convex inradius");
    CHECK_NEAR(out, 0.3, 1e-15, "convex bound");
    /* the same hull moved off its origin: the origin is outside, inradius 0 */
    for (int k = 0; k < 8; k++) pts[3 * k] += 0.5;
    CHECK(stf_collider_extent(&d, &in, &out) == 0 && in == 0, "off-origin convex inradius %g", in);
    d = stf_default_collider_def();
    d.shape = STF_SHAPE_PLANE, d.normal[2] = 1;
    CHECK(stf_collider_extent(&d, &in, &out) == -1, "a plane is unbounded");
}

int main(void)
{
    test_fluid_force_is_step_mean();
    test_extents();
    dCloseODE();
    return test_result("test_sim");
}
