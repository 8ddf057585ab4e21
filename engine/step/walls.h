#pragma once
/// \file Wall conditions on grid velocities.

#include <vector>

#include "engine/step/grid.h"
#include "engine/scene/scene_desc.h"

namespace mpm {

/// One half-space wall: nodes with (x - point) . normal <= 0 are inside it.
struct WallPlane {
  Vec3 point;          ///< A point on the plane, m.
  Vec3 normal;         ///< Unit normal pointing into the free side.
  Boundary boundary;   ///< Condition applied to nodes inside.
  Real friction;       ///< Coulomb coefficient.
  Vec3 velocity;       ///< Constant wall velocity, m/s (when path is empty).
  std::vector<WallKey> path;  ///< Keyframed offsets, linear in between.

  /// Displacement of the wall from `point` at time t, m.
  Vec3 offset(Real t) const;
  /// Velocity of the wall at time t, m/s.
  Vec3 velocity_at(Real t) const;
};

/// Displacement at time t of a wall that moves with constant `velocity` or along `path`
/// (keyframed offsets, linear in between, held after the last), m.
Vec3 path_offset(const Vec3& velocity, const std::vector<WallKey>& path, Real t);
/// Velocity at time t of a wall that moves with constant `velocity` or along `path`, m/s.
Vec3 path_velocity(const Vec3& velocity, const std::vector<WallKey>& path, Real t);

/// The planes of the scene's plane and box walls (a box gives six inward planes); colliders
/// are built by build_colliders (engine/step/colliders.h).
std::vector<WallPlane> build_wall_planes(const std::vector<WallDesc>& walls);

/// Applies each plane's condition, at time `time`, to the active nodes inside it. A moving
/// wall's condition acts on the velocity relative to the wall. Returns the work (J) the
/// moving walls did on the grid: sum_i m_i (v_i' - v_i) . v_wall.
Real apply_walls(const std::vector<WallPlane>& planes, Real time, Grid& grid);

/// How deep the grid's boundary buffer acts on each side: per axis, nodes at or below `low`
/// and at or above `high` have their outward velocity stopped.
struct BufferLayers {
  Vec3i low;   ///< Last node index of the low side's buffer (none below 0).
  Vec3i high;  ///< First node index of the high side's buffer (none past the last node).
};

/// The `buffer` cells of `grid` on every side.
BufferLayers buffer_layers(const Grid& grid);

/// True where plane wall `w` lies across `axis` with its solid side holding the grid's
/// buffer layer on `side` (0: low, 1: high) at time `time`: it already acts on those nodes.
bool covers_buffer_side(const WallPlane& w, int axis, int side, Real time, const Grid& grid);

/// The buffer for contact at the particles at time `time`: on a side that a plane wall of
/// `planes` covers (across the axis, its solid side holding the buffer's innermost layer), only
/// the nodes more than two cells behind the wall, which no stencil of a particle on the free
/// side reaches; so the wall's contact, not the buffer, stops a body moving toward it.
BufferLayers buffer_layers_behind_walls(const std::vector<WallPlane>& planes, Real time,
                                        const Grid& grid);

/// Keeps velocities of nodes in the grid's boundary buffer from pointing outward.
void apply_domain_boundary(Grid& grid);
/// The same, for the buffer's `layers`.
void apply_domain_boundary(const BufferLayers& layers, Grid& grid);

/// Velocity of a node after a wall condition: v with the normal part handled per `b`
/// and Coulomb friction mu |v_n| taken off the tangential part.
Vec3 wall_velocity(const Vec3& v, const Vec3& n, Boundary b, Real friction);

/// Sets the velocity of every active node with mass to `f(x, v, m)` (x its position, v its
/// velocity, m its mass), which returns the work the condition did on the node, or 0, in the
/// blocks whose box [lo, hi] of node positions passes `near(lo, hi)` (f must leave the nodes of
/// the others alone: it is not called there). Returns the total work, summed per block and then
/// in block order: the same for any thread count.
template <class Near, class Fn>
Real constrain_nodes(Grid& g, Near&& near, Fn&& f) {
  constexpr int E = Grid::kBlockEdge - 1;
  std::vector<Real> work(g.active_blocks(), 0);
  const auto visit = [&](const Vec3i& o) {
    return near(g.position(o.x(), o.y(), o.z()), g.position(o.x() + E, o.y() + E, o.z() + E));
  };
  for_each_active_node(g, visit, [&](int i, int j, int k, std::size_t idx) {
    if (g.mass[idx] <= 0) return;
    work[idx / Grid::kBlockNodes] += f(g.position(i, j, k), g.velocity[idx], g.mass[idx]);
  });
  Real total = 0;
  for (Real w : work) total += w;
  return total;
}

}  // namespace mpm
