/* A minimal outside user of libstf + libstf_ode: a blob of fluid settles on a fixed plane.
 * Exits 0 when it ran and the blob stayed above the plane. */
#include <stdio.h>
#include <stf_ode.h>

int main(void)
{
    dInitODE2(0);
    dWorldID w = dWorldCreate();
    dWorldSetGravity(w, 0, 0, -9.81);
    char err[256];
    stf_fluid_def d = stf_default_fluid_def();
    d.spacing = 0.02;
    stf_fluid *f;
    if (stf_fluid_create(&d, &f, err, sizeof err)) return fprintf(stderr, "%s\n", err), 1;
    stf_fluid_add_block(f, (double[3]){0, 0, 0.01}, (double[3]){0.1, 0.1, 0.1}, (double[3]){0, 0, 0});
    dSpaceID s = dSimpleSpaceCreate(0);
    dGeomID ground = dCreatePlane(s, 0, 0, 1, 0);
    stf_ode *c = stf_ode_create(w, s, f);
    if (stf_ode_attach_geom(c, ground, NULL, err, sizeof err)) return fprintf(stderr, "%s\n", err), 1;
    for (int i = 0; i < 200; i++)
        if (stf_ode_step(c, 0.001)) return fprintf(stderr, "%s\n", stf_fluid_failure(f)), 3;
    int n = stf_fluid_count(f);
    double x[3 * 125];
    if (n > 125) return 1;
    stf_fluid_get_positions(f, x);
    for (int i = 0; i < n; i++)
        if (x[3 * i + 2] < 0) return fprintf(stderr, "particle %d below the plane\n", i), 1;
    printf("outside: %d particles settled on the plane\n", n);
    stf_ode_destroy(c);
    stf_fluid_destroy(f);
    dSpaceDestroy(s);
    dWorldDestroy(w);
    dCloseODE();
    return 0;
}
