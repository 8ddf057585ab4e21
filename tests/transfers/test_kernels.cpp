// Quadratic B-spline weights: partition of unity, zero gradient sum, linear reproduction.
#include <catch2/catch.hpp>

#include <random>

#include "engine/kernels.h"

using namespace mpm;

TEST_CASE("quadratic B-spline: weights sum to one, gradients to zero", "[transfers]") {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.2, 0.8);
  const Vec3 origin(0.1, -0.2, 0.3), h(0.01, 0.02, 0.015);
  const Vec3 inv_h = h.cwiseInverse();
  for (int n = 0; n < 200; ++n) {
    const Vec3 x(u(rng), u(rng), u(rng));
    const Stencil s = quadratic_stencil(x, origin, inv_h);
    double sum = 0;
    Vec3 grad = Vec3::Zero(), first_moment = Vec3::Zero();
    Mat3 grad_moment = Mat3::Zero();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k) {
          const Vec3 xi = origin + (s.base + Vec3i(i, j, k)).cast<double>().cwiseProduct(h);
          sum += s.weight(i, j, k);
          grad += s.gradient(i, j, k);
          first_moment += s.weight(i, j, k) * (xi - x);
          grad_moment += (xi - x) * s.gradient(i, j, k).transpose();
          CHECK(s.weight(i, j, k) >= 0);
        }
    CHECK(sum == Approx(1).epsilon(1e-14));
    CHECK(grad.norm() < 1e-10 * inv_h.norm());
    // Linear functions are reproduced: sum w (x_i - x) = 0 and sum (x_i - x) grad w^T = I.
    CHECK(first_moment.norm() < 1e-14);
    CHECK((grad_moment - Mat3::Identity()).norm() < 1e-12);
  }
}

TEST_CASE("quadratic B-spline: matches the 1D formula", "[transfers]") {
  const Stencil s = quadratic_stencil(Vec3(0.5, 0.5, 0.5), Vec3::Zero(), Vec3::Ones());
  // x = 0.5 cells: base node 0 at distance 0.5 -> N = 0.5 (1.5 - 0.5)^2... the particle sits
  // halfway between nodes 0 and 1: weights 1/2, 1/2, 0.
  CHECK(s.base.x() == 0);
  CHECK(s.w[0][0] == Approx(0.5));
  CHECK(s.w[0][1] == Approx(0.5));
  CHECK(s.w[0][2] == Approx(0.0).margin(1e-15));
}
