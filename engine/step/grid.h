#pragma once
/// \file The background grid: sparse 4^3-node blocks where the particles are.

#include <array>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "engine/core/math.h"
#include "engine/scene/scene_desc.h"

namespace mpm {

/// Grid node state, stored sparsely: only the 4 x 4 x 4-node blocks the particles' stencils
/// touch in this substep have storage, so memory and time follow the particles, not the box.
///
/// A page table maps each block of the domain to a storage slot (or -1). Node (i, j, k) sits at
/// origin + (i, j, k) * h and is stored at slot * 64 + its offset inside the block. Slots are
/// given out in block order (x slowest) by activate_blocks, the same on any thread count.
struct Grid {
  static constexpr int kBlockBits = 2;                      ///< log2 of the block edge.
  static constexpr int kBlockEdge = 1 << kBlockBits;        ///< Nodes per block edge (4).
  static constexpr int kBlockNodes = kBlockEdge * kBlockEdge * kBlockEdge;  ///< 64.

  Vec3 origin;        ///< Position of node (0, 0, 0), m.
  Vec3 h;             ///< Cell size per axis, m.
  Vec3 inv_h;         ///< 1 / h.
  Vec3i nodes;        ///< Nodes per axis (cells + 1).
  int buffer = 3;     ///< Boundary cells particles never enter.
  Vec3i blocks;       ///< Blocks per axis covering the nodes.
  bool flip = false;  ///< True if force and velocity_old are kept (FLIP only).
  /// Node mass, momentum and velocity rounded to float where the transfers and grid_update
  /// store them (grid.precision: float); the arrays stay double-wide, arithmetic is double.
  bool float_nodes = false;

  std::vector<std::int32_t> slot;  ///< Page table: block -> storage slot, -1 if not in use.
  std::vector<Vec3i> block_first;  ///< First node (i, j, k) of the block in each slot.

  std::vector<Real> mass;          ///< Node mass, kg.
  std::vector<Vec3> velocity;      ///< Momentum after transfer, then velocity, m/s.
  std::vector<Vec3> force;         ///< Internal force from stress, N (FLIP only; else empty).
  std::vector<Vec3> velocity_old;  ///< Velocity before forces (FLIP only; else empty).
  /// Nodes per row of velocity_f for stencils of N nodes per axis: a block's kBlockEdge along
  /// z, then the next z block's first N - 1, so that the stencil's z nodes lie in one row.
  static constexpr int row_nodes(int N) { return kBlockEdge + N - 1; }
  /// Floats of velocity_f per block slot: kBlockEdge^2 rows (i, j) of row_nodes(N) x, y, z.
  static constexpr int row_block_floats(int N) {
    return kBlockEdge * kBlockEdge * 3 * row_nodes(N);
  }
  /// Scratch of the SIMD gather: the velocity in float in rows along z (simd::prepare_gather),
  /// row_block_floats(N) per slot, row (i, j) of the block at 3 row_nodes(N) (i kBlockEdge + j).
  mutable std::vector<float> velocity_f;

