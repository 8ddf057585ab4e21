#include "engine/step/validate.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <unordered_map>

namespace mpm {

double physical_memory_bytes() {
  return static_cast<double>(sysconf(_SC_PHYS_PAGES)) * static_cast<double>(sysconf(_SC_PAGE_SIZE));
}

namespace {

std::string fmt(const char* f, double a, double b = 0, double c = 0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, a, b, c);
  return buf;
}

/// Pairs of objects with particles in a common grid cell.
std::vector<std::pair<std::size_t, std::size_t>> overlapping_objects(const Simulation& sim) {
  const Grid& g = sim.grid();
  const Particles& p = sim.particles();
  std::unordered_map<std::size_t, std::uint32_t> owner;
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  std::vector<char> seen(sim.objects().size() * sim.objects().size(), 0);
  for (std::size_t q = 0; q < p.size(); ++q) {
    const Vec3 c = (p.x[q] - g.origin).cwiseProduct(g.inv_h);
    const std::size_t key =
        (static_cast<std::size_t>(c.x()) * g.nodes.y() + std::size_t(c.y())) * g.nodes.z() +
        std::size_t(c.z());
    auto [it, added] = owner.emplace(key, p.object[q]);
    if (added || it->second == p.object[q]) continue;
    const std::size_t a = std::min(it->second, p.object[q]), b = std::max(it->second, p.object[q]);
    char& flag = seen[a * sim.objects().size() + b];
    if (!flag) pairs.emplace_back(a, b), flag = 1;
  }
  return pairs;
}

/// Per wall and object, the particles that start on the wall's solid side: behind a plane, or
/// outside a box (a box holds the bodies in).
std::vector<std::string> objects_in_walls(const Simulation& sim) {
  std::vector<std::string> w;
  const Particles& p = sim.particles();
  const std::vector<WallDesc>& walls = sim.scene().walls;
  for (std::size_t k = 0; k < walls.size(); ++k) {
    const std::vector<WallPlane> planes = build_wall_planes({walls[k]});
    std::vector<std::size_t> inside_of(sim.objects().size(), 0);
    for (std::size_t q = 0; q < p.size(); ++q)
      for (const WallPlane& pl : planes)
        if ((p.x[q] - pl.point - pl.offset(0)).dot(pl.normal) < 0) {
          ++inside_of[p.object[q]];
          break;
        }
    for (std::size_t o = 0; o < sim.objects().size(); ++o) {
      const ObjectInfo& info = sim.objects()[o];
      const std::size_t inside = inside_of[o];
      if (inside == 0) continue;
      const WallDesc& d = walls[k];
      const std::string where =
          d.shape == WallDesc::Shape::plane
              ? fmt("behind the plane through [%g, %g, %g]", d.point.x(), d.point.y(), d.point.z()) +
                    fmt(" with normal [%g, %g, %g]", d.normal.x(), d.normal.y(), d.normal.z())
              : fmt("outside the box from [%g, %g, %g]", d.min.x(), d.min.y(), d.min.z()) +
                    fmt(" to [%g, %g, %g]", d.max.x(), d.max.y(), d.max.z());
      w.push_back("object '" + info.name + "' starts inside walls[" + std::to_string(k) + "]: " +
                  std::to_string(inside) + " of " + std::to_string(info.count) +
                  " particles lie " + where + "; the wall will push them out at once");
    }
  }
  return w;
}

/// Per collider and object, the particles that start inside the collider (phi < 0).
std::vector<std::string> objects_in_colliders(const Simulation& sim) {
  std::vector<std::string> w;
  const Particles& p = sim.particles();
  const std::vector<WallDesc>& walls = sim.scene().walls;
  std::size_t c = 0;
  for (std::size_t k = 0; k < walls.size(); ++k) {
    if (walls[k].shape == WallDesc::Shape::plane || walls[k].shape == WallDesc::Shape::box)
      continue;
    const Collider& col = sim.colliders()[c++];
    const ColliderPose pose = col.pose(0);
    std::vector<std::size_t> inside_of(sim.objects().size(), 0);
    for (std::size_t q = 0; q < p.size(); ++q)
      if (pose.bounds.contains(p.x[q]) && col.phi(pose.to_rest(p.x[q])) < 0)
        ++inside_of[p.object[q]];
    for (std::size_t o = 0; o < sim.objects().size(); ++o)
      if (inside_of[o] > 0)
        w.push_back("object '" + sim.objects()[o].name + "' overlaps the collider walls[" +
                    std::to_string(k) + "] at the start: " + std::to_string(inside_of[o]) + " of " +
                    std::to_string(sim.objects()[o].count) +
                    " particles lie inside it; the collider will push them out at once");
  }
  return w;
}

/// Per object and grid side, the particles whose kernel stencil reaches the nodes of the
/// grid's boundary buffer where no plane or box wall covers them: apply_domain_boundary then
/// stops the body's outward node velocities there like a hidden wall (docs/validation.md).
std::vector<std::string> objects_near_buffer(const Simulation& sim) {
  std::vector<std::string> w;
  const Grid& g = sim.grid();
  const Particles& p = sim.particles();
  const SceneDesc& scene = sim.scene();
  const Real reach = 0.5 * kernel_nodes(scene.simulation.kernel);
  const std::vector<WallPlane> planes = build_wall_planes(scene.walls);
  const char* axis_name = "xyz";
  for (int a = 0; a < 3; ++a)
    for (int side = 0; side < 2; ++side) {
      // The buffer's innermost node layer on this side, in grid units and in metres.
      const Real layer = side == 0 ? g.buffer : g.nodes[a] - 1 - g.buffer;
      const Real layer_x = g.origin[a] + layer * g.h[a];
      const bool covered = std::any_of(planes.begin(), planes.end(), [&](const WallPlane& pl) {
        return covers_buffer_side(pl, a, side, 0, g);
      });
      if (covered) continue;
      std::vector<std::size_t> near(sim.objects().size(), 0);
      for (std::size_t q = 0; q < p.size(); ++q) {
        const Real c = (p.x[q][a] - g.origin[a]) * g.inv_h[a];
        if (side == 0 ? c - layer < reach : layer - c < reach) ++near[p.object[q]];
      }
      for (std::size_t o = 0; o < sim.objects().size(); ++o)
        if (near[o] > 0)
          w.push_back("object '" + sim.objects()[o].name + "': " + std::to_string(near[o]) +
                      " particles lie within " + fmt("%g", reach) +
                      " cells of the grid's boundary buffer at " + axis_name[a] + " = " +
                      fmt("%g", layer_x) + " m, with no wall there: the buffer will stop " +
                      "their outward motion like a hidden wall; enlarge the grid");
    }
  return w;
}

}  // namespace

