#include "engine/step/colliders.h"

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/LevelSetRebuild.h>
#include <openvdb/tools/MeshToVolume.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "engine/core/error.h"
#include "engine/scene/mesh.h"
#include "engine/step/walls.h"

namespace mpm {

class LevelSetGrid {
 public:
  /// Wraps a float level set; bounds() is the world box of its active voxels.
  explicit LevelSetGrid(openvdb::FloatGrid::ConstPtr grid) : grid_(std::move(grid)) {
    const openvdb::CoordBBox active = grid_->evalActiveVoxelBoundingBox();
    const openvdb::BBoxd box = grid_->transform().indexToWorld(active);
    bounds_ = {Vec3(box.min().x(), box.min().y(), box.min().z()),
               Vec3(box.max().x(), box.max().y(), box.max().z())};
    step_ = 0.5 * grid_->voxelSize()[0];
  }

  /// The accessor sample() and phi() take: it keeps the tree nodes of the last lookup, so that
  /// a point near the last one is found without a walk from the root.
  using Accessor = openvdb::FloatGrid::ConstUnsafeAccessor;

  /// A new accessor of the level set (one per thread: it is not thread-safe).
  Accessor accessor() const { return grid_->getConstUnsafeAccessor(); }

  /// Trilinear phi (OpenVDB BoxSampler) and its gradient by central differences half a voxel
  /// apart, at world point x.
  SdfSample sample(const Vec3& x, Accessor& acc) const {
    SdfSample s;
    s.phi = phi(x, acc);
    Vec3 grad;
    for (int a = 0; a < 3; ++a) {
      const Vec3 e = step_ * Vec3::Unit(a);
      grad[a] = (phi(x + e, acc) - phi(x - e, acc)) / (2 * step_);
    }
    const Real norm = grad.norm();
    s.normal = norm > 1e-6 ? Vec3(grad / norm) : Vec3::Zero();
    return s;
  }

  /// Trilinear phi alone at world point x.
  Real phi(const Vec3& x, Accessor& acc) const {
    const openvdb::Vec3d ijk = grid_->transform().worldToIndex(openvdb::Vec3d(x.x(), x.y(), x.z()));
    return static_cast<Real>(openvdb::tools::BoxSampler::sample(acc, ijk));
  }

  /// sample() with an accessor of its own (thread-safe).
  SdfSample sample(const Vec3& x) const {
    Accessor acc = accessor();
    return sample(x, acc);
  }

  /// phi() with an accessor of its own (thread-safe).
  Real phi(const Vec3& x) const {
    Accessor acc = accessor();
    return phi(x, acc);
  }

  /// World box of the active voxels, m.
  const Eigen::AlignedBox<Real, 3>& bounds() const { return bounds_; }

