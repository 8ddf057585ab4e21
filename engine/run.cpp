#include "engine/run.h"

#include <chrono>
#include <cmath>
#include <limits>

namespace mpm {

RunResult run_frames(Simulation& sim, int frames, Real frame_dt,
                     const std::vector<Observer*>& observers, const std::atomic<bool>* stop,
                     int first_frame) {
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();
  RunResult result;
  result.dt_min = std::numeric_limits<Real>::infinity();
  const bool adaptive = sim.scene().simulation.cfl.has_value();
  try {
    for (Observer* o : observers) o->on_start(sim, frames);
    result.frames_done = first_frame - 1;
    for (int f = first_frame; f <= frames && result.status == "ok"; ++f) {
      const Real frame_end = f * frame_dt;
      // A whole number of equal substeps fills the frame, each no larger than the bound.
      int remaining_steps = 0;
      Real dt = 0;
      while (true) {
        const Real remaining = frame_end - sim.time();
        if (remaining <= frame_dt * 1e-9) break;
        if (adaptive || remaining_steps == 0) {
          const Real bound = sim.stable_dt();
          if (!(bound > 0) || !std::isfinite(bound)) {
            result.status = "unstable";
            result.message = "time step bound is not a positive finite number";
            break;
          }
          remaining_steps = static_cast<int>(std::ceil(remaining / bound * (1 - 1e-12)));
          dt = remaining / remaining_steps;
        }
        const auto s0 = clock::now();
        sim.substep(dt);
        result.loop_seconds += std::chrono::duration<double>(clock::now() - s0).count();
        result.dt_min = std::min(result.dt_min, dt);
        result.dt_max = std::max(result.dt_max, dt);
        --remaining_steps;
        if (sim.nonfinite_particles() > 0) {
          result.status = "unstable";
          result.message = std::to_string(sim.nonfinite_particles()) +
                           " particles have a non-finite position at substep " +
                           std::to_string(sim.substeps()) + " (frame " + std::to_string(f) +
                           "); a smaller dt or cfl may help";
          break;
        }
        for (Observer* o : observers) o->on_substep(sim, f);
        if (stop && stop->load()) {
          result.status = "interrupted";
          result.message = "stopped by a signal at substep " + std::to_string(sim.substeps()) +
                           "; the last complete frame is " + std::to_string(f - 1);
          break;
        }
      }
      if (result.status != "ok") break;
      sim.set_time(frame_end);
      result.frames_done = f;
      for (Observer* o : observers) o->on_frame(sim, f);
    }
  } catch (const std::exception& e) {
    result.status = "error";
    result.message = e.what();
  }
  if (!std::isfinite(result.dt_min)) result.dt_min = 0;
  result.wall_seconds = std::chrono::duration<double>(clock::now() - start).count();
  for (Observer* o : observers) {
    try {
      o->on_finish(sim, result);
    } catch (const std::exception& e) {
      if (result.status == "ok") result.status = "error", result.message = e.what();
    }
  }
  return result;
}

}  // namespace mpm
