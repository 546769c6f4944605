#!/usr/bin/env bash
# Builds the scene-parser fuzzer with clang (libFuzzer + ASan + UBSan) and runs it for
# SECONDS (default 60) from the shipped scenes as seed corpus. Exit 0 when nothing was found.
# Usage: tests/fuzz/run.sh [SECONDS] [BUILD_DIR]
set -euo pipefail
src=$(cd "$(dirname "$0")/../.." && pwd)
secs=${1:-60}
out=${2:-$src/build-fuzz}
mkdir -p "$out/corpus"
cp "$src"/scenes/*.yaml "$src"/tests/scenes/*.yaml "$out/corpus/"
clang -g -O1 -std=c11 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
  -I"$src/src" $(pkg-config --cflags libfyaml hdf5) \
  "$src"/tests/fuzz/fuzz_scene.c "$src"/src/*.c \
  $(pkg-config --libs libfyaml hdf5) -lhdf5_serial_hl -lccd -fopenmp -lm -o "$out/fuzz_scene"
cd "$out"
./fuzz_scene -max_total_time="$secs" -max_len=4096 -print_final_stats=1 corpus 2>&1 | tail -15
