#pragma once
/// \file Parallel reductions whose result does not depend on the thread count.

#include <algorithm>
#include <cstddef>
#include <vector>

#include "engine/core/math.h"

namespace mpm {

/// Items per chunk of `reduce_chunks`: fixed, so the chunks (and the order their results are
/// combined in) are the same for any number of threads.
inline constexpr std::size_t kReduceChunk = 4096;

/// Reduces items [0, n): `chunk(first, last)` returns the partial result of one chunk of at most
/// kReduceChunk items, computed in parallel; `combine(a, b)` merges them in chunk order. The
/// answer is bit-identical for 1 and N threads, unlike an OpenMP `reduction` clause.
template <class T, class Chunk, class Combine>
T reduce_chunks(std::size_t n, T zero, Chunk&& chunk, Combine&& combine) {
  const std::ptrdiff_t chunks = static_cast<std::ptrdiff_t>((n + kReduceChunk - 1) / kReduceChunk);
  std::vector<T> part(static_cast<std::size_t>(chunks), zero);
#pragma omp parallel for schedule(static) if (n >= static_cast<std::size_t>(kParallelMinItems))
  for (std::ptrdiff_t c = 0; c < chunks; ++c) {
    const std::size_t first = static_cast<std::size_t>(c) * kReduceChunk;
    part[static_cast<std::size_t>(c)] = chunk(first, std::min(n, first + kReduceChunk));
  }
  T out = zero;
  for (const T& p : part) out = combine(out, p);
  return out;
}

/// The sum of `term(i)` over items [0, n), in fixed chunks (see reduce_chunks).
template <class Term>
Real sum_chunks(std::size_t n, Term&& term) {
  return reduce_chunks(
      n, Real{0},
      [&](std::size_t first, std::size_t last) {
        Real s = 0;
        for (std::size_t i = first; i < last; ++i) s += term(i);
        return s;
      },
      [](Real a, Real b) { return a + b; });
}

}  // namespace mpm
