#pragma once
/// \file Shared helpers for the test suite.

#include <filesystem>
#include <limits>
#include <random>
#include <string>

#include "engine/scene/load_scene.h"
#include "engine/step/simulation.h"
#include "materials/material_checks.h"

namespace mpm::test {

/// The repository's root folder (set by CMake).
inline std::filesystem::path source_dir() { return MPM_SOURCE_DIR; }

/// The unit cube mesh shipped with the scenes.
inline std::string cube_mesh() { return (source_dir() / "scenes/meshes/cube.obj").string(); }

/// A fresh, empty temporary folder for one test.
inline std::filesystem::path temp_dir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("mpm_test_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

/// Loads a scene from YAML text as if it were a file in the repository's scenes/ folder.
inline SceneDesc scene_from(const std::string& yaml) {
  MaterialRegistry registry = builtin_registry();
  return load_scene_from_string(yaml, source_dir() / "scenes" / "test.yaml", registry);
}

/// Machine epsilon of the particles' stored matrices (F, C, stress): float unless the build
/// sets MPM_DOUBLE_PARTICLES. Tolerances that include storage rounding scale with it.
using checks::kStoredEps;

/// Bound on APIC's relative angular momentum drift over `substeps`: exact in exact arithmetic
/// (Jiang et al. 2015), so round-off (1e-11), plus the rounding of C to StoredReal in every
/// substep, each moving at most eps / 2 of the part of L that C carries (a fraction of L).
inline double apic_bound(std::size_t substeps) {
  return 1e-11 + static_cast<double>(substeps) * kStoredEps / 2;
}

/// `F` rounded to the stored precision; random matrices near I; random rotations (shared with
/// the generic material checks).
using checks::random_near_identity;
using checks::random_rotation;
using checks::stored;

}  // namespace mpm::test
