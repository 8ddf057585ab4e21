#include "engine/step/grid.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

namespace mpm {

Grid::Grid(const GridDesc& d, bool flip)
    : origin(d.origin), h(d.spacing()), inv_h(h.cwiseInverse()),
      nodes(d.dims + Vec3i::Ones()), buffer(d.buffer),
      blocks((nodes + Vec3i::Constant(kBlockEdge - 1)) / kBlockEdge), flip(flip),
      float_nodes(d.float_nodes) {
  slot.assign(static_cast<std::size_t>(blocks.x()) * blocks.y() * blocks.z(), -1);
}

void Grid::activate_blocks(const Vec3i& lo, const Vec3i& hi, std::span<std::uint8_t> spans) {
  block_first.clear();
  for (int bi = lo.x(); bi <= hi.x(); ++bi)
    for (int bj = lo.y(); bj <= hi.y(); ++bj)
      for (int bk = lo.z(); bk <= hi.z(); ++bk) {
        const std::size_t pg = page(bi, bj, bk);
        if (!spans.empty() && spans[pg] != 0) {
          // This block and the next ones its bits name, which come later in this scan.
          const int next = spans[pg] & 7;
          spans[pg] = 0;
          for (int d = 0; d < 8; ++d)
            if ((d & next) == d) slot[page(bi + (d & 1), bj + (d >> 1 & 1), bk + (d >> 2 & 1))] = 0;
        }
        std::int32_t& s = slot[pg];
        if (s < 0) continue;
        s = static_cast<std::int32_t>(block_first.size());
        block_first.emplace_back(bi * kBlockEdge, bj * kBlockEdge, bk * kBlockEdge);
      }
  const std::size_t n = block_first.size() * kBlockNodes;
  mass.resize(n);
  velocity.resize(n);
  if (flip) {
    force.resize(n);
    velocity_old.resize(n);
  }
}

void Grid::release_blocks() {
  for (const Vec3i& f : block_first)
    slot[page(f.x() / kBlockEdge, f.y() / kBlockEdge, f.z() / kBlockEdge)] = -1;
  block_first.clear();
}

}  // namespace mpm

