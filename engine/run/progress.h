#pragma once
/// \file Progress reporting: a live line on a terminal, plain log lines otherwise.

#include <chrono>

#include "engine/run/run.h"

namespace mpm {

/// Reports frame i/N, simulated time, substeps, particle-steps per second and time left.
class Progress : public Observer {
 public:
  /// `live` redraws one line on stderr (for a terminal); otherwise logs each frame.
  explicit Progress(bool live);
  void on_start(const Simulation& sim, int frames) override;
  void on_substep(const Simulation& sim, int frame) override;
  void on_frame(const Simulation& sim, int frame) override;
  void on_finish(const Simulation& sim, const RunResult& result) override;
  /// Reads only the time, the substep count and the particle count from on_start.
  bool reads_all_particles() const override { return false; }

 private:
  std::string line(const Simulation& sim, int frame) const;
  bool live_;
  int frames_ = 0;
  std::size_t start_substeps_ = 0;
  std::size_t particles_ = 0;
  std::chrono::steady_clock::time_point start_, last_draw_;
};

}  // namespace mpm
