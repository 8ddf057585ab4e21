// Surfaces for renderers (engine/io/surface.h): closed meshes that enclose each object's volume,
// VDB files read back with OpenVDB, `mpm surface` against the run's own files, bad input.
#include <catch2/catch.hpp>

#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <string>

#include "engine/io/surface.h"
#include "engine/scene/mesh.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// Volume enclosed by a triangle mesh (divergence theorem); positive if wound outward.
double enclosed_volume(const std::vector<Vec3>& v, const std::vector<std::array<int, 3>>& t) {
  double sum = 0;
  for (const auto& f : t) sum += v[f[0]].dot(v[f[1]].cross(v[f[2]])) / 6;
  return sum;
}

/// The PLY mesh as a TriangleMesh, for mesh.h's closedness check.
TriangleMesh as_triangle_mesh(const PlyMesh& m) {
  TriangleMesh t;
  for (const auto& p : m.vertices) t.vertices.emplace_back(p[0], p[1], p[2]);
  t.triangles = m.triangles;
  return t;
}

std::string slurp(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/// Runs `mpm ARGS` with stderr into `err`; returns the exit code.
int run_mpm(const std::string& args, const std::filesystem::path& err) {
  const std::string cmd = std::string(MPM_BINARY) + " " + args + " > /dev/null 2> " + err.string();
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// Each object's surface at frame 0 of `scene_file` (optionally with --set overrides).
void check_frame0_surfaces(const std::string& scene_file) {
  MaterialRegistry registry = builtin_registry();
  const SceneDesc scene = load_scene(test::source_dir() / "scenes" / scene_file, registry);
  const auto sim = Simulation::create(scene, registry);
  FrameArrays arrays;
  const FrameData frame =
      frame_data(frame_in_id_order(sim->particles(), sim->time(), 0, arrays));
  const std::vector<SurfaceObject> objects = surface_objects(scene);
  for (std::size_t o = 0; o < objects.size(); ++o) {
    const ObjectDesc& od = scene.objects[o];
    TriangleMesh body = load_mesh(od.mesh);
    transform_mesh(body, od.scale, od.rotation_deg, od.offset);
    const double want = enclosed_volume(body.vertices, body.triangles);
    const PlyMesh surface = build_surface(frame, static_cast<int>(o), objects[o].spacing,
                                          scene.output.surface);
    const TriangleMesh got_mesh = as_triangle_mesh(surface);
    const double got = enclosed_volume(got_mesh.vertices, got_mesh.triangles);
    INFO(scene_file << " object " << od.name << ": surface volume " << got << " m^3, mesh "
                    << want << " m^3, " << surface.triangles.size() << " triangles");
    std::printf("surface %s/%s: volume ratio %.4f, %zu triangles, spacing %.5f m\n",
                scene_file.c_str(), od.name.c_str(), got / want, surface.triangles.size(),
                objects[o].spacing);
    CHECK(closedness_problem(got_mesh).empty());
    CHECK(got == Approx(want).epsilon(0.05));
    // Normals point outwards: from the surface away from the body's centroid, on average.
    REQUIRE(surface.normals.size() == surface.vertices.size());
    Vec3 centre = Vec3::Zero();
    for (const Vec3& v : got_mesh.vertices) centre += v / double(got_mesh.vertices.size());
    double outward = 0;
    for (std::size_t i = 0; i < surface.vertices.size(); ++i)
      outward += Vec3(surface.normals[i][0], surface.normals[i][1], surface.normals[i][2])
                     .dot((got_mesh.vertices[i] - centre).normalized());
    CHECK(outward / surface.vertices.size() > 0.5);
  }
}

}  // namespace

TEST_CASE("frame-0 surfaces of the two cubes are closed and enclose their volume within 5%",
          "[surface]") {
  check_frame0_surfaces("two_cubes.yaml");
}

TEST_CASE("frame-0 surface of the bunny is closed and encloses its volume within 5%",
          "[surface]") {
  check_frame0_surfaces("bunny.yaml");
}

TEST_CASE("frame-0 surface of the snowball sphere is closed and encloses its volume within 5%",
          "[surface]") {
  check_frame0_surfaces("snowball.yaml");
}

TEST_CASE("PLY meshes read back as written, and bad meshes are refused", "[surface][ply]") {
  const auto dir = test::temp_dir("ply_mesh");
  PlyMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1.5f}};
  m.normals = {{0, 0, -1}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  write_ply_mesh(dir / "t.ply", m, {"frame 7"});
  const std::string bytes = slurp(dir / "t.ply");
  CHECK(bytes.find("element face 4\nproperty list uchar int vertex_indices\n") !=
        std::string::npos);
  const PlyMesh r = read_ply_mesh(dir / "t.ply");
  CHECK(r.vertices == m.vertices);
  CHECK(r.normals == m.normals);
  CHECK(r.triangles == m.triangles);
  m.normals.clear();
  write_ply_mesh(dir / "n.ply", m);
  CHECK(read_ply_mesh(dir / "n.ply").normals.empty());
  m.triangles.push_back({0, 1, 4});
  CHECK_THROWS_AS(write_ply_mesh(dir / "bad.ply", m), std::invalid_argument);
  CHECK_FALSE(std::filesystem::exists(dir / "bad.ply"));
}

