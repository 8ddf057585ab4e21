#include "engine/step/grid.h"

#include <cmath>

namespace mpm {

Grid::Grid(const GridDesc& d, bool flip)
    : origin(d.origin), h(d.spacing()), inv_h(h.cwiseInverse()),
      nodes(d.dims + Vec3i::Ones()), buffer(d.buffer),
      blocks((nodes + Vec3i::Constant(kBlockEdge - 1)) / kBlockEdge), flip(flip),
      float_nodes(d.float_nodes) {
  slot.assign(static_cast<std::size_t>(blocks.x()) * blocks.y() * blocks.z(), -1);
}

void Grid::activate_blocks(const Vec3i& lo, const Vec3i& hi) {
  block_first.clear();
  for (int bi = lo.x(); bi <= hi.x(); ++bi)
    for (int bj = lo.y(); bj <= hi.y(); ++bj)
      for (int bk = lo.z(); bk <= hi.z(); ++bk) {
        std::int32_t& s = slot[page(bi, bj, bk)];
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

void grid_update(Grid& g) {
  for_each_active_node(g, [&](int, int, int, std::size_t idx) {
    const Real m = g.mass[idx];
    g.velocity[idx] = m > 0 ? Vec3(g.velocity[idx] / m) : Vec3::Zero();
    if (g.float_nodes) g.velocity[idx] = g.velocity[idx].cast<float>().cast<Real>();
    if (g.flip) g.velocity_old[idx] = g.velocity[idx];
  });
}

void apply_stress_forces(Real dt, Grid& g) {
  for_each_active_node(g, [&](int, int, int, std::size_t idx) {
    const Real m = g.mass[idx];
    if (m > 0) g.velocity[idx] += (dt / m) * g.force[idx];
  });
}

void apply_gravity(Real dt, const Vec3& gravity, Grid& g) {
  const Vec3 dv = dt * gravity;
  for_each_active_node(g, [&](int, int, int, std::size_t idx) {
    if (g.mass[idx] > 0) g.velocity[idx] += dv;
  });
}

void apply_damping(Real dt, Real rate, Grid& g) {
  const Real factor = std::exp(-rate * dt);
  for_each_active_node(g, [&](int, int, int, std::size_t idx) { g.velocity[idx] *= factor; });
}

}  // namespace mpm
