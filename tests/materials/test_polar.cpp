// The quaternion polar decomposition, the symmetric Jacobi eigensolver and the snow return
// mapping built on them, against their definitions and against the SVD they replace.
#include <catch2/catch.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

#include "materials/corotated.h"
#include "materials/snow.h"
#include "materials/svd.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// Q1 diag(s) Q2 for random rotations Q1, Q2: a matrix with singular values |s| (and the sign
/// of det given by the product of s).
Mat3 with_singular_values(std::mt19937& rng, const Vec3& s) {
  return test::random_rotation(rng) * s.asDiagonal() * test::random_rotation(rng);
}

/// R is a proper rotation, R^T F is symmetric, R maximises tr(R^T F) over rotations (the
/// maximum is sigma_1 + sigma_2 + sigma_3, sigma_3 signed as in svd_rv). `cond` scales the
/// tolerances on S, for ill-conditioned F.
void check_polar(const Mat3& F, double cond = 1) {
  const Mat3 R = polar_rotation(F);
  Mat3 U, V;
  Vec3 sigma;
  svd_rv(F, U, sigma, V);
  const Mat3 S = R.transpose() * F;
  const double scale = std::max(1.0, F.norm()) * cond;
  INFO("F =\n" << F << "\nR =\n" << R << "\nsigma = " << sigma.transpose());
  CHECK((R.transpose() * R - Mat3::Identity()).norm() <= 1e-14);
  CHECK(std::abs(R.determinant() - 1) <= 1e-14);
  CHECK((S - S.transpose()).norm() <= 1e-13 * scale);
  CHECK(std::abs(S.trace() - sigma.sum()) <= 1e-13 * scale);
}

/// check_polar, and R equals the SVD's U V^T to `tol` (R is unique here: sigma_2 + sigma_3 > 0).
void check_polar_against_svd(const Mat3& F, double tol, double cond = 1) {
  check_polar(F, cond);
  const Mat3 R = polar_rotation(F), Rs = polar_rotation_svd(F);
  INFO("F =\n" << F << "\nR =\n" << R << "\nR_svd =\n" << Rs);
  CHECK((R - Rs).norm() <= tol);
}

/// True if the quaternion method (not its SVD fallback) handles F.
bool quaternion_path(const Mat3& F) {
  Mat3 R;
  return svd_detail::polar_rotation_quaternion(F, F.determinant(), R);
}

}  // namespace

TEST_CASE("polar_rotation: random, near-identity and rotated matrices match the SVD",
          "[materials]") {
  std::mt19937 rng(23);
  for (int k = 0; k < 300; ++k) check_polar(test::random_near_identity(rng, 1.0));
  for (int k = 0; k < 200; ++k) {
    const Mat3 F =
        test::random_rotation(rng) * test::random_near_identity(rng, std::pow(10.0, -1 - 0.05 * k));
    REQUIRE(quaternion_path(F));
    check_polar_against_svd(F, 1e-14);
  }
  for (int k = 0; k < 50; ++k) {
    const Mat3 Q = test::random_rotation(rng);
    REQUIRE(quaternion_path(Q));
    CHECK((polar_rotation(Q) - Q).norm() <= 1e-14);
  }
  check_polar_against_svd(Mat3::Identity(), 1e-15);
  CHECK(polar_rotation(Mat3::Identity()) == Mat3::Identity());
}

TEST_CASE("polar_rotation: inverted F gives a proper rotation", "[materials]") {
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> u(0.5, 1.5), small(0.01, 0.4);
  for (int k = 0; k < 200; ++k) {
    // sigma_3 < 0 with sigma_2 + sigma_3 >= 0.1: R is unique and det R = +1 although det F < 0.
    const double s2 = u(rng);
    const Mat3 F = with_singular_values(rng, Vec3(s2 + small(rng), s2, -(s2 - 0.1) * small(rng)));
    REQUIRE(F.determinant() < 0);
    check_polar_against_svd(F, 1e-12);
  }
  check_polar(Vec3(1, 1, -0.5).asDiagonal());
  check_polar(Vec3(2, 1, -1).asDiagonal());  // sigma_2 + sigma_3 = 0: R not unique
  check_polar(Vec3(1, 1, -1).asDiagonal());
  check_polar(-Mat3::Identity());
  CHECK_FALSE(quaternion_path(-Mat3::Identity()));  // left to the SVD
}

