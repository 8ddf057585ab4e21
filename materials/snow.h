#pragma once
/// \file Snow: fixed corotated elasticity with hardening and singular-value clamping
/// (Stomakhin, Schroeder, Chai, Teran, Selle 2013, "A material point method for snow
/// simulation", SIGGRAPH; sections 5 and 7, eq. 3 for the hardened Lamé parameters).

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "engine/core/hash.h"
#include "engine/core/reduce.h"
#include "materials/corotated.h"
#include "materials/plastic_group.h"
#include "materials/svd.h"

namespace mpm::materials {

/// True if the symmetric A is positive definite (Sylvester: its leading minors are > 0).
inline bool positive_definite(const Mat3& A) {
  return A(0, 0) > 0 && A(0, 0) * A(1, 1) - A(0, 1) * A(0, 1) > 0 && A.determinant() > 0;
}

/// The plastic part of the snow model: clamps the elastic singular values and tracks Jp.
struct SnowPlasticity {
  Real critical_compression = 2.5e-2;  ///< theta_c: elastic singular values >= 1 - theta_c.
  Real critical_stretch = 7.5e-3;      ///< theta_s: elastic singular values <= 1 + theta_s.
  Real hardening = 10;                 ///< xi: mu, lambda scale by exp(xi (1 - Jp)).
  Real min_Jp = 0;                     ///< Jp is kept >= this (0: no clamp, the paper's model).
  Real initial_Jp_spread = 0;          ///< Jp starts in [1 - this, 1 + this] (0: Jp = 1).
  /// l, m: with initial_Jp_spread, Jp varies smoothly in space over this length (weak zones
  /// a few cells wide); 0: independently per particle.
  Real initial_Jp_correlation = 0;

  /// Moves the part of Fe outside the clamp range into the plastic part (section 7):
  /// Fe = U clamp(Sigma) V^T and Jp *= det(Sigma) / det(clamp(Sigma)), so det(Fe) Jp is kept
  /// (unless min_Jp clamps Jp). Returns false if Fe was left unchanged.
  bool project(Mat3& Fe, Real& Jp) const {
    const Real lo = 1 - critical_compression, hi = 1 + critical_stretch;  // 0 < lo <= 1 <= hi
    // The common case: all singular values inside (lo, hi), so the clamp changes nothing. That
    // holds iff det Fe > 0 and Fe^T Fe - lo^2 I and hi^2 I - Fe^T Fe are positive definite.
    const Mat3 C = Fe.transpose() * Fe;
    if (Fe.determinant() > 0 && positive_definite(C - lo * lo * Mat3::Identity()) &&
        positive_definite(hi * hi * Mat3::Identity() - C)) {
      Jp = std::max(Jp, min_Jp);
      return false;
    }
    // Fe = R S with S = V Sigma V^T (Sigma signed as in svd_rv), so U = R V.
    Mat3 R, S, V;
    Vec3 s;
    polar_decomposition(Fe, R, S);
    symmetric_eigen(S, s, V);
    const Vec3 c = s.cwiseMax(lo).cwiseMin(hi);
    // A Jp clamp (as several codes do) bounds the hardening, and so the CFL step, at the
    // price of not keeping det(Fe) Jp once it acts.
    Jp = std::max(Jp * s.prod() / c.prod(), min_Jp);
    Fe = R * V * c.asDiagonal() * V.transpose();
    return true;
  }

  /// Hardening factor exp(xi (1 - Jp)) applied to mu and lambda.
  Real hardening_factor(Real Jp) const { return std::exp(hardening * (1 - Jp)); }

  /// Starting Jp of the particle with index `index` in its group, sampled at `x` (m): 1, or
  /// with a spread s > 0, 1 + s n, so the snow's hardness exp(xi (1 - Jp)) varies by up to
  /// exp(xi s) either way. With a correlation length l > 0, n = value_noise(x / l, seed), a
  /// smooth field in [-1, 1] (weak zones of size ~l); else n = 2 u - 1 for u uniform in [0, 1)
  /// from a hash of the index. Deterministic for any thread count.
  Real initial_Jp(std::uint64_t index, const Vec3& x = Vec3::Zero(), std::uint64_t seed = 1) const {
    if (initial_Jp_spread == 0) return 1;
    if (initial_Jp_correlation > 0)
      return 1 + initial_Jp_spread * value_noise(x / initial_Jp_correlation, seed);
    return 1 + initial_Jp_spread * (2 * unit_hash(index * 0x9e3779b97f4a7c15ull) - 1);
  }

