// B-spline weights (linear, quadratic, cubic): partition of unity, zero gradient sum, linear
// reproduction, gradients that match finite differences of the weights.
#include <catch2/catch.hpp>

#include <random>

#include "engine/step/kernels.h"

using namespace mpm;

namespace {

template <Kernel K>
void check_kernel() {
  constexpr int N = KernelTraits<K>::kNodes;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.2, 0.8);
  const Vec3 origin(0.1, -0.2, 0.3), h(0.01, 0.02, 0.015);
  const Vec3 inv_h = h.cwiseInverse();
  for (int n = 0; n < 200; ++n) {
    const Vec3 x(u(rng), u(rng), u(rng));
    const auto s = make_stencil<K>(x, origin, inv_h);
    double sum = 0;
    Vec3 grad = Vec3::Zero(), first_moment = Vec3::Zero();
    Mat3 grad_moment = Mat3::Zero();
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j)
        for (int k = 0; k < N; ++k) {
          const Vec3 xi = origin + (s.base + Vec3i(i, j, k)).template cast<double>().cwiseProduct(h);
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
    // The gradient is the derivative of the weight: central differences along each axis
    // (step 1e-7 h, away from the kernel's breakpoints by construction of the test points).
    for (int a = 0; a < 3; ++a) {
      const double step = 1e-7 * h[a];
      Vec3 xp = x, xm = x;
      xp[a] += step;
      xm[a] -= step;
      const auto sp = make_stencil<K>(xp, origin, inv_h), sm = make_stencil<K>(xm, origin, inv_h);
      if (sp.base != s.base || sm.base != s.base) continue;  // straddles a cell: skip this axis
      for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j)
          for (int k = 0; k < N; ++k) {
            const double fd = (sp.weight(i, j, k) - sm.weight(i, j, k)) / (2 * step);
            CHECK(std::abs(fd - s.gradient(i, j, k)[a]) < 1e-5 * inv_h[a]);
          }
    }
  }
}

}  // namespace

TEST_CASE("B-spline kernels: partition of unity, linear reproduction, exact gradients",
          "[transfers]") {
  check_kernel<Kernel::linear>();
  check_kernel<Kernel::quadratic>();
  check_kernel<Kernel::cubic>();
}

TEST_CASE("cubic B-spline: matches the 1D formula", "[transfers]") {
  // A particle on node 1: weights N(1) = 1/6, N(0) = 2/3, N(1) = 1/6, N(2) = 0.
  const auto s = make_stencil<Kernel::cubic>(Vec3(1, 1, 1), Vec3::Zero(), Vec3::Ones());
  CHECK(s.base.x() == 0);
  CHECK(s.w[0][0] == Approx(1.0 / 6));
  CHECK(s.w[0][1] == Approx(2.0 / 3));
  CHECK(s.w[0][2] == Approx(1.0 / 6));
  CHECK(s.w[0][3] == Approx(0.0).margin(1e-15));
  CHECK(s.dw[0][0] == Approx(-0.5));
  CHECK(s.dw[0][1] == Approx(0.0).margin(1e-15));
  CHECK(s.dw[0][2] == Approx(0.5));
}

TEST_CASE("quadratic B-spline: matches the 1D formula", "[transfers]") {
  const Stencil<3> s = quadratic_stencil(Vec3(0.5, 0.5, 0.5), Vec3::Zero(), Vec3::Ones());
  // x = 0.5 cells: base node 0 at distance 0.5 -> N = 0.5 (1.5 - 0.5)^2... the particle sits
  // halfway between nodes 0 and 1: weights 1/2, 1/2, 0.
  CHECK(s.base.x() == 0);
  CHECK(s.w[0][0] == Approx(0.5));
  CHECK(s.w[0][1] == Approx(0.5));
  CHECK(s.w[0][2] == Approx(0.0).margin(1e-15));
}
