#!/usr/bin/env bash
# What float particle storage costs in accuracy: the same sweeps of `mpm study` in the default
# build (build/, F, C and stress stored in float) and in a double build (build-double/,
# -DMPM_DOUBLE_PARTICLES=ON), written to docs/accuracy/precision/{float,double}/study.csv, then
# compared row by row in docs/accuracy/precision/compare.md. About ten minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
sweeps=${1:-transfer_bar,transfer_spin,column_h,collision,ppc,dt,compression}
scripts/build.sh
cmake -S . -B build-double -DCMAKE_BUILD_TYPE=Release -DMPM_DOUBLE_PARTICLES=ON \
  -DMPM_BUILD_TESTS=OFF > build-configure-double.log
cmake --build build-double --parallel "$(nproc)" --target mpm
out=docs/accuracy/precision
build/bin/mpm study --cases "$sweeps" -o "$out/float"
build-double/bin/mpm study --cases "$sweeps" -o "$out/double"
python3 scripts/compare_precision.py "$out/float/study.csv" "$out/double/study.csv" > "$out/compare.md"
cat "$out/compare.md"
