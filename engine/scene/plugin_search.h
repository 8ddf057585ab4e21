#pragma once
/// \file Where a scene's material plugins may come from: only the places the user chose.

#include <filesystem>
#include <string>
#include <vector>

namespace mpm {

/// The plugins the user allowed for a run, from the command line.
struct PluginPolicy {
  std::vector<std::filesystem::path> files;  ///< `--plugin PATH`: loaded before the scene.
  bool allow_scene_plugins = false;  ///< `--allow-scene-plugins`: also beside or by the scene.
};

/// The folders a bare plugin name is looked up in: each of $MPM_PLUGIN_PATH (colon-separated),
/// then the lib/ folder beside the running program's bin/ (where the build and the install put
/// plugins).
std::vector<std::filesystem::path> plugin_folders();

/// The file a scene's `plugins:` entry `written` names. A bare file name is one of the
/// `--plugin` files of that name, or is looked up in plugin_folders(); a path (absolute, or
/// relative to `scene_dir`) must be one of those files or lie in one of those folders. A file
/// found only beside the scene, or named by a path elsewhere, is refused unless the policy
/// allows scene plugins: loading it would run code that came with the scene. Throws
/// PluginError saying what was searched or how to allow the file.
std::filesystem::path find_scene_plugin(const std::string& written,
                                        const std::filesystem::path& scene_dir,
                                        const PluginPolicy& policy);

}  // namespace mpm
