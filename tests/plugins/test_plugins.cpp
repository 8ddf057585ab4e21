// The plugin loader: a good plugin registers its material; each broken one fails with the
// file and the reason, never a crash.
#include <catch2/catch.hpp>

#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "materials/plugin.h"
#include "support/helpers.h"

using namespace mpm;
using Catch::Matchers::Contains;

namespace {

std::string load_error(const std::string& file) {
  MaterialRegistry r = builtin_registry();
  try {
    load_plugin(file, r);
  } catch (const PluginError& e) {
    return e.what();
  }
  FAIL("expected a PluginError for " << file);
  return "";
}

/// Runs `mpm ARGS` (with `env` before it, e.g. "MPM_PLUGIN_PATH=/x"), returning the exit code
/// and what it printed on stderr.
std::pair<int, std::string> run_mpm(const std::string& args, const std::filesystem::path& dir,
                                    const std::string& env = "") {
  const auto err = dir / "stderr.txt";
  const std::string cmd = "env -u MPM_PLUGIN_PATH " + env + " " + MPM_BINARY + " " + args +
                          " > /dev/null 2> " + err.string();
  const int status = std::system(cmd.c_str());
  std::ifstream in(err);
  std::stringstream text;
  text << in.rdbuf();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, text.str()};
}

/// A one-object scene of `material` with the given E and nu (the object is on line 5), that
/// lists `plugin` (if not empty).
std::string plugin_scene(const std::string& plugin, const std::string& material,
                         const std::string& E = "1.0e4", const std::string& nu = "0.3") {
  return (plugin.empty() ? std::string("\n") : "plugins: [" + plugin + "]\n") +
         "simulation: {frames: 1, frame_dt: 0.01, dt: 1.0e-3}\n"
         "grid: {max: [1, 1, 1], dims: 16}\n"
         "objects:\n"
         "  - name: cube\n"
         "    mesh: " + test::cube_mesh() + "\n"
         "    scale: 0.3\n"
         "    offset: [0.5, 0.5, 0.5]\n"
         "    density: 1000\n"
         "    material: " + material + "\n"
         "    E: " + E + "\n"
         "    nu: " + nu + "\n";
}

}  // namespace

TEST_CASE("plugins: the example plugin registers stvk, once", "[plugins]") {
  MaterialRegistry r = builtin_registry();
  load_plugin(MPM_STVK_PLUGIN, r);
  REQUIRE(r.find("stvk"));
  CHECK(r.find("stvk")->params.size() == 2);
  const std::size_t n = r.all().size();
  load_plugin(MPM_STVK_PLUGIN, r);  // the same file again is a no-op
  CHECK(r.all().size() == n);
}

TEST_CASE("plugins: broken plugins fail with file and reason", "[plugins]") {
  CHECK_THAT(load_error("/nonexistent/libnothing.so"), Contains("no such file"));
  CHECK_THAT(load_error(MPM_SOURCE_DIR "/README.md"), Contains("cannot be loaded"));
  CHECK_THAT(load_error(BAD_PLUGIN_NO_ENTRY), Contains("not an mpm plugin"));
  CHECK_THAT(load_error(BAD_PLUGIN_EMPTY), Contains("registers no material"));
  CHECK_THAT(load_error(BAD_PLUGIN_DUPLICATE), Contains("'corotated', a name already taken"));
  CHECK_THAT(load_error(BAD_PLUGIN_ABI), Contains("plugin ABI"));
  CHECK_THAT(load_error(BAD_PLUGIN_EMPTY), Contains(BAD_PLUGIN_EMPTY));
}

TEST_CASE("plugins: a scene with a broken plugin names the scene line", "[plugins]") {
  const std::string yaml = std::string("plugins: [") + BAD_PLUGIN_EMPTY + "]\n" +
                           "simulation: {dt: 1.0e-3}\ngrid: {max: [1, 1, 1], dims: 10}\n";
  try {
    test::scene_from(yaml);
    FAIL("expected a SceneError");
  } catch (const SceneError& e) {
    CHECK_THAT(e.what(), Contains("test.yaml:1:11"));
    CHECK_THAT(e.what(), Contains("plugins[0]"));
    CHECK_THAT(e.what(), Contains("registers no material"));
  }
}

