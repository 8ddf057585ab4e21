#include "engine/step/initial_state.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

namespace mpm {

namespace {

/// F = I - (1 - lambda) u u^T: compressed to lambda along the unit vector u.
Mat3 uniaxial(const Vec3& u, Real lambda) {
  return Mat3::Identity() - (1 - lambda) * u * u.transpose();
}

}  // namespace

void settle_under_gravity(const Vec3& gravity, Real density, Real spacing,
                          const MaterialGroup& group, std::span<const Vec3> x,
                          std::span<StoredMat3> F) {
  const Real g = gravity.norm();
  if (!(g > 0))
    throw std::runtime_error("initial_stress: gravity needs a nonzero simulation.gravity");
  const std::size_t n = x.size();
  if (n == 0) return;
  const Vec3 up = -gravity / g;
  Real top = -1e300;
  for (const Vec3& p : x) top = std::max(top, p.dot(up));
  top += spacing / 2;  // the surface lies half a spacing above the top particles
  // Bisection on lambda in [kLowestStretch, 1] for tau_gg(lambda) = -rho g d lambda (the
  // Cauchy stress sigma = tau / J with J = lambda). Its residual grows with lambda: tau_gg
  // rises towards 0 as the compression is let off, and -rho g d lambda falls.
  std::vector<Real> lo(n, kLowestStretch), hi(n, 1);
  std::vector<StoredMat3> trial(n), stress(n);
  const Real volume0 = 1;  // compute_stress returns -volume0 tau
  const auto residual_sign = [&](const std::vector<Real>& lambda, std::vector<bool>& positive) {
    for (std::size_t p = 0; p < n; ++p) trial[p] = to_stored(uniaxial(up, lambda[p]));
    group.compute_stress(trial, volume0, stress);
    for (std::size_t p = 0; p < n; ++p) {
      const Real tau_gg = -up.dot(to_real(stress[p]) * up) / volume0;
      const Real weight = density * g * (top - x[p].dot(up));
      positive[p] = tau_gg + weight * lambda[p] > 0;
    }
  };
  std::vector<bool> positive(n);
  residual_sign(lo, positive);
  for (std::size_t p = 0; p < n; ++p)
    if (positive[p]) {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "the material cannot hold the weight of the layer above a particle %.3g m "
                    "deep (rho g d = %.3g Pa) without compressing it below J = %.2f: is it too "
                    "soft (E or bulk_modulus in Pa)?",
                    top - x[p].dot(up), density * g * (top - x[p].dot(up)), kLowestStretch);
      throw std::runtime_error(buf);
    }
  std::vector<Real> mid(n);
  for (int it = 0; it < 48; ++it) {
    for (std::size_t p = 0; p < n; ++p) mid[p] = (lo[p] + hi[p]) / 2;
    residual_sign(mid, positive);
    for (std::size_t p = 0; p < n; ++p) (positive[p] ? hi : lo)[p] = mid[p];
  }
  for (std::size_t p = 0; p < n; ++p) F[p] = to_stored(uniaxial(up, (lo[p] + hi[p]) / 2));
}

}  // namespace mpm
