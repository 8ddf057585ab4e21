#pragma once
/// \file The material registry: every material the engine can build, found by name.

#include <string>
#include <vector>

#include "materials/material.h"

namespace mpm {

/// Name -> MaterialInfo. Built explicitly at start-up; plugins add to it when loaded.
class MaterialRegistry {
 public:
  /// Adds `info`; throws std::invalid_argument if the name is taken or empty.
  void add(MaterialInfo info);
  /// The material called `name`, or nullptr.
  const MaterialInfo* find(const std::string& name) const;
  /// Every registered material, in registration order.
  const std::vector<MaterialInfo>& all() const { return materials_; }
  /// Registered names joined with ", " for error messages.
  std::string names() const;

 private:
  std::vector<MaterialInfo> materials_;
};

/// Registers the built-in materials, one line each.
void register_builtin_materials(MaterialRegistry& registry);

/// A registry holding the built-in materials.
MaterialRegistry builtin_registry();

}  // namespace mpm
