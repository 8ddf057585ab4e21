#pragma once
/// \file Work handed out to a team by shares that keep their place from stage to stage.

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>

namespace mpm {

/// Items [0, n) handed out to the threads of the calling parallel region: thread t first takes
/// its own share, items [t n / T, (t + 1) n / T) of T = `threads` shares, in order, `grain` at a
/// time; then it takes from the ends of the other shares, half of what is left of one (at
/// least `grain`) at a time, as a guided schedule shrinks its chunks.
///
/// Why: the particles lie in cell order, so a share is one part of the particles and of the
/// grid. Stages handed out this way give each thread the same part every time, whose
/// particles and nodes its own caches still hold from the stage before (two_cubes' scatter
/// and gather with their slabs and chunks dealt out in turn, not by share, took 6 % longer;
/// docs/performance.md). Taking from the others' ends keeps the balance of a dynamic schedule
/// on cores whose speeds differ: a thread done early takes the items that the owner would
/// reach last. Each item is taken once; which thread takes it depends on the timing, so what
/// a stage computes for an item must not depend on the thread. At most 2^32 - 1 items.
class Shares {
 public:
  /// Items [0, items) in `threads` shares (threads >= 1), taken `grain` (>= 1) at a time.
  Shares(std::size_t items, int threads, std::size_t grain)
      : threads_(std::max(threads, 1)),
        grain_(static_cast<std::uint32_t>(std::max<std::size_t>(grain, 1))),
        share_(std::make_unique<Share[]>(static_cast<std::size_t>(threads_))) {
    if (items > UINT32_MAX) throw std::length_error("Shares: more than 2^32 - 1 items");
    const std::size_t T = static_cast<std::size_t>(threads_);
    for (std::size_t t = 0; t < T; ++t)
      share_[t].range.store(pack(static_cast<std::uint32_t>(t * items / T),
                                 static_cast<std::uint32_t>((t + 1) * items / T)),
                            std::memory_order_relaxed);
  }

  /// The next items [first, last) for thread `t` (its own share's next ones, else the last ones
  /// of another's); false when every item has been taken.
  bool next(int t, std::size_t& first, std::size_t& last) {
    const int own = std::clamp(t, 0, threads_ - 1);
    if (take(share_[static_cast<std::size_t>(own)].range, true, first, last)) return true;
    for (int k = 1; k < threads_; ++k)
      if (take(share_[static_cast<std::size_t>((own + k) % threads_)].range, false, first, last))
        return true;
    return false;
  }

  /// The next items for the calling thread of an OpenMP team (next with its thread number).
  bool next(std::size_t& first, std::size_t& last) {
    return next(omp_get_thread_num(), first, last);
  }

 private:
  /// A share's items not yet taken, [front, back), packed into one word so that its owner
  /// (from the front) and the other threads (from the back) take items by one compare-exchange.
  struct alignas(64) Share {
    std::atomic<std::uint64_t> range{0};
  };

  static std::uint64_t pack(std::uint32_t front, std::uint32_t back) {
    return (std::uint64_t{back} << 32) | front;
  }

  /// Takes items of `range`: up to grain_ from its front (`owner`), else half of those left
  /// (at least grain_) from its back.
  bool take(std::atomic<std::uint64_t>& range, bool owner, std::size_t& first, std::size_t& last) {
    std::uint64_t seen = range.load(std::memory_order_relaxed);
    for (;;) {
      const std::uint32_t front = static_cast<std::uint32_t>(seen), back = seen >> 32;
      if (front >= back) return false;
      const std::uint32_t left = back - front, least = std::min(grain_, left);
      const std::uint32_t n = owner ? least : std::max(least, left / 2);
      const std::uint64_t rest = owner ? pack(front + n, back) : pack(front, back - n);
      if (range.compare_exchange_weak(seen, rest, std::memory_order_relaxed)) {
        first = owner ? front : back - n;
        last = first + n;
        return true;
      }
    }
  }

  int threads_;
  std::uint32_t grain_;
  std::unique_ptr<Share[]> share_;
};

}  // namespace mpm
