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
  /// A bound on every wave speed at F, m/s: exactly sqrt((lambda + 2 mu) / rho0) at rest, and
  /// never below it (StVK softens under compression; the time step does not grow with that).
  ///
  /// A wave of unit polarisation a along the unit current normal m has speed c with
  /// rho0 c^2 = A(a, F^T m), A(a, N) = d^2 psi/dF^2 [a N^T, a N^T] (the reference acoustic
  /// tensor; rho = rho0 / J). E(F + t a N^T) = E + t sym(b N^T) + t^2/2 N N^T with b = F^T a,
  /// so A(a, N) = 2 mu |sym(b N^T)|^2 + lambda (b.N)^2 + N^T S N, S = 2 mu E + lambda tr(E) I.
  /// With s the largest singular value of F, |b| <= s, |sym(b N^T)|^2 = (|b|^2 + (b.N)^2) / 2
  /// <= |b|^2, and the largest eigenvalue of S is mu (s^2 - 1) + lambda tr(E); |F^T m| <= s
  /// scales N. Hence
  ///   rho0 c^2 <= s^2 [(2 mu + max(lambda, 0)) s^2 + max(0, mu (s^2 - 1) + lambda tr(E))],
  /// equal for a uniaxial stretch along a = m, and increasing in s^2. s^2 is the largest
  /// eigenvalue of C = F^T F; without an eigensolver it is bounded by Samuelson's inequality:
  /// three numbers with mean tr(C) / 3 and squared deviations summing to |dev C|^2 have none
  /// above tr(C) / 3 + sqrt(2/3 |dev C|^2), with equality at rest and for a uniaxial stretch.
  /// (The trace alone, s^2 <= tr C, is three times too large at rest.)
  mpm::Real wave_speed(const mpm::Mat3& F, mpm::Real rho0) const {
    const mpm::Mat3 C = F.transpose() * F;
    const mpm::Real mean = C.trace() / 3;
    const mpm::Mat3 dev = C - mean * mpm::Mat3::Identity();
    const mpm::Real s2 = mean + std::sqrt(mpm::Real(2) / 3 * dev.squaredNorm());
    const mpm::Real trE = 0.5 * (C.trace() - 3);
    const mpm::Real bound = s2 * ((2 * mu + std::max<mpm::Real>(lambda, 0)) * s2 +
                                  std::max<mpm::Real>(0, mu * (s2 - 1) + lambda * trE));
    return std::sqrt(std::max(bound, lambda + 2 * mu) / rho0);
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
