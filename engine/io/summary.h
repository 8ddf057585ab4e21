#pragma once
/// \file Run summaries for scene-level regression tests: a few integrals per object and frame,
/// written as summary.yaml, read back, and compared against a golden summary with tolerances.
///
/// docs/regression-testing.md describes the fields, their units, the tolerances and the
/// `mpm compare` / `mpm golden` commands built on these functions.

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "engine/io/output.h"
#include "engine/run/run.h"
#include "engine/step/simulation.h"

namespace mpm {

/// One object's state at one frame, reduced to a few numbers (SI units).
struct ObjectSummary {
  std::string name;                 ///< Object name from the scene.
  std::size_t particles = 0;        ///< Number of particles.
  Vec3 centroid{0, 0, 0};           ///< Centre of mass sum m x / sum m, m.
  Vec3 bbox_min{0, 0, 0};           ///< Smallest particle coordinate per axis, m.
  Vec3 bbox_max{0, 0, 0};           ///< Largest particle coordinate per axis, m.
  double mean_speed = 0;            ///< Mean of |v| over the particles (unweighted), m/s.
  double max_speed = 0;             ///< Largest |v|, m/s.
  double kinetic_energy = 0;        ///< sum m |v|^2 / 2, J.
  double elastic_energy = 0;        ///< sum V0 psi(F) from the object's material, J.
  double gravitational_energy = 0;  ///< -sum m g . (x - grid origin), J.
  Vec3 linear_momentum{0, 0, 0};    ///< sum m v, kg m/s.
  Vec3 angular_momentum{0, 0, 0};   ///< sum m (x - grid origin) x v, kg m^2/s.
};

/// Every object at one frame.
struct FrameSummary {
  int frame = 0;                       ///< Frame number; 0 is the initial state.
  double time = 0;                     ///< Simulated time, s.
  std::vector<ObjectSummary> objects;  ///< In scene order.
};

/// A whole run: one FrameSummary per frame written, in order.
struct RunSummary {
  std::string scene;                 ///< File name of the scene (informative, not compared).
  std::vector<FrameSummary> frames;  ///< Frame 0 first.
};

/// Reduces the current state of `sim` to one FrameSummary. Sums run over fixed chunks in
/// particle order, so the result depends only on the state, not on the thread count. With
/// more than one rank it is collective: each rank sums its own particles and the parts are
/// combined in rank order on every rank.
FrameSummary summarize(const Simulation& sim, int frame);

/// The YAML text of `summary` (numbers in shortest round-trip form, so reading it back gives
/// the same doubles bit for bit).
std::string summary_to_yaml(const RunSummary& summary);

/// Writes `summary` to `file` through a temporary file and a rename, so the file is always
/// whole. Throws std::runtime_error on failure.
void write_summary(const std::filesystem::path& file, const RunSummary& summary);

/// Parses summary YAML text; `name` is used in error messages. Throws std::runtime_error
/// naming `name`, the line and the problem on bad input.
RunSummary parse_summary(const std::string& text, const std::string& name);

/// Reads a file written by write_summary; a folder stands for its summary.yaml (summary_path).
/// Throws std::runtime_error naming the file and the problem (missing file, bad YAML, missing
/// or mistyped key, with the line).
RunSummary read_summary(const std::filesystem::path& file);

/// `path` itself if it is a file, or `path`/summary.yaml if it is a folder (an output folder).
std::filesystem::path summary_path(const std::filesystem::path& path);

/// Records a RunSummary while a run goes: frame 0 on start, every completed frame, and writes
/// DIR/summary.yaml after each of them and at the end, so an interrupted run keeps what it has.
class SummaryWriter : public Observer {
 public:
  /// Writes `dir`/`file_name` (the folder is created if missing).
  explicit SummaryWriter(std::filesystem::path dir, std::string file_name = "summary.yaml");
  /// Records the state on entry (frame 0, or the resumed frame after the file's earlier ones).
  void on_start(const Simulation& sim, int frames) override;
  /// Records frame `frame` and rewrites the file.
  void on_frame(const Simulation& sim, int frame) override;
  /// Rewrites the file, whatever the status.
  void on_finish(const Simulation& sim, const RunResult& result) override;
  /// summarize() reduces over the ranks; only rank 0 keeps and writes the summary.
  bool collective() const override { return true; }
  /// What has been recorded so far.
  const RunSummary& summary() const { return summary_; }
  /// The file written.
  const std::filesystem::path& file() const { return file_; }

