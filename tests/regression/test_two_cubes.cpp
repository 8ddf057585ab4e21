// End to end: `mpm run scenes/two_cubes.yaml` for a few frames, then check report and frames.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdlib>
#include <set>

#include <yaml-cpp/yaml.h>

#include "engine/io/output.h"
#include "support/helpers.h"

using namespace mpm;

TEST_CASE("two_cubes runs end to end: report, frames, contact, floor", "[regression]") {
  const auto out = test::temp_dir("two_cubes");
  const int frames = 6;
  const std::string cmd = std::string(MPM_BINARY) + " run " +
                          (test::source_dir() / "scenes/two_cubes.yaml").string() + " --out " +
                          out.string() + " --frames " + std::to_string(frames) +
                          " --quiet > " + (out / "stdout.txt").string();
  REQUIRE(std::system(cmd.c_str()) == 0);

  const YAML::Node report = YAML::LoadFile((out / "report.yaml").string());
  CHECK(report["status"].as<std::string>() == "ok");
  const auto particles = report["particles"].as<std::size_t>();
  CHECK(particles > 200000);
  CHECK(particles < 240000);
  CHECK(report["frames"].as<int>() == frames);
  CHECK(report["substeps"].as<std::size_t>() >= static_cast<std::size_t>(frames) * 41);
  CHECK(report["wall_seconds"].as<double>() > 0);
  CHECK(report["particle_steps_per_second"].as<double>() > 0);
  // Walls act at the particles touching them (the default contact): no node-rule stage.
  // Gravity rides in the grid update's pass over the nodes (APIC keeps no old velocity).
  for (const char* stage :
       {"particles_to_grid", "grid_update_gravity", "contact", "grid_to_particles"})
    CHECK(report["stages"][stage].IsDefined());
  CHECK_FALSE(report["stages"]["gravity"].IsDefined());
  CHECK_FALSE(report["stages"]["walls"].IsDefined());
  // APIC scatters the stress as an impulse: no separate force stage (FLIP only).
  CHECK_FALSE(report["stages"]["stress_forces"].IsDefined());
  CHECK_FALSE(report["stages"]["plasticity"].IsDefined());  // no plastic material
  REQUIRE(report["objects"].size() == 2);
  CHECK(report["objects"][0]["material"].as<std::string>() == "corotated");
  CHECK(report["objects"][0]["mass"].as<double>() == Approx(10));

  const double h = 0.01, floor_y = 0.05;
  bool touched = false;
  for (int f = 0; f <= frames; ++f) {
    INFO("frame " << f);
    const FrameData d = read_frame_hdf5(frame_path(out, f));
    REQUIRE(d.size() == particles);
    CHECK(d.frame == f);
    CHECK(d.time == Approx(f * 0.0416667));
    double min_y = 1e9;
    for (std::size_t q = 0; q < d.size(); ++q) {
      for (int a = 0; a < 3; ++a) {
        REQUIRE(std::isfinite(d.position[3 * q + a]));
        REQUIRE(std::isfinite(d.velocity[3 * q + a]));
      }
      REQUIRE(std::isfinite(d.J[q]));
      min_y = std::min<double>(min_y, d.position[3 * q + 1]);
    }
    // The contact holds every particle within its radius of the floor; h is the bound the
    // node rule met (half a cell into the wall, plus a substep of travel).
    CHECK(min_y > floor_y - h);
    // Contact: some particle of one cube within 1.5 cells of a particle of the other.
    std::set<std::tuple<int, int, int>> lower_cells;
    for (std::size_t q = 0; q < d.size(); ++q)
      if (d.object_id[q] == 0)
        lower_cells.insert({int(std::floor(d.position[3 * q] / h)),
                            int(std::floor(d.position[3 * q + 1] / h)),
                            int(std::floor(d.position[3 * q + 2] / h))});
    for (std::size_t q = 0; q < d.size() && !touched; ++q) {
      if (d.object_id[q] != 1) continue;
      const int i = int(std::floor(d.position[3 * q] / h)),
                j = int(std::floor(d.position[3 * q + 1] / h)),
                k = int(std::floor(d.position[3 * q + 2] / h));
      for (int a = -1; a <= 1 && !touched; ++a)
        for (int b = -1; b <= 1 && !touched; ++b)
          for (int c = -1; c <= 1 && !touched; ++c)
            touched = lower_cells.count({i + a, j + b, k + c}) > 0;
    }
    if (f == 0) CHECK_FALSE(touched);  // they start apart
  }
  CHECK(touched);
}

TEST_CASE("two_cubes with contact at the particles: crushed on two walls of one floor, stable",
          "[regression]") {
  // The floor is both the plane and the box's bottom. The soft cubes are crushed against it
  // (J down to about 0.02) and rebound: with the warm start's memory holding one impulse per
  // particle, a particle on both walls started one of them from nothing in every substep, and
  // the run ended unstable in frame 7 (a particle at 12 m/s, 1.19 cells per substep).
  const auto out = test::temp_dir("two_cubes_particles");
  const int frames = 8;
  const std::string cmd =
      std::string(MPM_BINARY) + " run " + (test::source_dir() / "scenes/two_cubes.yaml").string() +
      " --out " + out.string() + " --frames " + std::to_string(frames) +
      " --set simulation.contact=particles --quiet > " + (out / "stdout.txt").string();
  REQUIRE(std::system(cmd.c_str()) == 0);
  const YAML::Node report = YAML::LoadFile((out / "report.yaml").string());
  CHECK(report["status"].as<std::string>() == "ok");
  CHECK(report["frames"].as<int>() == frames);
  const double h = 0.01, floor_y = 0.05;
  const FrameData d = read_frame_hdf5(frame_path(out, frames));
  double min_y = 1e9, top_speed = 0;
  for (std::size_t q = 0; q < d.size(); ++q) {
    min_y = std::min<double>(min_y, d.position[3 * q + 1]);
    top_speed =
        std::max(top_speed, std::hypot(double(d.velocity[3 * q]), double(d.velocity[3 * q + 1]),
                                       double(d.velocity[3 * q + 2])));
  }
  // No particle sinks a cell into the floor, and none runs away: the node rule's run of the
  // same frames tops at 4.9 m/s, the unstable one passed 12 m/s.
  CHECK(min_y > floor_y - h);
  CHECK(top_speed < 6);
}
