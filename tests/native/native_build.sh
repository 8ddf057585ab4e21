#!/usr/bin/env bash
# The -march=native configuration (scripts/build.sh -DMPM_NATIVE=ON): builds it in
# BUILD_DIR/native and runs the layers that depend on the instruction set the compiler targets:
# the materials (GCC 12's 512-bit auto-vectorization once dropped a float storage round trip
# there; CMakeLists.txt) and the SIMD transfers against the scalar ones. Run by .ci/run after
# the README's test command (not under ctest: a second build would push that past 30 minutes).
# Usage: native_build.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
mkdir -p "$1"
build=$1/native
src=$2
cmake -S "$src" -B "$build" -DCMAKE_BUILD_TYPE=Release -DMPM_NATIVE=ON \
  > "$build.configure.log" 2>&1 || { cat "$build.configure.log"; exit 1; }
cmake --build "$build" --parallel "$(nproc)" --target test_materials test_transfers mpm \
  > "$build.log" 2>&1 || { tail -50 "$build.log"; exit 1; }
"$build/bin/test_materials"
"$build/bin/test_transfers"
"$build/bin/mpm" bench --cases machine --threads 1 | grep "SIMD target"
echo "native build: built and tested"
