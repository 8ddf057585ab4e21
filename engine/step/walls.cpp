#include "engine/step/walls.h"

#include <algorithm>

namespace mpm {

std::vector<WallPlane> build_wall_planes(const std::vector<WallDesc>& walls) {
  std::vector<WallPlane> planes;
  for (const WallDesc& w : walls) {
    if (w.shape == WallDesc::Shape::plane) {
      planes.push_back({w.point, w.normal, w.boundary, w.friction, w.velocity, w.path});
      continue;
    }
    if (w.shape != WallDesc::Shape::box) continue;  // a collider (engine/step/colliders.h)
    for (int a = 0; a < 3; ++a) {
      const Vec3 n = Vec3::Unit(a);
      planes.push_back({w.min, n, w.boundary, w.friction, w.velocity, w.path});
      planes.push_back({w.max, -n, w.boundary, w.friction, w.velocity, w.path});
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

Vec3 path_offset(const Vec3& velocity, const std::vector<WallKey>& path, Real t) {
  if (path.empty()) return t * velocity;
  if (t <= path.front().t) return path.front().offset;
  for (std::size_t k = 1; k < path.size(); ++k)
    if (t <= path[k].t) {
      const Real s = (t - path[k - 1].t) / (path[k].t - path[k - 1].t);
      return (1 - s) * path[k - 1].offset + s * path[k].offset;
    }
  return path.back().offset;
}

Vec3 path_velocity(const Vec3& velocity, const std::vector<WallKey>& path, Real t) {
  if (path.empty()) return velocity;
  for (std::size_t k = 1; k < path.size(); ++k)
    if (t > path[k - 1].t && t <= path[k].t)
      return (path[k].offset - path[k - 1].offset) / (path[k].t - path[k - 1].t);
  return Vec3::Zero();
}

Vec3 WallPlane::offset(Real t) const {
  return path_offset(velocity, path, t);
}

Vec3 WallPlane::velocity_at(Real t) const {
  return path_velocity(velocity, path, t);
}

Real apply_walls(const std::vector<WallPlane>& planes, Real time, Grid& g) {
  struct Placed {
    Vec3 point, velocity;
  };
  std::vector<Placed> placed;
  bool moving = false;
  for (const WallPlane& w : planes) {
    placed.push_back({w.point + w.offset(time), w.velocity_at(time)});
    moving = moving || placed.back().velocity.squaredNorm() > 0;
  }
  // A block is near a plane where its box reaches the plane's back side: the box's lowest
  // point along the normal, centre minus half extent along |n|, with a margin for round-off.
  const auto near = [&](const Vec3& lo, const Vec3& hi) {
    const Vec3 centre = Real(0.5) * (lo + hi), half = Real(0.5) * (hi - lo);
    for (std::size_t w = 0; w < planes.size(); ++w) {
      const Vec3& n = planes[w].normal;
      if ((centre - placed[w].point).dot(n) - half.dot(n.cwiseAbs()) <= 1e-6 * half.norm())
        return true;
    }
    return false;
  };
  return constrain_nodes(g, near, [&](const Vec3& x, Vec3& v, Real m) {
    Real node_work = 0;
    for (std::size_t w = 0; w < planes.size(); ++w) {
      const WallPlane& p = planes[w];
      const Vec3& vw = placed[w].velocity;
      if ((x - placed[w].point).dot(p.normal) > 0) continue;
      const Vec3 after = vw + wall_velocity(v - vw, p.normal, p.boundary, p.friction);
      // The wall's impulse on the node times the wall's velocity: zero for a wall at rest.
      if (moving) node_work += m * (after - v).dot(vw);
      v = after;
    }
    return node_work;
  });
}

BufferLayers buffer_layers(const Grid& g) {
  return {Vec3i::Constant(g.buffer), g.nodes - Vec3i::Constant(1 + g.buffer)};
}

bool covers_buffer_side(const WallPlane& w, int axis, int side, Real time, const Grid& g) {
  const Real inward = side == 0 ? w.normal[axis] : -w.normal[axis];
  if (inward < 1 - Real(1e-9)) return false;
  const Real layer = side == 0 ? g.buffer : g.nodes[axis] - 1 - g.buffer;
  const Real at = ((w.point + w.offset(time))[axis] - g.origin[axis]) * g.inv_h[axis];
  const Real slack = 1e-9;  // a wall written at the layer's coordinate
  return side == 0 ? at >= layer - slack : at <= layer + slack;
}

BufferLayers buffer_layers_behind_walls(const std::vector<WallPlane>& planes, Real time,
                                        const Grid& g) {
  BufferLayers layers = buffer_layers(g);
  for (const WallPlane& w : planes)
    for (int a = 0; a < 3; ++a) {
      // The wall's node coordinate along its axis.
      const Real at = ((w.point + w.offset(time))[a] - g.origin[a]) * g.inv_h[a];
      if (covers_buffer_side(w, a, 0, time, g))
        layers.low[a] = std::min(layers.low[a], static_cast<int>(std::floor(at)) - 2);
      if (covers_buffer_side(w, a, 1, time, g))
        layers.high[a] = std::max(layers.high[a], static_cast<int>(std::ceil(at)) + 2);
    }
  return layers;
}

void apply_domain_boundary(Grid& g) {
  apply_domain_boundary(buffer_layers(g), g);
}

void apply_domain_boundary(const BufferLayers& layers, Grid& g) {
  // Only blocks that reach the buffer layers have nodes to change.
  const auto near = [&](const Vec3i& o) {
    return (o.array() <= layers.low.array()).any() ||
           (o.array() + Grid::kBlockEdge - 1 >= layers.high.array()).any();
  };
  for_each_active_node(g, near, [&](int i, int j, int k, std::size_t idx) {
    const Vec3i n(i, j, k);
    Vec3& v = g.velocity[idx];
    for (int a = 0; a < 3; ++a) {
      if (n[a] <= layers.low[a] && v[a] < 0) v[a] = 0;
      if (n[a] >= layers.high[a] && v[a] > 0) v[a] = 0;
    }
  });
}

}  // namespace mpm
