# cli_bad_input.sh - bad input to the command-line tool: every case exits 2 (bad
# input), says on stderr what is wrong and where (FILE:LINE:COL: KEY: ... for scene files,
# the override for --set, the flag, the path), and leaves no output behind: an existing
# out.h5 keeps its content and no out.xmf appears.
#
# usage: bash cli_bad_input.sh STF_BINARY PROJECT_DIR   (run in the build's tests directory)
. "$(dirname "$0")/lib_cli.sh" cli_bad_input "$@"

BASE="$PROJ/tests/scenes/small_drop.yaml"

[ -r "$BASE" ] || { echo "cli_bad_input: $BASE missing" >&2; exit 1; }

# The reference output file a failed run must not touch: a real output of an earlier run
# (a non-HDF5 file is refused before anything else, which would hide a late overwrite).
"$STF" run "$BASE" -o out.h5 --quiet --duration 0.01 || { echo "cli_bad_input: base run failed" >&2; exit 1; }
rm -f out.xmf
cp out.h5 out.h5.ref

# line_of FILE REGEX: 1-based number of the first line matching REGEX.
line_of() { grep -n -E -m1 "$2" "$1" | cut -d: -f1; }

# expect_bad NAME PATTERN... -- CMD ARGS...: CMD must exit 2, stderr must match every
# PATTERN (grep -E), out.h5 must be unchanged and no out.xmf created.
expect_bad() {
    local name=$1
    shift
    local pats=()
    while [ "$1" != "--" ]; do
        pats+=("$1")
        shift
    done
    shift
    "$@" >"$name.stdout" 2>"$name.stderr"
    local rc=$?
    [ $rc -eq 2 ] || fail "$name: exit $rc, want 2 (command: $*; stderr: $(head -c 300 "$name.stderr"))"
    [ -s "$name.stderr" ] || fail "$name: no message on stderr"
    local p
    for p in "${pats[@]}"; do
        grep -E -q -e "$p" "$name.stderr" || fail "$name: stderr does not match /$p/: $(head -c 300 "$name.stderr")"
    done
    cmp -s out.h5 out.h5.ref || fail "$name: out.h5 was overwritten"
    [ -e out.xmf ] && fail "$name: out.xmf was created" && rm -f out.xmf
    cp out.h5.ref out.h5
    return 0
}

# A scene made from the base scene by a sed script.
mk() { sed -e "$2" "$BASE" >"$1"; }

# --- scene files: FILE:LINE:COL: KEY: -------------------------------------------------
mk missing.yaml '/^duration:/d'
expect_bad missing 'missing\.yaml:1:1: duration: ' 'missing|required' -- \
    "$STF" run missing.yaml -o out.h5 --quiet

mk wrongtype.yaml 's/^  spacing: 0.01/  spacing: "abc"/'
L=$(line_of wrongtype.yaml '^  spacing:')
# the value starts at column 12 (13 inside the quotes)
expect_bad wrongtype "wrongtype\\.yaml:$L:1[23]: fluid\\.spacing: " -- \
    "$STF" run wrongtype.yaml -o out.h5 --quiet

mk unknown.yaml 's/^frame_rate: 50/frame_rate: 50\ncolour: red/'
L=$(line_of unknown.yaml '^colour:')
expect_bad unknown "unknown\\.yaml:$L:1: colour: " 'unknown key' -- \
    "$STF" run unknown.yaml -o out.h5 --quiet

# names become HDF5 group and file names
mk badname.yaml 's/^name: small_drop/name: "small drop\/x"/'
expect_bad badname 'badname\.yaml:3:[78]: name: ' 'A-Za-z0-9' -- \
    "$STF" run badname.yaml -o out.h5 --quiet

mk negspacing.yaml 's/^  spacing: 0.01/  spacing: -0.01/'
L=$(line_of negspacing.yaml '^  spacing:')
expect_bad negspacing "negspacing\\.yaml:$L:12: fluid\\.spacing: " '> 0' -- \
    "$STF" run negspacing.yaml -o out.h5 --quiet