  /// engine/core/hash.h's splitmix64, with an increment of its own.
  static std::uint64_t mix(std::uint64_t z) { return splitmix64(z, 0x632be59bd9b4e019ull); }

  /// A uniform number in [0, 1) from a 64-bit key.
  static Real unit_hash(std::uint64_t z) { return unit_from_bits(mix(z)); }

  /// Value noise in [-1, 1] at u (in lattice units): uniform values at the integer lattice
  /// points, from a hash of (seed, i, j, k), blended with the smoothstep weights 3t^2 - 2t^3
  /// (Perlin 1985's lattice noise with values instead of gradients; continuous with a
  /// continuous gradient, correlated over about one lattice spacing).
  static Real value_noise(const Vec3& u, std::uint64_t seed) {
    const Vec3 f = u.array().floor();
    const Vec3 t = u - f;
    const Vec3 w = t.array().square() * (3 - 2 * t.array());
    Real n = 0;
    for (int c = 0; c < 8; ++c) {
      std::uint64_t key = mix(seed);
      Real weight = 1;
      for (int a = 0; a < 3; ++a) {
        const int bit = (c >> a) & 1;
        key = mix(key ^ static_cast<std::uint64_t>(static_cast<std::int64_t>(f[a]) + bit));
        weight *= bit ? w[a] : 1 - w[a];
      }
      n += weight * (2 * unit_hash(key) - 1);
    }
    return n;
  }
};

/// MaterialGroup for snow: per-particle Jp, allocated for this group's particles only.
class SnowGroup final : public PlasticGroup<SnowGroup> {
 public:
  /// `elastic` holds the unhardened mu0 and lambda0; `count` particles start with
  /// plastic.initial_Jp(p, x[p], seed) (1 unless initial_Jp_spread > 0). `x`, the sampled
  /// positions, may be empty (a group rebuilt to take restored state): Jp then starts at 1.
  SnowGroup(const FixedCorotated& elastic, const SnowPlasticity& plastic, Real rho0,
            std::size_t count, std::span<const Vec3> x = {}, std::uint64_t seed = 1)
      : PlasticGroup(std::vector<Real>(count, 1)),
        elastic_(elastic),
        plastic_(plastic),
        rho0_(rho0) {
    const bool spatial = plastic_.initial_Jp_correlation > 0;
    if (spatial && x.size() != count) return;
    for (std::size_t p = 0; p < count; ++p)
      state_[p] = plastic_.initial_Jp(p, spatial ? x[p] : Vec3::Zero(), seed);
  }

  /// The elastic model of particle p: the moduli hardened by its Jp (PlasticGroup).
  FixedCorotated elastic_model(std::ptrdiff_t p) const {
    const Real h = plastic_.hardening_factor(state_[p]);
    return {elastic_.mu * h, elastic_.lambda * h};
  }

  /// The largest wave speed of particle p at F (PlasticGroup): hardened moduli, at the
  /// current density rho0 / (Je Jp) (references.md, "Time step"), m/s.
  Real wave_speed(const Mat3& F, std::ptrdiff_t p) const {
    const FixedCorotated m = elastic_model(p);
    const Real J = std::max(std::abs(F.determinant()) * state_[p], Real(1e-6));
    return std::sqrt((m.lambda + 2 * m.mu) * J / rho0_);
  }

  /// Clamps particle p's singular values and moves the rest into its Jp (PlasticGroup).
  void project(StoredMat3& F, std::ptrdiff_t p) {
    Mat3 Fe = to_real(F);
    if (plastic_.project(Fe, state_[p])) F = to_stored(Fe);
  }

  /// Snow in lanes: the hardened corotated stress and the clamp.
  BatchModel batch_model() const override {
    BatchModel b{BatchModel::Kind::snow, elastic_.mu, elastic_.lambda};
    b.hardening = plastic_.hardening;
    b.critical_compression = plastic_.critical_compression;
    b.critical_stretch = plastic_.critical_stretch;
    b.min_Jp = plastic_.min_Jp;
    b.rho0 = rho0_;
    b.state = state_.data();
    return b;
  }

  /// Plastic volume ratio Jp of each particle in the group.
  const std::vector<Real>& Jp() const { return state_; }
  /// Mutable Jp, for tests and restarts.
  std::vector<Real>& Jp() { return state_; }

 private:
  FixedCorotated elastic_;
  SnowPlasticity plastic_;
  Real rho0_;
};

}  // namespace mpm::materials
