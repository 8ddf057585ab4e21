#!/usr/bin/env bash
# Installs the engine into a temporary prefix, builds the example plugin on its own against
# the installed headers and CMake package exactly as docs/materials.md says (no build type),
# checks it was compiled with optimisation, runs the installed generic material checks on it
# (mpm_add_material_tests, through ctest), and checks the engine loads and runs what it built.
# Usage: build_out_of_tree.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" > "$work/install.log"
cmake -S "$src/materials/plugins/stvk" -B "$work/stvk" -DCMAKE_EXPORT_COMPILE_COMMANDS=ON \
  -DCMAKE_PREFIX_PATH="$work/prefix" > "$work/configure.log" || { cat "$work/configure.log"; exit 1; }
cmake --build "$work/stvk" > "$work/build.log" || { cat "$work/build.log"; exit 1; }
lib="$work/stvk/libmpm_stvk.so"
test -f "$lib"
# CMake's default (empty) build type adds no -O; the installed package must.
command=$(grep '"command"' "$work/stvk/compile_commands.json" | grep 'stvk.cpp')
for flag in -O3 -DNDEBUG; do
  echo "$command" | grep -q -- " $flag" ||
    { echo "the plugin was compiled without $flag:"; echo "$command"; exit 1; }
done
# The generic material checks, as the plugin's own test.
ctest --test-dir "$work/stvk" --output-on-failure > "$work/ctest.log" ||
  { cat "$work/ctest.log"; exit 1; }
grep -q 'generic material checks .*Passed' "$work/ctest.log" || { cat "$work/ctest.log"; exit 1; }
out=$("$work/prefix/bin/mpm" materials "$lib")
echo "$out" | grep -q '^stvk:' || { echo "stvk not listed:"; echo "$out"; exit 1; }
# And a scene runs with the out-of-tree plugin (two frames), given on the command line.
sed "s|mesh: meshes/|mesh: $src/scenes/meshes/|" "$src/scenes/plugin_stvk.yaml" > "$work/scene.yaml"
env -u MPM_PLUGIN_PATH "$work/prefix/bin/mpm" run "$work/scene.yaml" --plugin "$lib" --frames 2 \
  --out "$work/out" --quiet
grep -q '^status: ok' "$work/out/report.yaml"
echo "out-of-tree plugin: built with -O3 without a build type, checked, listed and run"
