// Table of malformed scenes: each runs `mpm validate` (or `mpm run`) and must exit with the
// documented code and a message that names the place and the problem. Never a crash.
#include <catch2/catch.hpp>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <sys/wait.h>

#include "support/helpers.h"

namespace {

const char* kBase = R"(simulation:
  frames: 2
  dt: 1.0e-3
grid:
  max: [1, 1, 1]
  dims: 20
objects:
  - name: a
    mesh: MESH
    scale: 0.2
    offset: [0.5, 0.5, 0.5]
    mass: 1
    material: corotated
    E: 1.0e4
    nu: 0.3
walls:
  - plane: {point: [0, 0.2, 0], normal: [0, 1, 0]}
    boundary: slip
)";

struct BadScene {
  const char* name;
  const char* find;     ///< Text of kBase to replace ("" appends `replace` at the end).
  const char* replace;  ///< Replacement text.
  std::vector<std::string> words;  ///< Each must appear in the message.
};

std::string replace_all(std::string s, const std::string& a, const std::string& b) {
  for (std::size_t p = s.find(a); p != std::string::npos; p = s.find(a, p + b.size()))
    s.replace(p, a.size(), b);
  return s;
}

/// Runs `mpm ARGS`, returning the exit code and what it printed on stderr.
std::pair<int, std::string> run_mpm(const std::string& args, const std::filesystem::path& dir) {
  const auto err = dir / "stderr.txt";
  const std::string cmd = std::string(MPM_BINARY) + " " + args + " > /dev/null 2> " + err.string();
  const int status = std::system(cmd.c_str());
  std::ifstream in(err);
  std::stringstream text;
  text << in.rdbuf();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, text.str()};
}

}  // namespace

