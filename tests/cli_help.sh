# cli_help.sh - the command line's conventions:
#  - `stf --help`, `stf -h`, and `stf CMD --help` / `-h` for every command and every
#    benchmark (stf bench NAME --help), wherever the option is on the line: the usage on
#    stdout ("usage: stf CMD ..."), with every option of the synopsis explained and the exit
#    codes, nothing on stderr, exit 0, nothing run or written;
#  - `stf --version`: "stf VERSION", the project version of CMakeLists.txt, exit 0;
#  - a usage error (an unknown option, no command): exit 2, the usage on stderr, nothing on
#    stdout;
#  - what cannot be run is refused, exit 2, with a message naming the option (or the scene
#    file's line and key, or the --set) and nothing written (an earlier out.h5 unchanged, no
#    out.xmf, no directory): a duration of 1e300 s or of 0 steps (its step count overflowed
#    and the run exited 0 after 0 steps), a dt or frame_rate whose steps overflow, a
#    fluid.settle of more than 1e9 steps, and counts beyond an int (threads, frames, steps,
#    sweep values and runs).
#
# usage: bash cli_help.sh STF_BINARY PROJECT_DIR   (run in the build's tests directory)
. "$(dirname "$0")/lib_cli.sh" cli_help "$@"

SCENE="$PROJ/tests/scenes/small_drop.yaml"
export OMP_NUM_THREADS=1

# ------------------------------------------------------------------------------- --help
# help_ok NAME CMD... : exit 0, stdout starts with "usage: stf NAME", explains every option
# of its synopsis (the lines up to the first one that is not indented) and the exit codes;
# stderr empty.
help_ok() {
    local name=$1
    shift
    "$STF" "$@" >help.out 2>help.err
    local rc=$?
    [ $rc -eq 0 ] || fail "stf $*: exit $rc, want 0"
    [ -s help.err ] && fail "stf $*: stderr not empty: $(head -c 200 help.err)"
    head -1 help.out | grep -q "^usage: stf $name\\b" || fail "stf $*: stdout does not start with 'usage: stf $name': $(head -1 help.out)"
    grep -q "^exit codes:" help.out || fail "stf $*: no exit codes"
    # the synopsis, then the rest: each --option of the synopsis is in the rest
    awk 'NR == 1 || (go && /^ /) { print; next } { go = 0 } BEGIN { go = 1 }' help.out >syn.txt
    awk 'NR == 1 || (go && /^ /) { next } { go = 0; print } BEGIN { go = 1 }' help.out >rest.txt
    local opt
    for opt in $(grep -o -- '--[a-z][a-z-]*' syn.txt | sort -u); do
        grep -q -- "$opt\\b" rest.txt || fail "stf $*: $opt of the synopsis is not explained"
    done
}

for h in --help -h; do
    "$STF" $h >top.out 2>top.err
    [ $? -eq 0 ] && [ ! -s top.err ] && grep -q "^usage: stf COMMAND" top.out ||
        fail "stf $h: want the usage on stdout, exit 0"
    for c in run check report render plot history sweep; do help_ok "$c" "$c" $h; done
    help_ok "bench" bench $h
    for b in table1 effects accuracy scaling grid dam convergence; do
        help_ok "bench $b" bench "$b" $h
    done
done
# every command is in stf --help, and its own help names only itself
for c in run check report render plot history bench sweep; do
    grep -q "^  stf $c " top.out || fail "stf --help does not list $c"
done
"$STF" render --help | grep -q "stf run" && fail "stf render --help: prints other commands' usage"

# --help anywhere on the line: the usage, nothing run, nothing written
help_ok run run "$SCENE" -o new.h5 --duration 1 --help
help_ok check check "$SCENE" -o new.h5 -h
help_ok "bench table1" bench table1 "$SCENE" --steps 1 --warmup 0 --help
help_ok "bench convergence" bench convergence "$SCENE" -o newdir --help
help_ok sweep sweep "$SCENE" --vary bodies.0.mass=0.05,0.1 -o newdir --help
help_ok render render new.h5 -o newdir --help
help_ok history history -o newdir -h
[ -e new.h5 ] || [ -e new.xmf ] || [ -e newdir ] && fail "a --help run wrote new.h5 or newdir"
rm -rf new.h5 new.xmf newdir

