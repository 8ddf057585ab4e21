#pragma once
/// \file Water: a weakly compressible fluid with the Tait equation of state
/// p = K / gamma (J^-gamma - 1) (Tait, as used for MPM fluids by Tampubolon, Gast, Klar, Fu,
/// Teran, Jiang, Museth 2017, "Multi-species simulation of porous sand and water mixtures",
/// SIGGRAPH, section 4.2; and Stomakhin, Schroeder, Jiang, Chai, Teran, Selle 2014, "Augmented
/// MPM for phase-change and varied materials", SIGGRAPH, where only J matters for a fluid).
///
/// The stress depends on J = det F alone: tau = -p J I (references.md, "Sand and water"). It is
/// the derivative of the energy per reference volume
///   psi(J) = K / gamma (J^(1 - gamma) / (gamma - 1) + J) - K / (gamma - 1),
/// with dpsi/dJ = -p, psi(1) = 0 and P = dpsi/dJ J F^-T, so tau = P F^T = -p J I.
/// The plasticity stage keeps F = J^(1/3) I after every F update, so no shear strain is stored.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "materials/elastic_group.h"
#include "materials/material.h"

namespace mpm::materials {

/// The Tait fluid: bulk modulus K and exponent gamma.
struct TaitWater {
  Real bulk_modulus = 0;  ///< K, Pa.
  Real gamma = 7;         ///< Tait exponent, dimensionless (> 1).

  /// Below this J the pressure is held at p(kJMin) (psi continued linearly), so a crushed or
  /// inverted particle has finite stress that still pushes J up (dpsi/dJ < 0 for every J).
  static constexpr Real kJMin = 0.1;

  /// Pressure p(J) = K / gamma (J^-gamma - 1), Pa; p(kJMin) below kJMin.
  Real pressure(Real J) const {
    return bulk_modulus / gamma * (std::pow(std::max(J, kJMin), -gamma) - 1);
  }

  /// Energy density psi(J), J/m^3 (see the file comment; linear below kJMin).
  Real energy_of_J(Real J) const {
    const Real K = bulk_modulus, g = gamma;
    const Real Jc = std::max(J, kJMin);
    const Real psi = K / g * (std::pow(Jc, 1 - g) / (g - 1) + Jc) - K / (g - 1);
    return psi - pressure(Jc) * (J - Jc);  // the linear continuation below kJMin
  }

  /// Energy density psi(F) = psi(det F), J/m^3.
  Real energy(const Mat3& F) const { return energy_of_J(F.determinant()); }

  /// Kirchhoff stress tau = -p(J) J I, Pa.
  Mat3 kirchhoff(const Mat3& F) const {
    const Real J = F.determinant();
    return -pressure(J) * J * Mat3::Identity();
  }

  /// Sound speed c = sqrt(dp/drho) at the current density rho = rho0 / J, m/s: with
  /// p = K / gamma ((rho / rho0)^gamma - 1), dp/drho = K / rho0 (rho / rho0)^(gamma - 1), so
  /// c = sqrt(K J^(1 - gamma) / rho0) (sqrt(K / rho0) at rest; J held >= kJMin).
  Real wave_speed(const Mat3& F, Real rho0) const {
    const Real J = std::max(F.determinant(), kJMin);
    return std::sqrt(bulk_modulus * std::pow(J, 1 - gamma) / rho0);
  }

  /// F = J^(1/3) I with the same J: drops the shear the F update adds.
  static Mat3 project(const Mat3& F) { return std::cbrt(F.determinant()) * Mat3::Identity(); }
};

/// The rate of deformation of a water particle from its F update: the plasticity stage sees
/// F_new = (I + dt grad v) F_old with F_old = J_old^(1/3) I, so
/// A = F_new / det(F_new)^(1/3) = (I + dt grad v) / det(I + dt grad v)^(1/3) and
/// dev(sym(A)) / dt = dev(sym(grad v)) + O(dt), the deviatoric strain rate (1/s). It holds for
/// every transfer (PIC, FLIP, APIC, MLS), since each updates F with its own grad v.
inline Mat3 deviatoric_rate(const Mat3& F_new, Real dt) {
  const Real J = F_new.determinant();
  if (!(J > 0) || !(dt > 0)) return Mat3::Zero();
  const Mat3 A = F_new / std::cbrt(J);
  const Mat3 D = (Real(0.5) * (A + A.transpose()) - Mat3::Identity()) / dt;
  return D - D.trace() / 3 * Mat3::Identity();
}

/// MaterialGroup for water. With viscosity it keeps each particle's deviatoric strain rate
/// (6 values, particle-major) as its state; without, it has no state beyond F.
class WaterGroup final : public MaterialGroup {
 public:
  /// `count` particles of `model` with reference density `rho0` and dynamic viscosity
  /// `viscosity` (eta, Pa s; 0 for none).
  WaterGroup(const TaitWater& model, Real rho0, Real viscosity = 0, std::size_t count = 0)
      : model_(model), rho0_(rho0), eta_(viscosity), rate_(viscosity > 0 ? 6 * count : 0) {}

