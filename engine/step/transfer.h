#pragma once
/// \file Particle <-> grid transfers and the particle-side stages of a substep.

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <span>
#include <thread>
#include <vector>

#include "engine/core/particles.h"
#include "engine/core/shares.h"
#include "engine/scene/scene_desc.h"
#include "engine/step/grid.h"
#include "materials/material.h"

namespace mpm {

/// Particles ordered by the grid cell of their stencil, with slabs for race-free scatter.
///
/// Slabs are a few cells thick along x (at least the kernel's width, about equal particle
/// counts). A particle in slab s writes only nodes of slabs s and s + 1, so all even slabs can
/// scatter at once, and each odd one once the even ones beside it are done (for_each_slab),
/// with no atomics. Slabs depend on the particles and the kernel only, not the thread count, so
/// sums are the same for any count.
struct ParticleOrder {
  std::vector<std::uint32_t> order;     ///< Particle indices sorted by stencil base cell.
  std::vector<std::size_t> slab_start;  ///< order[slab_start[s] .. slab_start[s+1]) is slab s.
  std::vector<std::uint32_t> counts;    ///< The counting sort's cell offsets: counts[c] is
                                        ///< where cell c's run in `order` starts (cells + 1;
                                        ///< dense boxes only: empty after the radix sort).
  std::vector<std::uint32_t> keys;      ///< Each particle's stencil base cell (particles_to_grid
                                        ///< sums a cell's particles before writing its nodes).
  Vec3i lo = Vec3i::Zero();             ///< The least stencil base: key 0's cell.
  Vec3i ext = Vec3i::Zero();            ///< Cells per axis of the keys' box (z fastest).

