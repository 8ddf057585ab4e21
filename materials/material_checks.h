#pragma once
/// \file The generic checks every material must pass, on one particle at a time: zero stress
/// at rest, P = dpsi/dF by central differences, frame indifference and isotropy, finite
/// results for nearly singular and inverted F, and a wave speed that grows with stiffness.
///
/// Header-only and installed with the plugin API. The engine's tests run them on every
/// registered material (tests/materials/test_all_materials.cpp), and the installed program
/// `mpm_material_check PLUGIN.so` runs them on a plugin's materials (CMake:
/// mpm_add_material_tests, docs/materials.md).

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "materials/material.h"

namespace mpm::checks {

/// Machine epsilon of the particles' stored matrices (F, C, stress): float unless the build
/// sets MPM_DOUBLE_PARTICLES. Tolerances that include storage rounding scale with it.
inline constexpr double kStoredEps = std::numeric_limits<StoredReal>::epsilon();

/// `F` rounded to the stored precision, as the engine would keep it.
inline Mat3 stored(const Mat3& F) { return to_real(to_stored(F)); }

/// A random matrix with entries in [-scale, scale] added to the identity.
inline Mat3 random_near_identity(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  Mat3 m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = (i == j ? 1.0 : 0.0) + u(rng);
  return m;
}

/// A uniformly random rotation.
inline Mat3 random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> n;
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  return q.normalized().toRotationMatrix();
}

/// Parameters at their defaults (typical values for required ones), Pa-valued ones scaled.
inline ParamValues params_of(const MaterialInfo& m, double stiffness_scale = 1) {
  ParamValues v;
  for (const ParamSpec& p : m.params)
    v[p.name] = p.default_value * (p.unit == "Pa" ? stiffness_scale : 1);
  return v;
}

/// A stress scale for tolerances: the material's first Pa-valued parameter's default (E).
inline double stress_scale(const MaterialInfo& m) {
  for (const ParamSpec& p : m.params)
    if (p.unit == "Pa") return p.default_value;
  return 1;
}

/// Stress error from storing F and the stress in StoredReal, relative to E: entries of F
/// rounded by eps / 2 strain a rotation by at most 3 eps, which costs at most about
/// (2 mu + 3 lambda) 3 eps < 10 E eps for nu <= 0.3; 50 E eps leaves a margin. Zero in double.
inline constexpr double kStorageStress = 50 * kStoredEps;

/// One particle of material `m` (density 1000), with V0 = 1 so group totals are densities.
/// F goes in, and the stress comes out, in the stored precision, as in the engine.
struct OneParticle {
  std::unique_ptr<MaterialGroup> group;  ///< Built by the material's factory.
  /// A group for one particle, parameters at their defaults and Pa ones times the scale.
  explicit OneParticle(const MaterialInfo& m, double stiffness_scale = 1)
      : group(m.create(params_of(m, stiffness_scale), GroupInfo{1000, 1})) {}
  /// Kirchhoff stress tau at F.
  Mat3 kirchhoff(const Mat3& F) const {
    const StoredMat3 Fs = to_stored(F);
    StoredMat3 out;
    group->compute_stress({&Fs, 1}, 1.0, {&out, 1});
    return -to_real(out);
  }
  /// Energy density psi(F).
  Real energy(const Mat3& F) const {
    const StoredMat3 Fs = to_stored(F);
    return group->elastic_energy({&Fs, 1}, 1.0);
  }
  /// First Piola-Kirchhoff stress P = tau F^-T.
  Mat3 first_piola(const Mat3& F) const { return kirchhoff(F) * stored(F).inverse().transpose(); }
  /// Wave speed the material reports at F.
  Real wave_speed(const Mat3& F) const {
    const StoredMat3 Fs = to_stored(F);
    return group->max_wave_speed({&Fs, 1});
  }
};

/// What failed in one check of one material: empty if it passed.
using Failures = std::vector<std::string>;

/// Zero stress and energy at F = I, zero stress under pure rotations.
inline Failures check_rest(const MaterialInfo& m) {
  Failures out;
  const OneParticle p(m);
  std::mt19937 rng(1);
  const double tol = (1e-9 + kStorageStress) * stress_scale(m);
  std::ostringstream s;
  if (const double t = p.kirchhoff(Mat3::Identity()).norm(); !(t <= tol))
    s << "|tau(I)| = " << t << " > " << tol << "\n";
  if (const double e = std::abs(p.energy(Mat3::Identity())); !(e <= tol))
    s << "|psi(I)| = " << e << " > " << tol << "\n";
  for (int k = 0; k < 10; ++k) {
    const Mat3 R = random_rotation(rng);
    if (const double t = p.kirchhoff(R).norm(); !(t <= tol))
      s << "|tau(R)| = " << t << " > " << tol << " for the rotation R =\n" << R << "\n";
  }
  if (!s.str().empty()) out.push_back(s.str());
  return out;
}