# mass on a kinematic body would be ignored: refused
mk kinmass.yaml 's/^    mass: 0.05/    mass: 0.05\n    motion: kinematic/'
L=$(line_of kinmass.yaml '^    mass:')
expect_bad kinmass "kinmass\\.yaml:$L:5: bodies\\.0\\.mass: " 'only for motion: dynamic' -- \
    "$STF" run kinmass.yaml -o out.h5 --quiet

mk q15.yaml 's/q: 0.5,/q: 1.5,/'
L=$(line_of q15.yaml '^  history:')
C=$(($(sed -n "${L}p" q15.yaml | awk '{print index($0, "1.5")}')))
expect_bad q15 "q15\\.yaml:$L:$C: effects\\.history\\.q: " -- \
    "$STF" run q15.yaml -o out.h5 --quiet

mk d0.yaml 's/d: 50,/d: 0,/'
L=$(line_of d0.yaml '^  history:')
C=$(($(sed -n "${L}p" d0.yaml | awk '{print index($0, "d: 0") + 3}')))
expect_bad d0 "d0\\.yaml:$L:$C: effects\\.history\\.d: " -- \
    "$STF" run d0.yaml -o out.h5 --quiet

# ranges of the fluid's def are the fluid's own check (stf_fluid_check_def), reported at
# the key: one the fluid alone refused before (no gauss_seidel), one of a material file
mk damping.yaml 's/plasticity: 2.0}/plasticity: 2.0, damping: 0.1}/'
L=$(line_of damping.yaml '^  springs:')
C=$(($(sed -n "${L}p" damping.yaml | awk '{print index($0, "0.1}")}')))
expect_bad damping "damping\\.yaml:$L:$C: effects\\.springs\\.damping: needs relaxation gauss_seidel" -- \
    "$STF" run damping.yaml -o out.h5 --quiet
mkdir -p materials
printf 'fluid:\n  density: 1300\neffects:\n  viscosity: {sigma: 3, beta: -1}\n' >materials/sticky.yaml
mk material.yaml 's/^frame_rate: 50/frame_rate: 50\nmaterial: sticky/; s/viscosity: {sigma: 2.0, beta: 0.0}/viscosity: {}/'
expect_bad material "materials/sticky\\.yaml:4:31: effects\\.viscosity\\.beta: must be >= 0" -- \
    "$STF" run material.yaml -o out.h5 --quiet

mk nan.yaml 's/^  density: 1270/  density: .nan/'
L=$(line_of nan.yaml '^  density:')
expect_bad nan "nan\\.yaml:$L:12: fluid\\.density: " -- \
    "$STF" run nan.yaml -o out.h5 --quiet

mk outside.yaml 's/max: \[0.04, 0.04, 0.08\]/max: [0.3, 0.04, 0.08]/'
L=$(line_of outside.yaml '^    - min:')
expect_bad outside "outside\\.yaml:$L:[0-9]+: fluid\\.blocks\\.0: " 'outside the container' -- \
    "$STF" run outside.yaml -o out.h5 --quiet

mk zerospacing.yaml 's/^  spacing: 0.01/  spacing: 0/'
L=$(line_of zerospacing.yaml '^  spacing:')
expect_bad zerospacing "zerospacing\\.yaml:$L:12: fluid\\.spacing: " '> 0' -- \
    "$STF" run zerospacing.yaml -o out.h5 --quiet

mk nanvec.yaml 's/velocity: \[0.2, 0, -0.5\]/velocity: [0.2, .NaN, -0.5]/'
L=$(line_of nanvec.yaml 'velocity: \[0.2')
C=$(($(sed -n "${L}p" nanvec.yaml | awk '{print index($0, ".NaN")}')))
expect_bad nanvec "nanvec\\.yaml:$L:$C: fluid\\.blocks\\.0\\.velocity\\.1: " 'finite' -- \
    "$STF" run nanvec.yaml -o out.h5 --quiet

