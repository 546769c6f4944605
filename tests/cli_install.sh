#!/usr/bin/env bash
# `cmake --install` gives an outside project what it needs: find_package(stf) and pkg-config.
# Args: STF_BINARY PROJECT_DIR (the build dir is the binary's grandparent).
set -u
build=$(cd "$(dirname "$1")/.." && pwd)
src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "cli_install: $*" >&2; exit 1; }

cmake --install "$build" --prefix "$tmp/prefix" > "$tmp/install.log" 2>&1 || { cat "$tmp/install.log"; fail "install failed"; }
for f in include/stf.h include/stf_ode.h include/stf_io.h lib/libstf.a lib/libstf_ode.a lib/libstf_io.a \
         lib/cmake/stf/stfConfig.cmake lib/pkgconfig/stf.pc lib/pkgconfig/stf_ode.pc lib/pkgconfig/stf_io.pc \
         bin/stf; do
  [ -e "$tmp/prefix/$f" ] || fail "not installed: $f"
done

# find_package(stf)
cmake -S "$src/tests/outside" -B "$tmp/outside" -DCMAKE_PREFIX_PATH="$tmp/prefix" > "$tmp/cfg.log" 2>&1 || { cat "$tmp/cfg.log"; fail "configure of the outside project failed"; }
cmake --build "$tmp/outside" > "$tmp/build.log" 2>&1 || { cat "$tmp/build.log"; fail "build of the outside project failed"; }
"$tmp/outside/outside" || fail "the outside project (CMake) did not run"
"$tmp/outside/outside_io" || fail "the outside project's stf_io program (CMake) did not run"

# The fluid library needs no file format: neither libstf.a nor stf.pc names libfyaml or HDF5.
pcl=$(PKG_CONFIG_PATH="$tmp/prefix/lib/pkgconfig" pkg-config --libs --static stf) || fail "pkg-config stf failed"
case "$pcl" in *fyaml*|*hdf5*) fail "stf.pc links a file format: $pcl";; esac
nm -u "$tmp/prefix/lib/libstf.a" 2>/dev/null | grep -qE ' (fy_|H5)' && fail "libstf.a calls libfyaml or HDF5"

# pkg-config
PKG_CONFIG_PATH="$tmp/prefix/lib/pkgconfig" cc -std=c11 "$src/tests/outside/main.c" -o "$tmp/outside_pc" \
  $(PKG_CONFIG_PATH="$tmp/prefix/lib/pkgconfig" pkg-config --cflags --libs stf_ode) || fail "pkg-config build failed"
"$tmp/outside_pc" || fail "the outside project (pkg-config) did not run"
PKG_CONFIG_PATH="$tmp/prefix/lib/pkgconfig" cc -std=c11 "$src/tests/outside/io_main.c" -o "$tmp/outside_io_pc" \
  $(PKG_CONFIG_PATH="$tmp/prefix/lib/pkgconfig" pkg-config --cflags --libs stf_io) || fail "pkg-config build (stf_io) failed"
"$tmp/outside_io_pc" || fail "the outside project's stf_io program (pkg-config) did not run"
echo "cli_install: ok"
