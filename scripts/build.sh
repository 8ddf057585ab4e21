#!/usr/bin/env bash
# Installs what is missing (Debian packages), then configures and builds a Release build in build/.
# Extra arguments go to CMake's configure step, e.g. scripts/build.sh -DMPM_NATIVE=ON
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release "$@" > build-configure.log 2>&1 || {
  cat build-configure.log
  exit 1
}
cmake --build build --parallel "$(nproc)"
