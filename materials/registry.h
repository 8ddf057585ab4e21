#pragma once
/// \file The material registry: every material the engine can build, found by name.

#include <filesystem>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "materials/material.h"

namespace mpm {

/// Name -> MaterialInfo. Built explicitly at start-up; plugins add to it when loaded.
///
/// Header-only, so a plugin compiled outside the tree needs no engine symbols to register.
class MaterialRegistry {
 public:
  /// Adds `info`; throws std::invalid_argument if the name is taken or empty.
  void add(MaterialInfo info) {
    if (info.name.empty()) throw std::invalid_argument("a material has an empty name");
    if (!info.create) throw std::invalid_argument("material '" + info.name + "' has no factory");
    if (find(info.name))
      throw std::invalid_argument("material '" + info.name + "' is already registered");
    materials_.push_back(std::move(info));
  }
  /// The material called `name`, or nullptr.
  const MaterialInfo* find(const std::string& name) const {
    for (const auto& m : materials_)
      if (m.name == name) return &m;
    return nullptr;
  }
  /// Every registered material, in registration order.
  const std::vector<MaterialInfo>& all() const { return materials_; }
  /// Registered names joined with ", " for error messages.
  std::string names() const {
    std::string out;
    for (const auto& m : materials_) out += (out.empty() ? "" : ", ") + m.name;
    return out;
  }
  /// Plugin files already loaded into this registry (canonical paths).
  std::set<std::filesystem::path>& loaded_plugins() { return plugins_; }

 private:
  std::vector<MaterialInfo> materials_;
  std::set<std::filesystem::path> plugins_;
};

/// Registers the built-in materials, one line each.
void register_builtin_materials(MaterialRegistry& registry);

/// A registry holding the built-in materials.
MaterialRegistry builtin_registry();

}  // namespace mpm
