#include "materials/registry.h"

#include <stdexcept>

#include "materials/corotated.h"
#include "materials/elastic_group.h"

namespace mpm {

void MaterialRegistry::add(MaterialInfo info) {
  if (info.name.empty()) throw std::invalid_argument("material with an empty name");
  if (!info.create) throw std::invalid_argument("material '" + info.name + "' has no factory");
  if (find(info.name))
    throw std::invalid_argument("material '" + info.name + "' is already registered");
  materials_.push_back(std::move(info));
}

const MaterialInfo* MaterialRegistry::find(const std::string& name) const {
  for (const auto& m : materials_)
    if (m.name == name) return &m;
  return nullptr;
}

std::string MaterialRegistry::names() const {
  std::string out;
  for (const auto& m : materials_) out += (out.empty() ? "" : ", ") + m.name;
  return out;
}

std::vector<ParamSpec> elastic_param_specs() {
  ParamSpec E{"E", "Pa", "Young's modulus", true};
  E.min = 0;
  E.min_exclusive = true;
  ParamSpec nu{"nu", "", "Poisson's ratio", true};
  nu.min = -1;
  nu.max = 0.5;
  nu.min_exclusive = nu.max_exclusive = true;
  return {E, nu};
}

namespace {

MaterialInfo corotated_info() {
  return {"corotated", "fixed corotated hyperelasticity, defined for inverted F",
          "Stomakhin et al. 2012, Energetically consistent invertible elasticity",
          elastic_param_specs(), [](const ParamValues& v, const GroupInfo& g) {
            const Lame l = lame_from_young(v.at("E"), v.at("nu"));
            return std::make_unique<materials::ElasticGroup<materials::FixedCorotated>>(
                materials::FixedCorotated{l.mu, l.lambda}, g.density);
          }};
}

}  // namespace

void register_builtin_materials(MaterialRegistry& registry) {
  registry.add(corotated_info());
}

MaterialRegistry builtin_registry() {
  MaterialRegistry r;
  register_builtin_materials(r);
  return r;
}

}  // namespace mpm
