#pragma once
/// \file The frame loop: substeps until each frame time, with observers between steps.

#include <atomic>
#include <string>
#include <vector>

#include "engine/simulation.h"

namespace mpm {

/// How a run ended.
struct RunResult {
  std::string status = "ok";  ///< ok | unstable | error | interrupted.
  std::string message;        ///< Why, when not ok.
  int frames_done = 0;        ///< Frames completed after the initial state.
  double wall_seconds = 0;    ///< Whole run including output.
  double loop_seconds = 0;    ///< Time inside substeps only.
  Real dt_min = 0;            ///< Smallest substep taken, s.
  Real dt_max = 0;            ///< Largest substep taken, s.
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
  /// Once at the end, whatever the status.
  virtual void on_finish(const Simulation& sim, const RunResult& result) {}
};

/// Runs frames first_frame..frames, frame f ending at time f * frame_dt (the state is at frame
/// first_frame - 1 on entry: 0 for a new run, the checkpoint's frame when resuming). An observer
/// that throws std::exception ends the run with status "error"; a non-finite particle ends it
/// with status "unstable"; `stop` becoming true (e.g. from a signal handler) ends it after the
/// current substep with status "interrupted".
RunResult run_frames(Simulation& sim, int frames, Real frame_dt,
                     const std::vector<Observer*>& observers,
                     const std::atomic<bool>* stop = nullptr, int first_frame = 1);

}  // namespace mpm
