#pragma once
/// \file Closed triangle meshes: loading, the closedness check, and a robust inside test.

#include <array>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/core/math.h"

namespace mpm {

/// An indexed triangle mesh with welded vertices.
struct TriangleMesh {
  std::vector<Vec3> vertices;                ///< Positions, m.
  std::vector<std::array<int, 3>> triangles; ///< Vertex indices per triangle.
};

/// A mesh that cannot be used (unreadable, empty or not closed).
class MeshError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Loads every triangle of a file assimp reads, welding vertices at identical positions.
TriangleMesh load_mesh(const std::filesystem::path& path);

/// Empty string if every edge is shared by exactly two triangles; otherwise why not.
std::string closedness_problem(const TriangleMesh& mesh);

/// Applies x' = offset + R (scale * x), with R = Rz Ry Rx from degrees about x, y, z.
void transform_mesh(TriangleMesh& mesh, const Vec3& scale, const Vec3& rotation_deg,
                    const Vec3& offset);

/// Rotation matrix Rz(c) Ry(b) Rx(a) for angles (a, b, c) in degrees.
Mat3 rotation_from_degrees(const Vec3& rotation_deg);

/// Inside/outside queries against a closed mesh by ray parity along +x.
///
/// Triangles are bucketed by their projection on the yz-plane. Points on shared edges and
/// vertices of the projection are resolved by a consistent tie-breaking rule with exactly
/// computed orientations, so a ray through an edge or vertex is counted once, not zero or
/// two times.
class InsideTester {
 public:
  /// Prepares the buckets for `mesh` (which must be closed).
  explicit InsideTester(const TriangleMesh& mesh);
  /// True if `p` is inside the closed surface.
  bool inside(const Vec3& p) const;
  /// Axis-aligned bounds of the mesh.
  const Eigen::AlignedBox<Real, 3>& bounds() const { return bounds_; }

 private:
  const TriangleMesh& mesh_;
  Eigen::AlignedBox<Real, 3> bounds_;
  int ny_ = 1, nz_ = 1;
  Real y0_ = 0, z0_ = 0, dy_ = 1, dz_ = 1;
  std::vector<int> bucket_start_;
  std::vector<int> bucket_tris_;
};

}  // namespace mpm
