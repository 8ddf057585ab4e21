// mpm_material_check: the generic material checks (materials/material_checks.h) on the
// materials a plugin registers. CMake's mpm_add_material_tests runs it as a test.
#include <cstdio>
#include <exception>
#include <set>
#include <string>
#include <vector>

#include "materials/material_checks.h"
#include "materials/plugin.h"

namespace {

constexpr const char* kUsage = R"(mpm_material_check - the generic material checks on a plugin

Usage:
  mpm_material_check PLUGIN.so [MATERIAL ...]

Loads PLUGIN.so as mpm would and runs, on every material it registers (or only the named
ones): zero stress at rest and under rotation; P = dpsi/dF by central differences; frame
indifference and isotropy; finite results for nearly singular and inverted F (if the material
supports inversion); a positive wave speed that grows with stiffness (docs/materials.md).

Exit codes: 0 every check passed; 1 a check failed; 2 bad usage or a plugin that cannot load.
)";

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    std::fputs(kUsage, args.empty() ? stderr : stdout);
    return args.empty() ? 2 : 0;
  }
  mpm::MaterialRegistry registry = mpm::builtin_registry();
  std::set<std::string> builtin;
  for (const mpm::MaterialInfo& m : registry.all()) builtin.insert(m.name);
  try {
    mpm::load_plugin(args[0], registry);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
  std::vector<const mpm::MaterialInfo*> materials;
  if (args.size() == 1) {
    for (const mpm::MaterialInfo& m : registry.all())
      if (!builtin.count(m.name)) materials.push_back(&m);
  }
  for (std::size_t i = 1; i < args.size(); ++i) {
    const mpm::MaterialInfo* m = registry.find(args[i]);
    if (!m || builtin.count(args[i])) {
      std::fprintf(stderr, "error: %s registers no material '%s'\n", args[0].c_str(),
                   args[i].c_str());
      return 2;
    }
    materials.push_back(m);
  }
  int failed = 0, passed = 0;
  for (const mpm::MaterialInfo* m : materials) {
    for (const mpm::checks::Check& c : mpm::checks::all_checks()) {
      mpm::checks::Failures failures;
      try {
        failures = c.run(*m);
      } catch (const std::exception& e) {
        failures.push_back(std::string("threw: ") + e.what());
      }
      const bool skipped = std::string(c.name) == "inversion" && !m->supports_inversion;
      std::printf("%-6s %s: %s%s\n", failures.empty() ? "ok" : "FAILED", m->name.c_str(), c.what,
                  skipped ? " (skipped: the material does not support inversion)" : "");
      for (const std::string& f : failures) std::printf("%s", f.c_str());
      (failures.empty() ? passed : failed) += 1;
    }
  }
  std::printf("%d checks passed, %d failed, on %zu material(s) of %s\n", passed, failed,
              materials.size(), args[0].c_str());
  return failed > 0 ? 1 : 0;
}
