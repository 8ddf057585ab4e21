#include "engine/run/run.h"

#include <malloc.h>
#include <omp.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

#include "engine/core/reduce.h"
#include "engine/parallel/comm.h"
#include "engine/parallel/domain.h"

namespace mpm {

void set_threads(int threads) {
  // A TBB cap holds while its global_control lives: one, replaced at each call.
  static std::unique_ptr<tbb::global_control> tbb_cap;
  tbb_cap.reset();
  if (threads <= 0) return;
  omp_set_num_threads(threads);
  tbb_cap = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  static_cast<std::size_t>(threads));
}

void keep_freed_memory() {
#ifdef __GLIBC__
  mallopt(M_MMAP_THRESHOLD, 32 << 20);  // glibc's largest (a fixed value ends its adjusting)
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

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

using Clock = std::chrono::steady_clock;

/// Seconds from t0 to now.
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// One run_frames call: the frame loop's state and its jobs (a frame's substeps, its checks,
/// its observers, the agreement between ranks). With more than one rank
/// (engine/parallel/domain.h) the substeps run on every rank's slab; each frame end checks
/// energy and inversion with reductions over the slabs, then gathers the state on rank 0,
/// which alone calls the observers (other ranks get none); rank 0's status is then every
/// rank's.
class FrameLoop {
 public:
  /// Prepares the run of `sim` up to frame `frames`: rank 0 keeps the whole state, the start
  /// energy, the dt to suggest, whether frames end with the gather to rank 0.
  FrameLoop(Simulation& sim, int frames, Real frame_dt, const std::vector<Observer*>& observers,
            const std::atomic<bool>* stop)
      : sim_(sim), frames_(frames), frame_dt_(frame_dt), observers_(observers), stop_(stop) {
    result_.dt_min = std::numeric_limits<Real>::infinity();
    adaptive_ = sim.scene().simulation.cfl.has_value();
    if (parallel::Domain* domain = parallel::domain_of(sim)) domain->keep_root_only(sim);
    result_.energy_start = result_.energy_max = over_ranks(sim, sim.total_energy());
    suggested_dt_ = sim.cfl_bound(kSuggestedCfl);
    inversion_warned_.assign(sim.objects().size(), 0);
    domain_ = parallel::domain_of(sim);
    // The frame's gather to rank 0 only when an observer there reads every particle (rank
    // 0's list decides: other ranks hold only collective observers).
    for (const Observer* o : observers) gather_ = gather_ || o->reads_all_particles();
    if (domain_) gather_ = parallel::any_all(gather_);
  }

  /// Runs frames first_frame..frames, then the observers' on_stop and on_finish; `start` is
  /// when run_frames began (the wall time counts from it).
  RunResult run(int first_frame, Clock::time_point start) {
    try {
      notify_timed([&] {
        for (Observer* o : observers_) o->on_start(sim_, frames_);
      });
      agree();
      result_.frames_done = first_frame - 1;
      for (int f = first_frame; f <= frames_ && result_.status == RunStatus::ok; ++f)
        if (!run_frame(f)) break;
    } catch (const std::exception& e) {
      result_.status = RunStatus::error;
      result_.message = e.what();
      if (domain_) {
        // A failure outside the compute stages (an exchange, the frame's gather or scatter):
        // only this rank may know, and the others wait in an exchange. Frames already written
        // are whole (each is renamed into place), so stopping every rank loses nothing
        // written.
        spdlog::error("rank {}: {}", parallel::rank(), e.what());
        std::fprintf(stderr, "error: rank %d: %s\n", parallel::rank(), e.what());
        parallel::abort_all(kExitRunFailed);
      }
    }
    if (!std::isfinite(result_.dt_min)) result_.dt_min = 0;
    notify_timed([&] {
      for (Observer* o : observers_) o->on_stop(sim_, result_);
    });
    agree();
    result_.wall_seconds = seconds_since(start);
    for (Observer* o : observers_) notify([&] { o->on_finish(sim_, result_); });
    return result_;
  }

 private:
  /// The cfl of the dt suggested when the run goes wrong.
  static constexpr Real kSuggestedCfl = 0.5;

  /// Frame f: its substeps, its checks, its observers; false when the run stops after it.
  bool run_frame(int f) {
    if (domain_) domain_->distribute(sim_);
    const Real frame_end = f * frame_dt_;
    result_.steps.push_back(run_substeps(f, frame_end));
    // The frame's checks run on each rank's own particles, with reductions (the status is the
    // same on every rank here: each way out of the substep loop is agreed).
    if (result_.status == RunStatus::ok) check_frame(f);
    // Collective observers (the summary) reduce over the slabs before the gather; the others
    // (frame files, checkpoint, progress) still read every particle on rank 0 after it.
    if (domain_ && result_.status == RunStatus::ok) {
      sim_.set_time(frame_end);
      notify_timed([&] {
        for (Observer* o : observers_)
          if (o->collective()) o->on_frame(sim_, f);
      });
      agree();  // an observer's error on rank 0 stops every rank after the gather
    }
    if (domain_ && gather_)
      domain_->collect(sim_);
    else if (domain_)
      domain_->collect_counters(sim_);
    if (result_.status != RunStatus::ok) return false;
    sim_.set_time(frame_end);
    result_.frames_done = f;
    notify_timed([&] {
      for (Observer* o : observers_) {
        if (!domain_ || !o->collective())
          o->on_frame(sim_, f);
        else if (o->reads_all_particles())
          o->on_frame_gathered(sim_, f);
      }
    });
    agree();
    return !stop_requested(f);
  }

  /// The substeps that fill frame f up to time frame_end: a whole number of equal substeps,
  /// each no larger than the bound; each is diagnosed, then shown to the observers.
  FrameSteps run_substeps(int f, Real frame_end) {
    int remaining_steps = 0;
    Real dt = 0;
    FrameSteps steps{f, 0, std::numeric_limits<Real>::infinity(), 0};
    while (true) {
      const Real remaining = frame_end - sim_.time();
      if (remaining <= frame_dt_ * 1e-9) break;
      // The loop time covers the bound and the substep: what the throughput is made of.
      const auto s0 = Clock::now();
      if ((adaptive_ || remaining_steps == 0) && !next_substeps(f, remaining, remaining_steps, dt))
        break;
      sim_.substep(dt);
      if (failed_on_a_rank(f)) break;
      result_.loop_seconds += seconds_since(s0);
      result_.dt_min = std::min(result_.dt_min, dt);
      result_.dt_max = std::max(result_.dt_max, dt);
      ++steps.substeps;
      steps.dt_min = std::min(steps.dt_min, dt);
      steps.dt_max = std::max(steps.dt_max, dt);
      --remaining_steps;
      const auto t0 = Clock::now();
      auto why = diagnose(sim_, dt);
      result_.check_seconds += seconds_since(t0);
      if (why) {
        fail(*why, f);
        break;
      }
      notify_timed([&] {
        for (Observer* o : observers_) o->on_substep(sim_, f);
      });
      if (domain_ && parallel::any_all(result_.status != RunStatus::ok)) {
        agree();
        if (result_.status == RunStatus::ok) result_.status = RunStatus::error;
        break;
      }
      if (result_.status != RunStatus::ok) break;
    }
    if (steps.substeps == 0) steps.dt_min = 0;
    return steps;
  }

  /// Splits the `remaining` time of frame f into `steps` equal substeps of `dt`, each no
  /// larger than the stable bound; false (the run failed) when the bound is unusable.
  bool next_substeps(int f, Real remaining, int& steps, Real& dt) {
    const Real bound = sim_.timed_stable_dt();
    if (!(bound > 0) || !std::isfinite(bound)) {
      fail({"the CFL time step bound is not a positive finite number", ""}, f);
      return false;
    }
    const double count = std::ceil(remaining / bound * (1 - 1e-12));
    if (count > 1e9) {
      fail({"the time step bound is over a billion times smaller than the frame time", ""}, f);
      return false;
    }
    steps = static_cast<int>(count);
    dt = remaining / steps;
    return true;
  }

  /// With more than one rank: whether a stage failed on some rank in frame f's last substep
  /// (then every rank stops here with its cause, status error).
  bool failed_on_a_rank(int f) {
    if (!domain_) return false;
    const std::string failure = parallel::first_nonempty(domain_->failure());
    if (failure.empty()) return false;
    result_.status = RunStatus::error;
    result_.message = failure + " (frame " + std::to_string(f) + ", substep " +
                      std::to_string(sim_.substeps()) + "); the last complete frame is " +
                      std::to_string(f - 1);
    return true;
  }

  /// The checks at the end of frame f: the energy budget and inverted particles; the dt to
  /// suggest from this healthy state.
  void check_frame(int f) {
    // Energy may only grow by the work moving walls and colliders do on the bodies.
    const auto t0 = Clock::now();
    const Real wall_work = over_ranks(sim_, sim_.wall_work());
    const Real energy = sim_.domain() ? over_ranks(sim_, sim_.total_energy()) - wall_work
                                      : sim_.total_energy() - sim_.wall_work();
    result_.energy_max = std::max(result_.energy_max, energy);
    // The allowance scales with the energy in play: the start's, or what walls put in.
    const Real scale = std::max(std::abs(result_.energy_start), std::abs(wall_work));
    if (energy > result_.energy_start + kEnergyGrowthLimit * scale + 1e-9) {
      char buf[200];
      std::snprintf(
          buf, sizeof buf,
          "total energy less the work of moving walls and colliders grew from %.4g J to %.4g J",
          static_cast<double>(result_.energy_start), static_cast<double>(energy));
      fail({buf, ""}, f);
    }
    agree();
    if (result_.status == RunStatus::ok) {
      check_inversion(sim_, f, inversion_warned_, result_.warnings);
      suggested_dt_ = sim_.cfl_bound(kSuggestedCfl);
    }
    result_.check_seconds += seconds_since(t0);
  }

  /// Whether a stop request ends the run after frame f (then status interrupted). It ends it
  /// at a frame end, with the frame written: the output's on_finish then writes this frame's
  /// checkpoint, so nothing computed is lost.
  bool stop_requested(int f) {
    const bool stopping = stop_ && stop_->load() && f < frames_ && result_.status == RunStatus::ok;
    if (!(domain_ ? parallel::any_all(stopping) : stopping)) return false;
    result_.status = RunStatus::interrupted;
    result_.message = "stopped by a signal after frame " + std::to_string(f) + " (substep " +
                      std::to_string(sim_.substeps()) +
                      "), the last complete frame; --resume continues from it";
    return true;
  }

  /// Ends the run as unstable in `frame` for reason `why`, with the dt to try.
  void fail(Instability why, int frame) {
    why.frame = frame;
    why.substep = sim_.substeps();
    why.suggested_dt = suggested_dt_;
    result_.status = RunStatus::unstable;
    char buf[160];
    std::snprintf(buf, sizeof buf, " (frame %d, substep %zu%s%s); try dt <= %.3g s or cfl <= 0.5",
                  frame, why.substep, why.object.empty() ? "" : ", object ", why.object.c_str(),
                  static_cast<double>(why.suggested_dt));
    result_.message = why.cause + buf;
    result_.instability = why;
  }

  /// With more than one rank: every rank takes rank 0's status and message.
  void agree() {
    if (!domain_) return;
    int status = static_cast<int>(result_.status);
    parallel::broadcast(status);
    result_.status = static_cast<RunStatus>(status);
    parallel::broadcast(result_.message);
  }

  /// Calls the observers through `call`: an observer's exception ends the run with status
  /// error, caught here, not by the outer handler, so that every rank leaves the frame loop at
  /// the same point.
  template <class Call>
  void notify(Call&& call) {
    try {
      call();
    } catch (const std::exception& e) {
      if (result_.status == RunStatus::ok)
        result_.status = RunStatus::error, result_.message = e.what();
    }
  }

  /// notify, with its time counted in observer_seconds.
  template <class Call>
  void notify_timed(Call&& call) {
    const auto t0 = Clock::now();
    notify(call);
    result_.observer_seconds += seconds_since(t0);
  }

  Simulation& sim_;
  const int frames_;
  const Real frame_dt_;
  const std::vector<Observer*>& observers_;
  const std::atomic<bool>* stop_;
  RunResult result_;
  bool adaptive_ = false;               ///< Whether dt is recomputed every substep (a cfl).
  Real suggested_dt_ = 0;               ///< The CFL bound at the last healthy frame end.
  std::vector<char> inversion_warned_;  ///< Per object: inversion already reported.
  parallel::Domain* domain_ = nullptr;  ///< Null with one rank.
  bool gather_ = false;                 ///< Whether each frame ends with the gather to rank 0.
};

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
  const auto start = Clock::now();
  return FrameLoop(sim, frames, frame_dt, observers, stop).run(first_frame, start);
}

}  // namespace mpm
