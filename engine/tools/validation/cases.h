#pragma once
/// \file Validation cases: scenes in scenes/validation with exact answers, and how each run is
/// scored against its answer. The references are in docs/validation.md.

#include <filesystem>
#include <string>
#include <vector>

#include "engine/scene/load_scene.h"
#include "engine/run/run.h"

namespace mpm::validation {

/// One measured quantity next to its exact answer.
struct Measure {
  std::string name;    ///< e.g. "period".
  double value = 0;    ///< What the run gave.
  double exact = 0;    ///< The reference answer.
  std::string unit;    ///< SI unit, "" for ratios.
};

/// A quantity sampled over a run, e.g. angular momentum / its start value, per frame.
struct Series {
  std::string name;                ///< What is sampled.
  std::vector<double> t, value;    ///< Times (s) and values.
};

/// What a scored validation run produced.
struct Outcome {
  std::string status = "ok";       ///< The run's status (ok, unstable, ...).
  std::string error_name;          ///< What `error` measures, e.g. "period relative error".
  double error = 0;                ///< The case's headline error (see error_name).
  std::vector<Measure> measures;   ///< Every measured quantity with its exact answer.
  std::vector<Series> series;      ///< Time series for drift plots.
  std::size_t particles = 0;       ///< Particles simulated.
  std::size_t substeps = 0;        ///< Substeps taken.
  double seconds = 0;              ///< Wall time of the substeps, s.

  /// The measure called `name`; throws std::out_of_range if there is none.
  const Measure& measure(const std::string& name) const;
};

/// Watches a validation run and scores it at the end.
class Probe : public Observer {
 public:
  /// Fills the case-specific part of `out` from the finished simulation.
  virtual void score(const Simulation& sim, Outcome& out) = 0;
};

/// A validation case: its scene and the probe that scores a run of it.
struct Case {
  std::string name;         ///< e.g. "bar_vibration".
  std::string description;  ///< One line: what is compared with what.
  Probe* (*make_probe)();   ///< A new probe (owned by the caller).
};

/// All validation cases, in the order of docs/validation.md.
const std::vector<Case>& cases();

/// The case called `name`, or nullptr.
const Case* find_case(const std::string& name);

/// scenes/validation/<name>.yaml in the source tree.
std::filesystem::path scene_path(const Case& c);

/// Loads the case's scene with `overrides`, runs it to its last frame and scores it.
/// Throws SceneError for overrides the scene does not accept.
Outcome run_case(const Case& c, const std::vector<SceneOverride>& overrides = {});

/// Total angular momentum about the origin, including APIC's affine part
/// sum_p m_p eps : (C_p D_p)^T (Jiang et al. 2015, section 5.3), kg m^2/s.
Vec3 angular_momentum(const Simulation& sim);

/// Total linear momentum, kg m/s.
Vec3 linear_momentum(const Simulation& sim);

}  // namespace mpm::validation
