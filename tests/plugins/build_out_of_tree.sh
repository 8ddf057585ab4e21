#!/usr/bin/env bash
# Installs the engine into a temporary prefix, builds the example plugin on its own against
# the installed headers and CMake package, and checks the engine loads what it built.
# Usage: build_out_of_tree.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" > "$work/install.log"
cmake -S "$src/materials/plugins/stvk" -B "$work/stvk" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$work/prefix" > "$work/configure.log" || { cat "$work/configure.log"; exit 1; }
cmake --build "$work/stvk" > "$work/build.log" || { cat "$work/build.log"; exit 1; }
lib="$work/stvk/libmpm_stvk.so"
test -f "$lib"
out=$("$work/prefix/bin/mpm" materials "$lib")
echo "$out" | grep -q '^stvk:' || { echo "stvk not listed:"; echo "$out"; exit 1; }
# And a scene runs with the out-of-tree plugin (two frames).
sed "s|plugins: \[libmpm_stvk.so\]|plugins: [$lib]|; s|mesh: meshes/|mesh: $src/scenes/meshes/|" \
  "$src/scenes/plugin_stvk.yaml" > "$work/scene.yaml"
"$work/prefix/bin/mpm" run "$work/scene.yaml" --frames 2 --out "$work/out" --quiet
grep -q '^status: ok' "$work/out/report.yaml"
echo "out-of-tree plugin: built, listed and run"