mk mass0.yaml 's/^    mass: 0.05/    mass: 0/'
L=$(line_of mass0.yaml '^    mass:')
expect_bad mass0 "mass0\\.yaml:$L:11: bodies\\.0\\.mass: " '> 0' -- \
    "$STF" run mass0.yaml -o out.h5 --quiet

mk massneg.yaml 's/^    mass: 0.05/    mass: -0.05/'
L=$(line_of massneg.yaml '^    mass:')
expect_bad massneg "massneg\\.yaml:$L:11: bodies\\.0\\.mass: " '> 0' -- \
    "$STF" run massneg.yaml -o out.h5 --quiet

mk density0.yaml 's/^    mass: 0.05/    density: 0/'
L=$(line_of density0.yaml '^    density:')
expect_bad density0 "density0\\.yaml:$L:14: bodies\\.0\\.density: " '> 0' -- \
    "$STF" run density0.yaml -o out.h5 --quiet

mk nomass.yaml '/^    mass: 0.05/d'
expect_bad nomass "nomass\\.yaml:[0-9]+:[0-9]+: bodies\\.0\\.mass: " 'required' -- \
    "$STF" run nomass.yaml -o out.h5 --quiet

# libfyaml 0.7.12 hangs on this (found by the fuzzer); refused before parsing
printf 'name: x\n%%\377\377\n' >utf8.yaml
expect_bad utf8 'utf8\.yaml:2:2: scene: not UTF-8' -- "$STF" run utf8.yaml -o out.h5 --quiet

# nested aliases that would expand to 10^9 nodes ("billion laughs")
{
    echo 'a0: &a0 [x, x, x, x, x, x, x, x, x, x]'
    for i in 1 2 3 4 5 6 7 8; do
        p=$((i - 1))
        echo "a$i: &a$i [*a$p, *a$p, *a$p, *a$p, *a$p, *a$p, *a$p, *a$p, *a$p, *a$p]"
    done
} >laughs.yaml
# cpu_limit S CMD ARGS...: CMD with at most S seconds of CPU time (killed past it: exit 137 or
# 152, not 2). CPU, not wall-clock time: a loaded machine makes the refusal slow, not costly.
cpu_limit() { (ulimit -t "$1" && shift && exec "$@"); }
expect_bad laughs 'laughs\.yaml:[0-9]+:[0-9]+: scene: aliases expand' -- \
    cpu_limit 20 "$STF" run laughs.yaml -o out.h5 --quiet

# the same errors through `stf check`
expect_bad check_q15 "q15\\.yaml:[0-9]+:[0-9]+: effects\\.history\\.q: " -- \
    "$STF" check q15.yaml -o out.h5

# --- the command line ------------------------------------------------------------------
expect_bad set_spacing '--set fluid\.spacing=-1' 'fluid\.spacing: ' '> 0' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --set fluid.spacing=-1
expect_bad set_q '--set effects\.history\.q=2' 'effects\.history\.q: ' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --set effects.history.q=2
expect_bad set_q0 '--set effects\.history\.q=0' 'effects\.history\.q: ' '\(0,1\)' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --set effects.history.q=0
expect_bad set_q1 '--set effects\.history\.q=1' 'effects\.history\.q: ' '\(0,1\)' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --set effects.history.q=1
expect_bad set_dneg '--set effects\.history\.d=-5' 'effects\.history\.d: ' '>= 1' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --set effects.history.d=-5
expect_bad set_nan '--set effects\.pressure\.k=\.nan' 'effects\.pressure\.k: ' 'finite' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --set effects.pressure.k=.nan
expect_bad set_onset '^--set effects\.history\.k_onset=-1: effects\.history\.k_onset: must be >= 0' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --set effects.history.k_onset=-1
expect_bad set_mass0 '--set bodies\.0\.mass=0' 'bodies\.0\.mass: ' '> 0' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --set bodies.0.mass=0
expect_bad set_outside '--set fluid\.blocks\.0\.max=' 'fluid\.blocks\.0: ' 'outside the container' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --set 'fluid.blocks.0.max=[0.04, 0.04, 0.3]'
# a body that overlaps a wall is refused, as is one under the floor (it would be thrown out
# by the collisions, or fall for ever)
expect_bad body_wall '--set bodies\.0\.position=' 'bodies\.0\.position: ' "overlaps the container's walls" -- \
    "$STF" run "$BASE" -o out.h5 --quiet --set 'bodies.0.position=[0.0, 0.04, 0.1]'
