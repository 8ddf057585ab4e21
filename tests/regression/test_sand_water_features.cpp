// Sand and (viscous) water in the scene features: a sphere collider, every output format,
// and a resumed run equal to the straight one bit for bit (their material state included).
#include <catch2/catch.hpp>

#include <cstdlib>
#include <fstream>
#include <sys/wait.h>

#include <yaml-cpp/yaml.h>

#include "engine/io/output.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// Sand and viscous water falling on a sphere collider and a floor.
std::filesystem::path sand_water_scene(const std::filesystem::path& dir) {
  const std::string cube = test::cube_mesh();
  std::ofstream(dir / "scene.yaml")
      << "simulation: {frames: 4, frame_dt: 0.02, cfl: 0.5, dt: 2.0e-3}\n"
         "grid: {max: [1, 1, 1], dims: 24}\n"
         "objects:\n"
         "  - {name: sand, mesh: " + cube + ", scale: 0.2, offset: [0.35, 0.55, 0.5],\n"
         "     density: 1600, material: sand, E: 1.0e5, nu: 0.3, friction_angle: 35}\n"
         "  - {name: water, mesh: " + cube + ", scale: 0.2, offset: [0.65, 0.55, 0.5],\n"
         "     density: 1000, material: water, bulk_modulus: 2.0e4, viscosity: 0.5}\n"
         "walls:\n"
         "  - sphere: {center: [0.5, 0.25, 0.5], radius: 0.12}\n"
         "    boundary: separate\n"
         "    friction: 0.3\n"
         "  - plane: {point: [0, 0.15, 0], normal: [0, 1, 0]}\n"
         "    boundary: sticky\n";
  return dir / "scene.yaml";
}

int run_mpm(const std::string& args) {
  const int status = std::system((std::string(MPM_BINARY) + " " + args + " > /dev/null 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

TEST_CASE("sand and viscous water: collider, every format, resume bit for bit", "[regression]") {
  const auto dir = test::temp_dir("sand_water_features");
  const auto scene = sand_water_scene(dir);
  const std::string a = (dir / "a").string(), b = (dir / "b").string();
  REQUIRE(run_mpm("run " + scene.string() + " --frames 4 --quiet --format hdf5,bgeo,ply,png,mesh --out " + a) == 0);
  for (const char* f : {"frame_00004.h5", "frame_00004.bgeo", "frame_00004.ply",
                        "preview/frame_00004.png", "frame_00004_sand.ply", "frame_00004_water.ply"}) {
    INFO(f);
    CHECK(std::filesystem::exists(dir / "a" / f));
  }
  REQUIRE(run_mpm("run " + scene.string() + " --frames 2 --quiet --out " + b) == 0);
  REQUIRE(run_mpm("run " + scene.string() + " --frames 4 --quiet --resume " + b) == 0);
  const FrameData x = read_frame_hdf5(frame_path(a, 4)), y = read_frame_hdf5(frame_path(b, 4));
  CHECK(x.position == y.position);
  CHECK(x.velocity == y.velocity);
  CHECK(x.J == y.J);
  // Nothing entered the collider: every particle is outside the sphere, to a cell's reach.
  double inside = 0;
  for (std::size_t q = 0; q < x.size(); ++q) {
    const Vec3 p(x.position[3 * q], x.position[3 * q + 1], x.position[3 * q + 2]);
    inside = std::max(inside, 0.12 - (p - Vec3(0.5, 0.25, 0.5)).norm());
  }
  CHECK(inside < 1.0 / 24);
  // Both bodies moved (they fell onto the collider and floor).
  const FrameData x0 = read_frame_hdf5(frame_path(a, 0));
  CHECK(x.position != x0.position);
}