/// P = dpsi/dF by central differences on 30 random F.
inline Failures check_piola(const MaterialInfo& m) {
  Failures out;
  const OneParticle p(m);
  std::mt19937 rng(2);
  for (int k = 0; k < 30; ++k) {
    const Mat3 F = stored(random_rotation(rng) * random_near_identity(rng, 0.25));
    const Mat3 P = p.first_piola(F);
    Mat3 Pn;
    const double eps = 1e-5;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        // The perturbed F as stored: the step actually taken, Fp - Fm, is then exact.
        Mat3 Fp = F, Fm = F;
        Fp(i, j) += eps;
        Fm(i, j) -= eps;
        Fp = stored(Fp);
        Fm = stored(Fm);
        Pn(i, j) = (p.energy(Fp) - p.energy(Fm)) / (Fp(i, j) - Fm(i, j));
      }
    // Truncation O(eps^2 psi'''), round-off O(psi * 1e-16 / eps), the off-centre step from
    // rounding Fp and Fm (eps_stored / 2 against 2 eps, times psi'') and P stored to
    // eps_stored: all far below this.
    const double tol = 1e-6 * stress_scale(m) * (1 + F.norm());
    if (!((P - Pn).norm() <= tol)) {
      std::ostringstream s;
      s << "|P - dpsi/dF| = " << (P - Pn).norm() << " > " << tol << " at F =\n"
        << F << "\nP =\n" << P << "\nnumeric =\n" << Pn << "\n";
      out.push_back(s.str());
    }
  }
  return out;
}

/// Frame indifference, P(RF) = R P(F), and isotropy, psi(FQ) = psi(F), on 20 random F.
inline Failures check_frame_indifference(const MaterialInfo& m) {
  Failures out;
  const OneParticle p(m);
  std::mt19937 rng(3);
  for (int k = 0; k < 20; ++k) {
    const Mat3 F = random_near_identity(rng, 0.3);
    const Mat3 R = random_rotation(rng), Q = random_rotation(rng);
    const Mat3 tau = p.kirchhoff(F);
    const double tol =
        (1e-9 + kStorageStress) * stress_scale(m) * (1 + tau.norm() / stress_scale(m));
    std::ostringstream s;
    // P(RF) = R P(F), i.e. tau(RF) = R tau(F) R^T.
    if (const double d = (p.kirchhoff(R * F) - R * tau * R.transpose()).norm(); !(d <= tol))
      s << "|tau(RF) - R tau(F) R^T| = " << d << " > " << tol << "\n";
    if (const double d = (p.first_piola(R * F) - R * p.first_piola(F)).norm(); !(d <= tol))
      s << "|P(RF) - R P(F)| = " << d << " > " << tol << "\n";
    // Isotropy: psi(F Q) = psi(F), so tau(F Q) = tau(F).
    if (const double d = (p.kirchhoff(F * Q) - tau).norm(); !(d <= tol))
      s << "|tau(FQ) - tau(F)| = " << d << " > " << tol << "\n";
    const double e = p.energy(F), eq = p.energy(F * Q);
    const double margin = (1e-9 + kStorageStress) * stress_scale(m);
    if (!(std::abs(eq - e) <= margin || std::abs(eq - e) <= 1e-9 * std::abs(e)))
      s << "psi(FQ) = " << eq << " differs from psi(F) = " << e << "\n";
    if (!s.str().empty()) {
      s << "at F =\n" << F << "\nR =\n" << R << "\nQ =\n" << Q << "\n";
      out.push_back(s.str());
    }
  }
  return out;
}

/// Finite stress, energy and wave speed for det F = 1e-6 and -0.5; skipped (no failures) for
/// a material whose MaterialInfo::supports_inversion is false.
inline Failures check_inversion(const MaterialInfo& m) {
  Failures out;
  if (!m.supports_inversion) return out;
  const OneParticle p(m);
  std::mt19937 rng(4);
  for (double det : {1e-6, -0.5}) {
    const Mat3 F =
        random_rotation(rng) * Vec3(1.1, 0.9, det / 0.99).asDiagonal() * random_rotation(rng);
    if (!p.kirchhoff(F).allFinite() || !std::isfinite(p.energy(F)) ||
        !std::isfinite(p.wave_speed(F))) {
      std::ostringstream s;
      s << "not finite at det F = " << det << ": tau =\n"
        << p.kirchhoff(F) << "\npsi = " << p.energy(F) << ", wave speed " << p.wave_speed(F)
        << ", F =\n" << F << "\n";
      out.push_back(s.str());
    }
  }
  return out;
}

/// A positive wave speed that grows with stiffness: four times every Pa parameter, twice the
/// speed at rest (c = sqrt(M / rho) for a modulus M).
inline Failures check_wave_speed(const MaterialInfo& m) {
  Failures out;
  const OneParticle soft(m, 1), stiff(m, 4);
  const Mat3 F = Vec3(1.05, 0.97, 1.0).asDiagonal();
  std::ostringstream s;
  if (!(soft.wave_speed(F) > 0)) s << "wave speed " << soft.wave_speed(F) << " is not positive\n";
  if (!(stiff.wave_speed(F) > soft.wave_speed(F)))
    s << "four times stiffer, the wave speed " << stiff.wave_speed(F) << " is not above "
      << soft.wave_speed(F) << "\n";
  const double c1 = soft.wave_speed(Mat3::Identity()), c4 = stiff.wave_speed(Mat3::Identity());
  if (!(std::abs(c4 - 2 * c1) <= 1e-9 * 2 * c1))
    s << "at rest, four times stiffer gives wave speed " << c4 << ", not twice " << c1 << "\n";
  if (!s.str().empty()) out.push_back(s.str());
  return out;
}

