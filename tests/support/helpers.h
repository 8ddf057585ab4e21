#pragma once
/// \file Shared helpers for the test suite.

#include <filesystem>
#include <limits>
#include <random>
#include <string>

#include "engine/scene/load_scene.h"
#include "engine/step/simulation.h"

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
inline constexpr double kStoredEps = std::numeric_limits<StoredReal>::epsilon();

/// Bound on APIC's relative angular momentum drift over `substeps`: exact in exact arithmetic
/// (Jiang et al. 2015), so round-off (1e-11), plus the rounding of C to StoredReal in every
/// substep, each moving at most eps / 2 of the part of L that C carries (a fraction of L).
inline double apic_bound(std::size_t substeps) {
  return 1e-11 + static_cast<double>(substeps) * kStoredEps / 2;
}

/// `F` rounded to the stored precision, as the engine would keep it.
inline Mat3 stored(const Mat3& F) { return to_real(to_stored(F)); }

/// A random matrix with entries in [-scale, scale] added to the identity.
inline Mat3 random_near_identity(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  Mat3 m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = (i == j ? 1.0 : 0.0) + u(rng);
  return m;
}

/// A uniformly random rotation.
inline Mat3 random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> n;
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  return q.normalized().toRotationMatrix();
}

}  // namespace mpm::test