 private:
  openvdb::FloatGrid::ConstPtr grid_;
  Eigen::AlignedBox<Real, 3> bounds_;
  Real step_ = 0;
};

namespace {

std::string key_of(std::size_t k, const char* shape, const char* key) {
  return "walls[" + std::to_string(k) + "]." + shape + "." + key;
}

/// The signed distance of the closed, placed `mesh` on voxels of `voxel` m, in a narrow band
/// of `exterior` voxels outside and `interior` inside (OpenVDB meshToVolume, Museth 2013).
openvdb::FloatGrid::Ptr mesh_signed_distance(const TriangleMesh& mesh, Real voxel, float exterior,
                                             float interior) {
  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> triangles;
  for (const Vec3& v : mesh.vertices) points.emplace_back(v.x(), v.y(), v.z());
  for (const auto& t : mesh.triangles) triangles.emplace_back(t[0], t[1], t[2]);
  const auto xform = openvdb::math::Transform::createLinearTransform(voxel);
  return openvdb::tools::meshToSignedDistanceField<openvdb::FloatGrid>(*xform, points, triangles,
                                                                       {}, exterior, interior);
}

/// A closed mesh, transformed like an object's, as a signed distance with `voxel` m voxels:
/// a narrow band of 3 voxels outside and the whole interior (so that a node deep inside still
/// has a normal). OpenVDB meshToVolume (Museth 2013).
openvdb::FloatGrid::ConstPtr mesh_level_set(const WallDesc& w, std::size_t k, Real voxel) {
  TriangleMesh mesh;
  try {
    mesh = load_mesh(w.file);
  } catch (const MeshError& e) {
    throw SceneError(w.file_loc, key_of(k, "mesh", "file"), e.what());
  }
  if (const std::string why = closedness_problem(mesh); !why.empty())
    throw SceneError(w.file_loc, key_of(k, "mesh", "file"),
                     "'" + w.file.string() + "': " + why + "; a collider mesh must be closed");
  transform_mesh(mesh, w.scale, w.rotation_deg, w.offset);
  openvdb::FloatGrid::Ptr grid =
      mesh_signed_distance(mesh, voxel, 3.0f, std::numeric_limits<float>::max());
  if (grid->activeVoxelCount() == 0)
    throw SceneError(w.file_loc, key_of(k, "mesh", "file"),
                     "'" + w.file.string() + "' encloses no volume at the voxel size " +
                         std::to_string(voxel) + " m (half the grid's cell)");
  return grid;
}

/// The level set `w.grid_name` of the VDB file `w.file`.
openvdb::FloatGrid::ConstPtr read_vdb(const WallDesc& w, std::size_t k) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(w.file, ec))
    throw SceneError(w.file_loc, key_of(k, "vdb", "file"),
                     "VDB file '" + w.file.string() + "' does not exist");
  openvdb::GridBase::Ptr base;
  std::string names;
  try {
    openvdb::io::File file(w.file.string());
    file.open();
    for (auto it = file.beginName(); it != file.endName(); ++it)
      names += (names.empty() ? "'" : ", '") + it.gridName() + "'";
    if (file.hasGrid(w.grid_name)) base = file.readGrid(w.grid_name);
    file.close();
  } catch (const openvdb::Exception& e) {
    throw SceneError(w.file_loc, key_of(k, "vdb", "file"),
                     "cannot read VDB file '" + w.file.string() + "': " + e.what());
  }
  if (!base)
    throw SceneError(w.grid_loc, key_of(k, "vdb", "grid"),
                     "VDB file '" + w.file.string() + "' has no grid '" + w.grid_name +
                         "'; its grids: " + (names.empty() ? "none" : names));
  openvdb::FloatGrid::Ptr grid = openvdb::gridPtrCast<openvdb::FloatGrid>(base);
  if (!grid || grid->getGridClass() != openvdb::GRID_LEVEL_SET)
    throw SceneError(w.grid_loc, key_of(k, "vdb", "grid"),
                     "grid '" + w.grid_name + "' is a " + base->valueType() + " " +
                         openvdb::GridBase::gridClassToString(base->getGridClass()) +
                         " grid; a collider needs a float level set (signed distance)");
  if (!grid->transform().isLinear() || grid->activeVoxelCount() == 0)
    throw SceneError(w.grid_loc, key_of(k, "vdb", "grid"),
                     "grid '" + w.grid_name + "' is empty or has a non-linear transform");
  // A narrow band (3 voxels, as Houdini writes) has a flat -background inside, with no
  // normal: rebuild it with the whole interior, as meshes get (OpenVDB levelSetRebuild).
  return openvdb::tools::levelSetRebuild(*grid, 0.0f, 3.0f, std::numeric_limits<float>::max());
}

}  // namespace

std::vector<Real> depth_below_surface(const TriangleMesh& mesh, std::span<const Vec3> points,
                                      Real voxel, Real cap) {
  openvdb::initialize();  // registers the grid types; safe to call again
  const LevelSetGrid sdf(
      mesh_signed_distance(mesh, voxel, 1.0f, static_cast<float>(cap / voxel) + 2));
  std::vector<Real> depth(points.size());
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(points.size());
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t q = 0; q < n; ++q) {
    const Real d = -sdf.phi(points[q]);
    depth[q] = d <= cap ? std::max(d, Real(0)) : Real(-1);
  }
  return depth;
}

std::vector<Collider> build_colliders(const std::vector<WallDesc>& walls, Real voxel) {
  std::vector<Collider> out;
  for (std::size_t k = 0; k < walls.size(); ++k) {
    const WallDesc& w = walls[k];
    if (w.shape == WallDesc::Shape::plane || w.shape == WallDesc::Shape::box) continue;
    Collider c;
    c.boundary = w.boundary;
    c.friction = w.friction;
    c.velocity = w.velocity;
    c.path = w.path;
    c.angular_velocity = w.angular_velocity;
    if (w.shape == WallDesc::Shape::sphere) {
      c.radius = w.radius;
      c.center = w.center;
      c.bounds = {w.center - Vec3::Constant(w.radius), w.center + Vec3::Constant(w.radius)};
    } else {
      openvdb::initialize();  // registers the grid types; safe to call again
      auto ls = std::make_shared<const LevelSetGrid>(
          w.shape == WallDesc::Shape::mesh ? mesh_level_set(w, k, voxel) : read_vdb(w, k));
      c.bounds = ls->bounds();
      c.center = w.shape == WallDesc::Shape::mesh ? w.offset : c.bounds.center();
      c.level_set = std::move(ls);
    }
    out.push_back(std::move(c));
  }
  return out;
}