  /// A grid for `desc`; `flip` keeps velocity_old and force, which only FLIP uses.
  Grid(const GridDesc& desc, bool flip);
  /// Offset inside its block of the node at (i, j, k) within the block (each below 4).
  static constexpr int block_offset(int i, int j, int k) {
    return (i << (2 * kBlockBits)) | (j << kBlockBits) | k;
  }
  /// Page-table entry of block (bi, bj, bk).
  std::size_t page(int bi, int bj, int bk) const {
    return (static_cast<std::size_t>(bi) * blocks.y() + bj) * blocks.z() + bk;
  }
  /// A stencil node with no storage (stencil_indices with kChecked).
  static constexpr std::size_t kNoStorage = ~std::size_t{0};
  /// Storage indices of the N^3 nodes from `base` (k fastest): one page-table lookup per
  /// block (at most two per axis), not one per node. Unchecked, every block must be active;
  /// with kChecked, nodes outside the grid or in blocks without storage get kNoStorage.
  template <int N, bool kChecked = false>
  void stencil_indices(const Vec3i& base, std::size_t* out) const {
    static_assert(N <= kBlockEdge + 1, "a stencil spans at most two blocks per axis");
    constexpr int m = kBlockEdge - 1;
    const Vec3i b0(base.x() >> kBlockBits, base.y() >> kBlockBits, base.z() >> kBlockBits);
    int blk[3][N], off[3][N];
    bool inside[3][N] = {};
    for (int a = 0; a < 3; ++a)
      for (int t = 0; t < N; ++t) {
        blk[a][t] = ((base[a] + t) >> kBlockBits) - b0[a];
        off[a][t] = (base[a] + t) & m;
        if constexpr (kChecked) inside[a][t] = base[a] + t >= 0 && base[a] + t < nodes[a];
      }
    std::size_t first[2][2][2] = {};  // blocks the stencil does not reach stay 0, unused
    for (int di = 0; di <= blk[0][N - 1]; ++di)
      for (int dj = 0; dj <= blk[1][N - 1]; ++dj)
        for (int dk = 0; dk <= blk[2][N - 1]; ++dk) {
          const Vec3i b = b0 + Vec3i(di, dj, dk);
          if constexpr (kChecked) {
            const bool in = (b.array() >= 0).all() && (b.array() < blocks.array()).all();
            const std::int32_t s = in ? slot[page(b.x(), b.y(), b.z())] : -1;
            first[di][dj][dk] = s < 0 ? kNoStorage : static_cast<std::size_t>(s) * kBlockNodes;
          } else {
            const std::int32_t s = slot[page(b.x(), b.y(), b.z())];
            assert(s >= 0 && "the sort activates every block a stencil touches");
            first[di][dj][dk] = static_cast<std::size_t>(s) * kBlockNodes;
          }
        }
    // Each (i, j) row's start in its two z blocks, then one add per node.
    int c = 0;
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j) {
        const std::size_t xy = block_offset(off[0][i], off[1][j], 0);
        const std::size_t* f = first[blk[0][i]][blk[1][j]];
        if constexpr (kChecked) {
          for (int k = 0; k < N; ++k, ++c) {
            const std::size_t start = f[blk[2][k]];
            out[c] = !inside[0][i] || !inside[1][j] || !inside[2][k] || start == kNoStorage
                         ? kNoStorage
                         : start + xy + off[2][k];
          }
        } else {
          // The second z block's start, at an index known only now: the compiler then loads
          // the two starts one by one, as they were stored (a load of both at once waits
          // until the stores reach the cache: it cannot take them from the store queue).
          const std::size_t row0 = f[0] + xy, row1 = f[blk[2][N - 1]] + xy;
          for (int k = 0; k < N; ++k) out[c++] = (blk[2][k] ? row1 : row0) + off[2][k];
        }
      }
  }
  /// Offsets in velocity_f of the N^2 rows (i, j) of the stencil from `base` (i slowest), each
  /// at node base + (i, j, 0): node (i, j, k)'s x, y and z follow at 3 k, 3 k + 1 and 3 k + 2.
  /// Every block of the stencil must be active.
  template <int N>
  void stencil_rows(const Vec3i& base, std::uint32_t* out) const {
    static_assert(N <= kBlockEdge + 1, "a stencil spans at most two blocks per axis");
    constexpr int m = kBlockEdge - 1, R = row_nodes(N);
    const Vec3i b0(base.x() >> kBlockBits, base.y() >> kBlockBits, base.z() >> kBlockBits);
    int blk[2][N], off[2][N];
    for (int a = 0; a < 2; ++a)
      for (int t = 0; t < N; ++t) {
        blk[a][t] = ((base[a] + t) >> kBlockBits) - b0[a];
        off[a][t] = (base[a] + t) & m;
      }
    std::uint32_t first[2][2] = {};  // blocks the stencil does not reach stay 0, unused
    for (int di = 0; di <= blk[0][N - 1]; ++di)
      for (int dj = 0; dj <= blk[1][N - 1]; ++dj) {
        const std::int32_t s = slot[page(b0.x() + di, b0.y() + dj, b0.z())];
        assert(s >= 0 && "the sort activates every block a stencil touches");
        first[di][dj] = static_cast<std::uint32_t>(s) * row_block_floats(N) + 3 * (base.z() & m);
      }
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j)
        out[N * i + j] = first[blk[0][i]][blk[1][j]] + 3 * R * (off[0][i] * kBlockEdge + off[1][j]);
  }
  /// Storage index of node (i, j, k), whose block must be active.
  std::size_t node_index(int i, int j, int k) const {
    const std::int32_t s = slot[page(i >> kBlockBits, j >> kBlockBits, k >> kBlockBits)];
    assert(s >= 0 && "the sort activates every block a stencil touches");
    constexpr int m = kBlockEdge - 1;
    return static_cast<std::size_t>(s) * kBlockNodes + block_offset(i & m, j & m, k & m);
  }
  /// World position of node (i, j, k), m.
  Vec3 position(int i, int j, int k) const {
    return origin + Vec3(i, j, k).cwiseProduct(h);
  }
  /// Number of blocks with storage this substep.
  std::size_t active_blocks() const { return block_first.size(); }
  /// Gives storage to the blocks marked 0 in `slot` inside the block box [lo, hi] (others
  /// must be -1), in block order, and sizes the node arrays to match. With `spans` (one entry
  /// per page), a block whose entry is not 0 is marked too, and so is the next block along each
  /// axis a whose bit 1 << a the entry sets (inside the box); the entries are reset to 0.
  void activate_blocks(const Vec3i& lo, const Vec3i& hi, std::span<std::uint8_t> spans = {});
  /// Returns every active block to -1 in the page table.
  void release_blocks();
};