namespace mpm {

namespace {

/// Calls f(idx) for every stored node, in parallel: one flat loop, with no per-node block
/// arithmetic. The nodes of a block past the grid's last node are
/// included: no stencil reaches them, so their sums stay the zeros clear_node_sums left, and
/// each stage here leaves a node without mass as it was (grid_update: zero velocity).
template <class Fn>
void for_each_stored_node(const Grid& g, Fn&& f) {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(g.mass.size());
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (std::ptrdiff_t i = 0; i < n; ++i) f(i);
}

/// Calls nodes(first, last) for the nodes of each storage block, in parallel over the blocks,
/// then sets `speeds` to the blocks' speeds after it (BlockSpeeds), from the nodes with mass,
/// while the block is in cache. After grid_update a node without mass has a zero velocity,
/// which raises no maximum: kAllNodes then skips the test.
template <bool kAllNodes, class Nodes>
void for_each_block_with_speeds(const Grid& g, const Nodes& nodes, BlockSpeeds& speeds) {
  const std::ptrdiff_t nb = static_cast<std::ptrdiff_t>(g.active_blocks());
  const bool par = nb * Grid::kBlockNodes >= kParallelMinItems;
  speeds.block.resize(g.active_blocks());
  const Real* mass = g.mass.data();
  const Real* v = g.velocity.data()->data();
  Real squared = 0;
#pragma omp parallel for schedule(static) reduction(max : squared) if (par)
  for (std::ptrdiff_t b = 0; b < nb; ++b) {
    std::array<Real, 6> most{};
    nodes(b * Grid::kBlockNodes, (b + 1) * Grid::kBlockNodes);
    for (std::ptrdiff_t i = b * Grid::kBlockNodes; i < (b + 1) * Grid::kBlockNodes; ++i) {
      if (!kAllNodes && !(mass[i] > 0)) continue;
      for (int a = 0; a < 3; ++a) {
        most[2 * a] = std::max(most[2 * a], v[3 * i + a]);
        most[2 * a + 1] = std::max(most[2 * a + 1], -v[3 * i + a]);
      }
    }
    speeds.block[b] = most;
    // The block's nodes' squared speeds only where they may pass the largest so far: each is
    // at most that of the block's largest components (rounding keeps the order).
    const Vec3 top(std::max(most[0], most[1]), std::max(most[2], most[3]),
                   std::max(most[4], most[5]));
    if (!(top.squaredNorm() > squared)) continue;
    for (std::ptrdiff_t i = b * Grid::kBlockNodes; i < (b + 1) * Grid::kBlockNodes; ++i)
      if (kAllNodes || mass[i] > 0)
        squared = std::max(squared, Eigen::Map<const Vec3>(v + 3 * i).squaredNorm());
  }
  speeds.fastest = std::sqrt(squared);
}

/// grid_update with the float rounding (kFloat) and gravity's velocity change (kGravity) known
/// to the compiler: the division by a mass of 1 where there is none, then a select, so that
/// the loop has no branch. With `speeds`, a pass over the blocks that also sets them.
template <bool kFloat, bool kGravity>
void update_nodes(const Vec3& dv, Grid& g, BlockSpeeds* speeds) {
  const Real* mass = g.mass.data();
  Real* v = g.velocity.data()->data();
  const auto update = [&](std::ptrdiff_t i) {
    const bool has = mass[i] > 0;
    const Real m = has ? mass[i] : Real(1);
    for (int a = 0; a < 3; ++a) {
      Real u = v[3 * i + a] / m;
      if constexpr (kFloat) u = static_cast<float>(u);
      if constexpr (kGravity) u += dv[a];
      v[3 * i + a] = has ? u : Real(0);
    }
  };
  if (speeds)
    for_each_block_with_speeds<true>(
        g,
        [&](std::ptrdiff_t first, std::ptrdiff_t last) {
          for (std::ptrdiff_t i = first; i < last; ++i) update(i);
        },
        *speeds);
  else
    for_each_stored_node(g, update);
}

}  // namespace

BlockSpeeds block_speeds(const Grid& g) {
  BlockSpeeds speeds;
  for_each_block_with_speeds<false>(
      g, [](std::ptrdiff_t, std::ptrdiff_t) {}, speeds);
  return speeds;
}

void grid_update(Grid& g, const Vec3& gravity_dv, BlockSpeeds* speeds) {
  const bool gravity = gravity_dv != Vec3::Zero();
  if (g.flip && gravity)
    throw std::logic_error(
        "grid_update: gravity folded in with FLIP, whose old velocity is before it");
  if (g.float_nodes)
    gravity ? update_nodes<true, true>(gravity_dv, g, speeds)
            : update_nodes<true, false>(gravity_dv, g, speeds);
  else
    gravity ? update_nodes<false, true>(gravity_dv, g, speeds)
            : update_nodes<false, false>(gravity_dv, g, speeds);
  if (g.flip) g.velocity_old = g.velocity;
}

void apply_stress_forces(Real dt, Grid& g) {
  for_each_stored_node(g, [&](std::ptrdiff_t i) {
    const Real m = g.mass[i];
    if (m > 0) g.velocity[i] += (dt / m) * g.force[i];
  });
}

void apply_gravity(Real dt, const Vec3& gravity, Grid& g) {
  const Vec3 dv = dt * gravity;
  for_each_stored_node(g, [&](std::ptrdiff_t i) {
    if (g.mass[i] > 0) g.velocity[i] += dv;
  });
}

void apply_damping(Real dt, Real rate, Grid& g) {
  const Real factor = std::exp(-rate * dt);
  for_each_stored_node(g, [&](std::ptrdiff_t i) { g.velocity[i] *= factor; });
}

}  // namespace mpm
