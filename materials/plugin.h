#pragma once
/// \file Material plugins: shared libraries, built outside the engine, that add materials.
///
/// A plugin includes this header and declares its registration function with
/// MPM_DECLARE_PLUGIN; the engine loads it with load_plugin() when a scene lists it under
/// `plugins:`. See docs/materials.md.

#include <filesystem>
#include <stdexcept>

#include "materials/registry.h"

namespace mpm {

/// Bumped whenever MaterialInfo, MaterialGroup or MaterialRegistry change layout. The last
/// digit is sizeof(StoredReal): a plugin built for float particle storage cannot load into a
/// double build, or the other way round.
inline constexpr int kPluginAbiVersion = 50 + static_cast<int>(sizeof(StoredReal));

/// A plugin that cannot be used. The message names the file and the reason.
class PluginError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Loads the shared library `file` and adds its materials to `registry`. Loading the same
/// file twice is a no-op. Throws PluginError if the file cannot be loaded, is not an mpm
/// plugin, was built for another ABI version, registers nothing, or registers a taken name.
void load_plugin(const std::filesystem::path& file, MaterialRegistry& registry);

}  // namespace mpm

/// Defines the two C entry points the engine looks for; `register_fn` is a function
/// void(mpm::MaterialRegistry&) that adds the plugin's materials.
#define MPM_DECLARE_PLUGIN(register_fn)                                                 \
  extern "C" int mpm_plugin_abi_version() { return mpm::kPluginAbiVersion; }           \
  extern "C" void mpm_register_materials(mpm::MaterialRegistry& registry) {            \
    register_fn(registry);                                                              \
  }
