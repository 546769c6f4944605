#!/usr/bin/env bash
# cli_walls.sh - the relaxation's walls and the fluid's energy (effects.pressure.wall).
# Clavet's pair displacements are the gradient of one energy; the ghost wall's push is its
# gradient too, the mirror's is not (src/pressure.c). A wall that is the gradient of the
# energy can only give back what it took, so with viscosity the fluid's motion at rest can
# only die down; a wall that is not can keep it up. Two boxes of the cornstarch material's
# liquid (tests/scenes/still_box.yaml, 1,728 particles at 2.5 cm, settled for 1 s), 3 s each:
#  1. under gravity, with viscosity: with the ghost wall the particles' rms speed at the end
#     must be below the one at t = 0 and below the mirror's at the end;
#  2. closed by a lid, without gravity or viscosity, held 8% above the rest density (a
#     fluid under a uniform pressure): with the ghost wall the settled fluid must stay at
#     rest (rms speed under 1 mm/s on every frame); the mirror's is printed beside it.
# Args: STF_BINARY PROJECT_DIR
. "$(dirname "$0")/lib_cli.sh" cli_walls "$@"
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive
box=$PROJ/tests/scenes/still_box.yaml
closed=(--set 'effects.gravity.g=[0,0,0]' --unset effects.viscosity
        --set effects.pressure.rest=lattice --set effects.pressure.rest_density=2.45
        --set 'container.size=[0.3,0.3,0.4]'
        --set 'bodies=[{name: lid, shape: box, size: [0.36, 0.36, 0.05], position: [0, 0, 0.325], motion: static}]')
for wall in mirror ghost; do
    "$STF" run "$box" --duration 3 --set effects.pressure.wall=$wall -o pool_$wall.h5 --quiet \
        2>err.txt || fail "the pool with the $wall wall did not run: $(cat err.txt)"
    "$STF" run "$box" --duration 3 "${closed[@]}" --set effects.pressure.wall=$wall \
        -o closed_$wall.h5 --quiet 2>err.txt || fail "the closed box with the $wall wall did not run: $(cat err.txt)"
done
[ $fails -eq 0 ] || exit 1
/usr/bin/python3 - <<'PY' || fail "the ghost wall added energy to a fluid at rest"
import sys, h5py, numpy as np
def rms(fn):
    """rms particle speed (mm/s) on every frame, particles inside the container only"""
    f = h5py.File(fn, "r")
    ks = sorted((k for k in f if k.startswith("Step#")), key=lambda k: int(k[5:]))
    z0 = f.attrs["container_z0"]
    out = []
    for k in ks:
        v = np.stack([f[k + "/vx"][:], f[k + "/vy"][:], f[k + "/vz"][:]], 1)
        inside = f[k + "/z"][:] > z0
        out.append(1000 * np.sqrt((v[inside] ** 2).sum(1).mean()))
    return np.array(out)
ok = True
pm, pg = rms("pool_mirror.h5"), rms("pool_ghost.h5")
print("cli_walls: pool under gravity, rms speed at 0 / 1.5 / 3 s: mirror %.1f / %.1f / %.1f mm/s, "
      "ghost %.1f / %.1f / %.1f mm/s" % (pm[0], pm[len(pm) // 2], pm[-1], pg[0], pg[len(pg) // 2], pg[-1]))
if not (pg[-1] < pg[0] and pg[-1] < pm[-1]):
    print("cli_walls: the ghost wall's pool did not calm down (or not below the mirror's)")
    ok = False
cm, cg = rms("closed_mirror.h5"), rms("closed_ghost.h5")
print("cli_walls: closed box under pressure, rms speed at 0 / 1.5 / 3 s: mirror %.1f / %.1f / %.1f "
      "mm/s, ghost %.2f / %.2f / %.2f mm/s (largest %.2f)" % (cm[0], cm[len(cm) // 2], cm[-1], cg[0],
      cg[len(cg) // 2], cg[-1], cg.max()))
if not cg.max() < 1.0:
    print("cli_walls: the closed box with the ghost wall did not stay at rest")
    ok = False
sys.exit(0 if ok else 1)
PY
if [ $fails -ne 0 ]; then
    echo "cli_walls: $fails failure(s)" >&2
    exit 1
fi
echo "cli_walls: ok"
