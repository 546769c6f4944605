# lib_cli.sh - the common start of the cli_*.sh tests. Source it first:
#     . "$(dirname "$0")/lib_cli.sh" NAME "$@"
# It reads the test's arguments STF_BINARY PROJECT_DIR into STF and PROJ, makes a work
# directory that is removed at exit and enters it (WORK), and defines fails (0) and
# fail MESSAGE, which prints "NAME: FAIL: MESSAGE" and counts it. The environment
# (OpenMP threads) stays the test's to set.
set -u
cli_name=$1
STF=${2:?usage: $cli_name.sh STF_BINARY PROJECT_DIR}
PROJ=${3:?usage: $cli_name.sh STF_BINARY PROJECT_DIR}
STF=$(realpath "$STF" 2>/dev/null || echo "$STF") # still valid once in WORK
WORK=$(mktemp -d "${PWD}/$cli_name.XXXXXX") || { echo "$cli_name: cannot make a work dir" >&2; exit 1; }
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
fails=0
fail() { echo "$cli_name: FAIL: $*" >&2; fails=$((fails + 1)); }

# grown FILE PID BYTES: waits until FILE holds more than BYTES (PID is past its start-up, in
# its loop, its signal handlers set); 1 if PID ended first. No wall-clock limit: a loaded
# machine makes a run slow, not wrong (ctest's timeout catches a hang).
grown() {
    while kill -0 "$2" 2>/dev/null; do
        [ "$(stat -c %s "$1" 2>/dev/null || echo 0)" -gt "$3" ] && return 0
        sleep 0.05
    done
    return 1
}
