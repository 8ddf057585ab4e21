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
/// this substep's sort_particles), so the next transfers read particle memory in order.
/// Particles never leave their range, so objects and material groups keep their ranges. It
/// runs between particles_to_grid and grid_to_particles, where v and C are dead for PIC, APIC
/// and MLS (grid_to_particles overwrites them): it moves x, F, id and the state, and v only
/// with `move_velocity` (FLIP blends the old v). The permutation is held in `order.keys` (no
/// array of its own), so `order` is spent until the next sort. No memory is added: x, F and
/// id are written out of place into the dead v, C and order.order and swap buffers with them
/// (x and F by in-place cycles where no dead array is there: FLIP, PIC). Ties in the stable
/// counting sort are broken by memory index, so reordering changes which particle of a cell
/// is summed first: results change at round-off only, and stay the same for any thread count.
void reorder_particles(std::span<const ReorderRange> ranges, bool move_velocity,
                       ParticleOrder& order, Particles& p);

}  // namespace mpm
