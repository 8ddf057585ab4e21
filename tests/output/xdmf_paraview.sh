#!/usr/bin/env bash
# A run's frames.xmf opened with ParaView's own default reader: every particle a cell, every
# attribute at the middle time step (tests/output/check_xdmf_paraview.py), opened as
# ./frames.xmf from the run folder and by its absolute path.
# Usage: xdmf_paraview.sh MPM SOURCE_DIR WORK_DIR
set -euo pipefail
mpm=$1
src=$2
work=$3
pvpython=/usr/bin/pvpython
if [ ! -x "$pvpython" ]; then
  echo "xdmf_paraview: $pvpython not found: install ParaView with scripts/install-deps.sh" >&2
  exit 1
fi
rm -rf "$work"
mkdir -p "$work"
# two_cubes at a coarser grid and 8 particles per cell: about 7,600 particles, 4 frames.
"$mpm" run "$src/scenes/two_cubes.yaml" --frames 4 --out "$work/run" --format hdf5 \
  --set grid.dims=40 --set 'objects[0].particles_per_cell=8' \
  --set 'objects[1].particles_per_cell=8' > "$work/mpm.log" 2>&1 ||
  { cat "$work/mpm.log"; exit 1; }
cd "$work/run"
"$pvpython" "$src/tests/output/check_xdmf_paraview.py" ./frames.xmf
"$pvpython" "$src/tests/output/check_xdmf_paraview.py" "$work/run/frames.xmf"
