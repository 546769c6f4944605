#!/usr/bin/env bash
# A shared build exports the public API and nothing else: libstf.so, libstf_ode.so and
# libstf_io.so are built (-DBUILD_SHARED_LIBS=ON, the libraries only) and every dynamic symbol
# they define must be a function their public headers declare with STF_API.
# Args: STF_BINARY PROJECT_DIR.
set -u
src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "cli_exports: $*" >&2; exit 1; }
command -v nm > /dev/null || { echo "cli_exports: no nm: skipped"; exit 77; }

cmake -S "$src" -B "$tmp/b" -DBUILD_SHARED_LIBS=ON -DSTF_BUILD_TESTS=OFF -DCMAKE_BUILD_TYPE=Release \
  > "$tmp/cfg.log" 2>&1 || { cat "$tmp/cfg.log"; fail "configure failed"; }
cmake --build "$tmp/b" -j2 --target stf stf_ode stf_io > "$tmp/build.log" 2>&1 ||
  { tail -30 "$tmp/build.log"; fail "shared build failed"; }

grep -hoE '^STF_API [^(]*\bstf_[a-z0-9_]+\(' "$src/src/stf.h" "$src/ode_glue/stf_ode.h" "$src/src/io/stf_io.h" |
  grep -oE 'stf_[a-z0-9_]+\($' | tr -d '(' | sort -u > "$tmp/api"
[ -s "$tmp/api" ] || fail "no STF_API declarations found"
bad=0
for so in src/libstf.so ode_glue/libstf_ode.so src/io/libstf_io.so; do
  f=$(ls "$tmp/b/$so" 2>/dev/null) || fail "not built: $so"
  # (a named OpenMP critical section's lock, .gomp_critical_user_NAME, is the compiler's: one
  # per program by the OpenMP standard, so it is global by design)
  nm -D --defined-only "$f" | awk '$2 ~ /^[TDBRVW]$/ {print $3}' | grep -v '^\.gomp_critical_user_stf_' |
    sort -u > "$tmp/exp"
  [ -s "$tmp/exp" ] || fail "$so exports nothing"
  extra=$(comm -23 "$tmp/exp" "$tmp/api")
  if [ -n "$extra" ]; then
    echo "cli_exports: $so exports what no public header declares:" $extra >&2
    bad=1
  else
    echo "cli_exports: $so: $(wc -l < "$tmp/exp") symbols, all public"
  fi
done
[ $bad -eq 0 ] || exit 1
# every public function is defined by one of the libraries
for so in src/libstf.so ode_glue/libstf_ode.so src/io/libstf_io.so; do nm -D --defined-only "$tmp/b/$so"; done |
  awk '{print $3}' | sort -u > "$tmp/all"
missing=$(comm -13 "$tmp/all" "$tmp/api")
[ -z "$missing" ] || fail "declared with STF_API but not exported: $missing"
echo "cli_exports: ok ($(wc -l < "$tmp/api") public functions)"
