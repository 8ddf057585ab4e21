#pragma once
/// \file The one parallel loop over a group's particles that every material's stage runs.

#include <algorithm>
#include <cstddef>

#include "engine/core/math.h"
#include "engine/core/reduce.h"

namespace mpm::materials {

/// Calls body(p) for every particle p in [0, n), on OpenMP threads when there are at least
/// kParallelMinItems particles (static schedule). Each p is independent of the others.
template <class Body>
void for_each_particle(std::size_t n, Body&& body) {
  const std::ptrdiff_t sn = static_cast<std::ptrdiff_t>(n);
#pragma omp parallel for schedule(static) if (sn >= kParallelMinItems)
  for (std::ptrdiff_t p = 0; p < sn; ++p) body(p);
}

/// The largest of 0 and value(p) over the particles p in [0, n), as for_each_particle runs
/// them (a maximum: the same for any thread count).
template <class Value>
Real max_over_particles(std::size_t n, Value&& value) {
  Real c = 0;
  const std::ptrdiff_t sn = static_cast<std::ptrdiff_t>(n);
#pragma omp parallel for schedule(static) reduction(max : c) if (sn >= kParallelMinItems)
  for (std::ptrdiff_t p = 0; p < sn; ++p) c = std::max(c, value(p));
  return c;
}

}  // namespace mpm::materials