expect_bad body_floor '--set bodies\.0\.position=' 'bodies\.0\.position: ' "under the container's floor" -- \
    "$STF" run "$BASE" -o out.h5 --quiet --set 'bodies.0.position=[0.0, 0.0, -0.5]'
# two fluid blocks that share a volume are legal (the stability tests stack them on purpose)
# but usually a mistake: the run goes on and stderr names the pair, with the file and line;
# blocks that only touch get no note
mk blocks_overlap.yaml '/^      velocity: \[0.2, 0, -0.5\]/a\
    - center: [0.0, 0.0, 0.085]\
      radius: 0.01'
L=$(line_of blocks_overlap.yaml '^    - center:')
"$STF" run blocks_overlap.yaml -o overlap.h5 --quiet --duration 0.01 >overlap.out 2>overlap.err ||
    fail "two overlapping blocks: exit $?: $(tail -n 2 overlap.err)"
grep -E -q "^stf: note: blocks_overlap\.yaml:$L:[0-9]+: fluid\.blocks\.1 overlaps fluid\.blocks\.0" overlap.err ||
    fail "two overlapping blocks: no note naming them: $(head -c 300 overlap.err)"
mk blocks_touch.yaml '/^      velocity: \[0.2, 0, -0.5\]/a\
    - center: [0.0, 0.0, 0.09]\
      radius: 0.01'
"$STF" run blocks_touch.yaml -o touch.h5 --quiet --duration 0.01 >touch.out 2>touch.err ||
    fail "two blocks that touch were refused: $(tail -n 2 touch.err)"
grep -q "note:" touch.err && fail "two blocks that touch got a note: $(head -c 300 touch.err)"
# a body that starts inside the fluid without fluid.settle runs, with a note that it will feel
# no buoyancy until the pressure has built up, naming the body and its line; with settle, none
L=$(line_of "$BASE" '^  - name: ball')
"$STF" run "$BASE" -o immersed.h5 --quiet --duration 0.01 --set 'bodies.0.position=[0, 0, 0.05]' \
    --set 'bodies.0.velocity=[0, 0, 0]' >immersed.out 2>immersed.err ||
    fail "a body inside the fluid: exit $?: $(tail -n 2 immersed.err)"
grep -E -q "^stf: note: body 'ball' \(.*small_drop\.yaml:$L\) starts inside fluid\.blocks\.0 and fluid\.settle is 0" immersed.err ||
    fail "a body inside the fluid: no note naming it: $(head -c 300 immersed.err)"
"$STF" run "$BASE" -o immersed.h5 --quiet --duration 0.01 --set 'bodies.0.position=[0, 0, 0.05]' \
    --set 'bodies.0.velocity=[0, 0, 0]' --set fluid.settle=0.02 >immersed.out 2>immersed.err ||
    fail "a body inside the settled fluid: exit $?: $(tail -n 2 immersed.err)"
grep -q "starts inside" immersed.err && fail "a body inside the settled fluid got the note: $(head -c 300 immersed.err)"
# pressure_gradient offset with a warm start above 0.8 runs, with a note (a tank blew up at 0.9)
/usr/bin/python3 "$PROJ/tests/settling_scene.py" 1.5 0.25 0.002 pressure_gradient=offset settle=0 warm_start=0.9 > offset.yaml
"$STF" run offset.yaml -o offset.h5 --quiet >offset.out 2>offset.err || fail "offset at warm start 0.9: exit $?: $(tail -n 2 offset.err)"
grep -q "^stf: note: .*offset\.yaml: effects\.carreau_yasuda\.pressure_gradient offset with effects\.carreau_yasuda\.warm_start 0\.9" offset.err ||
    fail "offset at warm start 0.9: no note: $(head -c 300 offset.err)"
