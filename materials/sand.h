#pragma once
/// \file Sand: Drucker-Prager elastoplasticity on the Hencky strain (Klar, Gast, Pradhana, Fu,
/// Schroeder, Jiang, Teran 2016, "Drucker-Prager elastoplasticity for sand animation",
/// SIGGRAPH, doi:10.1145/2897824.2925906; section 7: St. Venant-Kirchhoff elasticity on the
/// Hencky strain, the projection onto the yield cone with its three cases, and the volume
/// correction; the supplementary document's projection algorithm).
///
/// With F = U Sigma V^T and the Hencky strain eps = log Sigma (a diagonal, written as a
/// 3-vector), the energy is psi = mu tr(eps^2) + lambda/2 tr(eps)^2, and the Kirchhoff stress
/// tau = U (2 mu eps + lambda tr(eps) I) U^T. The yield condition is the Drucker-Prager cone
/// |dev tau| <= alpha (tr tau_apex - tr tau) with alpha = sqrt(2/3) 2 sin(phi) / (3 - sin(phi))
/// (the cone through the compressive meridian of Mohr-Coulomb with friction angle phi). Klar's
/// cone has its apex at zero stress; a cohesion c moves the apex to the Mohr-Coulomb one,
/// the isotropic tension c cot(phi) (tr tau_apex = 3 c cot(phi)), and c = 0 is exactly Klar's.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "materials/elastic_group.h"
#include "materials/material.h"
#include "materials/plastic_group.h"
#include "materials/svd.h"

namespace mpm::materials {

/// St. Venant-Kirchhoff on the Hencky strain, and its Drucker-Prager return mapping.
struct DruckerPragerSand {
  Real mu = 0;          ///< Shear modulus, Pa.
  Real lambda = 0;      ///< First Lame parameter, Pa.
  Real alpha = 0;       ///< Cone slope sqrt(2/3) 2 sin(phi) / (3 - sin(phi)), dimensionless.
  Real apex_trace = 0;  ///< tr(eps) of the cone's apex: 3 c cot(phi) / (3 lambda + 2 mu).
  bool volume_correction = true;  ///< Klar's volume correction (section 7.3.1) on or off.

  /// Singular values below this are raised to it before the logarithm, so the stress of a
  /// crushed or inverted particle stays finite (|sigma| is used, so the strain of an inverted
  /// particle is that of its mirror image; the return mapping then un-inverts it).
  static constexpr Real kSigmaMin = 1e-4;

  /// Slope alpha of the cone for friction angle `phi` (radians). phi is the angle of
  /// Mohr-Coulomb's triaxial-compression meridian (Klar et al. 2016, sec. 7.3): in plane-strain
  /// shear flow (a quasi-2D slot) the cone flows at tau / sigma_n = 3 alpha / sqrt(2) =
  /// 2 sqrt(3) sin(phi) / (3 - sin(phi)), so phi = 30 degrees flows at tan 34.7 degrees
  /// (docs/validation.md, section 12).
  static Real cone_alpha(Real phi) {
    const Real s = std::sin(phi);
    return std::sqrt(Real(2) / 3) * 2 * s / (3 - s);
  }

  /// Hencky strain log|sigma_i| of the singular values (floored at kSigmaMin).
  static Vec3 hencky(const Vec3& sigma) {
    return sigma.cwiseAbs().cwiseMax(kSigmaMin).array().log().matrix();
  }

  /// Principal Kirchhoff stresses 2 mu eps + lambda tr(eps), Pa.
  Vec3 principal_kirchhoff(const Vec3& eps) const {
    return 2 * mu * eps + Vec3::Constant(lambda * eps.sum());
  }

  /// Energy density psi(F) = mu tr(eps^2) + lambda/2 tr(eps)^2, J/m^3.
  Real energy(const Mat3& F) const {
    Mat3 U, V;
    Vec3 s;
    svd_rv(F, U, s, V);
    const Vec3 e = hencky(s);
    return mu * e.squaredNorm() + Real(0.5) * lambda * e.sum() * e.sum();
  }

  /// Kirchhoff stress tau = U (2 mu eps + lambda tr(eps) I) U^T, Pa. U and Sigma^2 come from
  /// the eigen-decomposition of F F^T = U Sigma^2 U^T, so no rotation V is needed.
  Mat3 kirchhoff(const Mat3& F) const {
    Mat3 U;
    Vec3 s2;
    symmetric_eigen(F * F.transpose(), s2, U);
    const Vec3 eps = Real(0.5) * s2.cwiseMax(kSigmaMin * kSigmaMin).array().log().matrix();
    return U * principal_kirchhoff(eps).asDiagonal() * U.transpose();
  }

  /// P-wave speed sqrt((lambda + 2 mu) max(1, J) / rho0), m/s: the engine's convention
  /// (lambda + 2 mu) J / rho0 for J >= 1; below, the Hencky model's tangent, whose Cauchy
  /// stiffness (lambda + 2 mu) / J over the density rho0 / J does not fall with J.
  Real wave_speed(const Mat3& F, Real rho0) const {
    const Real J = std::abs(F.determinant());
    return std::sqrt((lambda + 2 * mu) * std::max(J, Real(1)) / rho0);
  }

