#pragma once
/// \file Loops that a team's idle threads help with while one of its threads runs a long job.
///
/// The split gather (engine/step/split_gather.h) runs the contact stage on one thread of a
/// team while the others gather the particles no contact can reach. When they have gathered
/// them all they wait at the region's end, while the contact's solve still runs its loops on
/// one thread. A waiting thread is counted here (IdleTeam), and a loop of the job run through
/// for_ranges is then cut into one part per thread: the waiting threads take the others' parts
/// as OpenMP tasks (a barrier is a task scheduling point, where the team's threads run the
/// tasks queued for it). Outside such a job a loop runs as a parallel loop (or in one piece).
/// Each item is computed by itself, so what a loop computes does not depend on who helps.

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <vector>

namespace mpm {

/// The threads of the running split that have finished their own work and wait at its end.
/// One process runs one split at a time: the counter is the process's.
class IdleTeam {
 public:
  /// Starts a split: none waits.
  static void reset() { waiting().store(0, std::memory_order_relaxed); }
  /// The calling thread has finished its own work and waits at the region's end.
  static void arrive() { waiting().fetch_add(1, std::memory_order_release); }
  /// How many threads wait, seen from a thread of an active parallel region (0 outside one).
  static int waiting_now() {
    return omp_in_parallel() ? waiting().load(std::memory_order_acquire) : 0;
  }

 private:
  static std::atomic<int>& waiting() {
    static std::atomic<int> count{0};
    return count;
  }
};

/// Runs `part(first, last)` over items [0, n) in parts, and returns `fold` of the parts'
/// results (in part order; `zero` without parts): in parallel if `par` and outside a parallel
/// region; inside one, split among the calling thread and the team's waiting threads
/// (IdleTeam), the calling thread taking the first part; else in one part.
template <class T, class Part, class Fold>
T for_ranges(std::ptrdiff_t n, bool par, T zero, const Part& part, const Fold& fold) {
  if (n <= 0) return zero;
  const int helpers = IdleTeam::waiting_now();
  const int parts = static_cast<int>(std::min<std::ptrdiff_t>(
      n, helpers > 0 ? 1 + helpers : par && !omp_in_parallel() ? omp_get_max_threads() : 1));
  if (parts == 1) return fold(zero, part(std::ptrdiff_t{0}, n));
  std::vector<T> result(static_cast<std::size_t>(parts), zero);
  const auto run = [&](int k) {
    result[static_cast<std::size_t>(k)] = part(k * n / parts, (k + 1) * n / parts);
  };
  if (helpers > 0) {
#pragma omp taskgroup
    {
      for (int k = 1; k < parts; ++k) {
#pragma omp task firstprivate(k) shared(run)
        run(k);
      }
      run(0);
    }
  } else {
#pragma omp parallel for schedule(static, 1) num_threads(parts)
    for (int k = 0; k < parts; ++k) run(k);
  }
  T out = zero;
  for (const T& r : result) out = fold(out, r);
  return out;
}

}  // namespace mpm