# ---------------------------------------------------------------------------- --version
want=$(sed -n 's/^project(stf VERSION \([0-9.]*\).*/\1/p' "$PROJ/CMakeLists.txt")
"$STF" --version >ver.out 2>ver.err
rc=$?
[ $rc -eq 0 ] && [ ! -s ver.err ] || fail "stf --version: exit $rc, stderr $(cat ver.err)"
[ -n "$want" ] && [ "$(cat ver.out)" = "stf $want" ] || fail "stf --version: '$(cat ver.out)', want 'stf $want'"

# ------------------------------------------------------------------------- usage errors
# usage_error NAME CMD...: exit 2, "usage: stf NAME" and "unknown" on stderr, stdout empty
usage_error() {
    local name=$1
    shift
    "$STF" "$@" >ue.out 2>ue.err
    local rc=$?
    [ $rc -eq 2 ] || fail "stf $*: exit $rc, want 2"
    [ -s ue.out ] && fail "stf $*: stdout not empty: $(head -c 200 ue.out)"
    grep -q "usage: stf $name\\b" ue.err || fail "stf $*: no 'usage: stf $name' on stderr: $(head -c 300 ue.err)"
    grep -q "unknown" ue.err || fail "stf $*: stderr does not say unknown: $(head -1 ue.err)"
}
usage_error COMMAND --frobnicate
usage_error COMMAND frobnicate
for c in run check report history sweep; do usage_error "$c" "$c" --frobnicate; done
usage_error render render x.h5 --frobnicate
usage_error plot plot x.h5 --frobnicate
usage_error "bench table1" bench table1 --frobnicate
for b in effects accuracy scaling grid dam convergence; do
    usage_error "bench $b" bench "$b" "$SCENE" --frobnicate
done
usage_error bench bench frobnicate
"$STF" >none.out 2>none.err
[ $? -eq 2 ] && [ ! -s none.out ] && grep -q "^usage: stf" none.err || fail "stf without a command: want the usage on stderr, exit 2"

# -------------------------------------------------- what cannot be run: exit 2, no output
# A real earlier output, which a run would overwrite (a file that is not HDF5 is refused
# before anything else, which would hide an overwrite).
"$STF" run "$SCENE" -o out.h5 --quiet --duration 0.01 || { echo "cli_help: the base run failed" >&2; exit 1; }
rm -f out.xmf
cp out.h5 out.h5.ref

# refused NAME PATTERN CMD...: exit 2, stderr matches PATTERN (grep -E), out.h5 unchanged, no
# out.xmf, no dir.
refused() {
    local name=$1 pat=$2
    shift 2
    "$@" >"$name.out" 2>"$name.err"
    local rc=$?
    [ $rc -eq 2 ] || fail "$name: exit $rc, want 2 (command: $*; stderr: $(head -c 300 "$name.err"))"
    grep -E -q -e "$pat" "$name.err" || fail "$name: stderr does not match /$pat/: $(head -c 300 "$name.err")"
    cmp -s out.h5 out.h5.ref || { fail "$name: out.h5 was overwritten"; cp out.h5.ref out.h5; }
    [ -e out.xmf ] && { fail "$name: out.xmf was created"; rm -f out.xmf; }
    [ -e dir ] && { fail "$name: dir was created"; rm -rf dir; }
    return 0
}
RUN=(run "$SCENE" -o out.h5 --quiet)
refused dur_big '^stf run: --duration 1e300: .*more than 1000000000' "$STF" "${RUN[@]}" --duration 1e300
refused dur_check '^stf check: --duration 1e300: ' "$STF" check "$SCENE" -o out.h5 --duration 1e300
refused dur_zero '^stf run: --duration 1e-9: .*0 once rounded' "$STF" "${RUN[@]}" --duration 1e-9
refused dur_inf '--duration' "$STF" "${RUN[@]}" --duration inf
refused dur_nan '--duration' "$STF" "${RUN[@]}" --duration nan
refused set_duration '^--set duration=1e300: duration: ' "$STF" "${RUN[@]}" --set duration=1e300
refused set_dt '^--set dt=1e-300: dt: .*more than' "$STF" "${RUN[@]}" --set dt=1e-300
refused set_rate '^--set frame_rate=1e-20: frame_rate: ' "$STF" "${RUN[@]}" --set frame_rate=1e-20
refused set_settle '^--set fluid.settle=10: fluid\.settle: .*more than' \
    "$STF" "${RUN[@]}" --set dt=1e-9 --set fluid.settle=10
