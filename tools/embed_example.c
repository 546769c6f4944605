/* embed_example.c - an ODE program that drops a ball into a tank of shear-thickening fluid.
 *
 * Everything but the four marked lines is plain ODE: the program owns its world, space and
 * bodies and would run without the fluid. Exits 0 when the run completes. */
#include <ode/ode.h>
#include <stdio.h>

#include "stf_ode.h"

int main(void)
{
    dInitODE2(0);
    dWorldID world = dWorldCreate();
    dSpaceID space = dHashSpaceCreate(0);
    dWorldSetGravity(world, 0, 0, -9.81);
    dCreatePlane(space, 0, 0, 1, 0); /* the ground */

    dBodyID ball = dBodyCreate(world);
    dMass m;
    dMassSetSphereTotal(&m, 0.5, 0.04); /* 0.5 kg, 4 cm radius */
    dBodySetMass(ball, &m);
    dBodySetPosition(ball, 0, 0, 0.25);
    dBodySetLinearVel(ball, 0, 0, -2.0);
    dGeomSetBody(dCreateSphere(space, 0.04), ball);

    /* The fluid: a 20 x 20 x 8 cm block in a 24 x 24 x 20 cm tank on the ground. */
    char err[256];
    stf_fluid_def def = stf_default_fluid_def();
    def.spacing = 0.01;
    stf_fluid *fluid;
    if (stf_fluid_create(&def, &fluid, err, sizeof err) != 0) return fprintf(stderr, "%s\n", err), 1;
    stf_fluid_add_block(fluid, (double[3]){-0.1, -0.1, 0}, (double[3]){0.1, 0.1, 0.08},
                        (double[3]){0, 0, 0});

    stf_ode *coupler = stf_ode_create(world, space, fluid);                      /* 1 */
    stf_ode_attach_container(coupler, 0, (double[3]){0, 0, 0}, (double[3]){0.24, 0.24, 0.2},
                             0.01, NULL, err, sizeof err);                        /* 2 */
    stf_ode_attach_body(coupler, ball, NULL, err, sizeof err);                    /* 3 */

    for (int step = 0; step < 500; step++) {
        if (stf_ode_step(coupler, 0.001) != 0) {                                  /* 4 */
            fprintf(stderr, "fluid failed: %s\n", stf_fluid_failure(fluid));
            return 3;
        }
        if (step % 100 == 99) {
            const dReal *p = dBodyGetPosition(ball), *v = dBodyGetLinearVel(ball);
            printf("t = %.2f s  ball z = %.4f m  vz = %+.3f m/s\n", (step + 1) * 0.001, p[2], v[2]);
        }
    }
    stf_ode_destroy(coupler);
    stf_fluid_destroy(fluid);
    dSpaceDestroy(space);
    dWorldDestroy(world);
    dCloseODE();
    return 0;
}
