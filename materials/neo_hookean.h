#pragma once
/// \file Compressible Neo-Hookean elasticity (e.g. Bonet and Wood, "Nonlinear continuum
/// mechanics for finite element analysis", eq. 6.27; Jiang et al. 2016 course notes, eq. 48),
/// extended below J = kJMin so that it stays finite for nearly singular and inverted F.

#include <algorithm>
#include <cmath>

#include "materials/material.h"

namespace mpm::materials {

/// psi = mu/2 (tr(F^T F) - 3) + g(J), with g(J) = -mu log J + lambda/2 (log J)^2 for J >= kJMin.
///
/// log J is undefined for J <= 0. Below kJMin, g is replaced by its second-order Taylor
/// expansion about kJMin, so psi, P = dpsi/dF and the Kirchhoff stress stay finite and
/// consistent for any F, and the volumetric stress keeps pushing J back up (g'' > 0 there).
struct NeoHookean {
  Real mu = 0;      ///< Shear modulus, Pa.
  Real lambda = 0;  ///< First Lamé parameter, Pa.

  /// J below which the volumetric energy is continued by its quadratic Taylor expansion.
  static constexpr Real kJMin = 0.05;

  /// Volumetric energy g(J), J/m^3.
  Real g(Real J) const {
    if (J >= kJMin) {
      const Real l = std::log(J);
      return -mu * l + 0.5 * lambda * l * l;
    }
    const Real d = J - kJMin;
    return g(kJMin) + dg(kJMin) * d + 0.5 * d2g(kJMin) * d * d;
  }
  /// g'(J) = (lambda log J - mu) / J.
  Real dg(Real J) const {
    if (J >= kJMin) return (lambda * std::log(J) - mu) / J;
    return dg(kJMin) + d2g(kJMin) * (J - kJMin);
  }
  /// g''(J) = (lambda + mu - lambda log J) / J^2 (for J >= kJMin).
  Real d2g(Real J) const { return (lambda + mu - lambda * std::log(J)) / (J * J); }

  /// The SIMD lanes' description of this model.
  BatchModel batch() const { return {BatchModel::Kind::neo_hookean, mu, lambda}; }

  /// Energy density psi(F), J/m^3.
  Real energy(const Mat3& F) const {
    return 0.5 * mu * (F.squaredNorm() - 3) + g(F.determinant());
  }

  /// First Piola-Kirchhoff stress P = mu F + g'(J) J F^-T
  /// (= mu (F - F^-T) + lambda log J F^-T for J >= kJMin), Pa.
  Mat3 first_piola(const Mat3& F) const { return mu * F + dg(F.determinant()) * cofactor(F); }

  /// Kirchhoff stress tau = P F^T = mu F F^T + g'(J) J I
  /// (= mu (F F^T - I) + lambda log J I for J >= kJMin), Pa.
  Mat3 kirchhoff(const Mat3& F) const {
    const Real J = F.determinant();
    return mu * F * F.transpose() + dg(J) * J * Mat3::Identity();
  }

  /// P-wave speed at the current state, m/s. The spatial tangent has lambda' = lambda / J and
  /// mu' = (mu - lambda log J) / J, and rho = rho0 / J, so c^2 = (lambda + 2 (mu - lambda
  /// log J)) / rho0: stiffer under compression. J is taken no lower than kJMin, and c no lower
  /// than its value at rest (a safe bound for the time step under tension).
  Real wave_speed(const Mat3& F, Real rho0) const {
    const Real J = std::clamp(F.determinant(), kJMin, Real(1));
    return std::sqrt((lambda + 2 * (mu - lambda * std::log(J))) / rho0);
  }
};

}  // namespace mpm::materials
