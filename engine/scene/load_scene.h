#pragma once
/// \file Reading a scene file into a validated SceneDesc.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "engine/scene/plugin_search.h"
#include "engine/scene/scene_desc.h"
#include "materials/registry.h"

namespace mpm {

/// One `--set KEY=VALUE` override, e.g. {"objects[0].E", "2e4"}.
struct SceneOverride {
  std::string key;    ///< Dotted key path with [i] list indices.
  std::string value;  ///< YAML text of the new value ("64", "[1, 2, 3]", "apic").
};

/// How to load a scene.
struct LoadOptions {
  std::vector<SceneOverride> overrides;  ///< Applied to the document before validation.
  bool load_plugins = true;              ///< False rejects any `plugins:` entry (fuzzing).
  PluginPolicy plugins;  ///< `--plugin` files, loaded first, and where scene plugins may be.
};

/// The format called `name` (hdf5, bgeo, ply, png, mesh, vdb), or std::nullopt.
std::optional<Format> format_from_name(const std::string& name);

/// The format names for messages: "hdf5, bgeo, ply, png, mesh or vdb".
const char* format_names();

/// Splits "KEY=VALUE" into a SceneOverride; throws SceneError if there is no '='.
SceneOverride parse_override(const std::string& text);

/// Reads and validates the scene at `path`. Plugins the scene lists are loaded into
/// `registry` first. Throws SceneError naming file, line and key.
SceneDesc load_scene(const std::filesystem::path& path, MaterialRegistry& registry,
                     const LoadOptions& options = {});

/// Reads a scene from YAML text; `file_name` is used in messages and for relative paths.
SceneDesc load_scene_from_string(const std::string& yaml, const std::filesystem::path& file_name,
                                 MaterialRegistry& registry, const LoadOptions& options = {});

}  // namespace mpm
