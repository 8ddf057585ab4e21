#!/usr/bin/env bash
# Installs every Debian package the engine needs to build and test.
# Safe to run again: it only installs what is missing.
set -euo pipefail

packages=(
  build-essential cmake pkg-config
  libeigen3-dev libyaml-cpp-dev libassimp-dev libhdf5-dev
  libspdlog-dev libfmt-dev libpng-dev catch2
  libhwy-dev                         # Highway: the SIMD transfers
  libopenvdb-dev libboost-iostreams-dev python3-openvdb  # OpenVDB (its CMake module needs Boost iostreams); Python module for tests
  clang-14 libclang-rt-14-dev libomp-14-dev llvm-14  # fuzzing: libFuzzer, sanitizers, symbolizer
  paraview python3-paraview          # the frames.xmf test opens a run with ParaView's reader
  xvfb xauth libgl1-mesa-dri         # xvfb-run pvpython: ParaView screenshots without a display
  python3-h5py python3-matplotlib python3-yaml  # scripts/plot_frames.py (run by /usr/bin/python3)
  python3-scipy                      # scripts/snow_fragments.py (connected fragments)
  libopenmpi-dev openmpi-bin libhdf5-openmpi-dev  # MPI: mpirun -np N mpm run (docs/distributed.md)
  time                               # GNU time: scripts/ab_time.sh
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
sudo_cmd=()
[ "$(id -u)" -ne 0 ] && sudo_cmd=(sudo)
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