 private:
  void write() const;
  std::filesystem::path file_;
  RunSummary summary_;
};

/// Largest allowed absolute difference per kind of quantity, in SI units. Each applies to every
/// component, object and frame of the quantities it covers.
struct Tolerances {
  double centroid = 0;          ///< centroid, m.
  double bbox = 0;              ///< bbox_min and bbox_max, m.
  double speed = 0;             ///< mean_speed and max_speed, m/s.
  double energy = 0;            ///< kinetic, elastic and gravitational energy, J.
  double momentum = 0;          ///< linear_momentum, kg m/s.
  double angular_momentum = 0;  ///< angular_momentum, kg m^2/s.
};

/// Relative factors used by default_tolerances (documented in docs/regression-testing.md).
struct RelativeTolerances {
  double centroid = 1e-3;  ///< Times the largest object extent.
  double bbox = 5e-3;      ///< Times the largest object extent.
  double speed = 5e-3;     ///< Times the largest max_speed of the run.
  double energy = 1e-3;    ///< Times the energy scale E (see default_tolerances).
  double momentum = 5e-3;  ///< Times the largest |p| of an object (angular: times the lever arm).
};

/// Tolerances scaled to the reference run: lengths by L, the largest bbox extent of any object
/// in any frame; speeds by the largest max_speed; energies by E, the largest sum over objects
/// of |kinetic| + |elastic| in a frame plus the range of the total gravitational energy over
/// the run (its size depends only on where the grid origin is); linear momentum by the largest
/// |p| of an object; angular momentum by that |p| times R, the farthest bbox corner from the
/// grid origin. A scale that is zero (nothing moves) gives a zero tolerance.
Tolerances default_tolerances(const RunSummary& reference, const RelativeTolerances& rel = {});

/// Applies overrides like "centroid=1e-4" (absolute, SI units) to `base`. Quantities: centroid,
/// bbox, speed, energy, momentum, angular_momentum, and all (sets every one). Throws
/// std::invalid_argument naming the valid quantities for an unknown one, or for a value that is
/// not a finite number >= 0.
Tolerances parse_tolerance_overrides(Tolerances base, const std::vector<std::string>& items);

/// The largest difference of one quantity over all frames, objects and components.
struct Difference {
  std::string quantity;       ///< E.g. "centroid.y" or "kinetic_energy".
  int frame = 0;              ///< Frame where it occurs.
  std::string object;         ///< Object where it occurs.
  double value_a = 0;         ///< Value in the first summary.
  double value_b = 0;         ///< Value in the second (reference) summary.
  double difference = 0;      ///< |value_a - value_b| (infinite if either is not finite).
  double tolerance = 0;       ///< Allowed difference.
  int first_frame_over = -1;  ///< First frame where the tolerance is exceeded; -1 if none.
  /// True if within tolerance.
  bool ok() const { return difference <= tolerance; }
};

/// Outcome of compare_summaries.
struct CompareResult {
  bool ok = false;                  ///< No error and every quantity within tolerance.
  std::vector<Difference> largest;  ///< Per quantity, the largest difference and where.
  std::string error;                ///< Why the summaries cannot be compared; empty if they can.
  int frames = 0;                   ///< Frames compared.
  int objects = 0;                  ///< Objects per frame compared.
};

/// The frames `mpm compare` compares, picked from two whole summaries.
struct FrameSelection {
  RunSummary a;       ///< The frames of the first summary to compare.
  RunSummary b;       ///< The frames of the reference to compare.
  std::string note;   ///< A line saying which frames were compared and which left out; "" if all.
  std::string error;  ///< Why the frames asked for cannot be compared; "" if they can.
};

/// With `last_frame`, the frames up to number last_frame of both (both must reach it). Without,
/// every frame of the reference `b` and as many first frames of `a`: a run may go on past its
/// golden (its first frames are checked) but not stop short of it (compare_summaries then
/// reports the different frame counts).
FrameSelection select_frames(const RunSummary& a, const RunSummary& b,
                             std::optional<int> last_frame = std::nullopt);

/// Compares `a` with the reference `b`. Summaries that do not describe the same run (frame
/// count, frame numbers or times, object names or particle counts differ) give `error`.
CompareResult compare_summaries(const RunSummary& a, const RunSummary& b, const Tolerances& tol);

/// A table of the largest difference per quantity (frame, object, values, tolerance,
/// PASS/FAIL), then a one-line verdict; or the error.
std::string format_comparison(const CompareResult& result);

/// Particle-by-particle difference between two frame files.
struct ParticleDiff {
  std::size_t particles = 0;       ///< Particles compared.
  double max_position = 0;         ///< Largest |x_a - x_b|, m.
  std::size_t position_index = 0;  ///< Particle where it occurs.
  double max_velocity = 0;         ///< Largest |v_a - v_b|, m/s.
  std::size_t velocity_index = 0;  ///< Particle where it occurs.
  double max_J = 0;                ///< Largest |J_a - J_b|.
  std::size_t J_index = 0;         ///< Particle where it occurs.
  std::string error;               ///< Why they cannot be compared; empty if they can.
};

/// Compares two frames particle by particle (Euclidean distance per particle). Frames of
/// different sizes or with different object ids give `error`.
ParticleDiff compare_frames(const FrameData& a, const FrameData& b);

}  // namespace mpm