TEST_CASE("polar_rotation: singular and rank-deficient F", "[materials]") {
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> u(0.2, 2);
  for (int k = 0; k < 100; ++k) {
    const double s2 = u(rng);
    check_polar_against_svd(with_singular_values(rng, Vec3(s2 + u(rng), s2, 0)), 1e-12);
  }
  for (int k = 0; k < 100; ++k) {
    // Rank 2 from a zero column, and rank 1: R is not unique in the rank-1 case.
    Mat3 F = test::random_near_identity(rng, 1.0);
    F.col(k % 3).setZero();
    check_polar(F);
    check_polar(Vec3(u(rng), u(rng), u(rng)) * Vec3(u(rng), -u(rng), u(rng)).transpose());
  }
  check_polar(Mat3::Zero());
  CHECK_FALSE(quaternion_path(Mat3::Zero()));
  check_polar(Vec3(1, 1, 1e-9).asDiagonal());
  check_polar(Vec3(1, 1e-9, 1e-9).asDiagonal());
  CHECK(polar_rotation(Vec3(1, 1, 0).asDiagonal()).isApprox(Mat3::Identity(), 1e-15));
}

TEST_CASE("polar_rotation: large stretch and compression", "[materials]") {
  std::mt19937 rng(37);
  std::uniform_real_distribution<double> e(-2, 2);
  for (int k = 0; k < 200; ++k) {
    Vec3 s(std::pow(10.0, e(rng)), std::pow(10.0, e(rng)), std::pow(10.0, e(rng)));
    std::sort(s.data(), s.data() + 3, std::greater<>());
    // Error bound of both methods: round-off of F over the gap sigma_2 + sigma_3.
    const double cond = s(0) / (s(1) + s(2));
    check_polar_against_svd(with_singular_values(rng, s), 1e-14 * cond, cond);
  }
  check_polar_against_svd(Vec3(100, 1, 1).asDiagonal(), 1e-14);
  check_polar_against_svd(Vec3(1e-3, 1e-3, 1e-3).asDiagonal(), 1e-14);
  check_polar_against_svd(1e6 * Mat3::Identity(), 1e-14);
}

TEST_CASE("polar_decomposition: F = R S with S symmetric, eigenvalues the signed sigma",
          "[materials]") {
  std::mt19937 rng(41);
  for (int k = 0; k < 100; ++k) {
    const Mat3 F = k % 2 ? test::random_near_identity(rng, 0.5)
                         : with_singular_values(rng, Vec3(1.3, 0.9, -0.4));
    Mat3 R, S, U, V;
    Vec3 sigma;
    polar_decomposition(F, R, S);
    svd_rv(F, U, sigma, V);
    CHECK(S == S.transpose());
    CHECK((R * S - F).norm() <= 1e-14 * F.norm());
    Vec3 lambda = Eigen::SelfAdjointEigenSolver<Mat3>(S).eigenvalues();
    std::sort(sigma.data(), sigma.data() + 3);
    CHECK((lambda - sigma).norm() <= 1e-14 * F.norm());
  }
}

TEST_CASE("symmetric_eigen: S = V diag(lambda) V^T with V a rotation", "[materials]") {
  std::mt19937 rng(43);
  std::uniform_real_distribution<double> u(-1, 1);
  auto check = [](const Mat3& S) {
    Mat3 V;
    Vec3 lambda;
    symmetric_eigen(S, lambda, V);
    INFO("S =\n" << S << "\nlambda = " << lambda.transpose());
    const double scale = std::max(1.0, S.norm());
    CHECK((V * lambda.asDiagonal() * V.transpose() - S).norm() <= 1e-14 * scale);
    CHECK((V.transpose() * V - Mat3::Identity()).norm() <= 1e-14);
    CHECK(std::abs(V.determinant() - 1) <= 1e-14);
    std::sort(lambda.data(), lambda.data() + 3);
    CHECK((lambda - Eigen::SelfAdjointEigenSolver<Mat3>(S).eigenvalues()).norm() <= 1e-14 * scale);
  };
  for (int k = 0; k < 200; ++k) {
    const Mat3 A = test::random_near_identity(rng, 1.0);
    check(A + A.transpose());
  }
  for (int k = 0; k < 200; ++k) {
    // Snow's case: near the identity, eigenvalues a few per cent apart or nearly equal.
    const Mat3 Q = test::random_rotation(rng);
    const double spread = std::pow(10.0, -1 - 0.05 * k);
    check(Q * Vec3(1 + spread * u(rng), 1 + spread * u(rng), 1 - spread * u(rng)).asDiagonal() *
          Q.transpose());
  }
  check(Mat3::Identity());
  check(Mat3::Zero());
  check(Vec3(1, 1, -1).asDiagonal());
  Mat3 two_equal = Mat3::Identity();
  two_equal(0, 1) = two_equal(1, 0) = 1e-3;
  check(two_equal);
}