# from the scene file: FILE:LINE:COL: KEY:
sed 's/^duration: .*/duration: 1e300/' "$SCENE" >long.yaml
L=$(grep -n '^duration:' long.yaml | cut -d: -f1)
refused file_duration "^long\\.yaml:$L:11: duration: .*more than" "$STF" run long.yaml -o out.h5 --quiet
sed 's/^duration: .*/duration: 0.0001/' "$SCENE" >short.yaml
refused file_zero "^short\\.yaml:$L:11: duration: .*0 once rounded" "$STF" run short.yaml -o out.h5 --quiet
sed 's/^frame_rate: .*/frame_rate: 1e-20/' "$SCENE" >rate.yaml
L=$(grep -n '^frame_rate:' rate.yaml | cut -d: -f1)
refused file_rate "^rate\\.yaml:$L:13: frame_rate: " "$STF" run rate.yaml -o out.h5 --quiet
# counts beyond an int
BIG=99999999999999999999
refused threads '--threads' "$STF" "${RUN[@]}" --threads $BIG
refused threads_int '--threads' "$STF" "${RUN[@]}" --threads 4294967297
refused ckpt_frames '--checkpoint-frames' "$STF" "${RUN[@]}" --checkpoint-frames $BIG
refused render_every '--every' "$STF" render out.h5 -o dir --every 4294967297
refused render_frames 'frames' "$STF" render out.h5 -o dir --frames 0:4294967297
refused plot_width '--width' "$STF" plot out.h5 -o dir/p.png --width 4294967297
refused history_steps '--steps' "$STF" history -o dir --steps 4294967297
refused history_n '--n' "$STF" history -o dir --n $BIG
refused bench_steps '--steps' "$STF" bench effects "$SCENE" --steps 4294967297
refused bench_warmup '--warmup' "$STF" bench effects "$SCENE" --warmup $BIG
refused bench_dam '^stf bench dam: --duration 1e300: ' "$STF" bench dam "$SCENE" --duration 1e300
refused bench_conv '^stf bench convergence: --duration 1e300: ' \
    "$STF" bench convergence "$SCENE" --duration 1e300 -o dir
refused bench_acc '^stf bench accuracy: --duration 3e5: .*dt = 0\.00025 s' \
    "$STF" bench accuracy "$SCENE" --duration 3e5 -o dir
refused sweep_dur '^stf sweep: --duration 1e300 \(run 0\): ' \
    "$STF" sweep "$SCENE" --vary bodies.0.mass=0.05,0.1 -o dir --duration 1e300
refused sweep_dt '^stf sweep: --duration 10 \(run 1\): .*dt = 1e-09' \
    "$STF" sweep "$SCENE" --vary dt=0.001,1e-9 -o dir --duration 10
refused sweep_set '^--set duration=1e300: duration: ' \
    "$STF" sweep "$SCENE" --vary duration=0.1,1e300 -o dir
refused sweep_count 'COUNT' "$STF" sweep "$SCENE" --vary bodies.0.mass=0:1:4294967297 -o dir
refused sweep_runs 'more than 100000 runs' \
    "$STF" sweep "$SCENE" --vary bodies.0.mass=0:1:1000 --repeat 1000 -o dir
refused sweep_jobs '--jobs' "$STF" sweep "$SCENE" --vary bodies.0.mass=0.05 -o dir --jobs $BIG
refused sweep_repeat '--repeat' "$STF" sweep "$SCENE" --vary bodies.0.mass=0.05 -o dir --repeat 4294967297

if [ $fails -ne 0 ]; then
    echo "cli_help: $fails failure(s)" >&2
    exit 1
fi
echo "cli_help: ok"
exit 0