  /// The return mapping on the Hencky strain (Klar et al. 2016, section 7.3): moves the
  /// trial strain `eps` onto the yield cone, in place; false if it was left unchanged. `vc` is the
  /// particle's volume correction, the log of the plastic volume gained (>= 0), which later
  /// compression may give back without resistance; it is updated here.
  ///   Case II (tr eps' >= apex, expansion): to the apex; no tension beyond the cohesion.
  ///   Case I (dgamma <= 0): inside the cone, eps' kept.
  ///   Case III: eps' - dgamma eps_hat / |eps_hat|, the deviatoric part shortened onto the
  ///   cone at the same trace (a non-associative flow: no dilatancy).
  /// Here eps' = eps + (vc / 3) I (vc = 0 without volume correction) and
  /// dgamma = |eps_hat| + (3 lambda + 2 mu) / (2 mu) (tr eps' - apex) alpha.
  bool project(Vec3& eps, Real& vc) const {
    const bool corrected = volume_correction && vc != 0;
    const Vec3 e = corrected ? (eps.array() + vc / 3).matrix() : eps;
    const Real tr = e.sum();
    Vec3 out;
    if (tr >= apex_trace) {
      out = Vec3::Constant(apex_trace / 3);  // case II
    } else {
      const Vec3 dev = (e.array() - tr / 3).matrix();
      const Real dev_norm = dev.norm();
      const Real dgamma = dev_norm + (3 * lambda + 2 * mu) / (2 * mu) * (tr - apex_trace) * alpha;
      if (dgamma <= 0 || dev_norm == 0) {
        if (!corrected) return false;  // case I
        out = e;
      } else {
        out = e - dgamma / dev_norm * dev;  // case III
      }
    }
    // The plastic volume change: what the trial strain had beyond the projected one.
    if (volume_correction) vc += eps.sum() - out.sum();
    eps = out;
    return true;
  }
};

/// Projects F onto `model`'s yield cone, updating the particle's volume correction `vc`.
inline void project_sand(const DruckerPragerSand& model, StoredMat3& F, Real& vc) {
  const Mat3 Fe = to_real(F);
  // F^T F = V Sigma^2 V^T. For det F > 0 and sigma above the floor, U = F V Sigma^-1, so
  // the projected U exp(H) V^T is F V diag(exp(H) / sigma) V^T: no U needed.
  Mat3 V;
  Vec3 s2;
  symmetric_eigen(Fe.transpose() * Fe, s2, V);
  const Real floor2 = DruckerPragerSand::kSigmaMin * DruckerPragerSand::kSigmaMin;
  if (Fe.determinant() > 0 && s2.minCoeff() > floor2) {
    const Vec3 s = s2.cwiseSqrt();
    Vec3 e = s.array().log().matrix();
    if (model.project(e, vc))
      F = to_stored(Fe * V * (e.array().exp() / s.array()).matrix().asDiagonal() * V.transpose());
    return;
  }
  // Inverted or crushed: the rotation-variant SVD, rebuilt with positive singular values.
  Mat3 U;
  Vec3 s;
  svd_rv(Fe, U, s, V);
  Vec3 e = DruckerPragerSand::hencky(s);
  model.project(e, vc);
  F = to_stored(U * e.array().exp().matrix().asDiagonal() * V.transpose());
}

/// MaterialGroup for sand: the per-particle volume correction, for this group's range only.
class SandGroup final : public PlasticGroup<SandGroup> {
 public:
  /// `model` holds the moduli and cone; `count` particles start with no volume correction.
  SandGroup(const DruckerPragerSand& model, Real rho0, std::size_t count)
      : PlasticGroup(std::vector<Real>(count, 0)), model_(model), rho0_(rho0) {}

  /// The elastic model: the same for every particle (PlasticGroup).
  const DruckerPragerSand& elastic_model(std::ptrdiff_t) const { return model_; }

  /// The largest wave speed at F (PlasticGroup), m/s.
  Real wave_speed(const Mat3& F, std::ptrdiff_t) const { return model_.wave_speed(F, rho0_); }

  /// Projects particle p's F onto the yield cone, updating its volume correction
  /// (PlasticGroup).
  void project(StoredMat3& F, std::ptrdiff_t p) { project_sand(model_, F, state_[p]); }

  /// Sand in lanes: the Hencky stress and the return map.
  BatchModel batch_model() const override {
    BatchModel b{BatchModel::Kind::sand, model_.mu, model_.lambda};
    b.alpha = model_.alpha;
    b.apex_trace = model_.apex_trace;
    b.volume_correction = model_.volume_correction;
    return b;
  }

  /// Volume correction of each particle: the log of the plastic volume gained (>= 0).
  const std::vector<Real>& volume_correction() const { return state_; }
  /// Mutable volume correction, for tests.
  std::vector<Real>& volume_correction() { return state_; }
  /// The model.
  const DruckerPragerSand& model() const { return model_; }

 private:
  DruckerPragerSand model_;
  Real rho0_;
};

}  // namespace mpm::materials
