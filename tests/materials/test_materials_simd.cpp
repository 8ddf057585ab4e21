// Every built-in model in float SIMD lanes (engine/step/simd/materials-inl.h) against its scalar
// double model, on every instruction set this CPU runs: the stress of fixed corotated, snow,
// Neo-Hookean, Tait water and sand, and the return maps of snow and sand.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <limits>
#include <random>
#include <type_traits>
#include <vector>

#include "engine/step/simd/stress_simd.h"
#include "engine/step/simd/transfer_simd.h"
#include "materials/sand.h"
#include "materials/snow.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// Unit round-off of float, 2^-24.
constexpr double kU = 1.0 / (1 << 24);
constexpr Real kV0 = 1e-6;

/// The models under test, E = 1e6 Pa and nu = 0.3 where they have moduli.
std::vector<BatchModel> models() {
  using K = BatchModel::Kind;
  BatchModel snow{K::snow, 3.8e5, 5.8e5};
  snow.hardening = 10;
  snow.critical_compression = 2.5e-2;
  snow.critical_stretch = 7.5e-3;
  BatchModel water{K::water};
  water.bulk_modulus = 1e5;
  water.gamma = 7;
  BatchModel sand{K::sand, 3.8e5, 5.8e5};
  sand.alpha = materials::DruckerPragerSand::cone_alpha(30 * M_PI / 180);
  sand.volume_correction = true;
  return {{K::fixed_corotated, 3.8e5, 5.8e5}, snow, {K::neo_hookean, 3.8e5, 5.8e5}, water, sand};
}

/// Q1 diag(s) Q2 for random rotations Q1, Q2, rounded to particle storage.
StoredMat3 with_singular_values(std::mt19937& rng, const Vec3& s) {
  return to_stored(test::random_rotation(rng) * s.asDiagonal() * test::random_rotation(rng));
}

/// F with singular values drawn from [lo, hi], `n` of them.
std::vector<StoredMat3> samples(std::mt19937& rng, int n, double lo, double hi) {
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<StoredMat3> F;
  for (int i = 0; i < n; ++i) F.push_back(with_singular_values(rng, Vec3(u(rng), u(rng), u(rng))));
  return F;
}

/// The size of the stress's float error at F: float round-off of the terms the stress is made
/// of (the moduli times |F|^3, and for water the pressure's slope in J).
double error_scale(const BatchModel& m, const Mat3& F, Real state) {
  const Real f = std::max<Real>(1, F.norm());
  if (m.kind == BatchModel::Kind::water) {
    const Real J = std::max<Real>(F.determinant(), 0.1);
    return m.bulk_modulus * (1 + m.gamma * std::pow(J, -m.gamma - 1)) * f * f * f;
  }
  const Real h = m.kind == BatchModel::Kind::snow ? std::exp(m.hardening * (1 - state)) : 1;
  return h * (2 * m.mu + 3 * m.lambda) * f * f * f;
}

}  // namespace

TEST_CASE("SIMD stress of every built-in model matches its scalar model to float rounding",
          "[materials][simd]") {
  if (!simd::target_name()) {
    WARN("no SIMD target on this CPU");
    return;
  }
  std::mt19937 rng(5);
  std::vector<StoredMat3> F = samples(rng, 200, 0.9, 1.1);
  for (const StoredMat3& f : samples(rng, 200, 0.5, 1.6)) F.push_back(f);
  for (const StoredMat3& f : samples(rng, 40, 0.25, 0.35)) F.push_back(f);  // J below kJMin
  std::uniform_real_distribution<double> jp(0.9, 1.1);
  std::vector<Real> state(F.size());
  for (Real& s : state) s = jp(rng);
  simd::for_each_target([&](const char* target) {
    for (BatchModel m : models()) {
      INFO("target " << target << " model kind " << static_cast<int>(m.kind));
      if (m.kind == BatchModel::Kind::snow) m.state = state.data();
      std::vector<StoredMat3> out(F.size());
      simd::stress(m, F, kV0, out);
      for (std::size_t q = 0; q < F.size(); ++q) {
        const Mat3 Fq = to_real(F[q]);
        const Mat3 ref = -kV0 * simd::kirchhoff(m, Fq, state[q]);
        const double err = (to_real(out[q]) - ref).norm();
        INFO("particle " << q << " |F| " << Fq.norm() << " J " << Fq.determinant());
        // A wrong term would be off by the stress itself; float's is hundreds of u of it.
        CHECK(err <= 512 * kU * kV0 * error_scale(m, Fq, state[q]) + kU * ref.norm());
      }
    }
  });
}

