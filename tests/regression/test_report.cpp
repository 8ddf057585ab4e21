// report.yaml's timings: every timed part of the substep loop is a stage, and the throughput
// is taken over the whole loop.
#include <catch2/catch.hpp>

#include <sys/wait.h>

#include <cstdlib>
#include <fstream>

#include <yaml-cpp/yaml.h>

#include "support/helpers.h"

using namespace mpm;

TEST_CASE("report: the adaptive dt's wave-speed bound is a stage, and the stages fill the loop",
          "[regression]") {
  const auto dir = test::temp_dir("report_stages");
  // About 17,000 particles and 50 substeps: each substep takes long enough that the timer's
  // own cost is far below the 5% allowed below.
  std::ofstream(dir / "scene.yaml")
      << "simulation: {frames: 2, frame_dt: 0.01, cfl: 0.5}\n"
         "grid: {max: [1, 1, 1], dims: 32}\n"
         "objects:\n"
         "  - {name: jelly, mesh: " + test::cube_mesh() + ", scale: 0.4, offset: [0.5, 0.5, 0.5],\n"
         "     velocity: [0, -1, 0], density: 1000, material: corotated, E: 1.0e6, nu: 0.3}\n";
  const std::string cmd = std::string(MPM_BINARY) + " run " + (dir / "scene.yaml").string() +
                          " --quiet --threads 1 --out " + (dir / "out").string() + " > /dev/null";
  const int status = std::system(cmd.c_str());
  REQUIRE(WIFEXITED(status));
  REQUIRE(WEXITSTATUS(status) == 0);
  const YAML::Node report = YAML::LoadFile((dir / "out" / "report.yaml").string());
  const YAML::Node stages = report["stages"];
  REQUIRE(stages["cfl_bound"]);
  CHECK(stages["cfl_bound"].as<double>() > 0);
  double sum = 0;
  for (const auto& kv : stages)
    if (kv.first.as<std::string>() != "output") sum += kv.second.as<double>();
  const double loop = report["loop_seconds"].as<double>();
  INFO("stages sum to " << sum << " s, the substep loop took " << loop << " s");
  CHECK(sum <= loop);
  CHECK(sum >= 0.95 * loop);
  const double steps = report["particles"].as<double>() * report["substeps"].as<double>();
  CHECK(report["particle_steps_per_second"].as<double>() == Approx(steps / loop).epsilon(1e-6));
  // The whole run is the loop, the checks between substeps and frames, and the observers.
  const double wall = report["wall_seconds"].as<double>();
  const double parts = loop + report["check_seconds"].as<double>() +
                       report["observer_seconds"].as<double>();
  INFO("wall " << wall << " s, loop + checks + observers " << parts << " s");
  CHECK(parts <= wall);
  CHECK(parts >= 0.95 * wall);
  CHECK(report["observer_seconds"].as<double>() >= report["output_seconds"].as<double>());
  CHECK(report["run_particle_steps_per_second"].as<double>() == Approx(steps / wall).epsilon(1e-6));
  CHECK(report["substeps"].as<int>() >= 20);
}
