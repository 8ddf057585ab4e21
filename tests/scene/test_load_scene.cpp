// The scene loader: good scenes load; bad ones fail with file, line and key.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cctype>
#include <sstream>

#include "engine/step/validate.h"
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
  CHECK_FALSE(s.grid.sampling_origin);
  std::string moved = minimal_scene();
  moved.replace(moved.find("  max: [1, 1, 1]"), 16,
                "  max: [1, 1, 1]\n  sampling_origin: [0.01, 0, 0]");
  CHECK(scene_from(moved).grid.sampling_origin == Vec3(0.01, 0, 0));
  REQUIRE(s.objects.size() == 1);
  CHECK(s.objects[0].scale == Vec3::Constant(0.2));
  CHECK(s.objects[0].params.at("E") == Approx(1e4));
  CHECK(s.objects[0].mesh == test::source_dir() / "scenes" / "meshes/cube.obj");
  // Every choice key left out takes the described struct's default (scene_desc.h is the one
  // place defaults live; the loader once took the first name it lists instead).
  CHECK(s.simulation.transfer == SimulationDesc{}.transfer);
  CHECK(s.simulation.kernel == SimulationDesc{}.kernel);
  CHECK(s.simulation.contact == SimulationDesc{}.contact);
  CHECK(s.simulation.quadrature == SimulationDesc{}.quadrature);
  CHECK(s.grid.float_nodes == GridDesc{}.float_nodes);
  CHECK(s.objects[0].sampling == ObjectDesc{}.sampling);
  CHECK(s.objects[0].initial_stress == ObjectDesc{}.initial_stress);
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

namespace {

/// A scene that uses every section the loader reads, in block style; a line `#SECTION` marks
/// where a key of that section can be added (at that line's indentation).
const char* kEverySection = R"(#top
simulation:
  frames: 2
  dt: 1.0e-3
  #simulation
grid:
  max: [1, 1, 1]
  dims: 20
  #grid
objects:
  - name: a
    mesh: meshes/cube.obj
    mass: 1
    material: corotated
    E: 1.0e4
    nu: 0.3
    #objects[0]
  - name: b
    mesh: meshes/cube.obj
    mass: 1
    material: neo_hookean
    E: 1.0e4
    nu: 0.3
    #objects[1]
  - name: c
    mesh: meshes/cube.obj
    mass: 1
    material: snow
    E: 1.0e4
    nu: 0.3
    #objects[2]
walls:
  - plane:
      point: [0, 0.2, 0]
      normal: [0, 1, 0]
      #walls[0].plane
    #walls[0]
  - box:
      min: [0, 0, 0]
      max: [1, 1, 1]
      #walls[1].box
    #walls[1]
output:
  camera:
    position: [0.5, 0.5, 2]
    look_at: [0.5, 0.5, 0.5]
    #output.camera
  #output
)";

/// kEverySection with `key: 1` added to `section`.
std::string with_key(const std::string& section, const std::string& key) {
  std::string yaml = kEverySection;
  const std::size_t at = yaml.find("#" + section + "\n");
  REQUIRE(at != std::string::npos);
  yaml.replace(at, section.size() + 1, key + ": 1");
  return yaml;
}

/// The "did you mean" of loading kEverySection with `key` added to `section` ("" if none).
std::string suggestion(const std::string& section, const std::string& key) {
  const std::string e = error_of(with_key(section, key));
  const std::string head = "did you mean '";
  const std::size_t at = e.find(head);
  if (at == std::string::npos) return "";
  return e.substr(at + head.size(), e.find('\'', at + head.size()) - at - head.size());
}

/// The keys the loader knows in `section`, from the list its unknown-key error gives.
std::vector<std::string> known_keys(const std::string& section) {
  const std::string e = error_of(with_key(section, "zzzzzzzzzzzz"));
  const std::string head = "expected one of: ";
  const std::size_t at = e.find(head);
  REQUIRE(at != std::string::npos);
  std::vector<std::string> keys;
  std::stringstream list(e.substr(at + head.size()));
  for (std::string k; std::getline(list, k, ',');) keys.push_back(k.substr(k[0] == ' '));
  return keys;
}

