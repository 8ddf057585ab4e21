// The rotation-variant 3x3 SVD against its definition, on ordinary and hard matrices.
#include <catch2/catch.hpp>

#include <Eigen/SVD>

#include "materials/svd.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

void check_svd(const Mat3& F) {
  Mat3 U, V;
  Vec3 s;
  svd_rv(F, U, s, V);
  INFO("F =\n" << F << "\nsigma = " << s.transpose());
  const double tol = 1e-12 * std::max(1.0, F.norm());
  CHECK((U * s.asDiagonal() * V.transpose() - F).norm() <= tol);
  CHECK((U.transpose() * U - Mat3::Identity()).norm() <= 1e-12);
  CHECK((V.transpose() * V - Mat3::Identity()).norm() <= 1e-12);
  CHECK(U.determinant() == Approx(1));
  CHECK(V.determinant() == Approx(1));
  CHECK(s(0) >= s(1) - tol);
  CHECK(s(1) >= std::abs(s(2)) - tol);
  CHECK(s(1) >= -tol);
  // Same singular values as Eigen's, up to the sign of the last.
  const Vec3 ref = Eigen::JacobiSVD<Mat3>(F).singularValues();
  CHECK((s.cwiseAbs() - ref).norm() <= tol);
  if (F.determinant() < 0) CHECK(s(2) <= tol);
}

}  // namespace

TEST_CASE("svd_rv: random, rotated, inverted and degenerate matrices", "[materials]") {
  std::mt19937 rng(17);
  for (int k = 0; k < 200; ++k) check_svd(test::random_near_identity(rng, 1.0));
  for (int k = 0; k < 50; ++k) check_svd(test::random_rotation(rng));
  for (int k = 0; k < 50; ++k)
    check_svd(test::random_rotation(rng) * Vec3(1.2, 0.9, -0.5).asDiagonal() *
              test::random_rotation(rng));
  check_svd(Mat3::Identity());
  check_svd(Mat3::Zero());
  check_svd(Vec3(2, 2, 2).asDiagonal());
  check_svd(Vec3(1, 1, 1e-9).asDiagonal());
  check_svd(Vec3(1, 1, -1).asDiagonal());
  check_svd(Vec3(3, 1, 3).asDiagonal());
  Mat3 rank1 = Vec3(1, 2, 3) * Vec3(-1, 0.5, 2).transpose();
  check_svd(rank1);
}
