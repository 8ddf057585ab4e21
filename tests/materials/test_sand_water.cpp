// Model-specific checks of sand (Drucker-Prager on the Hencky strain, Klar et al. 2016) and
// water (Tait): the return mapping's three cases, the friction angle, cohesion and volume
// correction; the Tait pressure, sound speed and the projection F = J^(1/3) I.
#include <catch2/catch.hpp>
#include <numbers>

#include "materials/sand.h"
#include "materials/water.h"
#include "support/helpers.h"

using namespace mpm;
using materials::DruckerPragerSand;
using materials::TaitWater;

namespace {

/// Sand with E = 1e5, nu = 0.3, friction angle `phi_deg` and cohesion `c`.
DruckerPragerSand sand(double phi_deg = 30, double c = 0, bool volume_correction = false) {
  const Lame l = lame_from_young(1e5, 0.3);
  const double phi = phi_deg * std::numbers::pi / 180;
  return {l.mu, l.lambda, DruckerPragerSand::cone_alpha(phi),
          3 * c / std::tan(phi) / (3 * l.lambda + 2 * l.mu), volume_correction};
}

/// |dev tau| - alpha (tr tau_apex - tr tau) for principal Hencky strains `e`: <= 0 inside.
double yield(const DruckerPragerSand& m, const Vec3& e) {
  const Vec3 t = m.principal_kirchhoff(e);
  const double tr_apex = (3 * m.lambda + 2 * m.mu) * m.apex_trace;
  return (t.array() - t.sum() / 3).matrix().norm() - m.alpha * (tr_apex - t.sum());
}

const MaterialInfo& info(const std::string& name) {
  static const MaterialRegistry reg = builtin_registry();
  return *reg.find(name);
}

}  // namespace

TEST_CASE("sand: the return mapping ends on or inside the cone", "[materials][sand]") {
  for (double c : {0.0, 50.0}) {
    const DruckerPragerSand m = sand(30, c);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-0.02, 0.02);
    int inside = 0, tip = 0, cone = 0;
    for (int k = 0; k < 300; ++k) {
      const Vec3 trial(u(rng), u(rng), u(rng));
      Vec3 e = trial;
      Real vc = 0;
      const bool changed = m.project(e, vc);
      INFO("c = " << c << ", trial eps = " << trial.transpose() << ", projected " << e.transpose());
      const double scale = (3 * m.lambda + 2 * m.mu) * 0.02;
      CHECK(yield(m, e) <= 1e-12 * scale);
      if (!changed) {
        ++inside;
        CHECK(yield(m, trial) <= 0);
        CHECK(e == trial);
      } else if (trial.sum() >= m.apex_trace) {
        ++tip;  // case II: the apex, an isotropic strain
        CHECK((e.array() - m.apex_trace / 3).abs().maxCoeff() <= 1e-15);
      } else {
        ++cone;  // case III: on the cone, same trace, deviator shortened in the same direction
        CHECK(yield(m, e) == Approx(0).margin(1e-10 * scale));
        CHECK(e.sum() == Approx(trial.sum()).margin(1e-15));
        const Vec3 d0 = (trial.array() - trial.sum() / 3).matrix();
        const Vec3 d1 = (e.array() - e.sum() / 3).matrix();
        CHECK(d1.norm() < d0.norm());
        CHECK(d1.normalized().dot(d0.normalized()) == Approx(1));
      }
      // Projecting again changes nothing.
      Vec3 again = e;
      m.project(again, vc);
      CHECK((again - e).norm() <= 1e-15);
    }
    CHECK(inside > 10);  // all three cases were exercised
    CHECK(tip > 10);
    CHECK(cone > 10);
  }
}

