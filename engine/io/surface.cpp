#include "engine/io/surface.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetFilter.h>
#include <openvdb/tools/LevelSetUtil.h>
#include <openvdb/tools/ParticlesToLevelSet.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <stdexcept>

#include "engine/core/atomic_file.h"
#include "engine/core/error.h"

namespace mpm {

namespace {

/// Calls openvdb::initialize() once (it registers the grid types the file reader needs).
void init_openvdb() {
  static const bool done = [] {
    openvdb::initialize();
    return true;
  }();
  (void)done;
}

/// One object's particles as ParticlesToLevelSet reads them: positions and a common radius.
/// The attribute is the particle's row in the frame, to look its velocity up afterwards.
struct ParticleList {
  using PosType = openvdb::Vec3R;
  std::vector<openvdb::Vec3R> position;  ///< World positions, m.
  std::vector<openvdb::Index32> row;     ///< Row of each particle in the frame.
  double radius = 0;                     ///< Sphere radius, m.

  std::size_t size() const { return position.size(); }
  void getPos(std::size_t n, openvdb::Vec3R& xyz) const { xyz = position[n]; }
  void getPosRad(std::size_t n, openvdb::Vec3R& xyz, openvdb::Real& r) const {
    xyz = position[n];
    r = radius;
  }
  void getAtt(std::size_t n, openvdb::Index32& att) const { att = row[n]; }
};

/// An object's level set and, if asked, the velocity of the particle nearest to each voxel.
struct ObjectLevelSet {
  openvdb::FloatGrid::Ptr sdf;       ///< Narrow-band signed distance, m (negative inside).
  openvdb::Vec3SGrid::Ptr velocity;  ///< On the rasterised band, m/s (or null).
};

/// Steps 1 to 3 of the pipeline in surface.h for object `object` of `frame`.
ObjectLevelSet build_level_set(const FrameData& frame, int object, double spacing,
                               const SurfaceDesc& desc, bool with_velocity) {
  init_openvdb();
  const double dx = desc.voxel * spacing;
  ParticleList list;
  list.radius = desc.radius * spacing;
  for (std::size_t i = 0; i < frame.size(); ++i)
    if (frame.object_id[i] == object) {
      const float* x = &frame.position[3 * i];
      list.position.emplace_back(x[0], x[1], x[2]);
      list.row.push_back(static_cast<openvdb::Index32>(i));
    }
  ObjectLevelSet out;
  out.sdf = openvdb::createLevelSet<openvdb::FloatGrid>(dx, openvdb::LEVEL_SET_HALF_WIDTH);
  if (list.size() == 0) return out;

  // 1. Spheres into a narrow band (with the nearest particle's row when velocities are asked).
  openvdb::FloatGrid::ValueConverter<openvdb::Index32>::Type::Ptr rows;
  if (with_velocity) {
    openvdb::tools::ParticlesToLevelSet<openvdb::FloatGrid, openvdb::Index32> raster(*out.sdf);
    raster.setRmax(1e9);
    raster.rasterizeSpheres(list);
    raster.finalize(true);
    rows = raster.attributeGrid();
  } else {
    openvdb::tools::ParticlesToLevelSet<openvdb::FloatGrid> raster(*out.sdf);
    raster.setRmax(1e9);
    raster.rasterizeSpheres(list);
    raster.finalize(true);
  }
  // 2. Mean-value flow (3^3 box filter) flattens the bumps of single particles; LevelSetFilter
  //    renormalises the band to a signed distance after every pass (its default WENO5
  //    tracker: the cheaper first-order one moved the surface in by 1% of the cube's side).
  openvdb::tools::LevelSetFilter<openvdb::FloatGrid> filter(*out.sdf);
  for (int k = 0; k < desc.smoothing; ++k) filter.mean(1);
  // 3. In from the spheres' surface to the body's boundary (a positive offset erodes).
  filter.offset(static_cast<float>((desc.radius - kSurfaceInset) * spacing));

  if (rows) {
    out.velocity = openvdb::Vec3SGrid::create(openvdb::Vec3s(0, 0, 0));
    out.velocity->setTransform(out.sdf->transform().copy());
    out.velocity->tree().topologyUnion(rows->tree());
    auto acc = out.velocity->getAccessor();
    for (auto it = rows->cbeginValueOn(); it; ++it) {
      const float* v = &frame.velocity[3 * std::size_t(*it)];
      acc.setValue(it.getCoord(), openvdb::Vec3s(v[0], v[1], v[2]));
    }
  }
  return out;
}

/// Step 4: the zero level set as a closed triangle mesh, with area-weighted vertex normals.
PlyMesh mesh_level_set(const openvdb::FloatGrid& sdf, bool normals) {
  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> triangles;
  std::vector<openvdb::Vec4I> quads;
  openvdb::tools::volumeToMesh(sdf, points, triangles, quads, 0.0, 0.0);
  PlyMesh m;
  m.vertices.reserve(points.size());
  for (const openvdb::Vec3s& p : points) m.vertices.push_back({p[0], p[1], p[2]});
  m.triangles.reserve(triangles.size() + 2 * quads.size());
  // volumeToMesh winds its polygons clockwise seen from outside a level set (negative
  // inside); reverse them to the counter-clockwise order renderers take as front-facing.
  for (const openvdb::Vec3I& t : triangles)
    m.triangles.push_back({int(t[2]), int(t[1]), int(t[0])});
  for (const openvdb::Vec4I& q : quads) {
    m.triangles.push_back({int(q[2]), int(q[1]), int(q[0])});
    m.triangles.push_back({int(q[3]), int(q[2]), int(q[0])});
  }
  if (normals) {
    std::vector<Vec3> sum(m.vertices.size(), Vec3::Zero());
    const auto at = [&](int v) {
      return Vec3(m.vertices[v][0], m.vertices[v][1], m.vertices[v][2]);
    };
    for (const auto& t : m.triangles) {
      const Vec3 n = (at(t[1]) - at(t[0])).cross(at(t[2]) - at(t[0]));  // twice the area
      for (int v : t) sum[v] += n;
    }
    m.normals.resize(m.vertices.size());
    for (std::size_t i = 0; i < sum.size(); ++i) {
      const Real len = sum[i].norm();
      const Vec3 n = len > 0 ? Vec3(sum[i] / len) : Vec3(0, 0, 1);
      m.normals[i] = {float(n.x()), float(n.y()), float(n.z())};
    }
  }
  return m;
}

std::filesystem::path numbered(const std::filesystem::path& dir, const char* pattern, int frame) {
  char name[64];
  std::snprintf(name, sizeof name, pattern, frame);
  return dir / name;
}

}  // namespace

PlyMesh build_surface(const FrameData& frame, int object, double spacing, const SurfaceDesc& desc) {
  const ObjectLevelSet ls = build_level_set(frame, object, spacing, desc, false);
  return mesh_level_set(*ls.sdf, desc.normals);
}

std::filesystem::path surface_mesh_path(const std::filesystem::path& dir, int frame,
                                        const std::string& name) {
  std::string safe = name;
  for (char& c : safe)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_' && c != '.') c = '_';
  return numbered(dir, "frame_%05d_", frame).string() + safe + ".ply";
}

std::filesystem::path surface_vdb_path(const std::filesystem::path& dir, int frame) {
  return numbered(dir, "frame_%05d.vdb", frame);
}

void write_surfaces(const std::filesystem::path& dir, const FrameData& frame,
                    const std::vector<SurfaceObject>& objects, const SurfaceDesc& desc, bool mesh,
                    bool vdb) {
  openvdb::GridPtrVec grids;
  char time[64];
  std::snprintf(time, sizeof time, "time %.17g", frame.time);
  const std::vector<std::string> comments = {time, "frame " + std::to_string(frame.frame)};
  for (std::size_t o = 0; o < objects.size(); ++o) {
    const SurfaceObject& obj = objects[o];
    ObjectLevelSet ls =
        build_level_set(frame, static_cast<int>(o), obj.spacing, desc, vdb && desc.velocity);
    if (mesh)
      write_ply_mesh(surface_mesh_path(dir, frame.frame, obj.name),
                     mesh_level_set(*ls.sdf, desc.normals), comments);
    if (!vdb) continue;
    ls.sdf->setName(obj.name);
    ls.sdf->setGridClass(openvdb::GRID_LEVEL_SET);
    grids.push_back(ls.sdf);
    if (desc.density) {
      openvdb::FloatGrid::Ptr fog = ls.sdf->deepCopy();
      openvdb::tools::sdfToFogVolume(*fog);
      fog->setName(obj.name + "_density");
      grids.push_back(fog);
    }
    if (ls.velocity) {
      ls.velocity->setName(obj.name + "_velocity");
      ls.velocity->setVectorType(openvdb::VEC_CONTRAVARIANT_RELATIVE);
      grids.push_back(ls.velocity);
    }
  }
  if (!vdb) return;
  const std::filesystem::path file = surface_vdb_path(dir, frame.frame);
  const std::filesystem::path tmp = temporary_path(file);
  try {
    openvdb::io::File f(tmp.string());
    openvdb::MetaMap meta;
    meta.insertMeta("time", openvdb::DoubleMetadata(frame.time));
    meta.insertMeta("frame", openvdb::Int32Metadata(frame.frame));
    f.write(grids, meta);
    f.close();
  } catch (const openvdb::Exception& e) {
    throw std::runtime_error("cannot write '" + tmp.string() + "': " + e.what());
  }
  replace_file(tmp, file);
}

int surfaces_from_run(const std::filesystem::path& dir, bool mesh, bool vdb) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw SceneError({dir.string()}, "", "no such run folder");
  // The frames, in frame order.
  std::map<int, fs::path> frames;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    int k = -1;
    char tail = 0;
    if (name.size() == 14 && std::sscanf(name.c_str(), "frame_%5d.h%c", &k, &tail) == 2 &&
        tail == '5' && k >= 0)
      frames[k] = e.path();
  }
  if (frames.empty())
    throw SceneError({dir.string()}, "",
                     "no frame_NNNNN.h5 files: not the folder of a run that wrote hdf5 frames");
  const fs::path report_file = dir / "report.yaml";
  if (!fs::is_regular_file(report_file, ec))
    throw SceneError({report_file.string()}, "",
                     "no report.yaml (written when a run ends): the objects' names and particle "
                     "spacings come from it");
  std::vector<SurfaceObject> objects;
  SurfaceDesc desc;
  try {
    const YAML::Node report = YAML::LoadFile(report_file.string());
    for (const YAML::Node& o : report["objects"]) {
      if (!o["particle_spacing"])
        throw SceneError({report_file.string()}, "objects",
                         "object '" + o["name"].as<std::string>("?") +
                             "' has no particle_spacing: the run is older than surfaces; "
                             "run it again");
      objects.push_back({o["name"].as<std::string>(), o["particle_spacing"].as<double>()});
    }
    if (const YAML::Node s = report["surface"]) {
      desc.radius = s["radius"].as<double>(desc.radius);
      desc.voxel = s["voxel"].as<double>(desc.voxel);
      desc.smoothing = s["smoothing"].as<int>(desc.smoothing);
      desc.normals = s["normals"].as<bool>(desc.normals);
      desc.density = s["density"].as<bool>(desc.density);
      desc.velocity = s["velocity"].as<bool>(desc.velocity);
    }
  } catch (const YAML::Exception& e) {
    throw SceneError({report_file.string(), e.mark.line + 1, e.mark.column + 1}, "",
                     "cannot read the run report: " + e.msg);
  }
  if (objects.empty())
    throw SceneError({report_file.string()}, "objects", "the report lists no objects");
  for (const auto& [k, file] : frames) {
    FrameData frame;
    try {
      frame = read_frame_hdf5(file);
    } catch (const std::exception& e) {
      throw SceneError({file.string()}, "", e.what());
    }
    for (int id : frame.object_id)
      if (id < 0 || static_cast<std::size_t>(id) >= objects.size())
        throw SceneError({file.string()}, "object_id",
                         "object id " + std::to_string(id) + " but the report lists " +
                             std::to_string(objects.size()) + " objects");
    write_surfaces(dir, frame, objects, desc, mesh, vdb);
  }
  return static_cast<int>(frames.size());
}

std::vector<SurfaceObject> surface_objects(const SceneDesc& scene) {
  std::vector<SurfaceObject> out;
  const double cell_volume = scene.grid.spacing().prod();
  for (const ObjectDesc& o : scene.objects)
    out.push_back({o.name, std::cbrt(cell_volume / o.particles_per_cell)});
  return out;
}

}  // namespace mpm