std::vector<std::string> scene_warnings(Simulation& sim) {
  std::vector<std::string> w;
  const SceneDesc& scene = sim.scene();
  for (const auto& [a, b] : overlapping_objects(sim))
    w.push_back("objects '" + sim.objects()[a].name + "' and '" + sim.objects()[b].name +
                "' overlap at the start (they share grid cells)");
  for (std::string& line : objects_in_walls(sim)) w.push_back(std::move(line));
  for (std::string& line : objects_in_colliders(sim)) w.push_back(std::move(line));
  for (std::string& line : objects_near_buffer(sim)) w.push_back(std::move(line));
  const Real bound = sim.cfl_bound(1.0);
  if (!scene.simulation.cfl && scene.simulation.dt && *scene.simulation.dt > bound)
    w.push_back(fmt("simulation.dt = %g s is above the CFL bound h / (c + |v|max) = %.3g s at "
                    "the start; the run is likely to become unstable: lower dt or set cfl",
                    *scene.simulation.dt, bound));
  for (const ObjectDesc& o : scene.objects)
    if (o.particles_per_cell < 8)
      w.push_back("object '" + o.name + "': particles_per_cell " +
                  std::to_string(o.particles_per_cell) +
                  " is fewer than 2 per cell along each axis; expect gaps and cell-crossing noise");
  const double bytes = static_cast<double>(sim.particles().size()) * 500;
  if (sim.particles().size() > 20'000'000 || bytes > 0.5 * physical_memory_bytes())
    w.push_back(fmt("%.0f particles need about %.1f GB of memory", sim.particles().size(),
                    bytes / 1e9));
  return w;
}

std::string scene_summary(Simulation& sim) {
  const SceneDesc& s = sim.scene();
  std::string out;
  for (const ObjectInfo& o : sim.objects())
    out += "object " + o.name + ": " + o.material + ", " +
           std::to_string(o.count) + " particles, " + fmt("%g kg, %g kg/m^3\n", o.mass, o.density);
  const Vec3 h = s.grid.spacing();
  out += "grid: " + std::to_string(s.grid.dims.x()) + " x " + std::to_string(s.grid.dims.y()) +
         " x " + std::to_string(s.grid.dims.z()) + " cells, " +
         fmt("h = %g x %g x %g m, ", h.x(), h.y(), h.z()) + "buffer " +
         std::to_string(s.grid.buffer) + " cells\n";
  if (s.simulation.cfl)
    out += fmt("time step: adaptive, cfl %g, %.3g s at the start", *s.simulation.cfl,
               sim.cfl_bound(*s.simulation.cfl)) +
           (s.simulation.dt ? fmt(", capped at %g s\n", *s.simulation.dt) : std::string("\n"));
  else
    out += fmt("time step: fixed %g s (CFL bound h / (c + |v|max) at the start: %.3g s)\n",
               *s.simulation.dt, sim.cfl_bound(1.0));
  out += fmt("frames: %g of %g s\n", s.simulation.frames, s.simulation.frame_dt);
  out += "stages:";
  for (const Stage& st : sim.stages()) out += " " + st.name;
  out += "\n";
  return out;
}

}  // namespace mpm
