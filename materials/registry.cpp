#include "materials/registry.h"

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "materials/corotated.h"
#include "materials/elastic_group.h"
#include "materials/neo_hookean.h"
#include "materials/sand.h"
#include "materials/snow.h"
#include "materials/water.h"

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
  ParamSpec spread{"initial_Jp_spread", "",
                   "s: Jp starts in [1 - s, 1 + s] (hardness varies by exp(-xi (Jp - 1))); "
                   "0: uniform snow",
                   false, 0, 0, 0.5};
  ParamSpec corr{"initial_Jp_correlation", "m",
                 "l: Jp starts at 1 + s n(x / l), n a smooth noise in [-1, 1] seeded by "
                 "simulation.seed (weak zones ~l wide); 0: per particle",
                 false, 0, 0, 1e300};
  params.insert(params.end(), {tc, ts, xi, jp, spread, corr});
  return {"snow", "fixed corotated with hardening and singular-value clamping (plastic)",
          "Stomakhin et al. 2013, A material point method for snow simulation", params, true,
          [](const ParamValues& v, const GroupInfo& g) {
            const Lame l = lame_from_young(v.at("E"), v.at("nu"));
            const materials::SnowPlasticity plastic{
                v.at("critical_compression"), v.at("critical_stretch"), v.at("hardening"),
                v.at("min_Jp"), v.at("initial_Jp_spread"),
                v.at("initial_Jp_correlation")};
            return std::make_unique<materials::SnowGroup>(
                materials::FixedCorotated{l.mu, l.lambda}, plastic, g.density, g.count, g.x,
                g.seed);
          }};
}

MaterialInfo sand_info() {
  std::vector<ParamSpec> params = elastic_param_specs();
  params[0].default_value = 3.537e5;  // a typical value for sand simulations
  params[1].default_value = 0.3;
  ParamSpec phi{
      "friction_angle", "deg", "phi: Drucker-Prager friction angle", false, 30, 0, 60, true, true};
  ParamSpec c{"cohesion", "Pa", "c: the cone's apex is the isotropic tension c cot(phi)", false, 0,
              0,          1e300};
  ParamSpec vc{"volume_correction",
               "",
               "1: volume gained in tension is given back without "
               "resistance (Klar sec. 7.3.1); 0: off",
               false,
               1,
               0,
               1};
  params.insert(params.end(), {phi, c, vc});
  return {"sand",
          "Drucker-Prager elastoplasticity on the Hencky strain (plastic)",
          "Klar et al. 2016, Drucker-Prager elastoplasticity for sand animation",
          params,
          true,
          [](const ParamValues& v, const GroupInfo& g) {
            const double vcorr = v.at("volume_correction");
            if (vcorr != 0 && vcorr != 1)
              throw std::invalid_argument("volume_correction must be 0 (off) or 1 (on), not " +
                                          std::to_string(vcorr));
            const Lame l = lame_from_young(v.at("E"), v.at("nu"));
            const double phi = v.at("friction_angle") * std::numbers::pi / 180;
            materials::DruckerPragerSand m{
                l.mu, l.lambda, materials::DruckerPragerSand::cone_alpha(phi),
                3 * v.at("cohesion") / std::tan(phi) / (3 * l.lambda + 2 * l.mu), vcorr == 1};
            return std::make_unique<materials::SandGroup>(m, g.density, g.count);
          }};
}

MaterialInfo water_info() {
  ParamSpec K{"bulk_modulus", "Pa", "K: p = K / gamma (J^-gamma - 1)", true, 1e5, 0, 1e300, true};
  ParamSpec gamma{"gamma", "", "Tait exponent", false, 7, 1, 20, true};
  ParamSpec eta{"viscosity", "Pa s", "dynamic viscosity eta: tau += J 2 eta dev(sym(grad v))",
                false, 0, 0, 1e300};
  return {"water",
          "weakly compressible Tait fluid, optionally viscous; only J is kept (F = J^(1/3) I)",
          "Tampubolon et al. 2017, Multi-species simulation of porous sand and water mixtures",
          {K, gamma, eta},
          true,
          [](const ParamValues& v, const GroupInfo& g) {
            return std::make_unique<materials::WaterGroup>(
                materials::TaitWater{v.at("bulk_modulus"), v.at("gamma")}, g.density,
                v.at("viscosity"), g.count);
          }};
}

}  // namespace

void register_builtin_materials(MaterialRegistry& registry) {
  registry.add(corotated_info());
  registry.add(neo_hookean_info());
  registry.add(snow_info());
  registry.add(sand_info());
  registry.add(water_info());
}

MaterialRegistry builtin_registry() {
  MaterialRegistry r;
  register_builtin_materials(r);
  return r;
}

}  // namespace mpm