/// For a fluid (water): the stress is a pure pressure set by J alone. On 20 random F,
/// dev(tau(F)) = 0 and tau(F) = tau(J^(1/3) I), also for F sheared at the same J. Not in
/// all_checks(): it applies only to materials that store no shear (tests run it on water, and
/// check that it fails for an elastic solid).
inline Failures check_pressure_only(const MaterialInfo& m) {
  Failures out;
  const OneParticle p(m);
  std::mt19937 rng(5);
  for (int k = 0; k < 20; ++k) {
    const Mat3 F = stored(random_rotation(rng) * random_near_identity(rng, 0.2));
    const double J = stored(F).determinant();
    const Mat3 iso = stored(std::cbrt(J) * Mat3::Identity());
    const Mat3 tau = p.kirchhoff(F), tau_iso = p.kirchhoff(iso);
    const Mat3 dev = tau - tau.trace() / 3 * Mat3::Identity();
    // J of the stored F and of the stored J^(1/3) I differ by a few eps_stored, which moves
    // the pressure by about K (gamma + 1) 3 eps_stored.
    const double tol =
        (1e-9 + kStorageStress) * stress_scale(m) * (1 + tau.norm() / stress_scale(m));
    std::ostringstream s;
    if (const double d = dev.norm(); !(d <= tol))
      s << "|dev tau(F)| = " << d << " > " << tol << "\n";
    if (const double d = (tau - tau_iso).norm(); !(d <= tol))
      s << "|tau(F) - tau(J^(1/3) I)| = " << d << " > " << tol << " (J = " << J << ")\n";
    if (!s.str().empty()) {
      s << "at F =\n" << F << "\n";
      out.push_back(s.str());
    }
  }
  return out;
}

/// One named generic check.
/// A group with a lane kernel (MaterialGroup::has_lane_stress): its lane_stress equals its
/// compute_stress to float rounding, on 64 random F from near rest to 30 % strain, in batches of
/// kStressLanes with some lanes unused. A group without one passes.
inline Failures check_lane_stress(const MaterialInfo& m) {
  Failures out;
  constexpr std::size_t n = 4 * kStressLanes;
  const auto group = m.create(params_of(m), GroupInfo{1000, n});
  if (!group->has_lane_stress()) return out;
  std::mt19937 rng(3);
  std::vector<StoredMat3> F(n), ref(n);
  for (std::size_t q = 0; q < n; ++q)
    F[q] = to_stored(random_rotation(rng) * random_near_identity(rng, 0.3 * q / n));
  const Real v0 = 1e-6;
  group->compute_stress(F, v0, ref);
  // Float rounding of F and of the stress, amplified by the moduli: 100 float eps of E V0.
  const double tol = 100 * std::numeric_limits<float>::epsilon() * stress_scale(m) * v0;
  std::ostringstream s;
  for (std::size_t q0 = 0; q0 < n; q0 += kStressLanes) {
    StressLanes batch;
    batch.count = q0 == 0 ? kStressLanes : kStressLanes - q0 / kStressLanes;  // some unused
    for (std::size_t l = 0; l < kStressLanes; ++l) {
      const std::size_t q = q0 + (l < batch.count ? l : 0);
      for (int e = 0; e < 9; ++e) batch.F[e][l] = static_cast<float>(F[q].data()[e]);
      batch.index[l] = static_cast<std::uint32_t>(q);
    }
    group->lane_stress(batch, v0);
    for (std::size_t l = 0; l < batch.count; ++l) {
      Mat3 tau;
      for (int e = 0; e < 9; ++e) tau.data()[e] = batch.tau[e][l];
      if (const double d = (tau - to_real(ref[q0 + l])).norm(); !(d <= tol))
        s << "lane_stress differs from compute_stress by " << d << " > " << tol << " at particle "
          << q0 + l << "\n";
    }
  }
  if (!s.str().empty()) out.push_back(s.str());
  return out;
}

struct Check {
  const char* name;                        ///< Short name, e.g. "rest".
  const char* what;                        ///< What it checks, one line.
  Failures (*run)(const MaterialInfo& m);  ///< Runs it on one material.
};

/// Every generic check, in order.
inline const std::vector<Check>& all_checks() {
  static const std::vector<Check> checks = {
      {"rest", "zero stress at rest and under pure rotation", check_rest},
      {"piola", "P equals dpsi/dF by central differences", check_piola},
      {"frame_indifference", "frame indifference and isotropy", check_frame_indifference},
      {"inversion", "finite for nearly singular and inverted F", check_inversion},
      {"wave_speed", "positive wave speed that grows with stiffness", check_wave_speed},
      {"lane_stress", "lane_stress equals compute_stress to float rounding", check_lane_stress},
  };
  return checks;
}

}  // namespace mpm::checks
