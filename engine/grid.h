#pragma once
/// \file The background grid: node arrays over the whole domain, used only where particles are.

#include <cstddef>
#include <vector>

#include "engine/math.h"
#include "engine/scene_desc.h"

namespace mpm {

/// A box of node indices [lo, hi] (inclusive) that the current particles touch.
struct NodeRange {
  Vec3i lo{0, 0, 0};   ///< First node per axis.
  Vec3i hi{-1, -1, -1};///< Last node per axis.
};

/// Grid node state. Node (i, j, k) sits at origin + (i, j, k) * h; x is the slowest index.
struct Grid {
  Vec3 origin;        ///< Position of node (0, 0, 0), m.
  Vec3 h;             ///< Cell size per axis, m.
  Vec3 inv_h;         ///< 1 / h.
  Vec3i nodes;        ///< Nodes per axis (cells + 1).
  int buffer = 3;     ///< Boundary cells particles never enter.
  NodeRange active;   ///< Nodes the particles touch this substep.

  std::vector<Real> mass;          ///< Node mass, kg.
  std::vector<Vec3> velocity;      ///< Momentum after transfer, then velocity, m/s.
  std::vector<Vec3> force;         ///< Internal force from stress, N (FLIP only; else empty).
  std::vector<Vec3> velocity_old;  ///< Velocity before forces (FLIP only; else empty).

  /// A grid for `desc`; `flip` allocates velocity_old and force, which only FLIP uses.
  Grid(const GridDesc& desc, bool flip);
  /// Linear index of node (i, j, k).
  std::size_t index(int i, int j, int k) const {
    return (static_cast<std::size_t>(i) * nodes.y() + j) * nodes.z() + k;
  }
  /// World position of node (i, j, k), m.
  Vec3 position(int i, int j, int k) const {
    return origin + Vec3(i, j, k).cwiseProduct(h);
  }
};

/// Calls f(i, j, k, idx) for every active node, in parallel over x slices.
template <class Fn>
void for_each_active_node(const Grid& g, Fn&& f) {
  const NodeRange r = g.active;
  const long nodes = static_cast<long>(r.hi.x() - r.lo.x() + 1) * (r.hi.y() - r.lo.y() + 1) *
                     (r.hi.z() - r.lo.z() + 1);
#pragma omp parallel for schedule(static) if (nodes >= kParallelMinItems)
  for (int i = r.lo.x(); i <= r.hi.x(); ++i)
    for (int j = r.lo.y(); j <= r.hi.y(); ++j)
      for (int k = r.lo.z(); k <= r.hi.z(); ++k) f(i, j, k, g.index(i, j, k));
}

}  // namespace mpm

namespace mpm {

/// Momentum to velocity, v_i = (m v)_i / m_i; keeps a copy in velocity_old for FLIP.
void grid_update(Grid& grid);

/// v_i += dt f_i / m_i: the internal forces particles_to_grid scattered for FLIP.
void apply_stress_forces(Real dt, Grid& grid);

/// v_i += dt g on nodes with mass.
void apply_gravity(Real dt, const Vec3& gravity, Grid& grid);

/// v_i *= exp(-rate dt): viscous damping toward rest, for settling to static equilibrium.
void apply_damping(Real dt, Real rate, Grid& grid);

}  // namespace mpm
