// Deliberately broken plugins, one per BAD_* definition, for the loader's error tests.
#include <memory>
#include <stdexcept>

#include "materials/elastic_group.h"
#include "materials/corotated.h"
#include "materials/plugin.h"

namespace {

[[maybe_unused]] mpm::MaterialInfo named(const char* name) {
  return {name, "test", "none", mpm::elastic_param_specs(), true,
          [](const mpm::ParamValues&, const mpm::GroupInfo& g) {
            return std::make_unique<mpm::materials::ElasticGroup<mpm::materials::FixedCorotated>>(
                mpm::materials::FixedCorotated{1, 1}, g.density);
          }};
}

}  // namespace

#if defined(BAD_EMPTY)
void register_nothing(mpm::MaterialRegistry&) {}
MPM_DECLARE_PLUGIN(register_nothing)
#elif defined(BAD_DUPLICATE)
void register_taken(mpm::MaterialRegistry& r) { r.add(named("corotated")); }
MPM_DECLARE_PLUGIN(register_taken)
#elif defined(BAD_ABI)
extern "C" int mpm_plugin_abi_version() { return mpm::kPluginAbiVersion + 100; }
extern "C" void mpm_register_materials(mpm::MaterialRegistry& r) { r.add(named("future")); }
#elif defined(BAD_NO_ENTRY)
extern "C" int some_other_function() { return 1; }
#elif defined(BAD_THROWS)
// A material whose factory rejects a combination of parameters, as docs/materials.md shows.
void register_picky(mpm::MaterialRegistry& r) {
  mpm::MaterialInfo m = named("picky");
  auto build = m.create;
  m.create = [build](const mpm::ParamValues& v, const mpm::GroupInfo& g) {
    if (v.at("E") > 1e6 && v.at("nu") > 0.4)
      throw std::invalid_argument("E > 1e6 with nu > 0.4 is too stiff for this model");
    return build(v, g);
  };
  r.add(m);
}
MPM_DECLARE_PLUGIN(register_picky)
#endif