/usr/bin/python3 "$PROJ/tests/settling_scene.py" 1.5 0.25 0.002 pressure_gradient=offset settle=0 warm_start=0.5 > offset_5.yaml
"$STF" run offset_5.yaml -o offset.h5 --quiet >offset.out 2>offset.err || fail "offset at warm start 0.5: exit $?"
grep -q "pressure_gradient offset with" offset.err && fail "offset at warm start 0.5 got the note: $(head -c 300 offset.err)"
# a body that starts inside another (ODE would throw them apart) is refused; one that only
# touches it runs
expect_bad body_in_body 'bodies\.1\.position: the body .b2. starts inside bodies\.0 \(.ball.\)' -- \
    "$STF" run "$BASE" -o out.h5 --quiet \
    --set 'bodies.1={name: b2, shape: sphere, radius: 0.02, mass: 0.05, position: [0, 0, 0.16]}'
"$STF" run "$BASE" -o touching.h5 --quiet --duration 0.01 \
    --set 'bodies.1={name: b2, shape: box, size: [0.04, 0.04, 0.04], mass: 0.05, position: [0, 0, 0.19]}' \
    >touching.out 2>&1 || fail "a box touching the ball was refused: $(tail -n 2 touching.out)"
# bodies that fill the whole fluid leave nothing to simulate: refused, not run empty
expect_bad body_fills 'small_drop\.yaml: bodies: the bodies overlap every one of the fluid' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --set bodies.0.shape=box --unset bodies.0.radius \
    --set 'bodies.0.size=[0.095, 0.095, 0.07]' --set 'bodies.0.position=[0, 0, 0.055]'
# --set material= chooses the material (it is merged before the other overrides): a missing
# one is refused, not ignored
expect_bad set_material '--set material=nosuch' 'material: cannot read' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --set material=nosuch
expect_bad unset_missing 'effects\.nothing' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --unset effects.nothing
expect_bad bad_flag '--bogus' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --bogus
expect_bad bad_threads '--threads' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --threads zero
expect_bad bad_ckpt_frames '--checkpoint-frames must be a number of frames >= 1' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --checkpoint-frames 0
expect_bad ckpt_both '--checkpoint-frames cannot be combined with --checkpoint' -- \
    "$STF" run "$BASE" -o out.h5 --quiet --checkpoint 5 --checkpoint-frames 3
expect_bad bad_command 'unknown command' -- \
    "$STF" frobnicate "$BASE"
expect_bad no_scene 'nonexistent\.yaml' 'cannot read' -- \
    "$STF" run nonexistent.yaml -o out.h5 --quiet

# output in a directory that does not exist: nothing is created anywhere
expect_bad no_dir 'no_such_dir/out\.h5' -- \
    "$STF" run "$BASE" -o no_such_dir/out.h5 --quiet
[ -e no_such_dir ] && fail "no_dir: the directory was created"

# output paths that cannot be written, or must not be: nothing created, nothing changed
mkdir -p adir
expect_bad out_is_dir 'adir' -- "$STF" run "$BASE" -o adir --quiet
[ -z "$(ls -A adir)" ] || fail "out_is_dir: something was created in adir"
expect_bad out_under_file 'out\.h5/x\.h5' -- "$STF" run "$BASE" -o out.h5/x.h5 --quiet
cp "$BASE" scene_copy.yaml
expect_bad out_is_scene 'scene_copy\.yaml' 'overwrite the scene' -- \
    "$STF" run scene_copy.yaml -o scene_copy.yaml --quiet
cmp -s scene_copy.yaml "$BASE" || fail "out_is_scene: the scene file was changed"
printf 'my notes\n' >notes.txt
expect_bad out_not_hdf5 'notes\.txt' 'not an HDF5 file' -- "$STF" run "$BASE" -o notes.txt --quiet
[ "$(cat notes.txt)" = "my notes" ] || fail "out_not_hdf5: notes.txt was changed"
if [ "$(id -u)" -ne 0 ]; then # root writes into read-only directories
    mkdir -p rodir && chmod a-w rodir
    expect_bad out_readonly 'rodir/out\.h5' -- "$STF" run "$BASE" -o rodir/out.h5 --quiet
    [ -z "$(ls -A rodir)" ] || fail "out_readonly: something was created in rodir"
    chmod u+w rodir