SdfSample Collider::sample(const Vec3& x0) const {
  if (level_set) return level_set->sample(x0);
  const Vec3 d = x0 - center;
  const Real r = d.norm();
  return {r - radius, r > 0 ? Vec3(d / r) : Vec3::UnitY()};
}

Real Collider::phi(const Vec3& x0) const {
  return level_set ? level_set->phi(x0) : (x0 - center).norm() - radius;
}

/// The accessor a probe keeps (none for a sphere).
struct ColliderProbe::Cache {
  LevelSetGrid::Accessor acc;  ///< The level set's accessor.
};

ColliderProbe::ColliderProbe(const Collider& collider) : c_(collider) {
  if (c_.level_set) cache_ = std::make_unique<Cache>(Cache{c_.level_set->accessor()});
}

ColliderProbe::~ColliderProbe() = default;

SdfSample ColliderProbe::sample(const Vec3& x0) {
  return cache_ ? c_.level_set->sample(x0, cache_->acc) : c_.sample(x0);
}

Real ColliderProbe::phi(const Vec3& x0) {
  return cache_ ? c_.level_set->phi(x0, cache_->acc) : c_.phi(x0);
}

ColliderPose Collider::pose(Real t) const {
  ColliderPose p;
  const Real w = angular_velocity.norm();
  if (w > 0) p.rotation = Eigen::AngleAxis<Real>(w * t, angular_velocity / w).toRotationMatrix();
  p.rest_center = center;
  p.center = center + path_offset(velocity, path, t);
  p.velocity = path_velocity(velocity, path, t);
  p.angular_velocity = angular_velocity;
  if (w == 0) {
    p.bounds = bounds.translated(p.center - center);
    return p;
  }
  // The box of the rotated box's corners.
  for (int c = 0; c < 8; ++c) {
    const Vec3 corner = bounds.corner(static_cast<Eigen::AlignedBox<Real, 3>::CornerType>(c));
    p.bounds.extend(p.center + p.rotation * (corner - center));
  }
  return p;
}

Real apply_colliders(const std::vector<Collider>& colliders, Real time, Grid& g) {
  std::vector<ColliderPose> poses;
  bool moving = false;
  for (const Collider& c : colliders) {
    poses.push_back(c.pose(time));
    moving = moving || poses.back().velocity.squaredNorm() > 0 ||
             poses.back().angular_velocity.squaredNorm() > 0;
  }
  // A block is near a collider where its box meets the collider's bounds.
  const auto near = [&](const Vec3& lo, const Vec3& hi) {
    const Eigen::AlignedBox<Real, 3> box(lo, hi);
    for (const ColliderPose& p : poses)
      if (p.bounds.intersects(box)) return true;
    return false;
  };
  return constrain_nodes(g, near, [&](const Vec3& x, Vec3& v, Real m) {
    Real node_work = 0;
    for (std::size_t c = 0; c < colliders.size(); ++c) {
      const ColliderPose& p = poses[c];
      if (!p.bounds.contains(x)) continue;  // only the nodes near a collider pay for it
      const Vec3 x0 = p.to_rest(x);
      if (colliders[c].phi(x0) > 0) continue;  // the normal only where it is needed
      const SdfSample s = colliders[c].sample(x0);
      // The wall condition in the collider's frame (Stomakhin et al. 2013, sec. 8): on the
      // velocity relative to the collider's velocity at the node, v_c = v + w x (x - c). A
      // node where phi is flat has no normal (it cannot happen with the filled interiors
      // build_colliders makes, but a degenerate grid may): it moves with the collider.
      const Vec3 vc = p.velocity_at(x);
      const Vec3 after =
          s.normal.squaredNorm() > 0
              ? Vec3(vc + wall_velocity(v - vc, p.rotation * s.normal, colliders[c].boundary,
                                        colliders[c].friction))
              : vc;
      // The collider's impulse on the node times its velocity there: zero for one at rest.
      if (moving) node_work += m * (after - v).dot(vc);
      v = after;
    }
    return node_work;
  });
}

}  // namespace mpm
