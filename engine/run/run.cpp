#include "engine/run/run.h"

#include "engine/core/reduce.h"
#include "engine/parallel/comm.h"
#include "engine/parallel/domain.h"

#include <chrono>
#include <cmath>
#include <algorithm>
#include <cstdio>
#include <limits>

#include <spdlog/spdlog.h>

namespace mpm {

namespace {

/// The first sign of an unstable substep, or std::nullopt (references.md, "Time step").
std::optional<Instability> diagnose(const Simulation& sim, Real dt) {
  const AdvectStats& a = sim.last_advect();
  const Real h = sim.grid().h.minCoeff();
  char buf[256];
  if (a.nonfinite > 0 || !std::isfinite(a.max_speed)) {
    const std::size_t q = sim.first_nonfinite_particle();
    std::snprintf(buf, sizeof buf, "%zu particles have a non-finite position or velocity",
                  a.nonfinite);
    return Instability{buf, q < sim.particles().size() ? sim.object_of(q).name : ""};
  }
  if (a.max_speed * dt > h) {
    const std::size_t q = sim.fastest_particle();  // on this rank, with more than one
    std::snprintf(buf, sizeof buf,
                  "a particle moves %.3g m/s, %.2f cells per substep (more than the grid can "
                  "carry: at most 1)",
                  static_cast<double>(a.max_speed), static_cast<double>(a.max_speed * dt / h));
    return Instability{buf, sim.particles().size() > 0 ? sim.object_of(q).name : ""};
  }
  return std::nullopt;
}

/// `local` (this rank's part of a sum over particles or of the wall work) summed over all
/// ranks in rank order, so no particle leaves its rank; a one-rank run makes no MPI call.
Real over_ranks(const Simulation& sim, Real local) {
  if (!sim.domain()) return local;
  return static_cast<Real>(parallel::sum_in_rank_order(static_cast<double>(local)));
}

/// Appends a warning for each object not yet warned about that has a particle with
/// J = det F <= 0 (inverted: no elastic material survives it) at the end of `frame`. Once per
/// frame, one determinant per particle: cheap beside the frame's substeps. With more than one
/// rank each rank counts its own particles; the counts and the smallest J are then reduced
/// (collective: every rank calls it, and every rank gets the same flags).
void check_inversion(const Simulation& sim, int frame, std::vector<char>& warned,
                     std::vector<std::string>& warnings) {
  const Particles& p = sim.particles();
  struct Inverted {
    std::size_t count = 0;
    Real smallest = std::numeric_limits<Real>::infinity();
  };
  for (std::size_t o = 0; o < sim.objects().size(); ++o) {
    if (warned[o]) continue;
    const ObjectInfo& info = sim.objects()[o];
    const std::size_t n = std::min(info.count, p.size() - std::min(info.first, p.size()));
    const Inverted inv = reduce_chunks(
        n, Inverted{},
        [&](std::size_t first, std::size_t last) {
          Inverted c;
          for (std::size_t q = info.first + first; q < info.first + last; ++q) {
            const Real J = to_real(p.F[q]).determinant();
            if (!(J <= 0)) continue;
            ++c.count;
            c.smallest = std::min(c.smallest, J);
          }
          return c;
        },
        [](Inverted a, Inverted b) {
          return Inverted{a.count + b.count, std::min(a.smallest, b.smallest)};
        });
    std::size_t inverted = inv.count, count = info.count;
    Real smallest = inv.smallest;
    if (sim.domain()) {
      inverted = parallel::sum_all(static_cast<std::uint64_t>(inverted));
      count = parallel::sum_all(static_cast<std::uint64_t>(count));
      smallest = static_cast<Real>(parallel::min_all(static_cast<double>(smallest)));
    }
    if (inverted == 0) continue;
    warned[o] = 1;
    if (parallel::rank() != 0) continue;
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "object '%s': %zu of %zu particles inverted (J = det F <= 0, smallest %.3g) "
                  "by frame %d: the body was crushed beyond what its material can hold, and "
                  "what follows is not physical (E is in Pa: too small? dt too large?)",
                  info.name.c_str(), inverted, count, static_cast<double>(smallest), frame);
    warnings.emplace_back(buf);
    spdlog::warn("{}", warnings.back());
  }
}

}  // namespace

const char* status_name(RunStatus s) {
  switch (s) {
    case RunStatus::ok:
      return "ok";
    case RunStatus::unstable:
      return "unstable";
    case RunStatus::error:
      return "error";
    case RunStatus::interrupted:
      return "interrupted";
  }
  return "?";
}

