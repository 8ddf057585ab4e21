#pragma once
/// \file Solid colliders (mesh, sphere, vdb walls): rigid bodies given by a signed distance,
/// acting on grid velocities like the plane and box walls of walls.h.

#include <memory>
#include <span>
#include <vector>

#include "engine/scene/mesh.h"
#include "engine/scene/scene_desc.h"
#include "engine/step/grid.h"

namespace mpm {

/// An OpenVDB float level set (defined in colliders.cpp, so that OpenVDB stays out of headers).
class LevelSetGrid;

/// A collider's signed distance at one point, in its frame at t = 0.
struct SdfSample {
  Real phi = 0;          ///< Signed distance, m: negative inside the solid.
  Vec3 normal{0, 0, 0};  ///< Unit outward normal (grad phi), or zero where phi is flat.
};

/// Where a collider is at one time: x = center + rotation (x0 - rest center) for x0 in its
/// frame at t = 0, moving with velocity + angular_velocity x (x - center).
struct ColliderPose {
  Mat3 rotation = Mat3::Identity();   ///< Rotation since t = 0.
  Vec3 center{0, 0, 0};               ///< Spin centre now, m.
  Vec3 rest_center{0, 0, 0};          ///< Spin centre at t = 0, m.
  Vec3 velocity{0, 0, 0};             ///< Velocity of the spin centre, m/s.
  Vec3 angular_velocity{0, 0, 0};     ///< rad/s.
  Eigen::AlignedBox<Real, 3> bounds;  ///< World box that holds every point with phi <= 0 now.

  /// The point of the collider's t = 0 frame that is at world point x now.
  Vec3 to_rest(const Vec3& x) const { return rest_center + rotation.transpose() * (x - center); }
  /// The collider's velocity at world point x, m/s: v + w x (x - c).
  Vec3 velocity_at(const Vec3& x) const { return velocity + angular_velocity.cross(x - center); }
};

/// A solid obstacle that moves rigidly: a sphere, or a level set built from a closed mesh or
/// read from a VDB file, with a wall condition (walls.h) on the grid nodes inside it.
struct Collider {
  std::shared_ptr<const LevelSetGrid> level_set;  ///< Mesh or vdb; null for a sphere.
  Real radius = 0;                                ///< Sphere radius, m.
  /// Spin centre at t = 0 (sphere centre, mesh offset, vdb bounding-box centre), m.
  Vec3 center{0, 0, 0};
  Eigen::AlignedBox<Real, 3> bounds;     ///< Box holding every point with phi <= 0 at t = 0, m.
  Boundary boundary = Boundary::sticky;  ///< Condition on nodes inside.
  Real friction = 0;                     ///< Coulomb coefficient.
  Vec3 velocity{0, 0, 0};                ///< Constant velocity (when path is empty), m/s.
  std::vector<WallKey> path;             ///< Keyframed offsets of the centre, linear in between.
  Vec3 angular_velocity{0, 0, 0};        ///< Spin about the centre, rad/s.

  /// Signed distance and normal at x0, a point of the frame at t = 0.
  SdfSample sample(const Vec3& x0) const;
  /// Signed distance alone at x0 (a seventh of sample()'s work for a level set), m.
  Real phi(const Vec3& x0) const;
  /// Where the collider is at time t.
  ColliderPose pose(Real t) const;
  /// Signed distance at world point x at time t, m (negative inside).
  Real distance(const Vec3& x, Real t) const { return phi(pose(t).to_rest(x)); }
};

/// Samples one collider's signed distance point after point, keeping the level set's last tree
/// nodes between calls (an OpenVDB accessor), so that a point near the last one is found
/// without a walk from the tree's root: the same values as Collider::sample and phi. Not
/// thread-safe: one per thread.
class ColliderProbe {
 public:
  /// A probe of `collider`, which must outlive it.
  explicit ColliderProbe(const Collider& collider);
  ~ColliderProbe();
  ColliderProbe(const ColliderProbe&) = delete;
  ColliderProbe& operator=(const ColliderProbe&) = delete;
  /// Collider::sample at x0.
  SdfSample sample(const Vec3& x0);
  /// Collider::phi at x0, m.
  Real phi(const Vec3& x0);

 private:
  struct Cache;  // the accessor (colliders.cpp), so that OpenVDB stays out of headers
  const Collider& c_;
  std::unique_ptr<Cache> cache_;
};

/// Builds the colliders among `walls` (mesh, sphere and vdb walls; planes and boxes are
/// skipped). A mesh becomes a level set with voxels of `voxel` m (OpenVDB meshToVolume).
/// Throws SceneError at the wall's key for an unreadable, empty or open mesh, a missing VDB
/// file or grid (listing the grids found), or a grid that is not a float level set.
std::vector<Collider> build_colliders(const std::vector<WallDesc>& walls, Real voxel);

/// The depth of each of `points` below the surface of the closed `mesh`, m, where it is at
/// most `cap`, and -1 where it is deeper: the mesh's signed distance (OpenVDB meshToVolume,
/// voxels of `voxel` m, a band of `cap` inside), sampled trilinearly. Contact at the particles
/// gives each particle of an elastic body this radius (contact.h).
std::vector<Real> depth_below_surface(const TriangleMesh& mesh, std::span<const Vec3> points,
                                      Real voxel, Real cap);

/// Applies each collider's condition, at time `time`, to the active nodes with phi <= 0
/// (only nodes inside its bounding box are sampled), relative to the collider's velocity at
/// the node. Returns the work (J) the colliders did on the grid: sum_i m_i (v_i' - v_i) . v_c.
Real apply_colliders(const std::vector<Collider>& colliders, Real time, Grid& grid);

}  // namespace mpm