TEST_CASE("a frame's VDB file holds a level set named after each object", "[surface][vdb]") {
  // Two small cubes, with the density and velocity grids turned on.
  SceneDesc scene = test::scene_from(R"(
simulation: {frames: 1, dt: 1.0e-3}
grid: {max: [1, 1, 1], dims: 32}
objects:
  - {name: left, mesh: meshes/cube.obj, scale: 0.2, offset: [0.3, 0.5, 0.5], density: 1000,
     velocity: [1, 0, 0], material: corotated, E: 1.0e4, nu: 0.3}
  - {name: right, mesh: meshes/cube.obj, scale: 0.2, offset: [0.7, 0.5, 0.5], density: 1000,
     velocity: [0, -2, 0], material: corotated, E: 1.0e4, nu: 0.3}
output: {formats: [vdb], surface: {density: true, velocity: true}}
)");
  MaterialRegistry registry = builtin_registry();
  const auto sim = Simulation::create(scene, registry);
  FrameArrays arrays;
  const FrameData frame = frame_data(frame_in_id_order(sim->particles(), 0, 3, arrays));
  const auto dir = test::temp_dir("surface_vdb");
  write_surfaces(dir, frame, surface_objects(scene), scene.output.surface, false, true);
  REQUIRE(std::filesystem::exists(surface_vdb_path(dir, 3)));
  CHECK_FALSE(std::filesystem::exists(surface_mesh_path(dir, 3, "left")));

  openvdb::initialize();
  openvdb::io::File file(surface_vdb_path(dir, 3).string());
  file.open();
  std::set<std::string> names;
  for (auto it = file.beginName(); it != file.endName(); ++it) names.insert(it.gridName());
  CHECK(names == std::set<std::string>{"left", "left_density", "left_velocity", "right",
                                       "right_density", "right_velocity"});
  for (const std::string name : {"left", "right"}) {
    const auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid(name));
    REQUIRE(grid);
    CHECK(grid->getGridClass() == openvdb::GRID_LEVEL_SET);
    const double x = name == "left" ? 0.3 : 0.7, other = name == "left" ? 0.7 : 0.3;
    const auto phi = [&](double px) {
      return openvdb::tools::BoxSampler::sample(
          grid->tree(), grid->transform().worldToIndex(openvdb::Vec3R(px, 0.5, 0.5)));
    };
    CHECK(phi(x) < 0);      // inside its own cube
    CHECK(phi(other) > 0);  // outside: the other cube is not in this grid
    // The boundary at the cube's face (x +- 0.1) within a particle spacing.
    const double s = std::cbrt(std::pow(1.0 / 32, 3) / 8);
    CHECK(phi(x + 0.1 - s) < 0);
    CHECK(phi(x + 0.1 + s) > 0);
    const auto vel = openvdb::gridPtrCast<openvdb::Vec3SGrid>(file.readGrid(name + "_velocity"));
    REQUIRE(vel);
    REQUIRE(vel->activeVoxelCount() > 0);
    const openvdb::Vec3s want = name == "left" ? openvdb::Vec3s(1, 0, 0)
                                               : openvdb::Vec3s(0, -2, 0);
    for (auto v = vel->cbeginValueOn(); v; ++v) REQUIRE((*v - want).length() < 1e-5);
    const auto fog = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid(name + "_density"));
    REQUIRE(fog);
    CHECK(fog->getGridClass() == openvdb::GRID_FOG_VOLUME);
    const auto rho = [&](double px) {
      return openvdb::tools::BoxSampler::sample(
          fog->tree(), fog->transform().worldToIndex(openvdb::Vec3R(px, 0.5, 0.5)));
    };
    CHECK(rho(x) == Approx(1));
    CHECK(rho(other) == 0);
  }
  file.close();
}