TEST_CASE("SIMD return maps of snow and sand match the scalar ones to float rounding",
          "[materials][simd]") {
  if (!simd::target_name()) {
    WARN("no SIMD target on this CPU");
    return;
  }
  std::mt19937 rng(9);
  // Around the snow clamp window [0.975, 1.0075] and across sand's cone; a few inverted ones
  // go to the scalar path.
  std::vector<StoredMat3> F = samples(rng, 300, 0.95, 1.03);
  for (const StoredMat3& f : samples(rng, 100, 0.8, 1.2)) F.push_back(f);
  for (int i = 0; i < 8; ++i) F.push_back(with_singular_values(rng, Vec3(1.0, 0.9, -0.5)));
  std::uniform_real_distribution<double> u(0, 1);
  simd::for_each_target([&](const char* target) {
    for (const BatchModel& m : models()) {
      // water (every F moves) has its own test below
      if (!simd::supports_projection(m) || m.kind == BatchModel::Kind::water) continue;
      INFO("target " << target << " model kind " << static_cast<int>(m.kind));
      const bool snow = m.kind == BatchModel::Kind::snow;
      std::vector<Real> state(F.size());
      for (Real& s : state) s = snow ? 0.8 + 0.4 * u(rng) : (u(rng) < 0.5 ? 0 : 0.02 * u(rng));
      std::vector<StoredMat3> lanes = F, scalar = F;
      std::vector<Real> lane_state = state, scalar_state = state;
      const std::size_t fallbacks = simd::project(m, lanes, lane_state);
      CHECK(fallbacks >= 8);  // the inverted ones, at least
      std::size_t moved = 0;
      for (std::size_t q = 0; q < F.size(); ++q) {
        simd::project_scalar(m, scalar[q], scalar_state[q]);
        moved += scalar[q] != F[q];
        INFO("particle " << q);
        CHECK((to_real(lanes[q]) - to_real(scalar[q])).norm() <= 64 * kU * to_real(F[q]).norm());
        // The state's change is computed in float: Jp's factor to float round-off, and sand's
        // volume correction beyond the apex from float logarithms of Sigma (|eps| < 1 here).
        const double bound = snow ? 64 * kU * std::abs(state[q]) : 4 * kU;
        CHECK(std::abs(lane_state[q] - scalar_state[q]) <= bound);
      }
      CHECK(moved > F.size() / 4);  // the samples exercise the projection
      CHECK(moved < F.size());      // and the elastic case
    }
  });
}

TEST_CASE("SIMD return map of water, F = J^(1/3) I, matches the scalar one to F's rounding",
          "[materials][simd]") {
  if (!simd::target_name()) {
    WARN("no SIMD target on this CPU");
    return;
  }
  std::mt19937 rng(11);
  // Compressed, stretched and near-rest F, a few inverted ones (the scalar path), and a count
  // that leaves a partial batch.
  std::vector<StoredMat3> F = samples(rng, 300, 0.97, 1.03);
  for (const StoredMat3& f : samples(rng, 97, 0.3, 3.0)) F.push_back(f);
  for (int i = 0; i < 8; ++i) F.push_back(with_singular_values(rng, Vec3(1.0, 0.9, -0.5)));
  const BatchModel water = models()[3];
  REQUIRE(water.kind == BatchModel::Kind::water);
  REQUIRE(simd::supports_projection(water));
  simd::for_each_target([&](const char* target) {
    INFO("target " << target);
    std::vector<StoredMat3> lanes = F, scalar = F;
    std::vector<Real> no_state;
    CHECK(simd::project(water, lanes, no_state) == 8);  // the inverted ones
    std::size_t identical = 0;
    for (std::size_t q = 0; q < F.size(); ++q) {
      Real unused = 0;
      simd::project_scalar(water, scalar[q], unused);
      INFO("particle " << q << " J " << to_real(F[q]).determinant());
      const Mat3 a = to_real(lanes[q]), b = to_real(scalar[q]);
      // The same J (Eigen's order), a root within a double ulp or two of std::cbrt's: at most
      // one unit of F's storage apart, and off the diagonal exactly zero.
      CHECK((a - b).cwiseAbs().maxCoeff() <=
            2 * std::numeric_limits<StoredReal>::epsilon() * std::abs(b(0, 0)));
      CHECK((a - Mat3(a.diagonal().asDiagonal())).cwiseAbs().maxCoeff() == 0);
      CHECK(a(0, 0) == a(1, 1));
      CHECK(a(0, 0) == a(2, 2));
      identical += a == b;
    }
    // Stored in float, a root within a double ulp or two of the exact one rounds nearly always
    // to std::cbrt's: the lanes are not a looser approximation. (Stored in double, about half
    // differ from std::cbrt in the last place, which the bound above allows.)
    if constexpr (std::is_same_v<StoredReal, float>) CHECK(identical >= F.size() - 2);
  });
}

TEST_CASE("Snow's largest wave speed in lanes matches the group's scalar one",
          "[materials][simd]") {
  if (!simd::target_name()) {
    WARN("no SIMD target on this CPU");
    return;
  }
  // The CFL bound's wave speed of a snow group, hardened per particle by its Jp, over a range
  // that does not fill its last lane set; the fastest particle moved around the range (the
  // tail's lanes included) must still be the one found.
  materials::SnowPlasticity plastic;
  plastic.hardening = 10;
  const std::size_t n = 203;
  materials::SnowGroup group({3.8e5, 5.8e5}, plastic, 400, n);
  std::mt19937 rng(13);
  const std::vector<StoredMat3> base = samples(rng, static_cast<int>(n), 0.8, 1.2);
  std::uniform_real_distribution<double> jp(0.6, 1.3);
  for (Real& s : group.state()) s = jp(rng);
  BatchModel m = group.batch_model();
  simd::for_each_target([&](const char* target) {
    for (std::size_t fast : {std::size_t{0}, n / 2, n - 1}) {
      INFO("target " << target << " fastest particle " << fast);
      std::vector<StoredMat3> F = base;
      F[fast] = to_stored(Mat3(1.5 * Mat3::Identity()));
      group.state()[fast] = 0.5;  // the hardest, and the most stretched
      const Real scalar = group.max_wave_speed(F);
      const Real lanes = simd::max_wave_speed(m, F);
      CHECK(scalar ==
            Approx(std::sqrt((5.8e5 + 2 * 3.8e5) * std::exp(5.0) * 1.5 * 1.5 * 1.5 * 0.5 / 400)));
      // hn::Exp against std::exp: a few units of double's last place.
      CHECK(std::abs(lanes - scalar) <= 1e-14 * scalar);
      group.state()[fast] = jp(rng);
    }
  });
  BatchModel corotated{BatchModel::Kind::fixed_corotated, 3.8e5, 5.8e5};
  CHECK(simd::supports_wave_speed(m));
  CHECK_FALSE(simd::supports_wave_speed(corotated));
}