TEST_CASE("sand: no tension without cohesion, up to c cot(phi) with it", "[materials][sand]") {
  const Mat3 stretched = Vec3(1.01, 1.002, 1.0).asDiagonal();
  materials::SandGroup loose(sand(30, 0), 1600, 1);
  std::vector<StoredMat3> F{to_stored(stretched)};
  loose.apply_plasticity(F);
  CHECK(to_real(F[0]).isApprox(Mat3::Identity(), 1e-6));
  CHECK(sand(30, 0).kirchhoff(to_real(F[0])).norm() <= 1e-3);  // ~ E * eps_stored
  // With cohesion c, an isotropic stretch keeps its tension up to tr tau = 3 c cot(phi).
  const double c = 100, phi = 30 * std::numbers::pi / 180;
  const DruckerPragerSand m = sand(30, c);
  for (double s : {0.25, 4.0}) {
    Vec3 e = Vec3::Constant(s * m.apex_trace / 3);
    Real vc = 0;
    m.project(e, vc);
    const double tr_tau = m.principal_kirchhoff(e).sum();
    CHECK(tr_tau == Approx(std::min(s, 1.0) * 3 * c / std::tan(phi)));
  }
}

TEST_CASE("sand: a larger friction angle holds more shear", "[materials][sand]") {
  // A sheared, slightly compressed trial strain, outside every cone here (|dev tau| / -tr tau
  // = 1.5 against alpha <= 0.56): the deviator kept on the cone grows with phi.
  const Vec3 trial(-0.02, 0.0, 0.015);
  double last = 0;
  for (double phi : {10.0, 20.0, 30.0, 40.0, 50.0}) {
    const DruckerPragerSand m = sand(phi);
    Vec3 e = trial;
    Real vc = 0;
    INFO("phi = " << phi);
    REQUIRE(m.project(e, vc));
    const Vec3 t = m.principal_kirchhoff(e);
    const double q = (t.array() - t.sum() / 3).matrix().norm() / -t.sum();
    CHECK(q == Approx(m.alpha).epsilon(1e-9));  // |dev tau| / -tr tau = alpha on the cone
    CHECK(q > last);
    last = q;
  }
}

TEST_CASE("sand: volume correction gives back the volume gained", "[materials][sand]") {
  const DruckerPragerSand m = sand(30, 0, true);
  // Stretch by 3 % in volume: projected to the apex, the gain is stored.
  Vec3 e = Vec3::Constant(std::log(1.03) / 3);
  Real vc = 0;
  CHECK(m.project(e, vc));
  CHECK(e.norm() == 0);
  CHECK(vc == Approx(std::log(1.03)));
  // Compress by 2 %: still within the gain, so no stress, and 1 % is left.
  e = Vec3::Constant(std::log(1 / 1.02) / 3);
  m.project(e, vc);
  CHECK(e.norm() == 0);
  CHECK(vc == Approx(std::log(1.03 / 1.02)));
  // Compress by 2 % more: only the 1 % beyond the gain strains the sand, and vc is spent.
  e = Vec3::Constant(std::log(1 / 1.02) / 3);
  m.project(e, vc);
  CHECK(e.sum() == Approx(std::log(1.03 / 1.02 / 1.02)));
  CHECK(vc == 0);
  // Without the correction the same compression is all elastic.
  const DruckerPragerSand off = sand(30, 0, false);
  Vec3 e2 = Vec3::Constant(std::log(1 / 1.02) / 3);
  Real vc2 = 0;
  CHECK_FALSE(off.project(e2, vc2));
  CHECK(vc2 == 0);
}

TEST_CASE("sand: the group projects F and keeps its rotation", "[materials][sand]") {
  materials::SandGroup g(sand(30), 1600, 2);
  std::mt19937 rng(12);
  const Mat3 R = test::random_rotation(rng);
  // Particle 0: a pure rotation times a small compression (inside); particle 1: stretched.
  std::vector<StoredMat3> F{to_stored(R * Vec3::Constant(0.999).asDiagonal()),
                            to_stored(R * Vec3(1.02, 1.0, 1.0).asDiagonal())};
  const StoredMat3 before = F[0];
  g.apply_plasticity(F);
  CHECK(F[0] == before);
  CHECK(to_real(F[1]).isApprox(R, 1e-6));  // to the apex: F = R
}

TEST_CASE("sand and water: the factories reject what they cannot do", "[materials]") {
  ParamValues v = checks::params_of(info("sand"));
  v["volume_correction"] = 0.5;
  CHECK_THROWS_WITH(info("sand").create(v, GroupInfo{1600, 1}),
                    Catch::Contains("volume_correction must be 0 (off) or 1 (on)"));
}