TEST_CASE("plugins: a factory that rejects its parameters is a scene error at the object",
          "[plugins]") {
  const auto dir = test::temp_dir("plugin_throws");
  std::ofstream(dir / "stiff.yaml") << plugin_scene(BAD_PLUGIN_THROWS, "picky", "2.0e6", "0.45");
  std::ofstream(dir / "fine.yaml") << plugin_scene(BAD_PLUGIN_THROWS, "picky", "2.0e6", "0.3");
  for (const std::string command : {"validate", "run"}) {
    INFO("mpm " << command);
    const std::string out = command == "run" ? " --out " + (dir / "out").string() : "";
    const auto [code, message] = run_mpm(command + " " + (dir / "stiff.yaml").string() + out, dir);
    CHECK(code == 2);
    CHECK_THAT(message, Contains("stiff.yaml:5:5: objects[0]"));
    CHECK_THAT(message, Contains("material 'picky' rejects the parameters of object 'cube'"));
    CHECK_THAT(message, Contains("too stiff for this model"));
    CHECK_THAT(message, !Contains("terminate"));
  }
  CHECK(run_mpm("validate " + (dir / "fine.yaml").string(), dir).first == 0);
}

TEST_CASE("plugins: only from places the user chose", "[plugins]") {
  const auto dir = test::temp_dir("plugin_places");
  // A copy under a name the engine's lib/ does not hold: found only beside the scene.
  std::filesystem::copy_file(MPM_STVK_PLUGIN, dir / "libmy_stvk.so");
  std::ofstream(dir / "beside.yaml") << plugin_scene("libmy_stvk.so", "stvk");
  std::ofstream(dir / "relative.yaml") << plugin_scene("./libmy_stvk.so", "stvk");
  std::ofstream(dir / "none.yaml") << plugin_scene("", "stvk");
  const std::string beside = (dir / "beside.yaml").string();
  const std::string relative = (dir / "relative.yaml").string();
  const std::string plugin = (dir / "libmy_stvk.so").string();

  SECTION("a plugin beside the scene is refused, and the message says how to allow it") {
    for (const std::string command : {"validate", "run", "materials"}) {
      INFO("mpm " << command);
      const std::string out = command == "run" ? " --out " + (dir / "out").string() : "";
      const auto [code, message] = run_mpm(command + " " + beside + out, dir);
      CHECK(code == 2);
      CHECK_THAT(message, Contains("beside.yaml:1:11: plugins[0]"));
      CHECK_THAT(message, Contains("found only beside the scene"));
      CHECK_THAT(message, Contains("--allow-scene-plugins"));
    }
    CHECK(!std::filesystem::exists(dir / "out"));
  }
  SECTION("a path relative to the scene is refused too") {
    const auto [code, message] = run_mpm("validate " + relative, dir);
    CHECK(code == 2);
    CHECK_THAT(message, Contains("relative.yaml:1:11: plugins[0]"));
    CHECK_THAT(message, Contains("--allow-scene-plugins"));
  }
  SECTION("--allow-scene-plugins loads them") {
    CHECK(run_mpm("validate " + beside + " --allow-scene-plugins", dir).first == 0);
    CHECK(run_mpm("validate " + relative + " --allow-scene-plugins", dir).first == 0);
  }
  SECTION("--plugin PATH loads a plugin, and the scene's entry of its name uses it") {
    CHECK(run_mpm("validate " + beside + " --plugin " + plugin, dir).first == 0);
    CHECK(run_mpm("validate " + relative + " --plugin " + plugin, dir).first == 0);
    CHECK(run_mpm("validate " + (dir / "none.yaml").string() + " --plugin " + plugin, dir).first ==
          0);
    const auto [code, message] = run_mpm("validate " + beside + " --plugin /nonexistent/x.so", dir);
    CHECK(code == 2);
    CHECK_THAT(message, Contains("--plugin /nonexistent/x.so"));
    CHECK_THAT(message, Contains("no such file"));
  }
  SECTION("a folder of $MPM_PLUGIN_PATH is a place the user chose") {
    const std::string env = "MPM_PLUGIN_PATH=/nonexistent:" + dir.string();
    CHECK(run_mpm("validate " + beside, dir, env).first == 0);
    CHECK(run_mpm("validate " + relative, dir, env).first == 0);
  }
}

