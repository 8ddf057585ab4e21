#include "engine/scene/mesh.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <tuple>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

namespace mpm {

TriangleMesh load_mesh(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw MeshError("mesh file '" + path.string() + "' does not exist");
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(
      path.string(), aiProcess_Triangulate | aiProcess_PreTransformVertices |
                         aiProcess_FindDegenerates | aiProcess_DropNormals);
  if (!scene || !scene->mRootNode)
    throw MeshError("cannot read mesh '" + path.string() + "': " + importer.GetErrorString());

  TriangleMesh mesh;
  std::map<std::tuple<Real, Real, Real>, int> welded;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* am = scene->mMeshes[m];
    std::vector<int> index(am->mNumVertices);
    for (unsigned v = 0; v < am->mNumVertices; ++v) {
      const aiVector3D& a = am->mVertices[v];
      const auto key = std::make_tuple(Real(a.x), Real(a.y), Real(a.z));
      auto [it, added] = welded.emplace(key, static_cast<int>(mesh.vertices.size()));
      if (added) mesh.vertices.emplace_back(a.x, a.y, a.z);
      index[v] = it->second;
    }
    for (unsigned f = 0; f < am->mNumFaces; ++f) {
      const aiFace& face = am->mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines carry no volume
      std::array<int, 3> t{index[face.mIndices[0]], index[face.mIndices[1]],
                           index[face.mIndices[2]]};
      if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
      mesh.triangles.push_back(t);
    }
  }
  if (mesh.triangles.empty())
    throw MeshError("mesh '" + path.string() + "' has no triangles");
  return mesh;
}

std::string closedness_problem(const TriangleMesh& mesh) {
  std::map<std::pair<int, int>, int> uses;
  for (const auto& t : mesh.triangles)
    for (int e = 0; e < 3; ++e) {
      int a = t[e], b = t[(e + 1) % 3];
      if (a > b) std::swap(a, b);
      ++uses[{a, b}];
    }
  std::size_t open = 0, nonmanifold = 0;
  for (const auto& [edge, n] : uses) {
    if (n == 1) ++open;
    if (n > 2) ++nonmanifold;
  }
  if (open > 0)
    return "the mesh is not closed: " + std::to_string(open) +
           " edges belong to only one triangle";
  if (nonmanifold > 0)
    return "the mesh is not manifold: " + std::to_string(nonmanifold) +
           " edges belong to more than two triangles";
  return "";
}

Mat3 rotation_from_degrees(const Vec3& d) {
  const Vec3 r = d * (std::numbers::pi / 180.0);
  return (Eigen::AngleAxis<Real>(r.z(), Vec3::UnitZ()) *
          Eigen::AngleAxis<Real>(r.y(), Vec3::UnitY()) *
          Eigen::AngleAxis<Real>(r.x(), Vec3::UnitX()))
      .toRotationMatrix();
}

void transform_mesh(TriangleMesh& mesh, const Vec3& scale, const Vec3& rotation_deg,
                    const Vec3& offset) {
  const Mat3 R = rotation_from_degrees(rotation_deg);
  for (Vec3& v : mesh.vertices) v = offset + R * scale.cwiseProduct(v);
  // A mirroring scale turns the surface inside out; parity does not care, but keep it tidy.
  if (scale.prod() < 0)
    for (auto& t : mesh.triangles) std::swap(t[1], t[2]);
}

namespace {

/// Twice the signed area of (a, b, p) in the yz-plane, computed with the edge in a canonical
/// order so that the two triangles sharing an edge see exactly opposite values.
Real edge_function(const Vec3& a, const Vec3& b, Real py, Real pz) {
  const bool swap = std::tie(b.y(), b.z()) < std::tie(a.y(), a.z());
  const Vec3& u = swap ? b : a;
  const Vec3& v = swap ? a : b;
  const Real e = (v.y() - u.y()) * (pz - u.z()) - (v.z() - u.z()) * (py - u.y());
  return swap ? -e : e;
}

/// Tie-break for a point exactly on edge a->b: a fixed half-plane rule (like the top-left
/// fill rule of rasterisers) so exactly one of two triangles on opposite sides claims it.
bool owns_edge(const Vec3& a, const Vec3& b) {
  const Real dy = b.y() - a.y(), dz = b.z() - a.z();
  return dz > 0 || (dz == 0 && dy < 0);
}

}  // namespace

