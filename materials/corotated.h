#pragma once
/// \file Fixed corotated elasticity (Stomakhin, Howes, Schroeder, Teran 2012,
/// "Energetically consistent invertible elasticity", SCA; eq. 4 and its first Piola stress).

#include <cmath>

#include "materials/material.h"
#include "materials/svd.h"

namespace mpm::materials {

/// Fixed corotated hyperelasticity: psi = mu sum_i (sigma_i - 1)^2 + lambda/2 (J - 1)^2.
struct FixedCorotated {
  Real mu = 0;      ///< Shear modulus, Pa.
  Real lambda = 0;  ///< First Lamé parameter, Pa.

  /// Energy density psi(F), J/m^3. With F = R S (polar_rotation), S's eigenvalues are the
  /// signed sigma_i, so sum_i (sigma_i - 1)^2 = |S - I|^2 = |F - R|^2, which
  /// distance_to_rotation_squared gets from the sum of the sigma_i alone: no R, no SVD.
  Real energy(const Mat3& F) const {
    Real J;
    const Real d2 = distance_to_rotation_squared(F, J);
    return mu * d2 + 0.5 * lambda * (J - 1) * (J - 1);
  }

  /// First Piola-Kirchhoff stress P = 2 mu (F - R) + lambda (J - 1) J F^-T, Pa.
  Mat3 first_piola(const Mat3& F) const {
    Real J;
    const Mat3 R = polar_rotation(F, J);
    // J F^-T is the cofactor matrix of F, defined even when F is singular.
    return 2 * mu * (F - R) + lambda * (J - 1) * cofactor(F);
  }

  /// Kirchhoff stress tau = P F^T = 2 mu (F - R) F^T + lambda (J - 1) J I, Pa.
  Mat3 kirchhoff(const Mat3& F) const {
    Real J;
    const Mat3 R = polar_rotation(F, J);
    return 2 * mu * (F - R) * F.transpose() + lambda * (J - 1) * J * Mat3::Identity();
  }

  /// The engine's float SIMD kernel for this model (engine/step/simd/corotated-inl.h).
  BatchModel batch() const { return {BatchModel::Kind::fixed_corotated, mu, lambda}; }

  /// P-wave speed sqrt((lambda + 2 mu) / rho) at current density rho0 / J, m/s.
  Real wave_speed(const Mat3& F, Real rho0) const {
    const Real J = std::max(std::abs(F.determinant()), Real(1e-6));
    return std::sqrt((lambda + 2 * mu) * J / rho0);
  }
};

}  // namespace mpm::materials