/// Insertions, deletions, substitutions and swaps of neighbours, each costing one.
std::size_t edits(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1,
                          d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

}  // namespace

TEST_CASE("scene: every known key is suggested for its prefixes and one-letter typos",
          "[scene]") {
  const std::vector<std::string> sections = {
      "top",       "simulation",      "grid",      "objects[0]",     "objects[1]", "objects[2]",
      "walls[0]",  "walls[0].plane",  "walls[1]",  "walls[1].box",   "output",     "output.camera"};
  std::size_t checked = 0;
  for (const std::string& section : sections) {
    const std::vector<std::string> keys = known_keys(section);
    INFO("section " << section << " (" << keys.size() << " keys)");
    REQUIRE(keys.size() >= 2);
    const auto known = [&](const std::string& w) {
      return std::find(keys.begin(), keys.end(), w) != keys.end();
    };
    for (const std::string& key : keys) {
      // Every proper prefix: its shortest completion among the keys (the key if it is that).
      for (std::size_t n = 1; n < key.size(); ++n) {
        const std::string p = key.substr(0, n);
        if (known(p)) continue;
        std::vector<std::string> completions;
        for (const std::string& k : keys)
          if (k.rfind(p, 0) == 0) completions.push_back(k);
        std::size_t shortest = key.size();
        for (const std::string& k : completions) shortest = std::min(shortest, k.size());
        std::size_t tied = 0;
        for (const std::string& k : completions) tied += k.size() == shortest;
        INFO("prefix '" << p << "' of '" << key << "'");
        const std::string s = suggestion(section, p);
        if (key.size() == shortest && tied == 1) CHECK(s == key);
        else CHECK((s.rfind(p, 0) == 0 && s.size() == shortest));
        ++checked;
      }
      // One-letter typos: the key, unless the typo is as close to (or a prefix of) another key.
      std::vector<std::string> typos;
      for (std::size_t i = 0; i < key.size(); ++i) {
        typos.push_back(key.substr(0, i) + key.substr(i + 1));                    // deletion
        typos.push_back(key.substr(0, i) + (key[i] == 'q' ? 'z' : 'q') + key.substr(i + 1));
        typos.push_back(key.substr(0, i) + 'q' + key.substr(i));                  // insertion
        if (i + 1 < key.size() && key[i] != key[i + 1])
          typos.push_back(key.substr(0, i) + key[i + 1] + key[i] + key.substr(i + 2));
      }
      for (const std::string& t : typos) {
        if (t.empty() || known(t) || !std::isalpha(static_cast<unsigned char>(t[0]))) continue;
        bool ambiguous = false;
        for (const std::string& k : keys)
          if (k != key && (edits(t, k) <= 1 || k.rfind(t, 0) == 0)) ambiguous = true;
        INFO("typo '" << t << "' of '" << key << "'");
        const std::string s = suggestion(section, t);
        if (!ambiguous) CHECK(s == key);
        else CHECK((edits(t, s) <= 1 || s.rfind(t, 0) == 0));
        ++checked;
      }
    }
  }
  CHECK(checked > 1000);
  // The cases that were wrong: 'frame' suggested 'frame_dt'.
  CHECK(suggestion("simulation", "frame") == "frames");
  CHECK(suggestion("simulation", "frmaes") == "frames");
  CHECK(suggestion("objects[0]", "velocity_gradiant") == "velocity_gradient");
  CHECK(suggestion("top", "object") == "objects");
  CHECK(suggestion("top", "output_dir") == "output");
  // Nothing close: no suggestion rather than a wild one.
  CHECK(suggestion("objects[0]", "dt") == "");
}

