#include "engine/walls.h"

#include <algorithm>

namespace mpm {

std::vector<WallPlane> build_wall_planes(const std::vector<WallDesc>& walls) {
  std::vector<WallPlane> planes;
  for (const WallDesc& w : walls) {
    if (w.shape == WallDesc::Shape::plane) {
      planes.push_back({w.point, w.normal, w.boundary, w.friction});
      continue;
    }
    for (int a = 0; a < 3; ++a) {
      const Vec3 n = Vec3::Unit(a);
      planes.push_back({w.min, n, w.boundary, w.friction});
      planes.push_back({w.max, -n, w.boundary, w.friction});
    }
  }
  return planes;
}

Vec3 wall_velocity(const Vec3& v, const Vec3& n, Boundary b, Real friction) {
  if (b == Boundary::sticky) return Vec3::Zero();
  const Real vn = v.dot(n);
  if (b == Boundary::separate && vn >= 0) return v;  // moving away: free to leave
  Vec3 vt = v - vn * n;
  if (friction > 0 && vn < 0) {
    // Coulomb: the tangential speed drops by mu times the normal speed removed.
    const Real t = vt.norm();
    const Real drop = friction * -vn;
    vt = t <= drop ? Vec3::Zero() : Vec3(vt * (1 - drop / t));
  }
  return vt;
}

void apply_walls(const std::vector<WallPlane>& planes, Grid& g) {
  for_each_active_node(g, [&](int i, int j, int k, std::size_t idx) {
    if (g.mass[idx] <= 0) return;
    const Vec3 x = g.position(i, j, k);
    for (const WallPlane& w : planes)
      if ((x - w.point).dot(w.normal) <= 0)
        g.velocity[idx] = wall_velocity(g.velocity[idx], w.normal, w.boundary, w.friction);
  });
}

void apply_domain_boundary(Grid& g) {
  const Vec3i last = g.nodes - Vec3i::Ones();
  for_each_active_node(g, [&](int i, int j, int k, std::size_t idx) {
    const Vec3i n(i, j, k);
    Vec3& v = g.velocity[idx];
    for (int a = 0; a < 3; ++a) {
      if (n[a] <= g.buffer && v[a] < 0) v[a] = 0;
      if (n[a] >= last[a] - g.buffer && v[a] > 0) v[a] = 0;
    }
  });
}

}  // namespace mpm
