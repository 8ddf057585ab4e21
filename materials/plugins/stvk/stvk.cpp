// St. Venant-Kirchhoff elasticity as a material plugin: the whole example of docs/materials.md.
//
// psi = mu |E|^2 + lambda/2 tr(E)^2 with the Green strain E = (F^T F - I) / 2, and
// P = F (2 mu E + lambda tr(E) I) (e.g. Sifakis and Barbic 2012, "FEM simulation of 3D
// deformable solids", eq. 3.4). A polynomial in F, so finite for any F, but it softens under
// strong compression and does not resist inversion: fine for small strains only.
#include <algorithm>
#include <cmath>
#include <memory>

#include "materials/elastic_group.h"
#include "materials/plugin.h"

namespace {

/// The model: a small value type with energy, stress and wave speed.
struct StVenantKirchhoff {
  mpm::Real mu = 0, lambda = 0;

  mpm::Mat3 green_strain(const mpm::Mat3& F) const {
    return 0.5 * (F.transpose() * F - mpm::Mat3::Identity());
  }
  mpm::Real energy(const mpm::Mat3& F) const {
    const mpm::Mat3 E = green_strain(F);
    return mu * E.squaredNorm() + 0.5 * lambda * E.trace() * E.trace();
  }
  mpm::Mat3 kirchhoff(const mpm::Mat3& F) const {
    const mpm::Mat3 E = green_strain(F);
    const mpm::Mat3 S = 2 * mu * E + lambda * E.trace() * mpm::Mat3::Identity();
    return F * S * F.transpose();  // tau = P F^T = F S F^T
  }
  mpm::Real wave_speed(const mpm::Mat3& F, mpm::Real rho0) const {
    // Stiffness grows with stretch: bound it by the largest singular value squared.
    const mpm::Real s2 = std::max<mpm::Real>(1, (F.transpose() * F).trace());
    return std::sqrt((lambda + 2 * mu) * s2 / rho0);
  }
};

void register_stvk(mpm::MaterialRegistry& registry) {
  registry.add({"stvk", "St. Venant-Kirchhoff (example plugin): small strains only",
                "Sifakis and Barbic 2012, FEM simulation of 3D deformable solids",
                mpm::elastic_param_specs(), true,
                [](const mpm::ParamValues& v, const mpm::GroupInfo& g) {
                  const mpm::Lame l = mpm::lame_from_young(v.at("E"), v.at("nu"));
                  return std::make_unique<mpm::materials::ElasticGroup<StVenantKirchhoff>>(
                      StVenantKirchhoff{l.mu, l.lambda}, g.density);
                }});
}

}  // namespace

MPM_DECLARE_PLUGIN(register_stvk)
