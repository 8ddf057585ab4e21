#include "materials/registry.h"

#include "materials/corotated.h"
#include "materials/elastic_group.h"
#include "materials/neo_hookean.h"
#include "materials/snow.h"

namespace mpm {

namespace {

using materials::ElasticGroup;

MaterialInfo corotated_info() {
  return {"corotated", "fixed corotated hyperelasticity, defined for inverted F",
          "Stomakhin et al. 2012, Energetically consistent invertible elasticity",
          elastic_param_specs(), true, [](const ParamValues& v, const GroupInfo& g) {
            const Lame l = lame_from_young(v.at("E"), v.at("nu"));
            return std::make_unique<ElasticGroup<materials::FixedCorotated>>(
                materials::FixedCorotated{l.mu, l.lambda}, g.density);
          }};
}

MaterialInfo neo_hookean_info() {
  return {"neo_hookean",
          "compressible Neo-Hookean; volumetric term continued quadratically below J = 0.05",
          "Bonet and Wood 2008, eq. 6.27; Jiang et al. 2016 course notes, eq. 48",
          elastic_param_specs(), true, [](const ParamValues& v, const GroupInfo& g) {
            const Lame l = lame_from_young(v.at("E"), v.at("nu"));
            return std::make_unique<ElasticGroup<materials::NeoHookean>>(
                materials::NeoHookean{l.mu, l.lambda}, g.density);
          }};
}

MaterialInfo snow_info() {
  std::vector<ParamSpec> params = elastic_param_specs();
  params[0].default_value = 1.4e5;  // the paper's E0
  params[1].default_value = 0.2;
  ParamSpec tc{"critical_compression", "", "theta_c: elastic singular values >= 1 - theta_c",
               false, 2.5e-2, 0, 1, false, true};
  ParamSpec ts{"critical_stretch", "", "theta_s: elastic singular values <= 1 + theta_s", false,
               7.5e-3, 0, 1e300};
  ParamSpec xi{"hardening", "", "xi: moduli scale by exp(xi (1 - Jp))", false, 10, 0, 1e300};
  ParamSpec jp{"min_Jp", "", "smallest plastic volume ratio Jp (0: no clamp); bounds hardening",
               false, 0, 0, 1, false, true};
  params.insert(params.end(), {tc, ts, xi, jp});
  return {"snow", "fixed corotated with hardening and singular-value clamping (plastic)",
          "Stomakhin et al. 2013, A material point method for snow simulation", params, true,
          [](const ParamValues& v, const GroupInfo& g) {
            const Lame l = lame_from_young(v.at("E"), v.at("nu"));
            const materials::SnowPlasticity plastic{v.at("critical_compression"),
                                                    v.at("critical_stretch"), v.at("hardening"),
                                                    v.at("min_Jp")};
            return std::make_unique<materials::SnowGroup>(
                materials::FixedCorotated{l.mu, l.lambda}, plastic, g.density, g.count);
          }};
}

}  // namespace

void register_builtin_materials(MaterialRegistry& registry) {
  registry.add(corotated_info());
  registry.add(neo_hookean_info());
  registry.add(snow_info());
}

MaterialRegistry builtin_registry() {
  MaterialRegistry r;
  register_builtin_materials(r);
  return r;
}

}  // namespace mpm
