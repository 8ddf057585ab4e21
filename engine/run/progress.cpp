#include "engine/run/progress.h"

#include <cstdio>

#include <spdlog/spdlog.h>

namespace mpm {

Progress::Progress(bool live) : live_(live) {}

void Progress::on_start(const Simulation& sim, int frames) {
  frames_ = frames;
  start_substeps_ = sim.substeps();
  particles_ = sim.particles().size();  // all on rank 0 here; the count never changes
  start_ = last_draw_ = std::chrono::steady_clock::now();
}

std::string Progress::line(const Simulation& sim, int frame) const {
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double steps = static_cast<double>(sim.substeps() - start_substeps_);
  const double rate = elapsed > 0 ? steps * particles_ / elapsed : 0;
  const double done = frames_ > 0 ? static_cast<double>(frame) / frames_ : 1;
  const double left = done > 0 ? elapsed * (1 - done) / done : 0;
  char buf[200];
  std::snprintf(buf, sizeof buf,
                "frame %d/%d  t=%.4fs  substeps %zu  %.2fM particle-steps/s  %.0fs left", frame,
                frames_, static_cast<double>(sim.time()), sim.substeps(), rate / 1e6, left);
  return buf;
}

void Progress::on_substep(const Simulation& sim, int frame) {
  if (!live_) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_draw_ < std::chrono::milliseconds(200)) return;
  last_draw_ = now;
  std::fprintf(stderr, "\r%s\033[K", line(sim, frame - 1).c_str());
  std::fflush(stderr);
}

void Progress::on_frame(const Simulation& sim, int frame) {
  if (live_) {
    std::fprintf(stderr, "\r%s\033[K", line(sim, frame).c_str());
    std::fflush(stderr);
  } else {
    spdlog::info("{}", line(sim, frame));
  }
}

void Progress::on_finish(const Simulation&, const RunResult&) {
  if (live_) std::fprintf(stderr, "\n");
}

}  // namespace mpm
