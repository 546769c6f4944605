// embed_cxx.cpp - the public headers (src/stf.h, ode_glue/stf_ode.h, src/io/stf_io.h) from C++: all compile
// in one C++ translation unit and link to the C libraries (extern "C"). Run by ctest: it
// builds a fluid and a coupler, checks a bad def is refused by name and steps once.
#include <cmath>
#include <cstdio>
#include <cstring>

#include "stf.h"
#include "stf_ode.h"
#include "stf_io.h"

int main()
{
    dInitODE2(0);
    dWorldID world = dWorldCreate();
    dSpaceID space = dHashSpaceCreate(0);
    dWorldSetGravity(world, 0, 0, -9.81);
    char err[256];
    stf_fluid_def def = stf_default_fluid_def();
    def.spacing = 0.02;
    stf_fluid *fluid = nullptr;
    if (stf_fluid_create(&def, &fluid, err, sizeof err) != 0)
        return std::fprintf(stderr, "%s\n", err), 1;
    const double lo[3] = {-0.05, -0.05, 0}, hi[3] = {0.05, 0.05, 0.04}, v0[3] = {0, 0, 0};
    stf_fluid_add_block(fluid, lo, hi, v0);
    stf_ode *c = stf_ode_create(world, space, fluid);
    const double at[3] = {0, 0, 0}, size[3] = {0.1, 0.1, 0.1};
    if (stf_ode_attach_container(c, nullptr, at, size, 0.02, nullptr, err, sizeof err) != 0)
        return std::fprintf(stderr, "%s\n", err), 1;
    stf_ode_contact_def cd = stf_ode_default_contact_def();
    cd.bounce_vel = -1;
    int rc = 0;
    if (stf_ode_set_contact(c, &cd, err, sizeof err) != -1 || !std::strstr(err, "bounce_vel"))
        std::fprintf(stderr, "bad bounce_vel accepted: '%s'\n", err), rc = 1;
    stf_ode_step_def sd = stf_ode_default_step_def();
    sd.stepper = STF_ODE_QUICK_STEP;
    if (stf_ode_set_step(c, &sd, err, sizeof err) != 0) std::fprintf(stderr, "%s\n", err), rc = 1;
    if (stf_ode_step(c, 1.0 / 60) != 0) std::fprintf(stderr, "%s\n", stf_ode_failure(c)), rc = 1;
    stf_ode_stats st;
    stf_ode_get_stats(c, &st);
    std::printf("embed_cxx: %d particles, one step of 1/60 s in %d substeps\n",
                stf_fluid_count(fluid), st.last_substeps);
    stf_ode_destroy(c);
    stf_fluid_destroy(fluid);
    dSpaceDestroy(space);
    dWorldDestroy(world);
    dCloseODE();
    return rc;
}
