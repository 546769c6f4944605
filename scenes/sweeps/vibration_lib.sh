# vibration_lib.sh - sourced by vibration_checks.sh and vibration_why.sh.
# layer NAME HALF_WIDTH DEPTH HISTORY(0|1) D ONSET: a scene's head, 3 s at 1 cm, the bowling
# pool's fluid before the cornstarch material (its k_hist 2e5 at 2 cm without the material's
# spacing scaling, pressure k 1000, no liquid springs) in a box of the given half width and
# depth (m), with or without history: the set the "Not reproduced" measurements of
# scenes/README.md were taken with
layer() {
    cat <<YAML
name: $1
duration: 3.0
dt: 0.001
frame_rate: 30
fluid:
  model: clavet_stf
  spacing: 0.01
  density: 1270
  blocks:
    - {min: [-$2, -$2, 0.0], max: [$2, $2, $3]}
effects:
  gravity: {g: [0, 0, -9.81]}
  viscosity: {sigma: 10.0}
  pressure: {k: 1000, k_near: 200}
  springs: {k_min: 100, yield_ratio: 0.0, plasticity: 2.0}
YAML
    [ "$4" = 1 ] && cat <<YAML
  history: {q: 0.5, d: $5, k_hist: 200000, reference_spacing: 0.02, k_onset: $6}
  boundary_stick: {stick: 200}
YAML
    return 0
}