  /// The stencil base cell of key `key`: the one whose nodes sort_particles activated.
  Vec3i cell_base(std::uint32_t key) const {
    const auto z = static_cast<int>(key % ext.z()), yx = static_cast<int>(key / ext.z());
    return lo + Vec3i(yx / ext.y(), yx % ext.y(), z);
  }
  /// The sort's scratch: the counting sort's next place in `order` per thread and cell, or
  /// the radix sort's second array.
  std::vector<std::uint32_t> scratch;
  /// The sparse sort's marks, one per page of the grid (Grid::activate_blocks' `spans`); all
  /// zero between sorts.
  std::vector<std::uint8_t> spans;
};

/// Runs f(s) for every slab s of `order`, in parallel from `parallel_from` particles: the even
/// slabs first, then the odd ones, each colour handed out by Shares (each thread first its own
/// run of neighbouring slabs, where the particles and nodes of its share of the other stages
/// lie, then what is left of the other runs), and an odd slab starts once the even slabs
/// beside it are done. Every node so receives its even slab's sums before its odd slab's, on
/// any thread count, as when all even slabs ran before all odd ones, but a thread done with
/// its even slabs goes on to an odd one instead of waiting at a barrier for the last even slab
/// (slabs end at whole planes of cells, so their particle counts differ).
template <class Fn>
void for_each_slab(const ParticleOrder& order, Fn&& f, long parallel_from = kParallelMinItems) {
  const int slabs = static_cast<int>(order.slab_start.size()) - 1, evens = (slabs + 1) / 2;
  if (static_cast<long>(order.order.size()) < parallel_from) {
    for (int s = 0; s < slabs; s += 2) f(s);
    for (int s = 1; s < slabs; s += 2) f(s);
    return;
  }
  std::vector<std::atomic<bool>> done(static_cast<std::size_t>(std::max(slabs, 0)));
  const int team = omp_get_max_threads();
  Shares even(static_cast<std::size_t>(evens), team, 1);
  Shares odd(static_cast<std::size_t>(slabs - evens), team, 1);
  const auto run = [&](int s) {
    f(s);
    done[static_cast<std::size_t>(s)].store(true, std::memory_order_release);
  };
  const auto wait_for = [&](int s) {
    while (s < slabs && !done[static_cast<std::size_t>(s)].load(std::memory_order_acquire))
      std::this_thread::yield();
  };
#pragma omp parallel
  {
    std::size_t first = 0, last = 0;
    while (even.next(first, last))
      for (std::size_t k = first; k < last; ++k) run(2 * static_cast<int>(k));
    // Every even slab has been taken by a thread that runs it to the end: the waits end.
    while (odd.next(first, last))
      for (std::size_t k = first; k < last; ++k) {
        const int s = 2 * static_cast<int>(k) + 1;
        wait_for(s - 1);
        wait_for(s + 1);
        run(s);
      }
  }
}

/// Sorts particles by the base cell of `kernel`'s stencil and activates the grid blocks their
/// stencils touch (Grid::activate_blocks). Slabs are wide enough for the kernel (2 cells, 3
/// for cubic). A scatter that reaches `reach` nodes beyond the stencil on each side (the
/// particle domains', domain_quadrature.h) gets those nodes' blocks and wider slabs.
void sort_particles(const Particles& p, Kernel kernel, Grid& grid, ParticleOrder& order,
                    int reach = 0);

/// Zeroes every stored node's mass and momentum (and FLIP's force) before a scatter.
void clear_node_sums(Grid& grid);

/// Which implementation runs the transfers: the double scalar reference, or float SIMD
/// lanes (engine/step/simd/transfer_simd.h; FLIP always runs the scalar path).
enum class TransferPath { scalar, simd };

/// Clears the active nodes, then scatters mass, momentum (with the APIC affine term
/// m C (x_i - x_p), Jiang et al. 2015 eq. 11) and the stress force
/// f_i = -sum_p V0 tau_p grad w_ip (Jiang et al. 2016 course notes, eq. 189) to the grid.
/// For PIC and APIC the force enters the momentum as the impulse dt f_i, so grid_update's
/// v_i = (m v)_i / m_i is already v_i + dt f_i / m_i. FLIP keeps f_i in grid.force, to be
/// applied after the velocity before forces is saved. The particles of one stencil base cell
/// are summed locally and written to their nodes once. MLS (Hu et al. 2018, eq. 29) scatters
/// no force: the stress enters the affine term, m C + dt (-V0 tau) D^-1.
///
/// The stress -V0 tau is read from p.stress, except on the SIMD path for the particles of an
/// object o with a model in fold[o] (see simd::scatter): their stress is computed in the
/// scatter and never stored. `fold` must be empty unless simd::supports(transfer, kernel, grid).
void particles_to_grid(const Particles& p, const ParticleOrder& order, Transfer transfer,
                       Kernel kernel, Real dt, Grid& grid,
                       TransferPath path = TransferPath::scalar,
                       std::span<const BatchModel> fold = {});

/// What advection saw.
struct AdvectStats {
  std::size_t clamped = 0;    ///< Particles pushed back out of the buffer.
  std::size_t nonfinite = 0;  ///< Particles with a NaN or infinite position (left as they were).
  Real max_speed = 0;         ///< Largest particle speed, m/s.
};

/// Gathers velocity (PIC, FLIP blend, or APIC with C = B D^-1, D = h^2 / 4 quadratic, h^2 / 3
/// cubic, Jiang et al. 2015 eq. 8-10) into the particles, and updates F <- (I + dt grad v) F
/// with grad v = sum_i v_i grad w_ip^T (Stomakhin et al. 2013, eq. 7, elastic part), fused so
/// the gradient is never stored. For the linear kernel APIC takes C = grad v (Jiang et al.
/// 2015, section 5.3). MLS takes C as APIC does and updates F <- (I + dt C) F (Hu et al.
/// 2018, eq. 17), so it needs no weight gradients.
///
/// With `advect`, the particles are also advected with their new velocities (as
/// advect_particles, which then must not run) and what advection saw is written there: on the
/// SIMD path in the same pass over the particles, so x and v are read from memory once.
void grid_to_particles(const Grid& grid, Transfer transfer, Kernel kernel, Real flip_blend,
                       Real dt, Particles& p, TransferPath path = TransferPath::scalar,
                       AdvectStats* advect = nullptr);

/// The box advection keeps particles in: the grid interior, outside the buffer cells.
struct AdvectBox {
  Vec3 lo;  ///< Smallest allowed position, m.
  Vec3 hi;  ///< Largest allowed position, m.
  /// The interior of `g`.
  explicit AdvectBox(const Grid& g)
      : lo(g.origin + g.buffer * g.h),
        hi(g.origin + (g.nodes - Vec3i::Ones() - Vec3i::Constant(g.buffer)).cast<Real>()
                          .cwiseProduct(g.h)) {}
};

/// One particle's advection, x <- x + dt v kept inside `box` (a non-finite result leaves x as
/// it was), counted into clamped and nonfinite; v2 becomes the largest squared speed seen.
inline void advect_particle(const AdvectBox& box, Real dt, const Vec3& v, Vec3& x,
                            std::size_t& clamped, std::size_t& nonfinite, Real& v2) {
  v2 = std::max(v2, v.squaredNorm());
  const Vec3 moved = x + dt * v;
  if (!moved.allFinite()) {
    ++nonfinite;
    return;
  }
  const Vec3 c = moved.cwiseMax(box.lo).cwiseMin(box.hi);
  if (c != moved) ++clamped;
  x = c;
}

/// x <- x + dt v, kept inside the grid interior (outside the buffer).
AdvectStats advect_particles(Real dt, const Grid& grid, Particles& p);

}  // namespace mpm
