#pragma once
/// \file Reading a scene file into a validated SceneDesc.

#include <filesystem>
#include <string>

#include "engine/scene_desc.h"
#include "materials/registry.h"

namespace mpm {

/// Reads and validates the scene at `path`. Plugins the scene lists are loaded into
/// `registry` first. Throws SceneError naming file, line and key.
SceneDesc load_scene(const std::filesystem::path& path, MaterialRegistry& registry);

/// Reads a scene from YAML text; `file_name` is used in messages and for relative paths.
SceneDesc load_scene_from_string(const std::string& yaml, const std::filesystem::path& file_name,
                                 MaterialRegistry& registry);

}  // namespace mpm
