#pragma once
/// \file Particle order that follows the grid: the particle arrays permuted by stencil cell.

#include <cstdint>
#include <span>
#include <vector>

#include "engine/core/particles.h"
#include "engine/step/transfer.h"

namespace mpm {

/// A contiguous particle range whose particles may be permuted among themselves (one object),
/// with its material state (MaterialGroup::state(), particle-major; may be empty).
struct ReorderRange {
  std::size_t first = 0;        ///< First particle index.
  std::size_t count = 0;        ///< Number of particles.
  std::span<Real> state;        ///< count x s values (s >= 0) that move with the particles.
};

/// Permutes the particles of each range into the order of `order` (the stencil-cell order of
/// the last sort_particles), so the transfers read particle memory in order. Particles never
/// leave their range, so objects and material groups keep their ranges. `order.order` and
/// `order.keys` are rewritten for the new indices, so the substep continues without a new
/// sort. The counting sort is stable, so the particles of one cell keep their relative order
/// and every grid sum is unchanged: results are bit-identical with or without reordering.
/// The permutation is held in `order.keys` while it is applied (no array of its own), and the
/// keys are then rebuilt from the sort's cell ranges (`order.counts`, as sort_particles leaves
/// them: counts[c] is the end of cell c).
void reorder_particles(std::span<const ReorderRange> ranges, ParticleOrder& order,
                       Particles& p);

}  // namespace mpm
