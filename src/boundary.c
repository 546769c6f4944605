/* boundary.c - the boundary treatment of the paper's section 3.3.
 *
 * A thickened particle at a wall (within half a spacing of touching it, the mean history
 * stiffness kh of its springs > 0) loses the part of its velocity that goes into the wall,
 * and its tangential velocity decays at the rate stick * kh / (k_min + kh) (a rate, so the
 * result does not depend on dt). Solid-like fluid then sticks to the walls and passes its
 * load to them; as the history stiffness fades the factor returns to 1, and a liquid
 * particle (kh = 0) is left as it is: its wall is the ordinary one, the collision stage's,
 * at contact ("as the stiffness decreases, the particles at the boundaries gradually return
 * to their original behavior"). Cancelling a liquid particle's approach half a spacing
 * before contact as well would be a velocity constraint at a distance: a ball held inside
 * the liquid cornstarch pool (2.5 cm spacing, no history) then felt 1.04 rho V g instead of
 * 1.00-1.02, and a free 7.26 kg ball 6.6% denser than the pool hovered at 1-2 mm/s instead of
 * sinking at 15-35 mm/s (scenes/README.md, "Sinking"). Velocities are relative to the wall,
 * and each change is an impulse the wall receives back. */
#include <math.h>

#include "fluid.h"

static int stick_one(stf_fluid *f, const collider *c, int i, double dt, double *imp)
{
    const double *x = f->x + 3 * i;
    double *v = f->v + 3 * i;
    double band = f->def.spacing, nrm[3];
    double kh = f->khist_mean[i];
    if (!(kh > 0)) return 0; /* liquid: the collision stage's wall, nothing here */
    double d = stf_collider_sdf(c, x, nrm);
    if (d >= band) return 0;
    double keep = exp(-f->def.stick * kh / (f->def.k_min + kh) * dt);
    double vb[3], vrel[3];
    stf_collider_velocity_at(c, x, vb);
    for (int a = 0; a < 3; a++) vrel[a] = v[a] - vb[a];
    double vn = vrel[0] * nrm[0] + vrel[1] * nrm[1] + vrel[2] * nrm[2];
    double old[3] = {v[0], v[1], v[2]};
    double vn_keep = vn < 0 ? 0.0 : vn; /* cancel the part going into the wall */
    for (int a = 0; a < 3; a++) {
        double vt = vrel[a] - vn * nrm[a];
        v[a] = vb[a] + vn_keep * nrm[a] + keep * vt;
    }
    for (int a = 0; a < 3; a++) imp[3 * i + a] = f->mass * (v[a] - old[a]);
    return 1;
}

void stf_boundary_stick(stf_fluid *f, double dt)
{
    if (!f->khist_mean) return; /* no history: nothing thickens, every particle is liquid */
    int n = f->n;
    for (int k = 0; k < f->ncolliders; k++) {
        collider *c = &f->colliders[k];
        if (!c->def.stick) continue;
        char *hit = f->hit;
#pragma omp parallel for schedule(static)
        for (int i = 0; i < n; i++) hit[i] = (char)stick_one(f, c, i, dt, f->dx);
        stf_collider_take_reaction(c, f->dx, f->x, hit, n, STF_PART_STICK);
    }
}
