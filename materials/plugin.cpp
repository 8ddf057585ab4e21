#include "materials/plugin.h"

#include <dlfcn.h>

namespace mpm {

void load_plugin(const std::filesystem::path& file, MaterialRegistry& registry) {
  const std::string name = "plugin '" + file.string() + "'";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec))
    throw PluginError(name + ": no such file (build it first? see docs/materials.md)");
  const std::filesystem::path canonical = std::filesystem::canonical(file, ec);
  if (registry.loaded_plugins().count(canonical)) return;

  // Never closed: the registry keeps factories that point into the library.
  void* handle = dlopen(canonical.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!handle) throw PluginError(name + ": cannot be loaded: " + dlerror());
  using AbiFn = int (*)();
  using RegisterFn = void (*)(MaterialRegistry&);
  auto abi = reinterpret_cast<AbiFn>(dlsym(handle, "mpm_plugin_abi_version"));
  auto reg = reinterpret_cast<RegisterFn>(dlsym(handle, "mpm_register_materials"));
  if (!abi || !reg)
    throw PluginError(name + ": not an mpm plugin (it exports no mpm_plugin_abi_version and "
                             "mpm_register_materials; use MPM_DECLARE_PLUGIN)");
  if (abi() != kPluginAbiVersion)
    throw PluginError(name + ": built for plugin ABI " + std::to_string(abi()) +
                      ", this engine has ABI " + std::to_string(kPluginAbiVersion) +
                      "; rebuild the plugin");
  MaterialRegistry added;
  try {
    reg(added);
  } catch (const std::exception& e) {
    throw PluginError(name + ": failed while registering: " + e.what());
  }
  if (added.all().empty()) throw PluginError(name + ": registers no material");
  for (const MaterialInfo& m : added.all())
    if (registry.find(m.name))
      throw PluginError(name + ": registers material '" + m.name +
                        "', a name already taken; registered: " + registry.names());
  for (const MaterialInfo& m : added.all()) registry.add(m);
  registry.loaded_plugins().insert(canonical);
}

}  // namespace mpm
