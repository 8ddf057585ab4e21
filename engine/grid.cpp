#include "engine/grid.h"

#include <cmath>

namespace mpm {

Grid::Grid(const GridDesc& d, bool flip)
    : origin(d.origin), h(d.spacing()), inv_h(h.cwiseInverse()),
      nodes(d.dims + Vec3i::Ones()), buffer(d.buffer) {
  const std::size_t n = static_cast<std::size_t>(nodes.x()) * nodes.y() * nodes.z();
  mass.assign(n, 0);
  velocity.assign(n, Vec3::Zero());
  if (flip) {
    force.assign(n, Vec3::Zero());
    velocity_old.assign(n, Vec3::Zero());
  }
}

}  // namespace mpm

namespace mpm {

void grid_update(Grid& g) {
  const bool flip = !g.velocity_old.empty();
  for_each_active_node(g, [&](int, int, int, std::size_t idx) {
    const Real m = g.mass[idx];
    g.velocity[idx] = m > 0 ? Vec3(g.velocity[idx] / m) : Vec3::Zero();
    if (flip) g.velocity_old[idx] = g.velocity[idx];
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