TEST_CASE("scene: a misnamed required key is named at its own place, with the key it stands for",
          "[scene]") {
  std::string yaml = minimal_scene();
  yaml.replace(yaml.find("    E: 1.0e4"), 12, "    youngs_modulus: 1.0e4");
  const std::string e = error_of(yaml);
  CHECK_THAT(e, Contains("test.yaml:14:5"));  // the key's line, not the object's (8)
  CHECK_THAT(e, Contains("objects[0].youngs_modulus"));
  CHECK_THAT(e, Contains("unknown key 'youngs_modulus' (did you mean 'E'?)"));
  CHECK_THAT(e, Contains("missing required key 'E' (Young's modulus)"));

  // A required engine key misspelt by one letter: that key, not the mapping.
  std::string grid = minimal_scene();
  grid.replace(grid.find("  dims: 20"), 10, "  dimz: 20");
  const std::string g = error_of(grid);
  CHECK_THAT(g, Contains("test.yaml:6:3"));
  CHECK_THAT(g, Contains("unknown key 'dimz' (did you mean 'dims'?)"));
  // But a valid key read later is not taken for the missing one (box min missing, max given).
  const std::string box = error_of(minimal_scene() +
                                   "walls:\n  - box:\n      max: [1, 1, 1]\n    boundary: slip\n");
  CHECK_THAT(box, Contains("walls[0].box.min: missing required key 'min'"));
}

TEST_CASE("scene: a key that lost its colon is named, wherever YAML puts it", "[scene]") {
  SECTION("joined into the value above") {
    std::string yaml = minimal_scene();
    yaml.replace(yaml.find("  dt: 1.0e-3\n"), 13, "  dt: 1.0e-3\n    cfl 0.5\n");
    const std::string e = error_of(yaml);
    CHECK_THAT(e, Contains("test.yaml:4:5"));
    CHECK_THAT(e, Contains("simulation.dt"));
    CHECK_THAT(e, Contains("a colon seems to be missing after 'cfl'"));
    CHECK_THAT(e, Contains("write 'cfl: 0.5'"));
  }
  SECTION("joined into a text value") {
    std::string yaml = minimal_scene();
    const std::string lines = "    material: corotated\n    E: 1.0e4";
    yaml.replace(yaml.find(lines), lines.size(), "    material: corotated\n      E 1.0e4");
    CHECK_THAT(error_of(yaml), Contains("a colon seems to be missing after 'E'"));
  }
  SECTION("a syntax error at the next key") {
    std::string yaml = minimal_scene();
    yaml.replace(yaml.find("  frames: 2\n"), 12, "  frames: 2\n  cfl 0.5\n");
    const std::string e = error_of(yaml);
    CHECK_THAT(e, Contains("YAML syntax error"));
    CHECK_THAT(e, Contains("line 3 ('cfl 0.5') seems to be missing a colon: write 'cfl: 0.5'"));
  }
  SECTION("a key of its own at the end") {
    const std::string e = error_of(minimal_scene("    friction 0.5\n"));
    CHECK_THAT(e, Contains("objects[0].friction 0.5"));
    CHECK_THAT(e, Contains("a colon seems to be missing; write 'friction: 0.5'"));
  }
  SECTION("a document made cyclic by an alias is still checked, not walked forever") {
    CHECK_THAT(error_of("a: &a [*a]\n" + minimal_scene()), Contains("unknown key 'a'"));
  }
  SECTION("a value with spaces on one line is not taken for one") {
    CHECK_NOTHROW(scene_from(minimal_scene("", "  kernel: quadratic  # the default\n")));
  }
}

