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
  /// -V0 tau of a batch of particles in float lanes, the same formula: the plugin's entry to the
  /// engine's SIMD scatter (MaterialGroup::lane_stress). Each loop runs over the lanes, so the
  /// compiler vectorises it.
  void lane_kirchhoff(mpm::StressLanes& b, mpm::Real volume0) const {
    constexpr std::size_t L = mpm::kStressLanes;
    const float two_mu = static_cast<float>(2 * mu), lam = static_cast<float>(lambda);
    const float v0 = static_cast<float>(volume0);
    const auto F = [&](int r, int c, std::size_t l) { return b.F[3 * c + r][l]; };
    float S[3][3][L];  // E = (F^T F - I) / 2 first, then S = 2 mu E + lambda tr(E) I
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        for (std::size_t l = 0; l < L; ++l) {
          const float c =
              F(0, i, l) * F(0, j, l) + F(1, i, l) * F(1, j, l) + F(2, i, l) * F(2, j, l);
          S[i][j][l] = 0.5f * (c - (i == j ? 1.0f : 0.0f));
        }
    for (std::size_t l = 0; l < L; ++l) {
      const float tr = S[0][0][l] + S[1][1][l] + S[2][2][l];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) S[i][j][l] = two_mu * S[i][j][l] + (i == j ? lam * tr : 0.0f);
    }
    float FS[3][3][L];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        for (std::size_t l = 0; l < L; ++l)
          FS[r][c][l] = F(r, 0, l) * S[0][c][l] + F(r, 1, l) * S[1][c][l] + F(r, 2, l) * S[2][c][l];
    for (int r = 0; r < 3; ++r)  // tau = F S F^T, times -V0
      for (int c = 0; c < 3; ++c)
        for (std::size_t l = 0; l < L; ++l)
          b.tau[3 * c + r][l] = -v0 * (FS[r][0][l] * F(c, 0, l) + FS[r][1][l] * F(c, 1, l) +
                                       FS[r][2][l] * F(c, 2, l));
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