InsideTester::InsideTester(const TriangleMesh& mesh) : mesh_(mesh) {
  for (const Vec3& v : mesh.vertices) bounds_.extend(v);
  const int n = static_cast<int>(mesh.triangles.size());
  const int side = std::clamp(static_cast<int>(std::sqrt(n / 2.0)), 1, 256);
  ny_ = nz_ = side;
  y0_ = bounds_.min().y();
  z0_ = bounds_.min().z();
  dy_ = std::max(bounds_.sizes().y() / ny_, Real(1e-30));
  dz_ = std::max(bounds_.sizes().z() / nz_, Real(1e-30));
  auto cell_range = [&](const std::array<int, 3>& t, int& ya, int& yb, int& za, int& zb) {
    Real lo_y = 1e300, hi_y = -1e300, lo_z = 1e300, hi_z = -1e300;
    for (int k : t) {
      lo_y = std::min(lo_y, mesh.vertices[k].y()), hi_y = std::max(hi_y, mesh.vertices[k].y());
      lo_z = std::min(lo_z, mesh.vertices[k].z()), hi_z = std::max(hi_z, mesh.vertices[k].z());
    }
    ya = std::clamp(static_cast<int>(std::floor((lo_y - y0_) / dy_)), 0, ny_ - 1);
    yb = std::clamp(static_cast<int>(std::floor((hi_y - y0_) / dy_)), 0, ny_ - 1);
    za = std::clamp(static_cast<int>(std::floor((lo_z - z0_) / dz_)), 0, nz_ - 1);
    zb = std::clamp(static_cast<int>(std::floor((hi_z - z0_) / dz_)), 0, nz_ - 1);
  };
  std::vector<int> count(ny_ * nz_ + 1, 0);
  for (const auto& t : mesh.triangles) {
    int ya, yb, za, zb;
    cell_range(t, ya, yb, za, zb);
    for (int y = ya; y <= yb; ++y)
      for (int z = za; z <= zb; ++z) ++count[y * nz_ + z + 1];
  }
  for (std::size_t i = 1; i < count.size(); ++i) count[i] += count[i - 1];
  bucket_start_ = count;
  bucket_tris_.resize(count.back());
  for (int i = 0; i < n; ++i) {
    int ya, yb, za, zb;
    cell_range(mesh.triangles[i], ya, yb, za, zb);
    for (int y = ya; y <= yb; ++y)
      for (int z = za; z <= zb; ++z) bucket_tris_[count[y * nz_ + z]++] = i;
  }
}

bool InsideTester::inside(const Vec3& p) const {
  if (!bounds_.contains(p)) return false;
  const int cy = std::clamp(static_cast<int>(std::floor((p.y() - y0_) / dy_)), 0, ny_ - 1);
  const int cz = std::clamp(static_cast<int>(std::floor((p.z() - z0_) / dz_)), 0, nz_ - 1);
  const int b = cy * nz_ + cz;
  int crossings = 0;
  for (int k = bucket_start_[b]; k < bucket_start_[b + 1]; ++k) {
    const auto& t = mesh_.triangles[bucket_tris_[k]];
    const Vec3* v[3] = {&mesh_.vertices[t[0]], &mesh_.vertices[t[1]], &mesh_.vertices[t[2]]};
    Real e[3];
    for (int i = 0; i < 3; ++i) e[i] = edge_function(*v[i], *v[(i + 1) % 3], p.y(), p.z());
    const Real area = e[0] + e[1] + e[2];
    if (area == 0) continue;  // projects to a segment: the ray grazes it, neighbours decide
    const Real sgn = area > 0 ? 1 : -1;
    bool in = true;
    for (int i = 0; i < 3 && in; ++i) {
      const Real ei = sgn * e[i];
      if (ei < 0) in = false;
      else if (ei == 0) {
        // On the edge: claimed only by the triangle for which the edge runs "forward"
        // in its counter-clockwise order.
        const Vec3& a = sgn > 0 ? *v[i] : *v[(i + 1) % 3];
        const Vec3& c = sgn > 0 ? *v[(i + 1) % 3] : *v[i];
        in = owns_edge(a, c);
      }
    }
    if (!in) continue;
    // x of the triangle's plane at (p.y, p.z), from barycentric weights of the projection.
    const Real x = (e[1] * v[0]->x() + e[2] * v[1]->x() + e[0] * v[2]->x()) / area;
    if (x > p.x()) ++crossings;
  }
  return crossings % 2 == 1;
}

}  // namespace mpm
