// The fixed-corotated stress in float SIMD lanes (engine/step/simd/stress_simd.h) against the
// scalar double model, under stretch, compression and inversion.
#include <catch2/catch.hpp>

#include <omp.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "engine/step/simd/stress_simd.h"
#include "materials/corotated.h"
#include "materials/svd.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// Unit round-off of float, 2^-24.
constexpr double kU = 1.0 / (1 << 24);

const materials::FixedCorotated kModel{3.8e5, 5.8e5};  // E = 1e6 Pa, nu = 0.3
constexpr Real kV0 = 1e-6;

/// Q1 diag(s) Q2 for random rotations Q1, Q2, rounded to particle storage.
StoredMat3 with_singular_values(std::mt19937& rng, const Vec3& s) {
  return to_stored(test::random_rotation(rng) * s.asDiagonal() * test::random_rotation(rng));
}

/// -V0 tau from R = U V^T of the rotation-variant SVD (svd_rv), in double: a reference that
/// shares no code with the quaternion path of either implementation.
Mat3 reference(const StoredMat3& Fs) {
  const Mat3 F = to_real(Fs), R = polar_rotation_svd(F);
  const Real J = F.determinant();
  return -kV0 * (2 * kModel.mu * (F - R) * F.transpose() +
                 kModel.lambda * (J - 1) * J * Mat3::Identity());
}

/// The bound on one stress's error from float arithmetic. R from the float quaternion is within
/// 32 u of the exact rotation where the SIMD lanes keep it (P'(lambda) > 2 |F|^3 bounds K's
/// eigenvalue gaps below by |F| / 6, so the eigenvector's error is at most 6 times the
/// ~5 u round-off of the adjugate's entries), so 2 mu (F - R) F^T is off by 32 u 2 mu |F| plus
/// its own rounding (4 u of 2 mu (|F| + |R|) |F|); J by 6 u |F|^3 (two products per
/// cofactor term), so lambda (J - 1) J by lambda |2 J - 1| 6 u |F|^3 plus 3 u of
/// lambda (|J| + 1) |J|; the final store rounds by u / 2 of |tau|.
double error_bound(const StoredMat3& Fs) {
  const Mat3 F = to_real(Fs);
  const Real f = F.norm(), J = F.determinant();
  const Real shear = 2 * kModel.mu * (32 * f + 4 * (f + std::sqrt(3.0)) * f);
  const Real bulk = kModel.lambda * (std::abs(2 * J - 1) * 6 * f * f * f + 3 * (std::abs(J) + 1) * std::abs(J));
  return kV0 * kU * (shear + bulk) + 0.5 * kU * reference(Fs).norm();
}

/// Runs the SIMD stress on `F` and checks each particle against the SVD reference; returns the
/// number of particles the kernel handed to the scalar model.
std::size_t check_against_reference(const std::vector<StoredMat3>& F) {
  std::vector<StoredMat3> out(F.size());
  const BatchModel model = kModel.batch();
  REQUIRE(simd::supports_stress(model));
  const std::size_t fallbacks = simd::stress(model, F, kV0, out);
  double worst = 0;
  for (std::size_t q = 0; q < F.size(); ++q) {
    const double err = (to_real(out[q]) - reference(F[q])).norm(), bound = error_bound(F[q]);
    worst = std::max(worst, err / bound);
    INFO("particle " << q << ", F =\n" << F[q] << "\ndet F = " << to_real(F[q]).determinant());
    CHECK(err <= bound);
  }
  WARN("largest error / bound: " << worst << "; scalar fallbacks: " << fallbacks << " of "
                                 << F.size());
  return fallbacks;
}

}  // namespace

TEST_CASE("SIMD corotated stress: near-identity and stretched F match the scalar model to float rounding",
          "[materials][simd]") {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1), stretch(0.3, 3.0);
  std::vector<StoredMat3> F;
  for (int i = 0; i < 1000; ++i) {  // what a simulation holds: F near I, rotated
    Mat3 A = Mat3::Identity();
    for (int e = 0; e < 9; ++e) A.data()[e] += 0.1 * u(rng);
    F.push_back(to_stored(test::random_rotation(rng) * A));
  }
  for (int i = 0; i < 1000; ++i)  // strong stretch and compression, det > 0
    F.push_back(with_singular_values(rng, Vec3(stretch(rng), stretch(rng), stretch(rng))));
  F.push_back(StoredMat3::Identity());
  F.push_back(to_stored(test::random_rotation(rng)));
  // Every one of these is well-conditioned: the SIMD lanes, not the fallback, computed them.
  CHECK(check_against_reference(F) == 0);
}

TEST_CASE("SIMD corotated stress: inverted F (det F < 0) gets the proper rotation", "[materials][simd]") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> big(0.8, 1.5), small(0.05, 0.3);
  std::vector<StoredMat3> F;
  // Mildly inverted: sigma_3 < 0 well apart from sigma_2, where R is unique and the lanes keep it.
  for (int i = 0; i < 500; ++i)
    F.push_back(with_singular_values(rng, Vec3(big(rng), big(rng), -small(rng))));
  CHECK(check_against_reference(F) == 0);
  for (const StoredMat3& f : F) {  // the reference R is proper: tr(R^T F) = sum of signed sigma
    Mat3 U, V;
    Vec3 s;
    svd_rv(to_real(f), U, s, V);
    REQUIRE(s(2) < 0);
  }
}

TEST_CASE("SIMD corotated stress: near-singular and badly inverted F fall back to the scalar model",
          "[materials][simd]") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> big(0.5, 2.0), tiny(1e-4, 1e-2);
  std::vector<StoredMat3> F;
  for (int i = 0; i < 200; ++i) {
    const double s2 = big(rng);
    F.push_back(with_singular_values(rng, Vec3(big(rng) + s2, s2, -s2 * (1 - tiny(rng)))));
    F.push_back(with_singular_values(rng, Vec3(big(rng), tiny(rng), tiny(rng))));
  }
  F.push_back(StoredMat3::Zero());
  std::vector<StoredMat3> out(F.size());
  const std::size_t fallbacks = simd::stress(kModel.batch(), F, kV0, out);
  CHECK(fallbacks > 0);
  for (std::size_t q = 0; q < F.size(); ++q) {
    INFO("particle " << q << ", F =\n" << F[q]);
    REQUIRE(out[q].allFinite());
  }
  // Inverted with sigma_2 ~ |sigma_3|: R is ill-determined, so the lanes must not answer; the
  // scalar model's answer is bit-identical to compute_stress's.
  for (std::size_t q = 0; q < F.size(); q += 2) {
    const StoredMat3 scalar = to_stored(-kV0 * kModel.kirchhoff(to_real(F[q])));
    INFO("particle " << q << ", F =\n" << F[q]);
    CHECK(out[q] == scalar);
  }
}

TEST_CASE("SIMD corotated stress: bit-identical for 1 and 2 threads", "[materials][simd]") {
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<StoredMat3> F(20011);  // above kParallelMinItems, not a multiple of the lanes
  for (StoredMat3& f : F) {
    Mat3 A = Mat3::Identity();
    for (int e = 0; e < 9; ++e) A.data()[e] += 0.3 * u(rng);
    f = to_stored(A);
  }
  std::vector<StoredMat3> one(F.size()), two(F.size());
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  simd::stress(kModel.batch(), F, kV0, one);
  omp_set_num_threads(2);
  simd::stress(kModel.batch(), F, kV0, two);
  omp_set_num_threads(threads);
  CHECK(std::memcmp(one.data(), two.data(), F.size() * sizeof(StoredMat3)) == 0);
}
