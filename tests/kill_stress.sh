#!/usr/bin/env bash
# kill -9 stress (not part of ctest: it counts, it does not decide). Runs
# tests/scenes/small_drop.yaml with a frame every step, kills it with SIGKILL at a random
# moment N times, and counts the files h5py cannot read completely (every Step#N group's
# x and TimeValue). Unreadable files are kept as bad_I.h5 in the working directory.
# Usage: tests/kill_stress.sh STF_BINARY [N=100]
set -u
stf=$1; n=${2:-100}
src=$(cd "$(dirname "$0")/.." && pwd)
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive
bad=0
for i in $(seq "$n"); do
    rm -f k.h5 k.xmf
    "$stf" run "$src/tests/scenes/small_drop.yaml" -o k.h5 --duration 1000 --quiet \
        --threads 1 --set frame_rate=1000 2>/dev/null &
    pid=$!
    for _ in $(seq 400); do
        [ "$(stat -c %s k.h5 2>/dev/null || echo 0)" -gt 100000 ] && break
        sleep 0.05
    done
    sleep "0.$((RANDOM % 900 + 100))"
    kill -KILL $pid
    wait $pid 2>/dev/null
    /usr/bin/python3 -c '
import h5py
f = h5py.File("k.h5", "r")
for k in f:
    if k.startswith("Step#"):
        f[k]["x"][:]
        f[k].attrs["TimeValue"]' >/dev/null 2>&1 || { bad=$((bad + 1)); cp k.h5 "bad_$i.h5"; }
done
rm -f k.h5 k.xmf
echo "kill_stress: $bad of $n files unreadable ($(uptime | sed 's/.*load/load/'))"