TEST_CASE("mpm surface on a finished run writes the files the run wrote", "[surface][cli]") {
  const auto dir = test::temp_dir("surface_cli");
  const std::string scene = (test::source_dir() / "scenes/two_cubes.yaml").string();
  // A small two_cubes: 40^3 cells, 8 particles per cell, 2 frames.
  const std::string small = " --set grid.dims=40 --set objects[0].particles_per_cell=8"
                            " --set objects[1].particles_per_cell=8 --frames 2 --quiet";
  REQUIRE(run_mpm("run " + scene + small + " --format hdf5,mesh,vdb --out " +
                      (dir / "run").string(), dir / "err") == 0);
  // The frames and the report only, then the surfaces afterwards.
  std::filesystem::create_directories(dir / "later");
  for (int k = 0; k <= 2; ++k)
    std::filesystem::copy(frame_path(dir / "run", k), frame_path(dir / "later", k));
  std::filesystem::copy(dir / "run" / "report.yaml", dir / "later" / "report.yaml");
  REQUIRE(run_mpm("surface " + (dir / "later").string() + " --format mesh,vdb", dir / "err") ==
          0);

  openvdb::initialize();
  for (int k = 0; k <= 2; ++k) {
    for (const char* name : {"lower", "upper"}) {
      const auto during = surface_mesh_path(dir / "run", k, name);
      const auto after = surface_mesh_path(dir / "later", k, name);
      REQUIRE(std::filesystem::exists(during));
      REQUIRE(std::filesystem::exists(after));
      CHECK(read_ply_mesh(during).triangles.size() > 1000);
      CHECK(slurp(during) == slurp(after));  // byte for byte
    }
    // VDB files carry a random id in their header: compare the grids voxel by voxel.
    openvdb::io::File a(surface_vdb_path(dir / "run", k).string());
    openvdb::io::File b(surface_vdb_path(dir / "later", k).string());
    a.open();
    b.open();
    for (const char* name : {"lower", "upper"}) {
      const auto ga = openvdb::gridPtrCast<openvdb::FloatGrid>(a.readGrid(name));
      const auto gb = openvdb::gridPtrCast<openvdb::FloatGrid>(b.readGrid(name));
      REQUIRE(ga);
      REQUIRE(gb);
      REQUIRE(ga->activeVoxelCount() == gb->activeVoxelCount());
      REQUIRE(ga->activeVoxelCount() > 0);
      auto acc = gb->getConstAccessor();
      std::size_t differ = 0;
      for (auto v = ga->cbeginValueOn(); v; ++v)
        if (!acc.isValueOn(v.getCoord()) || acc.getValue(v.getCoord()) != *v) ++differ;
      CHECK(differ == 0);
    }
  }
}