  /// Kirchhoff stress tau = -p J I + J 2 eta D, with D the deviatoric strain rate of the last
  /// F update (Newtonian viscosity, references.md "Sand and water"; explicit, as is the rest).
  void compute_stress(std::span<const StoredMat3> F, Real volume0,
                      std::span<StoredMat3> out) const override {
    if (rate_.empty()) return model_stress(model_, F, volume0, out);
    for_each_particle(F.size(), [&](std::ptrdiff_t p) {
      const Mat3 Fp = to_real(F[p]);
      const Mat3 tau = model_.kirchhoff(Fp) + 2 * eta_ * Fp.determinant() * rate(p);
      out[p] = to_stored(-volume0 * tau);
    });
  }

  bool has_plasticity() const override { return true; }

  void apply_plasticity(std::span<StoredMat3> F) override { apply_plasticity_step(F, 0); }

  /// Keeps the deviatoric strain rate of this F update (viscosity only), then F = J^(1/3) I.
  void apply_plasticity_step(std::span<StoredMat3> F, Real dt) override {
    for_each_particle(F.size(), [&](std::ptrdiff_t p) {
      const Mat3 Fp = to_real(F[p]);
      if (!rate_.empty()) {
        const Mat3 D = deviatoric_rate(Fp, dt);
        Real* r = &rate_[6 * p];
        r[0] = D(0, 0), r[1] = D(1, 1), r[2] = D(2, 2), r[3] = D(0, 1), r[4] = D(0, 2),
        r[5] = D(1, 2);
      }
      F[p] = to_stored(TaitWater::project(Fp));
    });
  }

  Real max_wave_speed(std::span<const StoredMat3> F) const override {
    return model_max_wave_speed(model_, F, rho0_);
  }

  /// eta / rho at the current density rho0 / J, m^2/s.
  Real max_kinematic_viscosity(std::span<const StoredMat3> F) const override {
    if (eta_ <= 0) return 0;
    // Largest J in parallel over fixed chunks, as the wave speed's bound is: this runs before
    // every adaptive substep.
    const Real J = reduce_chunks(
        F.size(), Real(0),
        [&](std::size_t first, std::size_t last) {
          Real j = 0;
          for (std::size_t p = first; p < last; ++p)
            j = std::max(j, Real(to_real(F[p]).determinant()));
          return j;
        },
        [](Real a, Real b) { return std::max(a, b); });
    return eta_ * J / rho0_;
  }

  Real elastic_energy(std::span<const StoredMat3> F, Real volume0) const override {
    return model_elastic_energy(model_, F, volume0);
  }

  std::span<Real> state() override { return rate_; }

  /// Tait water in lanes, without viscosity (whose stress needs the kept strain rate).
  BatchModel batch_model() const override {
    BatchModel b;
    if (eta_ > 0) return b;
    b.kind = BatchModel::Kind::water;
    b.bulk_modulus = model_.bulk_modulus;
    b.gamma = model_.gamma;
    return b;
  }

  /// The model.
  const TaitWater& model() const { return model_; }

 private:
  Mat3 rate(std::ptrdiff_t p) const {
    const Real* r = &rate_[6 * p];
    Mat3 D;
    D << r[0], r[3], r[4], r[3], r[1], r[5], r[4], r[5], r[2];
    return D;
  }

  TaitWater model_;
  Real rho0_;
  Real eta_;
  std::vector<Real> rate_;
};

}  // namespace mpm::materials
