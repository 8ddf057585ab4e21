/// \file libFuzzer target: the scene loader and validator must never crash, leak or hang.
///
/// Each input is a scene file. Lines starting with "#set " (YAML comments, so the document is
/// unchanged) are also applied as `--set KEY=VALUE` overrides. A SceneError is the expected
/// answer to bad input; any other exception, a crash, a sanitizer report, a leak, a hang, or a
/// loaded scene that breaks a promise of SceneDesc is a bug. Only loads and validates: no mesh
/// is read, no grid allocated, no plugin loaded. Built with -DMPM_FUZZ=ON; run by run_fuzz.sh.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <set>
#include <string>
#include <vector>

#include "engine/core/error.h"
#include "engine/scene/load_scene.h"
#include "materials/registry.h"

namespace {

/// Where the fuzzed scene pretends to live, so relative mesh paths resolve into scenes/.
const char* const kSceneFile = MPM_SOURCE_DIR "/scenes/fuzz.yaml";

/// Reports a broken promise of a scene that loaded without error, and stops.
[[noreturn]] void broken(const std::string& what) {
  std::fprintf(stderr, "fuzz_scene: the loader accepted a scene that %s\n", what.c_str());
  std::abort();
}

/// The `#set KEY=VALUE` lines of `text` as overrides; throws SceneError like `--set`.
std::vector<mpm::SceneOverride> overrides_in(const std::string& text) {
  std::vector<mpm::SceneOverride> out;
  const std::string tag = "#set ";
  for (std::size_t start = 0; start < text.size();) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    if (text.compare(start, tag.size(), tag) == 0)
      out.push_back(mpm::parse_override(text.substr(start + tag.size(), end - start - tag.size())));
    start = end + 1;
  }
  return out;
}

/// What Simulation::create() relies on: checks it for a scene the loader accepted.
void check_scene(const mpm::SceneDesc& s, const mpm::MaterialRegistry& registry) {
  if (!s.simulation.dt && !s.simulation.cfl) broken("has neither dt nor cfl");
  const mpm::GridDesc& g = s.grid;
  if (g.dims.minCoeff() < 1) broken("has a grid axis without cells");
  if (2 * g.buffer + 1 > g.dims.minCoeff()) broken("has no grid interior");
  const mpm::Vec3 h = g.spacing();
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(h[a]) || !(h[a] > 0)) broken("has a cell size that is not finite and > 0");
  if (s.objects.empty()) broken("has no object");
  std::set<std::string> names;
  for (const mpm::ObjectDesc& o : s.objects) {
    if (!names.insert(o.name).second) broken("uses an object name twice");
    if (o.mass.has_value() == o.density.has_value()) broken("has not exactly one of mass, density");
    const mpm::MaterialInfo* info = registry.find(o.material);
    if (!info) broken("names an unknown material");
    for (const mpm::ParamSpec& spec : info->params)
      if (!o.params.count(spec.name)) broken("lacks material parameter " + spec.name);
  }
  for (const mpm::WallDesc& w : s.walls)
    if (w.shape == mpm::WallDesc::Shape::plane && !(std::abs(w.normal.norm() - 1) < 1e-9))
      broken("has a wall normal that is not a unit vector");
}

}  // namespace

/// libFuzzer's entry point: loads `data` as a scene file. Returns 0 (input kept if useful).
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  mpm::MaterialRegistry registry = mpm::builtin_registry();
  mpm::LoadOptions options;
  options.load_plugins = false;  // never dlopen a path taken from fuzzed input
  try {
    options.overrides = overrides_in(text);
    const mpm::SceneDesc scene = mpm::load_scene_from_string(text, kSceneFile, registry, options);
    check_scene(scene, registry);
  } catch (const mpm::SceneError&) {
    // The expected answer to a bad scene.
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fuzz_scene: unexpected exception (not SceneError): %s\n", e.what());
    std::abort();
  }
  return 0;
}
