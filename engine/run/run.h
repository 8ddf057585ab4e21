#pragma once
/// \file The frame loop: substeps until each frame time, with observers between steps.

#include <atomic>
#include <optional>
#include <string>
#include <vector>

#include "engine/step/simulation.h"

namespace mpm {

/// Substep sizes within one frame.
struct FrameSteps {
  int frame = 0;           ///< Frame number.
  std::size_t substeps = 0;///< Substeps taken in the frame.
  Real dt_min = 0;         ///< Smallest substep, s.
  Real dt_max = 0;         ///< Largest substep, s.
};

/// Why a run was declared unstable.
struct Instability {
  std::string cause;        ///< What was measured, in words with numbers.
  std::string object;       ///< Object of the offending particle ("" if none in particular).
  int frame = 0;            ///< Frame being computed.
  std::size_t substep = 0;  ///< Substep (counted from the start of the run).
  Real suggested_dt = 0;    ///< dt the CFL bound (cfl 0.5) suggests, s.
};

/// How a run ended: every frame done, stopped by the instability check, by an error, or by a
/// signal (written as status_name in report.yaml).
enum class RunStatus { ok, unstable, error, interrupted };

/// The name report.yaml and the command line use for `s`: ok, unstable, error, interrupted.
const char* status_name(RunStatus s);

/// How a run ended.
struct RunResult {
  RunStatus status = RunStatus::ok;  ///< How it ended.
  std::string message;        ///< Why, when not ok.
  std::optional<Instability> instability;  ///< Details when status is unstable.
  std::vector<FrameSteps> steps;           ///< Substep sizes per frame.
  Real energy_start = 0;      ///< Total energy at the start, J.
  Real energy_max = 0;        ///< Largest total energy less wall work at a frame end, J.
  int frames_done = 0;        ///< Frames completed after the initial state.
  double wall_seconds = 0;    ///< Whole run including output.
  double loop_seconds = 0;    ///< The substep loop: each substep and its dt bound.
  double check_seconds = 0;   ///< Per-substep diagnosis and per-frame checks (energy, J, dt).
  double observer_seconds = 0;  ///< In observers: output, summaries, progress.
  Real dt_min = 0;            ///< Smallest substep taken, s.
  Real dt_max = 0;            ///< Largest substep taken, s.
  /// What went wrong without stopping the run (inverted particles), one line each.
  std::vector<std::string> warnings;
};

/// Watches a run between steps: output, progress, checks. Must not change the state.
class Observer {
 public:
  virtual ~Observer() = default;
  /// Before the first substep, with the initial state as frame 0.
  virtual void on_start(const Simulation& sim, int frames) {}
  /// After every substep.
  virtual void on_substep(const Simulation& sim, int frame) {}
  /// After frame `frame` (1-based) is complete.
  virtual void on_frame(const Simulation& sim, int frame) {}
  /// Once when the frame loop ends, whatever the status, inside the run's timing (final
  /// writes: its time counts in observer_seconds); an exception sets status error.
  virtual void on_stop(const Simulation& sim, const RunResult& result) {}
  /// Once at the end, whatever the status, with the run's times.
  virtual void on_finish(const Simulation& sim, const RunResult& result) {}
  /// True for an observer whose frame-end work is a reduction (engine/parallel/comm.h): with
  /// more than one rank it is called on every rank with the rank's own particles, before the
  /// frame's gather, and writes on rank 0 only. Others are called on rank 0 after the gather.
  virtual bool collective() const { return false; }
  /// True if on_frame (or, for a collective observer, on_frame_gathered) reads every particle
  /// on rank 0, so that with more than one rank each frame ends with the gather to rank 0
  /// (without such an observer it is skipped).
  virtual bool reads_all_particles() const { return !collective(); }
  /// With more than one rank, after the frame's gather, on every rank, for a collective
  /// observer that reads_all_particles (rank 0 then holds every particle).
  virtual void on_frame_gathered(const Simulation& sim, int frame) {}
};

/// Caps every parallel part of the engine at `threads` threads (0: no cap, OpenMP's default):
/// OpenMP's loops and TBB's, which OpenVDB runs its mesh-to-level-set conversions in (an object's
/// rest depths and a mesh collider at set-up), so that `--threads 1` runs on one core throughout.
void set_threads(int threads);

/// Has the C library keep the memory a run frees for its next allocations (glibc: no mmap for
/// blocks up to 32 MiB, no trimming below 1 GiB free), instead of returning it to the system
/// and faulting fresh pages in at the next substep: each fault is a trap to the kernel (to the
/// hypervisor on a virtual machine), and returning pages to the system while other threads
/// run makes every core flush its TLB. A process-wide setting, for the mpm program's main;
/// the peak memory moves by about 1 % (docs/performance.md). No effect with another C library.
void keep_freed_memory();

/// Total energy less wall work may not exceed its start by more than this fraction of the
/// larger of the start energy and the wall work: explicit MPM only dissipates when stable.
inline constexpr Real kEnergyGrowthLimit = 0.5;

/// Runs frames first_frame..frames, frame f ending at time f * frame_dt (the state is at frame
/// first_frame - 1 on entry: 0 for a new run, the checkpoint's frame when resuming). An observer
/// that throws std::exception ends the run with status "error"; a non-finite particle ends it
/// with status "unstable"; `stop` becoming true (e.g. from a signal handler) ends it at the end
/// of the current frame, after its observers, with status "interrupted".
RunResult run_frames(Simulation& sim, int frames, Real frame_dt,
                     const std::vector<Observer*>& observers,
                     const std::atomic<bool>* stop = nullptr, int first_frame = 1);

}  // namespace mpm