/// Calls f(i, j, k, idx) for every node of every active block whose first node o passes
/// `visit(o)`, in parallel over blocks. A block is visited by one thread, so f may accumulate
/// into per-block (idx / 64) slots. A stage that acts near a wall skips the other blocks whole.
template <class Visit, class Fn>
void for_each_active_node(const Grid& g, Visit&& visit, Fn&& f) {
  const std::ptrdiff_t nb = static_cast<std::ptrdiff_t>(g.active_blocks());
  constexpr int E = Grid::kBlockEdge;
#pragma omp parallel for schedule(static) if (nb * Grid::kBlockNodes >= kParallelMinItems)
  for (std::ptrdiff_t b = 0; b < nb; ++b) {
    const Vec3i o = g.block_first[b];
    if (!visit(o)) continue;
    std::size_t idx = static_cast<std::size_t>(b) * Grid::kBlockNodes;
    for (int i = o.x(); i < o.x() + E; ++i)
      for (int j = o.y(); j < o.y() + E; ++j)
        for (int k = o.z(); k < o.z() + E; ++k, ++idx)
          if (i < g.nodes.x() && j < g.nodes.y() && k < g.nodes.z()) f(i, j, k, idx);
  }
}

/// Calls f(i, j, k, idx) for every node of every active block (as above, every block visited).
template <class Fn>
void for_each_active_node(const Grid& g, Fn&& f) {
  for_each_active_node(
      g, [](const Vec3i&) { return true; }, f);
}

}  // namespace mpm

namespace mpm {

/// How fast the nodes of each storage block move: what the contact search bounds a particle's
/// closing speed with (contact.cpp, GridSpeed).
struct BlockSpeeds {
  /// Per storage slot, [2 a] the largest velocity component along +a of its nodes with mass
  /// and [2 a + 1] along -a (at least 0), m/s.
  std::vector<std::array<Real, 6>> block;
  Real fastest = 0;  ///< The largest speed of any node with mass, m/s.
};

/// The block speeds of `grid`'s velocities as they are, in parallel over its blocks.
BlockSpeeds block_speeds(const Grid& grid);

/// Momentum to velocity, v_i = (m v)_i / m_i, then v_i += gravity_dv on nodes with mass (gravity
/// folded into the same pass over the nodes); keeps a copy in velocity_old for FLIP. If
/// `speeds` is given, also sets it to block_speeds of the new velocities, in the same pass.
void grid_update(Grid& grid, const Vec3& gravity_dv = Vec3::Zero(), BlockSpeeds* speeds = nullptr);

/// v_i += dt f_i / m_i: the internal forces particles_to_grid scattered for FLIP.
void apply_stress_forces(Real dt, Grid& grid);

/// v_i += dt g on nodes with mass.
void apply_gravity(Real dt, const Vec3& gravity, Grid& grid);

/// v_i *= exp(-rate dt): viscous damping toward rest, for settling to static equilibrium.
void apply_damping(Real dt, Real rate, Grid& grid);

}  // namespace mpm