TEST_CASE("snow: the return mapping matches the one by full SVD", "[materials]") {
  // The reference: Fe = U clamp(Sigma) V^T, Jp *= det(Sigma) / det(clamp(Sigma)) by svd_rv.
  const materials::SnowPlasticity plastic{2.5e-2, 7.5e-3, 10, 0.5};
  auto reference = [&](Mat3& Fe, Real& Jp) {
    Mat3 U, V;
    Vec3 s;
    svd_rv(Fe, U, s, V);
    const Vec3 c =
        s.cwiseMax(1 - plastic.critical_compression).cwiseMin(1 + plastic.critical_stretch);
    Jp = std::max(Jp * s.prod() / c.prod(), plastic.min_Jp);
    Fe = U * c.asDiagonal() * V.transpose();
  };
  std::mt19937 rng(47);
  std::uniform_real_distribution<double> u(-1, 1);
  int inside = 0;
  for (int k = 0; k < 600; ++k) {
    // Inside the elastic range, just outside it, far outside, inverted.
    const double amp = k % 4 == 0 ? 0.004 : k % 4 == 1 ? 0.02 : 0.3;
    Vec3 s(1 + amp * u(rng), 1 + amp * u(rng), 1 + amp * u(rng));
    if (k % 4 == 3) s(2) = -0.5 * s(2);  // |sigma_3| <= 0.65 < sigma_2: U, V well defined
    Mat3 Fe = with_singular_values(rng, s), Fe_ref = Fe;
    Real Jp = 1 + 0.3 * u(rng), Jp_ref = Jp;
    const Mat3 F0 = Fe;
    plastic.project(Fe, Jp);
    reference(Fe_ref, Jp_ref);
    INFO("Fe =\n" << F0 << "\nsigma = " << s.transpose());
    CHECK((Fe - Fe_ref).norm() <= 5e-14);
    CHECK(std::abs(Jp - Jp_ref) <= 1e-14);
    if (Fe == F0) ++inside;
  }
  CHECK(inside > 100);  // the no-op fast path was exercised
}

TEST_CASE("corotated: Kirchhoff stress matches the one from the SVD's rotation", "[materials]") {
  const Lame l = lame_from_young(1e5, 0.3);
  const materials::FixedCorotated m{l.mu, l.lambda};
  std::mt19937 rng(53);
  for (int k = 0; k < 200; ++k) {
    const Mat3 F = test::random_rotation(rng) * test::random_near_identity(rng, 0.3);
    const Real J = F.determinant();
    const Mat3 ref = 2 * m.mu * (F - polar_rotation_svd(F)) * F.transpose() +
                     m.lambda * (J - 1) * J * Mat3::Identity();
    CHECK((m.kirchhoff(F) - ref).norm() <= 1e-13 * l.lambda);
  }
}

TEST_CASE("distance_to_rotation_squared equals |F - R|^2 without R, through its fallback too",
          "[materials]") {
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> u(0.5, 1.5), small(0.01, 0.4);
  // |F - R|^2 by the stress's own R, against the root-only route: the subtraction
  // |F|^2 - 2 tr(R^T F) + 3 costs a few ulps of its terms, about 1e-15 (1 + |F|^2).
  auto check = [](const Mat3& F) {
    Real J, J_ref;
    const Real d2 = distance_to_rotation_squared(F, J);
    const Real ref = (F - polar_rotation(F, J_ref)).squaredNorm();
    INFO("F =\n" << F << "\n|F - R|^2 = " << ref << ", root route " << d2);
    CHECK(J == J_ref);
    CHECK(std::abs(d2 - ref) <= 4e-15 * (1 + F.squaredNorm()));
  };
  for (int k = 0; k < 200; ++k) check(test::random_near_identity(rng, 1.0));
  for (int k = 0; k < 200; ++k)
    check(test::random_rotation(rng) *
          test::random_near_identity(rng, std::pow(10.0, -1 - 0.05 * k)));
  for (int k = 0; k < 100; ++k)  // inverted: sigma_3 < 0
    check(with_singular_values(rng, Vec3(u(rng), u(rng), -small(rng))));
  Real J;
  CHECK(distance_to_rotation_squared(Mat3::Identity(), J) == 0);
  // Where the quaternion method gives up (rank 1, sigma_2 = |sigma_3| inverted) the SVD's
  // singular values answer.
  const Mat3 rank1 = Vec3(1, 2, 3) * Vec3(0.5, -1, 2).transpose();
  REQUIRE_FALSE(quaternion_path(rank1));
  check(rank1);
  const Mat3 tie = with_singular_values(rng, Vec3(1.2, 0.7, -0.7));
  REQUIRE_FALSE(quaternion_path(tie));
  check(tie);
  // The fixed corotated energy is built on it: mu |F - R|^2 + lambda / 2 (J - 1)^2.
  const materials::FixedCorotated m{2.0, 3.0};
  const Mat3 F = test::random_near_identity(rng, 0.3);
  const Real Jf = F.determinant();
  CHECK(m.energy(F) ==
        Approx(2.0 * (F - polar_rotation(F)).squaredNorm() + 1.5 * (Jf - 1) * (Jf - 1))
            .epsilon(1e-12));
}
