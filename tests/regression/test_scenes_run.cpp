// Every shipped scene starts and runs two frames through the `mpm` program with status ok.
#include <catch2/catch.hpp>

#include <cstdlib>

#include <yaml-cpp/yaml.h>

#include "engine/output.h"
#include "support/helpers.h"

using namespace mpm;

TEST_CASE("every scene in scenes/ runs two frames", "[regression]") {
  int scenes = 0;
  for (const auto& entry : std::filesystem::directory_iterator(test::source_dir() / "scenes")) {
    if (entry.path().extension() != ".yaml") continue;
    ++scenes;
    const std::string name = entry.path().stem().string();
    INFO("scene " << name);
    const auto out = test::temp_dir("scene_" + name);
    const std::string cmd = std::string(MPM_BINARY) + " run " + entry.path().string() +
                            " --frames 2 --quiet --out " + out.string() + " > " +
                            (out / "stdout.txt").string() + " 2>&1";
    CHECK(std::system(cmd.c_str()) == 0);
    const YAML::Node report = YAML::LoadFile((out / "report.yaml").string());
    CHECK(report["status"].as<std::string>() == "ok");
    CHECK(report["frames"].as<int>() == 2);
    const FrameData last = read_frame_hdf5(frame_path(out, 2));
    CHECK(last.size() == report["particles"].as<std::size_t>());
    bool finite = true;
    for (float x : last.position) finite = finite && std::isfinite(x);
    CHECK(finite);
  }
  CHECK(scenes >= 8);
}
