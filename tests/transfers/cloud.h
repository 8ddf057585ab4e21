#pragma once
/// \file Random particle clouds and grid totals, shared by the transfer tests.

#include <random>

#include "engine/core/particles.h"
#include "engine/step/grid.h"

namespace mpm::test {

/// A cloud of particles with random velocities and masses (and random C for APIC) in a 16^3
/// grid. Each particle is its own object, so each has its own mass.
inline Particles random_cloud(std::size_t n, bool apic, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> pos(0.3, 0.7), vel(-1, 1), m(0.5, 2);
  Particles p;
  for (std::size_t i = 0; i < n; ++i) {
    p.x.emplace_back(pos(rng), pos(rng), pos(rng));
    p.v.emplace_back(vel(rng), vel(rng), vel(rng));
    p.object_mass.push_back(m(rng));
    p.object_volume0.push_back(1e-4);
    p.object.push_back(static_cast<std::uint32_t>(i));
    p.F.push_back(StoredMat3::Identity());
    p.stress.push_back(StoredMat3::Zero());
    if (apic) {
      StoredMat3 C;
      for (int a = 0; a < 9; ++a) C.data()[a] = static_cast<StoredReal>(vel(rng));
      p.C.push_back(C);
    }
  }
  return p;
}

/// A unit box of `cells` cells per axis with a 2-cell buffer.
inline GridDesc unit_grid(int cells) {
  GridDesc d;
  d.dims = Vec3i::Constant(cells);
  d.buffer = 2;
  return d;
}

/// Mass, momentum and angular momentum summed over a grid.
struct GridTotals {
  double mass = 0;
  Vec3 momentum = Vec3::Zero(), angular = Vec3::Zero();
};

/// Totals over the grid while `velocity` still holds momentum (right after the scatter).
inline GridTotals grid_totals_of_momentum(const Grid& g) {
  GridTotals t;
  for (std::size_t b = 0; b < g.active_blocks(); ++b) {  // serial: a fixed summation order
    std::size_t idx = b * Grid::kBlockNodes;
    const Vec3i o = g.block_first[b];
    for (int i = o.x(); i < o.x() + Grid::kBlockEdge; ++i)
      for (int j = o.y(); j < o.y() + Grid::kBlockEdge; ++j)
        for (int k = o.z(); k < o.z() + Grid::kBlockEdge; ++k, ++idx) {
          t.mass += g.mass[idx];
          t.momentum += g.velocity[idx];
          t.angular += g.position(i, j, k).cross(g.velocity[idx]);
        }
  }
  return t;
}

}  // namespace mpm::test
