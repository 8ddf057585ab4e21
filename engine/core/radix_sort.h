#pragma once
/// \file A stable least-significant-digit radix sort of indices by integer keys: the particle
/// sort in a sparse box (engine/step/transfer.cpp) and the contacts' sort by patch and id
/// (engine/step/contact.cpp).

#include <omp.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "engine/core/math.h"

namespace mpm {

/// Puts the indices 0 .. n - 1 in `order` sorted by key(i), an unsigned integer below 2^bits
/// (equal keys keep index order): passes of a stable counting sort on up to 11 bits each, so
/// the time is in proportion to n. `scratch` is the second array the passes alternate with.
/// From kParallelMinItems indices each pass runs on the team: each thread counts the digits of
/// its own contiguous part, takes its places after those of the same digit in the parts before
/// it, and moves its part, so the order is the same on any thread count.
template <class Key>
void radix_order(std::size_t n, int bits, const Key& key, std::vector<std::uint32_t>& order,
                 std::vector<std::uint32_t>& scratch) {
  bits = std::max(bits, 1);
  const int passes = (bits + 10) / 11, digit = (bits + passes - 1) / passes;
  const std::size_t radix = std::size_t{1} << digit;
  const std::uint64_t mask = radix - 1;
  order.resize(n);
  scratch.resize(n);
  // The passes alternate between the two arrays and end in `order`; the first reads the
  // indices in order.
  std::uint32_t* src = nullptr;
  std::uint32_t* dst = passes % 2 ? order.data() : scratch.data();
  constexpr int kMaxThreads = 64;
  const int team = n >= static_cast<std::size_t>(kParallelMinItems)
                       ? std::min(omp_get_max_threads(), kMaxThreads)
                       : 1;
  // Per thread, the count of each digit in its part, then where its first such index goes.
  std::vector<std::uint32_t> at(static_cast<std::size_t>(team) * radix);
  for (int pass = 0, shift = 0; pass < passes; ++pass, shift += digit) {
    const auto index = [&](std::size_t j) { return src ? src[j] : static_cast<std::uint32_t>(j); };
    const auto bucket = [&](std::uint32_t i) {
      return (static_cast<std::uint64_t>(key(i)) >> shift) & mask;
    };
#pragma omp parallel num_threads(team) if (team > 1)
    {
      const std::size_t t = static_cast<std::size_t>(omp_get_thread_num());
      const std::size_t parts = static_cast<std::size_t>(omp_get_num_threads());
      const std::size_t first = n * t / parts, last = n * (t + 1) / parts;
      const std::span<std::uint32_t> mine(&at[t * radix], radix);
      std::fill(mine.begin(), mine.end(), 0u);
      for (std::size_t j = first; j < last; ++j) ++mine[bucket(index(j))];
#pragma omp barrier
#pragma omp single
      {
        std::uint32_t end = 0;
        for (std::size_t b = 0; b < radix; ++b)
          for (std::size_t u = 0; u < parts; ++u) end += std::exchange(at[u * radix + b], end);
      }  // (a barrier)
      for (std::size_t j = first; j < last; ++j) {
        const std::uint32_t i = index(j);
        dst[mine[bucket(i)]++] = i;
      }
    }
    src = dst;
    dst = dst == scratch.data() ? order.data() : scratch.data();
  }
}

}  // namespace mpm
