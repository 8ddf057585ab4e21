#pragma once
/// \file Shared helpers for the test suite.

#include <filesystem>
#include <random>
#include <string>

#include "engine/load_scene.h"
#include "engine/simulation.h"

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
