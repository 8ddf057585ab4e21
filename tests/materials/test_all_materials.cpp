// Checks every registered material gets for free, the example plugin's included: write a
// material, register it, and these run on it with no new test code.
#include <catch2/catch.hpp>

#include <cmath>

#include "materials/plugin.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// The built-in materials plus the example plugin.
MaterialRegistry all_materials() {
  MaterialRegistry r = builtin_registry();
  load_plugin(MPM_STVK_PLUGIN, r);
  return r;
}

/// Parameters at their defaults (typical values for required ones), Pa-valued ones scaled.
ParamValues params_of(const MaterialInfo& m, double stiffness_scale = 1) {
  ParamValues v;
  for (const ParamSpec& p : m.params)
    v[p.name] = p.default_value * (p.unit == "Pa" ? stiffness_scale : 1);
  return v;
}

/// One particle of material `m`, with V0 = 1 so group totals are densities. F goes in, and
/// the stress comes out, in the stored precision (test::stored), as in the engine.
struct OneParticle {
  std::unique_ptr<MaterialGroup> group;
  explicit OneParticle(const MaterialInfo& m, double stiffness_scale = 1)
      : group(m.create(params_of(m, stiffness_scale), GroupInfo{1000, 1})) {}
  Mat3 kirchhoff(const Mat3& F) const {
    const StoredMat3 Fs = to_stored(F);
    StoredMat3 out;
    group->compute_stress({&Fs, 1}, 1.0, {&out, 1});
    return -to_real(out);
  }
  Real energy(const Mat3& F) const {
    const StoredMat3 Fs = to_stored(F);
    return group->elastic_energy({&Fs, 1}, 1.0);
  }
  Mat3 first_piola(const Mat3& F) const {
    return kirchhoff(F) * test::stored(F).inverse().transpose();
  }
  Real wave_speed(const Mat3& F) const {
    const StoredMat3 Fs = to_stored(F);
    return group->max_wave_speed({&Fs, 1});
  }
};

/// Stress error from storing F and the stress in StoredReal, relative to E: entries of F
/// rounded by eps / 2 strain a rotation by at most 3 eps, which costs at most about
/// (2 mu + 3 lambda) 3 eps < 10 E eps for nu <= 0.3; 50 E eps leaves a margin. Zero in double.
constexpr double kStorageStress = 50 * test::kStoredEps;

/// A stress scale for tolerances: the material's E (or its first Pa parameter).
double stress_scale(const MaterialInfo& m) {
  for (const ParamSpec& p : m.params)
    if (p.unit == "Pa") return p.default_value;
  return 1;
}

}  // namespace

TEST_CASE("every material: zero stress at rest and under pure rotation", "[materials]") {
  const MaterialRegistry reg = all_materials();
  std::mt19937 rng(1);
  for (const MaterialInfo& m : reg.all()) {
    INFO("material " << m.name);
    const OneParticle p(m);
    const double tol = (1e-9 + kStorageStress) * stress_scale(m);
    CHECK(p.kirchhoff(Mat3::Identity()).norm() <= tol);
    CHECK(std::abs(p.energy(Mat3::Identity())) <= tol);
    for (int k = 0; k < 10; ++k) CHECK(p.kirchhoff(test::random_rotation(rng)).norm() <= tol);
  }
}

TEST_CASE("every material: P equals dpsi/dF by central differences", "[materials]") {
  const MaterialRegistry reg = all_materials();
  for (const MaterialInfo& m : reg.all()) {
    INFO("material " << m.name);
    const OneParticle p(m);
    std::mt19937 rng(2);
    for (int k = 0; k < 30; ++k) {
      const Mat3 F =
          test::stored(test::random_rotation(rng) * test::random_near_identity(rng, 0.25));
      const Mat3 P = p.first_piola(F);
      Mat3 Pn;
      const double eps = 1e-5;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          // The perturbed F as stored: the step actually taken, Fp - Fm, is then exact.
          Mat3 Fp = F, Fm = F;
          Fp(i, j) += eps;
          Fm(i, j) -= eps;
          Fp = test::stored(Fp);
          Fm = test::stored(Fm);
          Pn(i, j) = (p.energy(Fp) - p.energy(Fm)) / (Fp(i, j) - Fm(i, j));
        }
      INFO("F =\n" << F << "\nP =\n" << P << "\nnumeric =\n" << Pn);
      // Truncation O(eps^2 psi'''), round-off O(psi * 1e-16 / eps), the off-centre step from
      // rounding Fp and Fm (eps_stored / 2 against 2 eps, times psi'') and P stored to
      // eps_stored: all far below this.
      CHECK((P - Pn).norm() <= 1e-6 * stress_scale(m) * (1 + F.norm()));
    }
  }
}

TEST_CASE("every material: frame indifference and isotropy", "[materials]") {
  const MaterialRegistry reg = all_materials();
  for (const MaterialInfo& m : reg.all()) {
    INFO("material " << m.name);
    const OneParticle p(m);
    std::mt19937 rng(3);
    for (int k = 0; k < 20; ++k) {
      const Mat3 F = test::random_near_identity(rng, 0.3);
      const Mat3 R = test::random_rotation(rng), Q = test::random_rotation(rng);
      const Mat3 tau = p.kirchhoff(F);
      const double tol =
          (1e-9 + kStorageStress) * stress_scale(m) * (1 + tau.norm() / stress_scale(m));
      // P(RF) = R P(F), i.e. tau(RF) = R tau(F) R^T.
      CHECK((p.kirchhoff(R * F) - R * tau * R.transpose()).norm() <= tol);
      CHECK((p.first_piola(R * F) - R * p.first_piola(F)).norm() <= tol);
      // Isotropy: psi(F Q) = psi(F), so tau(F Q) = tau(F).
      CHECK((p.kirchhoff(F * Q) - tau).norm() <= tol);
      CHECK(p.energy(F * Q) ==
            Approx(p.energy(F)).epsilon(1e-9).margin((1e-9 + kStorageStress) * stress_scale(m)));
    }
  }
}

TEST_CASE("every material: finite for nearly singular and inverted F", "[materials]") {
  const MaterialRegistry reg = all_materials();
  std::mt19937 rng(4);
  for (const MaterialInfo& m : reg.all()) {
    INFO("material " << m.name);
    if (!m.supports_inversion) continue;  // the material says it does not claim this
    const OneParticle p(m);
    for (double det : {1e-6, -0.5}) {
      INFO("det F = " << det);
      const Mat3 F =
          test::random_rotation(rng) * Vec3(1.1, 0.9, det / 0.99).asDiagonal() *
          test::random_rotation(rng);
      REQUIRE(F.determinant() == Approx(det));
      CHECK(p.kirchhoff(F).allFinite());
      CHECK(std::isfinite(p.energy(F)));
      CHECK(std::isfinite(p.wave_speed(F)));
    }
  }
}

TEST_CASE("every material: positive wave speed that grows with stiffness", "[materials]") {
  const MaterialRegistry reg = all_materials();
  for (const MaterialInfo& m : reg.all()) {
    INFO("material " << m.name);
    const OneParticle soft(m, 1), stiff(m, 4);
    const Mat3 F = Vec3(1.05, 0.97, 1.0).asDiagonal();
    CHECK(soft.wave_speed(F) > 0);
    CHECK(stiff.wave_speed(F) > soft.wave_speed(F));
    // For a linear-elastic limit c = sqrt((lambda + 2 mu) / rho): four times E, twice c.
    CHECK(stiff.wave_speed(Mat3::Identity()) ==
          Approx(2 * soft.wave_speed(Mat3::Identity())).epsilon(1e-9));
  }
}