TEST_CASE("plugins: a plugin not found lists the folders searched; an unknown material says "
          "how to load a plugin",
          "[plugins]") {
  const auto dir = test::temp_dir("plugin_missing");
  std::ofstream(dir / "missing.yaml") << plugin_scene("libnowhere.so", "stvk");
  std::ofstream(dir / "unknown.yaml") << plugin_scene("", "stvk");
  {
    const auto [code, message] =
        run_mpm("validate " + (dir / "missing.yaml").string(), dir, "MPM_PLUGIN_PATH=/opt/mine");
    CHECK(code == 2);
    CHECK_THAT(message, Contains("missing.yaml:1:11: plugins[0]"));
    CHECK_THAT(message, Contains("plugin 'libnowhere.so' not found; searched:"));
    CHECK_THAT(message, Contains("/opt/mine ($MPM_PLUGIN_PATH)"));
    const std::string lib = std::filesystem::path(MPM_BINARY).parent_path().parent_path() / "lib";
    CHECK_THAT(message, Contains(lib + " (the lib/ beside the engine's bin/)"));
  }
  {
    const auto [code, message] = run_mpm("validate " + (dir / "unknown.yaml").string(), dir);
    CHECK(code == 2);
    CHECK_THAT(message, Contains("unknown material 'stvk'"));
    CHECK_THAT(message, Contains("list it under 'plugins:' or give --plugin PATH"));
  }
}

TEST_CASE("plugins: the example's wave speed bounds the acoustic speed, exactly at rest",
          "[plugins]") {
  MaterialRegistry r = builtin_registry();
  load_plugin(MPM_STVK_PLUGIN, r);
  const MaterialInfo& m = *r.find("stvk");
  const checks::OneParticle p(m);  // E = 1e4, nu = 0.3 (the defaults), rho0 = 1000
  const Lame l = lame_from_young(1.0e4, 0.3);
  const double rho0 = 1000;
  CHECK(p.wave_speed(Mat3::Identity()) ==
        Approx(std::sqrt((l.lambda + 2 * l.mu) / rho0)).epsilon(1e-12));
  // rho0 c^2 = A(a, F^T m) for polarisation a and current normal m, A(a, N) the second
  // derivative of psi along a N^T: by central differences of P.
  auto acoustic = [&](const Mat3& F, const Vec3& a, const Vec3& m_dir) {
    const Vec3 N = F.transpose() * m_dir;
    const Mat3 dF = a * N.transpose();
    const double t = 1e-3;
    return ((p.first_piola(F + t * dF) - p.first_piola(F - t * dF)).cwiseProduct(dF)).sum() /
           (2 * t);
  };
  // A uniaxial stretch along a = m is where the bound is exact.
  for (double s : {1.1, 1.3, 1.6}) {
    const Mat3 F = Vec3(s, 1, 1).asDiagonal();
    const double c = p.wave_speed(F);
    INFO("stretch " << s);
    CHECK(rho0 * c * c == Approx(acoustic(F, Vec3::UnitX(), Vec3::UnitX())).epsilon(1e-3));
  }
  std::mt19937 rng(7);
  std::normal_distribution<double> n;
  for (int k = 0; k < 200; ++k) {
    const Mat3 F = checks::random_rotation(rng) * checks::random_near_identity(rng, 0.4);
    const Vec3 a = Vec3(n(rng), n(rng), n(rng)).normalized();
    const Vec3 dir = Vec3(n(rng), n(rng), n(rng)).normalized();
    const double c = p.wave_speed(F);
    INFO("F =\n" << F << "\na = " << a.transpose() << ", m = " << dir.transpose());
    CHECK(rho0 * c * c >= acoustic(F, a, dir) * (1 - 1e-3));
  }
}