TEST_CASE("scene: an object outside the grid interior says where both are", "[scene]") {
  for (const char* offset : {"[3, 3, 3]", "[0.95, 0.5, 0.5]"}) {
    INFO("offset " << offset);
    std::string yaml = minimal_scene();
    yaml.replace(yaml.find("[0.5, 0.5, 0.5]"), 15, offset);
    try {
      Simulation::create(scene_from(yaml), builtin_registry());
      FAIL("expected a SceneError");
    } catch (const SceneError& e) {
      const std::string m = e.what();
      CHECK_THAT(m, Contains("test.yaml:8:5"));
      CHECK_THAT(m, Contains("outside the grid interior"));
      CHECK_THAT(m, !Contains("samples zero particles"));
      CHECK_THAT(m, Contains("the interior [0.15, 0.15, 0.15] to [0.85, 0.85, 0.85]"));
      if (std::string(offset) == "[3, 3, 3]")
        CHECK_THAT(m, Contains("lies outside the grid interior") &&
                          Contains("the object spans [2.9, 2.9, 2.9] to [3.1, 3.1, 3.1]"));
      else
        CHECK_THAT(m, Contains("lies partly outside the grid interior") &&
                          Contains("the object spans [0.85, 0.4, 0.4] to [1.05, 0.6, 0.6]"));
    }
  }
  // Moved there by --set: the error says so instead of blaming the file's line.
  MaterialRegistry registry = builtin_registry();
  LoadOptions options;
  options.overrides = {parse_override("objects[0].offset=[3, 3, 3]")};
  const SceneDesc s =
      load_scene_from_string(minimal_scene(), test::source_dir() / "scenes/test.yaml", registry,
                             options);
  CHECK_THROWS_WITH(Simulation::create(s, registry),
                    Contains("test.yaml (--set): objects[0].offset") &&
                        Contains("outside the grid interior"));
}

TEST_CASE("scene: an object that starts inside a wall is warned about", "[scene]") {
  const auto warnings_of = [](const std::string& walls) {
    const SceneDesc s = scene_from(minimal_scene() + walls);
    std::unique_ptr<Simulation> sim = Simulation::create(s, builtin_registry());
    std::string all;
    for (const std::string& w : scene_warnings(*sim)) all += w + "\n";
    return all;
  };
  // The cube spans [0.4, 0.6] on every axis.
  CHECK(warnings_of("walls:\n  - plane: {point: [0, 0.2, 0], normal: [0, 1, 0]}\n") == "");
  CHECK(warnings_of("walls:\n  - box: {min: [0.1, 0.1, 0.1], max: [0.9, 0.9, 0.9]}\n") == "");
  const std::string floor =
      warnings_of("walls:\n  - plane: {point: [0, 0.5, 0], normal: [0, 1, 0]}\n");
  CHECK_THAT(floor, Contains("object 'a' starts inside walls[0]"));
  CHECK_THAT(floor, Contains("behind the plane through [0, 0.5, 0]"));
  const std::string box = warnings_of(
      "walls:\n  - plane: {point: [0, 0.2, 0], normal: [0, 1, 0]}\n"
      "  - box: {min: [0.1, 0.1, 0.1], max: [0.9, 0.9, 0.45]}\n");
  CHECK_THAT(box, Contains("object 'a' starts inside walls[1]"));
  CHECK_THAT(box, Contains("outside the box from [0.1, 0.1, 0.1] to [0.9, 0.9, 0.45]"));
  CHECK_THAT(box, !Contains("walls[0]"));
}

TEST_CASE("scene: a body within the kernel's reach of the grid's buffer is warned about",
          "[scene]") {
  // h = 0.05 and a 3-cell buffer: the buffer's innermost node layer is y = 0.15. The cube's
  // bottom at y = 0.18 is 0.6 cells from it, inside the quadratic kernel's 1.5.
  const auto warnings_of = [](const std::string& object_extra, const std::string& walls) {
    std::string yaml = minimal_scene(object_extra) + walls;
    const std::string at = "offset: [0.5, 0.5, 0.5]";
    yaml.replace(yaml.find(at), at.size(), "offset: [0.5, 0.28, 0.5]");
    const SceneDesc s = scene_from(yaml);
    std::unique_ptr<Simulation> sim = Simulation::create(s, builtin_registry());
    std::string all;
    for (const std::string& w : scene_warnings(*sim)) all += w + "\n";
    return all;
  };
  CHECK_THAT(warnings_of("", ""), Contains("particles lie within 1.5 cells of the grid's boundary "
                                           "buffer at y = 0.15 m, with no wall there"));
  // A floor at the buffer's layer or above holds those nodes already; one below does not.
  CHECK(warnings_of("", "walls:\n  - plane: {point: [0, 0.15, 0], normal: [0, 1, 0]}\n") == "");
  CHECK_THAT(warnings_of("", "walls:\n  - plane: {point: [0, 0.1, 0], normal: [0, 1, 0]}\n"),
             Contains("boundary buffer at y = 0.15 m"));
}
