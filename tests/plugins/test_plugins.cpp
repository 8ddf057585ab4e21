// The plugin loader: a good plugin registers its material; each broken one fails with the
// file and the reason, never a crash.
#include <catch2/catch.hpp>

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