TEST_CASE("bad surface input: unknown formats, folders without frames, bad settings",
          "[surface][cli]") {
  const auto dir = test::temp_dir("surface_bad");
  const auto err = dir / "err";
  std::filesystem::create_directories(dir / "empty");
  CHECK(run_mpm("surface " + (dir / "empty").string(), err) == 2);
  CHECK(slurp(err).find("no frame_NNNNN.h5 files") != std::string::npos);
  CHECK(run_mpm("surface " + (dir / "missing").string(), err) == 2);
  CHECK(slurp(err).find("no such run folder") != std::string::npos);
  CHECK(run_mpm("surface " + (dir / "empty").string() + " --format obj", err) == 2);
  CHECK(slurp(err).find("writes the formats mesh and vdb, not 'obj'") != std::string::npos);
  const std::string scene = (test::source_dir() / "scenes/two_cubes.yaml").string();
  CHECK(run_mpm("run " + scene + " --format hdf5,meshes --out " + (dir / "o").string(), err) ==
        2);
  CHECK(slurp(err).find("unknown format 'meshes'; expected hdf5, bgeo, ply, png, mesh or vdb") !=
        std::string::npos);
  // Frames but no report (a run still going, or killed): said so.
  {
    FrameData one;
    one.position = {0.5f, 0.5f, 0.5f};
    one.velocity = {0, 0, 0};
    one.object_id = {0};
    one.J = {1};
    one.id = {0};
    const std::vector<Vec3> x{{0.5, 0.5, 0.5}}, v{{0, 0, 0}};
    const std::vector<std::uint32_t> obj{0}, id{0};
    const std::vector<Real> J{1};
    write_frame_hdf5(frame_path(dir / "empty", 0), FrameView{x, v, obj, J, 0.0, 0, id});
    CHECK(run_mpm("surface " + (dir / "empty").string(), err) == 2);
    CHECK(slurp(err).find("no report.yaml") != std::string::npos);
  }
  // Settings: unknown keys, ranges, and a voxel too coarse for the spheres, at their line.
  const auto fails_with = [](const std::string& surface, const std::string& what) {
    const std::string yaml = "simulation: {dt: 1.0e-3}\ngrid: {max: [1, 1, 1], dims: 16}\nobjects:\n  - {name: a, mesh: "
                             "meshes/cube.obj, density: 1, material: corotated, E: 1.0e4, nu: 0.3}\noutput:\n"
                             "  surface: " + surface + "\n";
    INFO(surface);
    try {
      test::scene_from(yaml);
      FAIL("accepted");
    } catch (const SceneError& e) {
      CHECK_THAT(e.what(), Catch::Contains(what) && Catch::Contains("test.yaml:6:"));
    }
  };
  fails_with("{radius: 0.1}", "output.surface.radius");
  fails_with("{smoothing: -1}", "output.surface.smoothing");
  fails_with("{radius: 1, voxel: 0.8}", "a sphere narrower than 1.5 voxels would be dropped");
  fails_with("{smoothin: 3}", "unknown key 'smoothin'");
  SceneDesc ok = test::scene_from(
      "simulation: {dt: 1.0e-3}\ngrid: {max: [1, 1, 1], dims: 16}\nobjects:\n  - {name: a, mesh: meshes/cube.obj, density: 1, "
      "material: corotated, E: 1.0e4, nu: 0.3}\noutput: {formats: [mesh, vdb], surface: {radius: 1.5, voxel: 0.25, "
      "smoothing: 2, normals: false}}\n");
  CHECK(ok.output.formats == std::vector<Format>{Format::mesh, Format::vdb});
  CHECK(ok.output.surface.radius == 1.5);
  CHECK(ok.output.surface.voxel == 0.25);
  CHECK(ok.output.surface.smoothing == 2);
  CHECK_FALSE(ok.output.surface.normals);
}