RunResult run_frames(Simulation& sim, int frames, Real frame_dt,
                     const std::vector<Observer*>& observers, const std::atomic<bool>* stop,
                     int first_frame) {
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();
  RunResult result;
  result.dt_min = std::numeric_limits<Real>::infinity();
  const bool adaptive = sim.scene().simulation.cfl.has_value();
  if (parallel::Domain* domain = parallel::domain_of(sim)) domain->keep_root_only(sim);
  result.energy_start = result.energy_max = over_ranks(sim, sim.total_energy());
  // The dt to suggest if the run goes wrong: the CFL bound at cfl 0.5, from the last healthy
  // state seen at a frame end.
  const Real cfl = 0.5;
  Real suggested_dt = sim.cfl_bound(cfl);
  std::vector<char> inversion_warned(sim.objects().size(), 0);
  auto fail = [&](Instability why, int frame) {
    why.frame = frame;
    why.substep = sim.substeps();
    why.suggested_dt = suggested_dt;
    result.status = RunStatus::unstable;
    char buf[160];
    std::snprintf(buf, sizeof buf, " (frame %d, substep %zu%s%s); try dt <= %.3g s or cfl <= 0.5",
                  frame, why.substep, why.object.empty() ? "" : ", object ",
                  why.object.c_str(), static_cast<double>(why.suggested_dt));
    result.message = why.cause + buf;
    result.instability = why;
  };
  auto seconds_since = [](clock::time_point t0) {
    return std::chrono::duration<double>(clock::now() - t0).count();
  };
  // With more than one rank (engine/parallel/domain.h) the substeps run on every rank's
  // slab; each frame end checks energy and inversion with reductions over the slabs, then
  // gathers the state on rank 0, which alone calls the observers (other ranks get none);
  // rank 0's status is then every rank's.
  parallel::Domain* domain = parallel::domain_of(sim);
  auto agree = [&] {
    if (!domain) return;
    int status = static_cast<int>(result.status);
    parallel::broadcast(status);
    result.status = static_cast<RunStatus>(status);
    parallel::broadcast(result.message);
  };
  // An observer's exception ends the run with status error: caught here, not by the outer
  // handler, so that every rank leaves the frame loop at the same point.
  auto notify = [&](auto&& call) {
    try {
      call();
    } catch (const std::exception& e) {
      if (result.status == RunStatus::ok)
        result.status = RunStatus::error, result.message = e.what();
    }
  };
  // The frame's gather to rank 0 only when an observer there reads every particle (rank 0's
  // list decides: other ranks hold only collective observers).
  bool gather = false;
  for (const Observer* o : observers) gather = gather || o->reads_all_particles();
  if (domain) gather = parallel::any_all(gather);
  try {
    auto t0 = clock::now();
    notify([&] {
      for (Observer* o : observers) o->on_start(sim, frames);
    });
    result.observer_seconds += seconds_since(t0);
    agree();
    result.frames_done = first_frame - 1;
    for (int f = first_frame; f <= frames && result.status == RunStatus::ok; ++f) {
      if (domain) domain->distribute(sim);
      const Real frame_end = f * frame_dt;
      // A whole number of equal substeps fills the frame, each no larger than the bound.
      int remaining_steps = 0;
      Real dt = 0;
      FrameSteps steps{f, 0, std::numeric_limits<Real>::infinity(), 0};
      while (true) {
        const Real remaining = frame_end - sim.time();
        if (remaining <= frame_dt * 1e-9) break;
        // The loop time covers the bound and the substep: what the throughput is made of.
        const auto s0 = clock::now();
        if (adaptive || remaining_steps == 0) {
          const Real bound = sim.timed_stable_dt();
          if (!(bound > 0) || !std::isfinite(bound)) {
            fail({"the CFL time step bound is not a positive finite number", ""}, f);
            break;
          }
          const double steps = std::ceil(remaining / bound * (1 - 1e-12));
          if (steps > 1e9) {
            fail({"the time step bound is over a billion times smaller than the frame time", ""}, f);
            break;
          }
          remaining_steps = static_cast<int>(steps);
          dt = remaining / remaining_steps;
        }
        sim.substep(dt);
        if (domain) {
          // A stage that failed on some rank: every rank stops here with its cause.
          const std::string failure = parallel::first_nonempty(domain->failure());
          if (!failure.empty()) {
            result.status = RunStatus::error;
            result.message = failure + " (frame " + std::to_string(f) + ", substep " +
                             std::to_string(sim.substeps()) + "); the last complete frame is " +
                             std::to_string(f - 1);
            break;
          }
        }
        result.loop_seconds += std::chrono::duration<double>(clock::now() - s0).count();
        result.dt_min = std::min(result.dt_min, dt);
        result.dt_max = std::max(result.dt_max, dt);
        ++steps.substeps;
        steps.dt_min = std::min(steps.dt_min, dt);
        steps.dt_max = std::max(steps.dt_max, dt);
        --remaining_steps;
        t0 = clock::now();
        auto why = diagnose(sim, dt);
        result.check_seconds += seconds_since(t0);
        if (why) {
          fail(*why, f);
          break;
        }
        t0 = clock::now();
        notify([&] {
          for (Observer* o : observers) o->on_substep(sim, f);
        });
        result.observer_seconds += seconds_since(t0);
        if (domain && parallel::any_all(result.status != RunStatus::ok)) {
          agree();
          if (result.status == RunStatus::ok) result.status = RunStatus::error;
          break;
        }
        if (result.status != RunStatus::ok) break;
      }
      if (steps.substeps == 0) steps.dt_min = 0;
      result.steps.push_back(steps);
      // The frame's checks run on each rank's own particles, with reductions (the status is
      // the same on every rank here: each way out of the substep loop is agreed).
      if (result.status == RunStatus::ok) {
        // Energy may only grow by the work moving walls and colliders do on the bodies.
        t0 = clock::now();
        const Real wall_work = over_ranks(sim, sim.wall_work());
        const Real energy = sim.domain() ? over_ranks(sim, sim.total_energy()) - wall_work
                                         : sim.total_energy() - sim.wall_work();
        result.energy_max = std::max(result.energy_max, energy);
        // The allowance scales with the energy in play: the start's, or what walls put in.
        const Real scale = std::max(std::abs(result.energy_start), std::abs(wall_work));
        if (energy > result.energy_start + kEnergyGrowthLimit * scale + 1e-9) {
          char buf[200];
          std::snprintf(
              buf, sizeof buf,
              "total energy less the work of moving walls and colliders grew from %.4g J to %.4g J",
              static_cast<double>(result.energy_start), static_cast<double>(energy));
          fail({buf, ""}, f);
        }
        agree();
        if (result.status == RunStatus::ok) {
          check_inversion(sim, f, inversion_warned, result.warnings);
          suggested_dt = sim.cfl_bound(cfl);
        }
        result.check_seconds += seconds_since(t0);
      }
      // Collective observers (the summary) reduce over the slabs before the gather; the others
      // (frame files, checkpoint, progress) still read every particle on rank 0 after it.
      if (domain && result.status == RunStatus::ok) {
        t0 = clock::now();
        sim.set_time(frame_end);
        notify([&] {
          for (Observer* o : observers)
            if (o->collective()) o->on_frame(sim, f);
        });
        result.observer_seconds += seconds_since(t0);
        agree();  // an observer's error on rank 0 stops every rank after the gather
      }
      if (domain && gather) domain->collect(sim);
      else if (domain) domain->collect_counters(sim);
      if (result.status != RunStatus::ok) break;
      sim.set_time(frame_end);
      result.frames_done = f;
      t0 = clock::now();
      notify([&] {
        for (Observer* o : observers) {
          if (!domain || !o->collective()) o->on_frame(sim, f);
          else if (o->reads_all_particles()) o->on_frame_gathered(sim, f);
        }
      });
      result.observer_seconds += seconds_since(t0);
      agree();
      // A stop request ends the run at a frame end, with the frame written: the output's
      // on_finish then writes this frame's checkpoint, so nothing computed is lost.
      const bool stopping = stop && stop->load() && f < frames && result.status == RunStatus::ok;
      if (domain ? parallel::any_all(stopping) : stopping) {
        result.status = RunStatus::interrupted;
        result.message = "stopped by a signal after frame " + std::to_string(f) + " (substep " +
                         std::to_string(sim.substeps()) +
                         "), the last complete frame; --resume continues from it";
        break;
      }
    }
  } catch (const std::exception& e) {
    result.status = RunStatus::error;
    result.message = e.what();
    if (domain) {
      // A failure outside the compute stages (an exchange, the frame's gather or scatter):
      // only this rank may know, and the others wait in an exchange. Frames already written
      // are whole (each is renamed into place), so stopping every rank loses nothing written.
      spdlog::error("rank {}: {}", parallel::rank(), e.what());
      std::fprintf(stderr, "error: rank %d: %s\n", parallel::rank(), e.what());
      parallel::abort_all(kExitRunFailed);
    }
  }
  if (!std::isfinite(result.dt_min)) result.dt_min = 0;
  {
    const auto t0 = clock::now();
    notify([&] {
      for (Observer* o : observers) o->on_stop(sim, result);
    });
    result.observer_seconds += seconds_since(t0);
    agree();
  }
  result.wall_seconds = std::chrono::duration<double>(clock::now() - start).count();
  for (Observer* o : observers) {
    try {
      o->on_finish(sim, result);
    } catch (const std::exception& e) {
      if (result.status == RunStatus::ok)
        result.status = RunStatus::error, result.message = e.what();
    }
  }
  return result;
}

}  // namespace mpm