fi

# --- container.periodic (scenes/cy_film_flow.yaml): axes, model, motion, period, bodies ---
FILM="$PROJ/scenes/cy_film_flow.yaml"
# bad_periodic NAME SCENE SED_EXPR REST: SCENE edited by SED_EXPR into NAME.yaml must be
# refused at its container.periodic line, the message matching REST after "LINE:".
bad_periodic() {
    sed "$3" "$2" >"$1.yaml"
    local line
    line=$(line_of "$1.yaml" '^  periodic:')
    expect_bad "$1" "$1\\.yaml:$line:$4" -- "$STF" run "$1.yaml" -o out.h5 --quiet
}
bad_periodic per_z "$FILM" 's/^  periodic: \[x, y\]/  periodic: [x, z]/' \
    "[0-9]+: container\\.periodic\\.1: expected an axis \\(allowed: x, y"
bad_periodic per_twice "$FILM" 's/^  periodic: \[x, y\]/  periodic: [x, x]/' \
    "[0-9]+: container\\.periodic\\.1: axis x given twice"
bad_periodic per_scalar "$FILM" 's/^  periodic: \[x, y\]/  periodic: x/' \
    "[0-9]+: container\\.periodic: expected a list of axes"
bad_periodic per_short "$FILM" 's/^  size: \[0.08, 0.06, 0.2\].*/  size: [0.08, 0.05, 0.2]/' \
    "[0-9]+: container\\.periodic: the period along y .* must be >= 3 h = 0\\.06 m"
bad_periodic per_moving "$FILM" 's/^  periodic: \[x, y\]/  periodic: [x]\n  motion: kinematic/' \
    "3: container\\.periodic: only with a static container"
bad_periodic per_clavet "$BASE" 's/^  friction: 0.2/  friction: 0.2\n  periodic: [x]/' \
    "3: container\\.periodic: only with fluid\\.model: carreau_yasuda"
{ cat "$FILM"; printf 'bodies:\n  - {name: lid, shape: box, size: [0.02, 0.02, 0.02], mass: 0.01, position: [0, 0, 0.15]}\n'; } >per_body.yaml
L=$(line_of per_body.yaml '^bodies:')
expect_bad per_body "per_body\\.yaml:$L:1: bodies: not with container\\.periodic" -- \
    "$STF" run per_body.yaml -o out.h5 --quiet
expect_bad per_set '^--set container\.periodic=\[w\]: container\.periodic\.0: expected an axis' -- \
    "$STF" run "$FILM" --set 'container.periodic=[w]' -o out.h5 --quiet

# --- stf report on a file that is not an stf output ---------------------------------
head -c 4096 /dev/urandom >random.h5
expect_bad report_random 'random\.h5' -- "$STF" report random.h5
expect_bad report_missing 'missing\.h5' -- "$STF" report missing.h5
expect_bad report_json_random 'random\.h5' -- "$STF" report random.h5 --json
: >empty.h5
expect_bad report_empty 'empty\.h5' -- "$STF" report empty.h5
head -c $(($(stat -c %s out.h5.ref) / 2)) out.h5.ref >half.h5
expect_bad report_truncated 'half\.h5' -- "$STF" report half.h5
expect_bad report_dir 'adir' -- "$STF" report adir
/usr/bin/python3 -c 'import h5py; f = h5py.File("other.h5", "w"); f["a"] = [1, 2, 3]' &&
    expect_bad report_other 'other\.h5' 'not an stf output' -- "$STF" report other.h5

if [ $fails -ne 0 ]; then
    echo "cli_bad_input: $fails failure(s)" >&2
    exit 1
fi
echo "cli_bad_input: ok"
exit 0
