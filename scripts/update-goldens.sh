#!/usr/bin/env bash
# Regenerates tests/golden/<scene>.summary.yaml for every scene in scenes/ (1 frame each),
# with the build in build/. Review the diff before committing: see docs/regression-testing.md.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p tests/golden
for scene in scenes/*.yaml; do
  name=$(basename "$scene" .yaml)
  build/bin/mpm golden "$scene" --frames 1 -o "tests/golden/$name.summary.yaml" --force --quiet
done
