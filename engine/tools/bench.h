#pragma once
/// \file `mpm bench`: standard cases timed by the engine itself.

#include <optional>
#include <string>
#include <vector>

#include "engine/scene/load_scene.h"

namespace mpm {

/// What to benchmark.
struct BenchOptions {
  /// Case names: jello, snow, sparse (timed substeps of a cube built in code) and two_cubes
  /// (scenes/two_cubes.yaml as a whole run, once: about 12 minutes; not in the default list).
  std::vector<std::string> cases{"jello", "snow", "sparse"};
  long particles = 100000;  ///< Target particle count per case (sparse and jello alike).
  int substeps = 20;        ///< Substeps per timed repetition.
  int repeats = 3;          ///< Timed repetitions (the median is reported), after one warm-up.
  int threads = 0;          ///< 0: all cores.
  bool simd = true;         ///< simulation.simd of every case (false: the scalar double path).
  /// A scene file to time instead of the cases, as `mpm run` runs it: its frames written to a
  /// scratch folder, removed after.
  std::string scene;
  LoadOptions load;           ///< How to load `scene` (its --set overrides and plugins).
  std::optional<int> frames;  ///< `scene`'s frames (default: the file's).
  bool simd_given = false;    ///< `simd` overrides `scene`'s simulation.simd (--simd given).
};

/// One case's measurements.
struct BenchResult {
  std::string name;                  ///< Case name.
  long particles = 0;                ///< Particles simulated.
  long grid_nodes = 0;               ///< Nodes of the whole domain.
  long stored_nodes = 0;             ///< Nodes with storage (the active blocks) at the end.
  int substeps = 0;                  ///< Substeps per repetition.
  int threads = 0;                   ///< Threads used.
  bool simd = true;                  ///< Whether simulation.simd was on.
  double particle_steps_per_second = 0;  ///< Median over repetitions.
  double peak_rss_bytes_per_particle = 0;  ///< Peak resident memory of the case / particles.
  std::vector<std::pair<std::string, double>> stage_ns;  ///< ns per particle-step per stage.
  double contact_iterations = 0;  ///< Mean contact solve iterations per substep with contacts.
  double contact_residual = 0;    ///< Their mean residual (ContactSolveStats), m/s.
};

/// Runs each case in its own child process (so peak memory is per case) and returns results.
/// Throws std::invalid_argument for an unknown case name.
std::vector<BenchResult> run_benchmarks(const BenchOptions& options);

/// The results as an aligned text table, with precision and commit in the header.
std::string format_bench_table(const std::vector<BenchResult>& results);

/// The results as CSV (one row per case and stage).
std::string format_bench_csv(const std::vector<BenchResult>& results);

}  // namespace mpm
