// Model-specific checks: Neo-Hookean closed forms and its extension below J_min; snow's
// return mapping and hardening.
#include <catch2/catch.hpp>

#include "materials/neo_hookean.h"
#include "materials/snow.h"
#include "support/helpers.h"

using namespace mpm;
using materials::NeoHookean;

TEST_CASE("neo_hookean: uniaxial stretch matches the closed form", "[materials]") {
  const Lame l = lame_from_young(1e4, 0.3);
  const NeoHookean m{l.mu, l.lambda};
  const double s = 1.3;
  // F = diag(s, 1, 1): P_xx = mu (s - 1/s) + lambda log(s) / s, P_yy = 0 + lambda log(s).
  const Mat3 P = m.first_piola(Vec3(s, 1, 1).asDiagonal());
  CHECK(P(0, 0) == Approx(l.mu * (s - 1 / s) + l.lambda * std::log(s) / s));
  CHECK(P(1, 1) == Approx(l.lambda * std::log(s)));
}

TEST_CASE("neo_hookean: the extension below J_min is continuous and restoring", "[materials]") {
  const Lame l = lame_from_young(1e4, 0.3);
  const NeoHookean m{l.mu, l.lambda};
  const double J0 = NeoHookean::kJMin;
  CHECK(m.g(J0 * (1 - 1e-9)) == Approx(m.g(J0)).epsilon(1e-7));
  CHECK(m.dg(J0 * (1 - 1e-9)) == Approx(m.dg(J0)).epsilon(1e-7));
  // The volumetric pressure pushes J up everywhere below J0, inverted states included.
  for (double J : {J0, 1e-3, 1e-6, 0.0, -0.5}) CHECK(m.dg(J) < 0);
  // Energy falls as an inverted element turns back.
  const Mat3 F = Vec3(1, 1, -0.5).asDiagonal();
  Mat3 F2 = F;
  F2(2, 2) += 0.01;
  CHECK(m.energy(F2) < m.energy(F));
}

TEST_CASE("snow: the return mapping clamps and keeps det(Fe) Jp", "[materials]") {
  const materials::SnowPlasticity plastic;  // the paper's theta_c, theta_s, xi
  std::mt19937 rng(9);
  for (int k = 0; k < 100; ++k) {
    Mat3 Fe = test::random_rotation(rng) * test::random_near_identity(rng, 0.1);
    Real Jp = 1.0 + 0.2 * (k % 3 - 1);
    const Real before = Fe.determinant() * Jp;
    plastic.project(Fe, Jp);
    Mat3 U, V;
    Vec3 s;
    svd_rv(Fe, U, s, V);
    INFO("sigma = " << s.transpose());
    CHECK(s.minCoeff() >= 1 - plastic.critical_compression - 1e-12);
    CHECK(s.maxCoeff() <= 1 + plastic.critical_stretch + 1e-12);
    CHECK(Fe.determinant() * Jp == Approx(before).epsilon(1e-12));
  }
}

TEST_CASE("snow: compression hardens, stretch softens", "[materials]") {
  const Lame l = lame_from_young(1.4e5, 0.2);
  const materials::SnowPlasticity plastic;
  materials::SnowGroup g(materials::FixedCorotated{l.mu, l.lambda}, plastic, 400, 3);
  // Squeeze all three particles by 10 % per axis: the plastic step keeps 2.5 % of it.
  std::vector<StoredMat3> F(3, to_stored(Vec3::Constant(0.9).asDiagonal()));
  g.apply_plasticity(F);
  CHECK(g.Jp()[0] == Approx(std::pow(0.9 / 0.975, 3)));
  CHECK(to_real(F[0]).diagonal().isApprox(Vec3::Constant(0.975), 10 * test::kStoredEps));
  g.Jp() = {1.0, 0.9, 1.1};  // unhardened, compressed, stretched
  std::vector<StoredMat3> out(3);
  const std::vector<StoredMat3> same(3, to_stored(Vec3(1.01, 0.99, 1.0).asDiagonal()));
  g.compute_stress(same, 1.0, out);
  CHECK(out[1].norm() == Approx(std::exp(1.0) * out[0].norm()));  // exp(xi (1 - 0.9))
  CHECK(out[2].norm() < out[0].norm());
}