TEST_CASE("malformed scenes exit with code 2 and say where and what", "[scene]") {
  const auto dir = mpm::test::temp_dir("bad_scenes");
  const std::string mesh = mpm::test::cube_mesh();
  std::ofstream(dir / "open.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n";
  std::ofstream(dir / "garbage.obj") << "this is not a mesh\n";
  std::ofstream(dir / "empty.obj") << "";
  const std::vector<BadScene> cases = {
      {"yaml syntax", "dims: 20", "dims: [20, 20", {"YAML syntax error", "bad.yaml:"}},
      {"tab indentation", "  frames: 2", "\tframes: 2", {"YAML syntax error"}},
      {"unknown key typo", "  frames: 2", "  frams: 2", {"bad.yaml:2:3", "did you mean 'frames'"}},
      {"truncated key", "  frames: 2", "  frame: 2", {"bad.yaml:2:3", "did you mean 'frames'"}},
      {"required material key under another name",
       "    E: 1.0e4",
       "    youngs_modulus: 1.0e4",
       {"bad.yaml:14:5", "objects[0].youngs_modulus", "did you mean 'E'",
        "missing required key 'E'"}},
      {"key without its colon, joined to the value above",
       "  dt: 1.0e-3",
       "  dt: 1.0e-3\n    cfl 0.5",
       {"bad.yaml:4:5", "simulation.dt", "colon seems to be missing after 'cfl'", "'cfl: 0.5'"}},
      {"key without its colon, before the next key",
       "  frames: 2",
       "  frames: 2\n  cfl 0.5",
       {"YAML syntax error", "line 3 ('cfl 0.5') seems to be missing a colon"}},
      {"unknown object key",
       "    E: 1.0e4",
       "    E: 1.0e4\n    youngs_modulus: 3",
       {"objects[0].youngs_modulus", "unknown key"}},
      {"unknown top-level section",
       "",
       "output_dir: x\n",
       {"unknown key 'output_dir'", "did you mean 'output'"}},
      {"wrong type: number",
       "  dt: 1.0e-3",
       "  dt: fast",
       {"simulation.dt", "expected a number, found 'fast'"}},
      {"wrong type: list",
       "    offset: [0.5, 0.5, 0.5]",
       "    offset: 0.5",
       {"objects[0].offset", "list of three"}},
      {"wrong type: integer",
       "  frames: 2",
       "  frames: 2.5",
       {"simulation.frames", "whole number"}},
      {"list of two", "  max: [1, 1, 1]", "  max: [1, 1]", {"grid.max", "three numbers"}},
      {"missing grid",
       "grid:\n  max: [1, 1, 1]\n  dims: 20\n",
       "",
       {"missing required key 'grid'"}},
      {"missing material",
       "    material: corotated\n",
       "",
       {"objects[0]", "missing required key 'material'"}},
      {"missing E", "    E: 1.0e4\n", "", {"objects[0].E", "missing required key 'E'"}},
      {"E zero", "E: 1.0e4", "E: 0", {"objects[0].E", "out of range", "> 0"}},
      {"nu too large", "nu: 0.3", "nu: 0.5", {"objects[0].nu", "(-1, 0.5)"}},
      {"nu too small", "nu: 0.3", "nu: -1", {"objects[0].nu", "out of range"}},
      {"negative mass", "mass: 1", "mass: -2", {"objects[0].mass", "out of range"}},
      {"mass and density", "mass: 1", "mass: 1\n    density: 1000", {"not both"}},
      {"neither mass nor density", "    mass: 1\n", "", {"'mass' (kg) or 'density'"}},
      {"dims zero", "dims: 20", "dims: 0", {"grid.dims", "out of range"}},
      {"buffer too large",
       "dims: 20",
       "dims: 20\n  buffer: 10",
       {"grid.buffer", "leaves no interior"}},
      {"negative frames", "frames: 2", "frames: -1", {"simulation.frames", "out of range"}},
      {"dt zero", "dt: 1.0e-3", "dt: 0", {"simulation.dt", "out of range"}},
      {"cfl above one", "dt: 1.0e-3", "cfl: 1.5", {"simulation.cfl", "(0, 1]"}},
      {"no time step", "  dt: 1.0e-3\n", "", {"'dt'", "'cfl'"}},
      {"particles per cell zero",
       "    mass: 1",
       "    mass: 1\n    particles_per_cell: 0",
       {"particles_per_cell", "out of range"}},
      {"zero wall normal",
       "normal: [0, 1, 0]",
       "normal: [0, 0, 0]",
       {"walls[0].plane.normal", "must not be zero"}},
      {"box min above max",
       "  - plane: {point: [0, 0.2, 0], normal: [0, 1, 0]}",
       "  - box: {min: [0.5, 0, 0], max: [0.4, 1, 1]}",
       {"walls[0].box.max", "exceed"}},
      {"plane and box",
       "    boundary: slip",
       "    box: {min: [0, 0, 0], max: [1, 1, 1]}\n    boundary: slip",
       {"exactly one of 'plane', 'box', 'mesh', 'sphere' or 'vdb'"}},
      {"unknown boundary",
       "boundary: slip",
       "boundary: sticy",
       {"walls[0].boundary", "sticky, slip or separate"}},
      {"collider sphere of zero radius",
       "",
       "  - sphere: {center: [0.5, 0.5, 0.5], radius: 0}\n",
       {"bad.yaml:19:", "walls[1].sphere.radius", "out of range", "> 0"}},
      {"collider sphere of negative radius",
       "",
       "  - sphere: {center: [0.5, 0.5, 0.5], radius: -1}\n",
       {"bad.yaml:19:", "walls[1].sphere.radius", "out of range"}},
      {"open collider mesh",
       "",
       "  - mesh: {file: OPEN}\n",
       {"bad.yaml:19:", "walls[1].mesh.file", "not closed"}},
      {"empty collider mesh",
       "",
       "  - mesh: {file: EMPTY}\n",
       {"bad.yaml:19:", "walls[1].mesh.file"}},
      {"missing vdb file",
       "",
       "  - vdb: {file: nowhere.vdb, grid: surface}\n",
       {"bad.yaml:19:", "walls[1].vdb.file", "does not exist"}},
      {"vdb without a grid name",
       "",
       "  - vdb: {file: nowhere.vdb}\n",
       {"bad.yaml:19:", "walls[1].vdb", "missing required key 'grid'"}},
      {"a plane that spins",
       "    boundary: slip",
       "    boundary: slip\n    angular_velocity: [0, 0, 1]",
       {"walls[0].angular_velocity", "only colliders"}},
      {"unknown transfer",
       "dt: 1.0e-3",
       "dt: 1.0e-3\n  transfer: mpm",
       {"simulation.transfer", "apic, pic, flip or mls"}},
      {"mls with the linear kernel",
       "dt: 1.0e-3",
       "dt: 1.0e-3\n  transfer: mls\n  kernel: linear",
       {"simulation.transfer", "needs kernel quadratic or cubic"}},
      {"unknown kernel",
       "dt: 1.0e-3",
       "dt: 1.0e-3\n  kernel: quintic",
       {"simulation.kernel", "quadratic, linear or cubic"}},
      {"unknown quadrature",
       "dt: 1.0e-3",
       "dt: 1.0e-3\n  quadrature: gauss",
       {"simulation.quadrature", "point or domain"}},
      {"domain quadrature with the cubic kernel",
       "dt: 1.0e-3",
       "dt: 1.0e-3\n  kernel: cubic\n  quadrature: domain",
       {"bad.yaml:5:15", "simulation.quadrature", "needs kernel quadratic"}},
      {"domain quadrature with a float grid",
       "  dt: 1.0e-3\ngrid:\n",
       "  dt: 1.0e-3\n  quadrature: domain\ngrid:\n  precision: float\n",
       {"bad.yaml:4:", "simulation.quadrature", "grid.precision double"}},
      {"negative damping",
       "dt: 1.0e-3",
       "dt: 1.0e-3\n  damping: -1",
       {"simulation.damping", "out of range"}},
      {"unknown sampling",
       "    mass: 1",
       "    mass: 1\n    sampling: grid",
       {"objects[0].sampling", "jittered or regular"}},
      {"regular sampling of a non-cube count",
       "    mass: 1",
       "    mass: 1\n    particles_per_cell: 6\n    sampling: regular",
       {"objects[0].sampling", "cube", "not 6"}},
      {"velocity_gradient not 3x3",
       "    mass: 1",
       "    mass: 1\n    velocity_gradient: [1, 0, 0]",
       {"objects[0].velocity_gradient", "three rows of three"}},
      {"angular_velocity not a vector",
       "    mass: 1",
       "    mass: 1\n    angular_velocity: 4",
       {"objects[0].angular_velocity", "list of three"}},
      {"unknown material",
       "material: corotated",
       "material: jelly",
       {"unknown material 'jelly'", "corotated", "neo_hookean", "snow"}},
      {"material key of another material",
       "    E: 1.0e4",
       "    E: 1.0e4\n    hardening: 3",
       {"objects[0].hardening", "unknown key"}},
      {"missing mesh",
       "mesh: MESH",
       "mesh: nowhere.obj",
       {"bad.yaml:9:11", "objects[0].mesh", "does not exist"}},
      {"open mesh", "mesh: MESH", "mesh: OPEN", {"objects[0].mesh", "not closed"}},
      {"unparsable mesh",
       "mesh: MESH",
       "mesh: GARBAGE",
       {"objects[0].mesh", "garbage.obj", "no triangles"}},
      {"empty mesh", "mesh: MESH", "mesh: EMPTY", {"objects[0].mesh"}},
      {"object outside the grid",
       "offset: [0.5, 0.5, 0.5]",
       "offset: [0.95, 0.5, 0.5]",
       {"objects[0]", "partly outside the grid interior",
        "spans [0.85, 0.4, 0.4] to [1.05, 0.6, 0.6]",
        "the interior [0.15, 0.15, 0.15] to [0.85, 0.85, 0.85]"}},
      {"object entirely outside the grid",
       "offset: [0.5, 0.5, 0.5]",
       "offset: [3, 0.5, 0.5]",
       {"bad.yaml:8:5", "objects[0].offset", "object 'a' lies outside the grid interior",
        "spans [2.9, 0.4, 0.4] to [3.1, 0.6, 0.6]", "the interior [0.15"}},
      {"object in the buffer",
       "offset: [0.5, 0.5, 0.5]",
       "offset: [0.5, 0.14, 0.5]",
       {"outside the grid interior"}},
      {"object that samples nothing", "scale: 0.2", "scale: 0.001", {"samples zero particles"}},
      {"duplicate object names",
       "walls:",
       "  - {name: a, mesh: MESH, scale: 0.1, offset: [0.3, 0.3, 0.3], mass: 1, material: "
       "corotated, E: 1.0e4, nu: 0.3}\nwalls:",
       {"objects[1].name", "used twice"}},
      {"no objects", "objects:", "objects: []\nunused:", {"objects"}},
      {"plugin that is missing",
       "",
       "plugins: [libnothing.so]\n",
       {"plugins[0]", "not found; searched:"}},
      {"grid too large for memory", "dims: 20", "dims: 100000", {"grid.dims", "GB of memory"}},
      {"a list where a mapping belongs",
       "simulation:\n  frames: 2\n  dt: 1.0e-3\n",
       "simulation: [1, 2]\n",
       {"simulation", "expected a mapping"}},
      {"scene that is not a mapping", "", "- just a list\n", {"bad.yaml"}},
  };
  REQUIRE(cases.size() >= 30);
  for (const BadScene& c : cases) {
    INFO("case: " << c.name);
    std::string yaml = kBase;
    if (std::string(c.find).empty()) {
      yaml += c.replace;
    } else {
      REQUIRE(yaml.find(c.find) != std::string::npos);
      yaml = replace_all(yaml, c.find, c.replace);
    }
    if (std::string(c.name) == "scene that is not a mapping") yaml = c.replace;
    yaml = replace_all(yaml, "MESH", mesh);
    yaml = replace_all(yaml, "OPEN", (dir / "open.obj").string());
    yaml = replace_all(yaml, "GARBAGE", (dir / "garbage.obj").string());
    yaml = replace_all(yaml, "EMPTY", (dir / "empty.obj").string());
    std::ofstream(dir / "bad.yaml") << yaml;
    const auto [code, message] = run_mpm("validate " + (dir / "bad.yaml").string(), dir);
    INFO("message: " << message);
    CHECK(code == 2);
    CHECK(message.rfind("error: ", 0) == 0);
    for (const std::string& w : c.words) CHECK(message.find(w) != std::string::npos);
  }
}

TEST_CASE("bad command lines and overrides exit with code 2", "[scene]") {
  const auto dir = mpm::test::temp_dir("bad_cli");
  const std::string scene = (mpm::test::source_dir() / "scenes/jello_cube.yaml").string();
  struct Cli {
    std::string args;
    std::vector<std::string> words;
  };
  std::ofstream(dir / "old.summary.yaml") << "frames: []\n";  // a golden already there
  const std::filesystem::path ran = dir / "ran";              // an earlier run's output
  std::filesystem::create_directories(ran);
  std::ofstream(ran / "frame_00000.h5") << "old";
  const std::vector<Cli> cases = {
      {"", {"no command"}},
      {"fly " + scene, {"unknown command 'fly'"}},
      {"run", {"needs a scene file"}},
      {"run " + scene + " --frames x", {"--frames expects a whole number"}},
      {"run " + scene + " --threads 0", {"--threads expects a whole number >= 1"}},
      {"run " + scene + " --bogus", {"unknown option '--bogus'"}},
      {"validate " + scene + " --set grid.dims", {"expected KEY=VALUE"}},
      {"validate " + scene + " --set objects[0].nu=0.7",
       {"(--set)", "objects[0].nu", "out of range"}},
      {"validate " + scene + " --set objects[3].E=1", {"has no entry [3]"}},
      {"validate " + scene + " --set simulation.frams=3", {"did you mean 'frames'"}},
      {"validate " + scene + " --set object[1].nu=0.2",
       {"there is no list 'object'", "did you mean 'objects'"}},
      {"validate " + scene + " --set objects[0].offset=[3,3,3]",
       {"(--set)", "objects[0].offset", "outside the grid interior"}},
      {"validate " + scene + " --frames 3", {"'mpm validate' does not take --frames"}},
      {"validate " + scene + " --out " + (dir / "x").string(),
       {"'mpm validate' does not take --out"}},
      {"materials " + scene + " --set objects[0].E=1", {"'mpm materials' does not take --set"}},
      {"golden " + scene + " --frames 1 -o " + (dir / "old.summary.yaml").string(),
       {"old.summary.yaml' exists", "--force"}},
      {"golden " + scene + " --frames 1 --format png -o " + (dir / "g.yaml").string(),
       {"'mpm golden' does not take --format"}},
      {"compare " + scene + " " + scene + " --set a=1", {"'mpm compare' does not take --set"}},
      {"validate /nonexistent/scene.yaml", {"/nonexistent/scene.yaml", "no such file"}},
      {"run " + scene + " --out /proc/forbidden", {"--out", "cannot create output folder"}},
      {"run " + scene + " --out " + ran.string(), {"--out", "already holds results", "--force"}},
      // Refused before the build: an object that samples nothing fails only in the build.
      {"run " + scene + " --out " + ran.string() + " --set objects[0].scale=0.001",
       {"--out", "already holds results"}},
      {"run " + scene + " --out " + ran.string() + " --force --set objects[0].scale=0.001",
       {"samples zero particles"}},
      {"study --quick", {"'mpm study' needs -o DIR"}},
      {"bench --cases jello --simd AVX9", {"--simd expects on, off or an instruction set", "AVX9"}},
      {"study --cases h_convergance -o " + (dir / "study").string(),
       {"unknown study sweep", "h_convergence"}},
  };
  for (const Cli& c : cases) {
    INFO("mpm " << c.args);
    const auto [code, message] = run_mpm(c.args, dir);
    INFO("message: " << message);
    CHECK(code == 2);
    for (const std::string& w : c.words) CHECK(message.find(w) != std::string::npos);
  }
  // A scene that fails to build, even with --force, leaves the earlier run's results.
  CHECK(std::filesystem::exists(ran / "frame_00000.h5"));
}

TEST_CASE("overrides change the scene like the file would", "[scene]") {
  mpm::MaterialRegistry registry = mpm::builtin_registry();
  mpm::LoadOptions options;
  options.overrides = {mpm::parse_override("grid.dims=64"),
                       mpm::parse_override("objects[0].E=2e4"),
                       mpm::parse_override("simulation.gravity=[0, 0, 0]"),
                       mpm::parse_override("simulation.cfl=0.4")};
  const mpm::SceneDesc s =
      mpm::load_scene(mpm::test::source_dir() / "scenes/jello_cube.yaml", registry, options);
  CHECK(s.grid.dims == mpm::Vec3i(64, 64, 64));
  CHECK(s.objects[0].params.at("E") == Approx(2e4));
  CHECK(s.simulation.gravity.norm() == 0);
  CHECK(s.simulation.cfl == Approx(0.4));
}
