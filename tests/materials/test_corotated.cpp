// Fixed corotated: stress at rest, stress as the derivative of the energy, Kirchhoff = P F^T.
#include <catch2/catch.hpp>

#include "materials/corotated.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

const Lame kLame = lame_from_young(1.0e4, 0.35);
const materials::FixedCorotated kModel{kLame.mu, kLame.lambda};

/// dpsi/dF by central differences.
Mat3 numeric_piola(const materials::FixedCorotated& m, const Mat3& F, double eps) {
  Mat3 P;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      Mat3 Fp = F, Fm = F;
      Fp(i, j) += eps;
      Fm(i, j) -= eps;
      P(i, j) = (m.energy(Fp) - m.energy(Fm)) / (2 * eps);
    }
  return P;
}

}  // namespace

TEST_CASE("corotated: zero stress and energy at rest and under rotation", "[materials]") {
  CHECK(kModel.first_piola(Mat3::Identity()).norm() < 1e-9);
  CHECK(kModel.energy(Mat3::Identity()) == Approx(0).margin(1e-12));
  std::mt19937 rng(7);
  for (int k = 0; k < 20; ++k) {
    const Mat3 R = test::random_rotation(rng);
    INFO("rotation " << k);
    CHECK(kModel.first_piola(R).norm() < 1e-8 * kLame.mu);
    CHECK(kModel.kirchhoff(R).norm() < 1e-8 * kLame.mu);
  }
}

TEST_CASE("corotated: P equals dpsi/dF by central differences", "[materials]") {
  std::mt19937 rng(11);
  for (int k = 0; k < 50; ++k) {
    const Mat3 F = test::random_rotation(rng) * test::random_near_identity(rng, 0.3);
    const Mat3 P = kModel.first_piola(F);
    const Mat3 Pn = numeric_piola(kModel, F, 1e-6);
    INFO("F = \n" << F << "\nP = \n" << P << "\nnumeric = \n" << Pn);
    // Central differences have error O(eps^2 psi''') plus round-off psi / eps.
    CHECK((P - Pn).norm() <= 1e-5 * (1 + P.norm()));
  }
}

TEST_CASE("corotated: Kirchhoff stress is P F^T and is symmetric", "[materials]") {
  std::mt19937 rng(3);
  for (int k = 0; k < 20; ++k) {
    const Mat3 F = test::random_near_identity(rng, 0.4);
    const Mat3 tau = kModel.kirchhoff(F);
    CHECK((tau - kModel.first_piola(F) * F.transpose()).norm() <= 1e-9 * (1 + tau.norm()));
    CHECK((tau - tau.transpose()).norm() <= 1e-9 * (1 + tau.norm()));
  }
}

TEST_CASE("corotated: uniaxial stretch matches the closed form", "[materials]") {
  // F = diag(s, 1, 1): R = I, J = s, P_xx = 2 mu (s - 1) + lambda (s - 1), P_yy = lambda (s - 1) s.
  const double s = 1.1;
  const Mat3 F = Vec3(s, 1, 1).asDiagonal();
  const Mat3 P = kModel.first_piola(F);
  CHECK(P(0, 0) == Approx(2 * kLame.mu * (s - 1) + kLame.lambda * (s - 1)));
  CHECK(P(1, 1) == Approx(kLame.lambda * (s - 1) * s));
  CHECK(P(0, 1) == Approx(0).margin(1e-9));
}

TEST_CASE("corotated: inverted F gives finite, restoring stress", "[materials]") {
  const Mat3 F = Vec3(1, 1, -0.5).asDiagonal();
  const Mat3 P = kModel.first_piola(F);
  REQUIRE(P.allFinite());
  // The energy falls when the inverted axis moves back toward +1.
  Mat3 F2 = F;
  F2(2, 2) += 0.01;
  CHECK(kModel.energy(F2) < kModel.energy(F));
}