TEST_CASE("water: viscosity adds J 2 eta dev(sym(grad v)) from the F update", "[materials][water]") {
  // F_old = s I, F_new = (I + dt L) F_old: the group reads the rate of deformation back.
  const TaitWater m{2e5, 7};
  const double eta = 3, rho0 = 1000, dt = 1e-4, V0 = 2e-6, s = std::cbrt(0.99);
  std::mt19937 rng(21);
  Mat3 L;
  for (int i = 0; i < 9; ++i) L(i / 3, i % 3) = std::uniform_real_distribution<double>(-2, 2)(rng);
  materials::WaterGroup g(m, rho0, eta, 1);
  REQUIRE(g.state().size() == 6);
  std::vector<StoredMat3> F{to_stored(s * (Mat3::Identity() + dt * L))};
  const double J_new = to_real(F[0]).determinant();
  g.apply_plasticity_step(F, dt);
  const Mat3 Fp = to_real(F[0]);
  CHECK((Fp - Fp(0, 0) * Mat3::Identity()).norm() == 0);  // still F = J^(1/3) I
  const Mat3 D = 0.5 * (L + L.transpose()) - L.trace() / 3 * Mat3::Identity();
  std::vector<StoredMat3> out(1);
  g.compute_stress(F, V0, out);
  const double J = Fp.determinant();
  const Mat3 expected = -V0 * (-m.pressure(J) * J * Mat3::Identity() + 2 * eta * J * D);
  // The rate is exact to O(dt |L|^2) and to the storage rounding of F over dt.
  const double tol = 2 * eta * V0 * (dt * L.squaredNorm() + 8 * test::kStoredEps / dt);
  CHECK((to_real(out[0]) - expected).norm() <= tol + 1e-6 * expected.norm());
  CHECK(J == Approx(J_new).epsilon(1e-6));
  // eta / rho at the current density.
  CHECK(g.max_kinematic_viscosity(F) == Approx(eta * J / rho0));
  // Without viscosity: no state, no viscous bound.
  materials::WaterGroup plain(m, rho0);
  CHECK(plain.state().empty());
  CHECK(plain.max_kinematic_viscosity(F) == 0);
}

TEST_CASE("water: stress is a pressure set by J alone", "[materials][water]") {
  const checks::Failures f = checks::check_pressure_only(info("water"));
  for (const std::string& s : f) FAIL_CHECK(s);
  CHECK(f.empty());
  // The check can fail: an elastic solid has shear stress.
  CHECK(!checks::check_pressure_only(info("corotated")).empty());
  CHECK(!checks::check_pressure_only(info("sand")).empty());
}

TEST_CASE("water: Tait pressure, sound speed and F = J^(1/3) I", "[materials][water]") {
  const TaitWater m{2e5, 7};
  const double J = 0.98;
  const double p = 2e5 / 7 * (std::pow(J, -7.0) - 1);
  const Mat3 F = Vec3(1.0, 0.98, 1.0).asDiagonal();
  CHECK(m.kirchhoff(F).isApprox(-p * J * Mat3::Identity(), 1e-14));
  // c^2 = dp/drho at rho = rho0 / J, by central differences in rho.
  const double rho0 = 1000, rho = rho0 / J, d = 1e-3;
  const double dp = (m.pressure(rho0 / (rho + d)) - m.pressure(rho0 / (rho - d))) / (2 * d);
  CHECK(m.wave_speed(F, rho0) == Approx(std::sqrt(dp)).epsilon(1e-7));
  CHECK(m.wave_speed(Mat3::Identity(), rho0) == Approx(std::sqrt(2e5 / rho0)));
  // The plasticity stage drops shear and keeps J.
  materials::WaterGroup g(m, rho0);
  std::mt19937 rng(13);
  const Mat3 sheared = test::random_rotation(rng) * test::random_near_identity(rng, 0.1);
  std::vector<StoredMat3> Fs{to_stored(sheared)};
  g.apply_plasticity(Fs);
  const Mat3 Fp = to_real(Fs[0]);
  CHECK(Fp.determinant() == Approx(sheared.determinant()).epsilon(1e-6));
  CHECK((Fp - Fp(0, 0) * Mat3::Identity()).norm() == 0);
  // Crushed and inverted: the pressure stays finite and positive.
  CHECK(m.pressure(-0.5) == m.pressure(TaitWater::kJMin));
  CHECK(m.pressure(-0.5) > 0);
}
