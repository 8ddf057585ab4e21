#pragma once
/// \file `mpm study`: the validation cases over sweeps of grid spacing, particles per cell,
/// CFL number, dt, transfer scheme, kernel, grid precision and SIMD transfers, with error, wall
/// time and memory per run.

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "engine/tools/validation/cases.h"

namespace mpm::validation {

/// One setting of a sweep, applied to a case's scene as --set overrides.
struct Setting {
  int refine = 1;                     ///< Grid cells per axis = the scene's times this.
  std::optional<int> ppc;             ///< particles_per_cell of every object.
  std::optional<std::string> sampling;///< jittered or regular, every object.
  std::optional<double> cfl;          ///< simulation.cfl.
  std::optional<double> dt;           ///< simulation.dt: the substep, or its cap with cfl.
  std::optional<std::string> transfer;///< apic, pic or flip.
  std::optional<double> flip_blend;   ///< FLIP fraction.
  std::optional<std::string> kernel;  ///< linear, quadratic or cubic.
  std::optional<int> frames;          ///< simulation.frames.
  std::optional<std::string> grid_precision;  ///< grid.precision: float or double.
  std::optional<bool> simd;           ///< simulation.simd: SIMD (true) or scalar transfers.
  std::optional<std::string> boundary;  ///< walls[0].boundary: sticky, slip or separate.
  std::optional<double> friction_angle;  ///< friction_angle of every object, degrees (sand).
  std::optional<int> buffer;  ///< grid.buffer, cells.
  /// The grid moved by minus this many cells on every axis (origin and max alike), so every
  /// wall lies this fraction of a cell further from the node row below it; the particles are
  /// sampled where they were (grid.sampling_origin).
  std::optional<double> wall_offset;
  std::optional<std::string> contact;  ///< simulation.contact: nodes or particles.
  std::optional<std::string> quadrature;  ///< simulation.quadrature: point or domain.
  /// Cells added to the grid on every side, its node rows kept (so walls on the buffer's edge
  /// can move against them).
  std::optional<int> margin;
};

/// One run of a study: what was set and what came out.
struct StudyRow {
  std::string experiment;  ///< Sweep name, e.g. "h_convergence".
  std::string case_name;   ///< Validation case.
  Setting setting;         ///< The settings.
  double h = 0;            ///< Grid spacing, m.
  int ppc = 0;             ///< Particles per cell of the first object.
  std::string sampling;    ///< jittered or regular (first object).
  std::string transfer;    ///< Transfer scheme (with the FLIP fraction, e.g. "flip0.99").
  std::string grid_precision;  ///< Grid node values: "float" or "double".
  bool simd = false;       ///< simulation.simd as run (flip has no SIMD path: scalar anyway).
  std::string kernel;      ///< Kernel name.
  double cfl = 0;          ///< CFL number (0 when dt is fixed).
  double dt = 0;           ///< Fixed dt or dt cap, s.
  Outcome outcome;         ///< Error, measures, series, particles, substeps, seconds.
  double peak_rss_bytes = 0;  ///< Peak resident memory of the run's process.
};

/// What to run.
struct StudyOptions {
  bool quick = false;                    ///< The few-minute variant (tests use it).
  std::vector<std::string> experiments;  ///< Empty: all.
  int threads = 0;                       ///< 0: all cores.
};

/// Names of the study's sweeps.
std::vector<std::string> experiment_names();

/// Runs every setting of the chosen sweeps, each in its own child process (so peak memory is
/// its own); `progress` is called after each run. Throws std::invalid_argument for an unknown
/// sweep.
std::vector<StudyRow> run_study(const StudyOptions& options,
                                const std::function<void(const StudyRow&)>& progress = {});

/// One CSV line per run: settings, error, measures, time, particle-steps, memory.
std::string study_csv(const std::vector<StudyRow>& rows);

/// Long-format CSV of every run's time series: experiment, case, label, series, t, value.
std::string series_csv(const std::vector<StudyRow>& rows);

/// A short label of a row's setting, e.g. "quadratic h=0.025 ppc=8 cfl=0.4 apic".
std::string setting_label(const StudyRow& row);

/// `mpm study`: runs the sweeps, prints one line per run, writes DIR/study.csv and
/// DIR/series.csv. Returns the process exit code (2 for an unknown sweep, 1 if a run failed).
int study_main(const StudyOptions& options, const std::filesystem::path& dir);

/// Least-squares slope of log(error) against log(h): the observed convergence order.
double convergence_order(const std::vector<double>& h, const std::vector<double>& error);

}  // namespace mpm::validation
