// The scene loader: good scenes load; bad ones fail with file, line and key.
#include <catch2/catch.hpp>

#include "support/helpers.h"

using namespace mpm;
using Catch::Matchers::Contains;
using test::scene_from;

namespace {

std::string minimal_scene(const std::string& object_extra = "",
                          const std::string& sim_extra = "") {
  return "simulation:\n"
         "  frames: 2\n"
         "  dt: 1.0e-3\n" +
         sim_extra +
         "grid:\n"
         "  max: [1, 1, 1]\n"
         "  dims: 20\n"
         "objects:\n"
         "  - name: a\n"
         "    mesh: meshes/cube.obj\n"
         "    scale: 0.2\n"
         "    offset: [0.5, 0.5, 0.5]\n"
         "    mass: 1\n"
         "    material: corotated\n"
         "    E: 1.0e4\n"
         "    nu: 0.3\n" +
         object_extra;
}

/// The message of the SceneError that loading `yaml` throws.
std::string error_of(const std::string& yaml) {
  try {
    scene_from(yaml);
  } catch (const SceneError& e) {
    return e.what();
  }
  FAIL("expected a SceneError");
  return "";
}

}  // namespace

TEST_CASE("scene: a minimal scene loads with defaults", "[scene]") {
  const SceneDesc s = scene_from(minimal_scene());
  CHECK(s.simulation.frames == 2);
  CHECK(s.simulation.dt == Approx(1e-3));
  CHECK(s.simulation.gravity.y() == Approx(-9.81));
  CHECK(s.simulation.transfer == Transfer::apic);
  CHECK(s.grid.dims == Vec3i(20, 20, 20));
  CHECK(s.grid.spacing().x() == Approx(0.05));
  REQUIRE(s.objects.size() == 1);
  CHECK(s.objects[0].scale == Vec3::Constant(0.2));
  CHECK(s.objects[0].params.at("E") == Approx(1e4));
  CHECK(s.objects[0].mesh == test::source_dir() / "scenes" / "meshes/cube.obj");
}

TEST_CASE("scene: every shipped scene loads", "[scene]") {
  for (const auto& entry : std::filesystem::directory_iterator(test::source_dir() / "scenes")) {
    if (entry.path().extension() != ".yaml") continue;
    INFO(entry.path());
    MaterialRegistry registry = builtin_registry();
    CHECK_NOTHROW(load_scene(entry.path(), registry));
  }
}

TEST_CASE("scene: errors name file, line, column and key", "[scene]") {
  SECTION("unknown key with a suggestion") {
    const std::string e = error_of(minimal_scene("    youngs: 3\n"));
    CHECK_THAT(e, Contains("test.yaml:16:5"));
    CHECK_THAT(e, Contains("objects[0].youngs"));
    CHECK_THAT(e, Contains("unknown key 'youngs'"));
  }
  SECTION("misspelt top-level key") {
    const std::string e = error_of(minimal_scene("", "  frams: 3\n"));
    CHECK_THAT(e, Contains("test.yaml:4:3"));
    CHECK_THAT(e, Contains("did you mean 'frames'"));
  }
  SECTION("malformed number") {
    std::string yaml = minimal_scene();
    yaml.replace(yaml.find("1.0e4"), 5, "1.0e4x");
    const std::string e = error_of(yaml);
    CHECK_THAT(e, Contains("test.yaml:14:8"));
    CHECK_THAT(e, Contains("objects[0].E"));
    CHECK_THAT(e, Contains("expected a number"));
  }
  SECTION("missing required key") {
    std::string yaml = minimal_scene();
    yaml.erase(yaml.find("    nu: 0.3\n"));
    const std::string e = error_of(yaml);
    CHECK_THAT(e, Contains("objects[0].nu"));
    CHECK_THAT(e, Contains("missing required key 'nu'"));
  }
  SECTION("out of range") {
    std::string yaml = minimal_scene();
    yaml.replace(yaml.find("nu: 0.3"), 7, "nu: 0.5");
    CHECK_THAT(error_of(yaml), Contains("out of range"));
  }
  SECTION("unknown material lists the registered ones") {
    std::string yaml = minimal_scene();
    yaml.replace(yaml.find("corotated"), 9, "jelly");
    const std::string e = error_of(yaml);
    CHECK_THAT(e, Contains("unknown material 'jelly'"));
    CHECK_THAT(e, Contains("corotated"));
  }
  SECTION("YAML syntax error") {
    const std::string e = error_of("simulation: [1, 2\ngrid: {}\n");
    CHECK_THAT(e, Contains("test.yaml:"));
    CHECK_THAT(e, Contains("YAML syntax error"));
  }
  SECTION("mass and density together") {
    CHECK_THAT(error_of(minimal_scene("    density: 1000\n")), Contains("not both"));
  }
  SECTION("wrong type for a list") {
    CHECK_THAT(error_of(minimal_scene("    velocity: 3\n")),
               Contains("expected a list of three numbers"));
  }
}

TEST_CASE("scene: a missing mesh fails when the simulation is built", "[scene]") {
  std::string yaml = minimal_scene();
  yaml.replace(yaml.find("meshes/cube.obj"), 15, "meshes/nope.obj");
  const SceneDesc s = scene_from(yaml);
  try {
    Simulation::create(s, builtin_registry());
    FAIL("expected a SceneError");
  } catch (const SceneError& e) {
    CHECK_THAT(e.what(), Contains("test.yaml:9:11"));
    CHECK_THAT(e.what(), Contains("objects[0].mesh"));
    CHECK_THAT(e.what(), Contains("does not exist"));
  }
}

TEST_CASE("scene: an object outside the grid interior is rejected", "[scene]") {
  std::string yaml = minimal_scene();
  yaml.replace(yaml.find("[0.5, 0.5, 0.5]"), 15, "[0.05, 0.5, 0.5]");
  CHECK_THROWS_WITH(Simulation::create(scene_from(yaml), builtin_registry()),
                    Contains("outside the grid interior"));
}
