// The stress integrated over particle domains (simulation.quadrature: domain): the domain
// means of the B-spline, the nodal least-squares fits, and the force of a linear pressure.
#include <catch2/catch.hpp>
#include <cmath>
#include <map>
#include <random>

#include "engine/step/domain_quadrature.h"
#include "engine/step/grid.h"
#include "engine/step/kernels.h"
#include "engine/step/transfer.h"
#include "support/helpers.h"
#include "transfers/cloud.h"

using namespace mpm;

namespace {

/// The quadratic B-spline and its derivative in cell units.
double spline(double r) {
  const double a = std::abs(r);
  return a < 0.5 ? 0.75 - a * a : a < 1.5 ? 0.5 * (1.5 - a) * (1.5 - a) : 0.0;
}
double spline_slope(double r) {
  const double a = std::abs(r), s = r < 0 ? -1.0 : 1.0;
  return a < 0.5 ? -2 * r : a < 1.5 ? -s * (1.5 - a) : 0.0;
}

/// A regular lattice of 2 x 2 x 2 particles per cell filling the box [lo, hi] (whole
/// particle spacings), unloaded (F = I), each with the volume of its lattice cell.
Particles lattice(const Vec3& lo, const Vec3i& count, double spacing) {
  Particles p;
  p.object_mass.push_back(1000 * spacing * spacing * spacing);
  p.object_volume0.push_back(spacing * spacing * spacing);
  for (int i = 0; i < count.x(); ++i)
    for (int j = 0; j < count.y(); ++j)
      for (int k = 0; k < count.z(); ++k) {
        p.x.push_back(lo + spacing * (Vec3(i, j, k) + Vec3::Constant(0.5)));
        p.v.push_back(Vec3::Zero());
        p.F.push_back(StoredMat3::Identity());
        p.stress.push_back(StoredMat3::Zero());
        p.object.push_back(0);
        p.id.push_back(static_cast<std::uint32_t>(p.id.size()));
      }
  return p;
}

GridDesc grid_of(double h, int cells) {
  GridDesc d;
  d.origin = Vec3::Zero();
  d.max = Vec3::Constant(h * cells);
  d.dims = Vec3i::Constant(cells);
  d.buffer = 2;
  return d;
}

}  // namespace

TEST_CASE("domain quadrature: the domain means are the B-spline's, integrated numerically",
          "[transfers][domain]") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  const double h = 0.02;
  for (int t = 0; t < 200; ++t) {
    const double fx = 5 + 3 * u(rng), cells = 0.05 + 0.95 * u(rng);
    const DomainAxis a = domain_axis(fx, cells, h);
    double n_sum = 0, s_sum = 0, q_sum = 0, m_sum = 0, s_moment = 0;
    for (int k = 0; k < 4; ++k) {
      // Midpoint rule over the domain (20,000 points; the B-spline is C1, so O(1e-9)).
      const int M = 20000;
      double n = 0, s = 0, q = 0, m = 0;
      for (int e = 0; e < M; ++e) {
        const double off = cells * ((e + 0.5) / M - 0.5);  // x - x_p, cells
        const double r = fx + off - (a.base + k);
        n += spline(r) / M;
        s += spline_slope(r) / h / M;
        q += off * h * spline(r) / M;
        m += off * spline_slope(r) / M;
      }
      INFO("fx " << fx << ", domain " << cells << " cells, node " << k);
      CHECK(a.n[k] == Approx(n).margin(1e-8));
      CHECK(a.s[k] * h == Approx(s * h).margin(1e-8));
      CHECK(a.q[k] / h == Approx(q / h).margin(1e-8));
      CHECK(a.m[k] == Approx(m).margin(1e-8));
      n_sum += a.n[k], s_sum += a.s[k], q_sum += a.q[k], m_sum += a.m[k];
      s_moment += a.s[k] * (a.base + k) * h;
    }
    // A partition of unity whose gradient reproduces linear fields, over the four nodes.
    CHECK(n_sum == Approx(1).epsilon(1e-12));
    CHECK(std::abs(s_sum) * h < 1e-12);
    CHECK(std::abs(q_sum) / h < 1e-12);
    CHECK(std::abs(m_sum) < 1e-12);
    CHECK(s_moment == Approx(1).epsilon(1e-12));
  }
  // The antiderivatives: N1 runs 0 to 1, N2(r) = r past the support, both continuous.
  CHECK(bspline_integral(-1.5) == 0);
  CHECK(bspline_integral(0) == Approx(0.5));
  CHECK(bspline_integral(1.5) == Approx(1));
  CHECK(bspline_second_integral(1.5) == Approx(1.5));
  for (double r : {-0.5, 0.5})
    CHECK(bspline_second_integral(r - 1e-12) == Approx(bspline_second_integral(r + 1e-12)));
}

TEST_CASE("domain quadrature: the nodal least-squares fits reproduce a linear field",
          "[transfers][domain]") {
  const double h = 0.05;
  Grid g(grid_of(h, 16), false);
  // A jittered block with one face at a fraction of a cell: every fit is one-sided there.
  Particles p = lattice(Vec3(0.213, 0.187, 0.2411), Vec3i(14, 11, 9), h / 2);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> jitter(-0.2 * h, 0.2 * h);
  for (Vec3& x : p.x) x += Vec3(jitter(rng), jitter(rng), jitter(rng));
  ParticleOrder order;
  sort_particles(p, Kernel::quadratic, g, order, kDomainReach);
  const Vec3 b(3.0, -7.5, 1.25);
  std::vector<Real> values, value(p.size());
  std::vector<Vec3> gradient(p.size());
  for (const Vec3& x : p.x) values.push_back(2.0 + b.dot(x));
  NodeFits fits;
  fit_linear(p, order, g, values, fits, value, gradient);
  for (std::size_t q = 0; q < p.size(); ++q) {
    INFO("particle " << q << " at " << p.x[q].transpose());
    REQUIRE((gradient[q] - b).norm() < 1e-8 * b.norm());
    REQUIRE(value[q] == Approx(values[q]).epsilon(1e-10));
  }
}

TEST_CASE(
    "domain quadrature: a linear pressure's force is its integral over the body, wherever the "
    "surface lies",
    "[transfers][domain]") {
  // A block whose faces lie at fractions of a cell, holding p = p0 + g . (x - x0): the domain
  // scatter integrates p grad w_i over each particle's domain exactly, and the domains tile
  // the block, so every node's force is the integral over the block (here by a fine midpoint
  // rule). The point form misses it at the nodes the surface cuts.
  const double h = 0.05, spacing = h / 2;
  const Vec3 lo(0.2137, 0.1871, 0.2411);
  const Vec3i count(6, 5, 4);
  const Vec3 x0(0.3, 0.3, 0.3), grad_p(-200, -9810, 500);
  const double p0 = 1500;
  const auto pressure = [&](const Vec3& x) { return p0 + grad_p.dot(x - x0); };
  Particles p = lattice(lo, count, spacing);
  const double V = p.volume0(0);
  for (std::size_t q = 0; q < p.size(); ++q)
    p.stress[q] = (V * pressure(p.x[q]) * Mat3::Identity()).cast<StoredReal>();  // -V sigma
  Grid g(grid_of(h, 16), true);  // FLIP keeps the force apart
  ParticleOrder order;
  sort_particles(p, Kernel::quadratic, g, order, kDomainReach);
  const std::vector<Vec3> gradients(p.size(), grad_p);
  domain_particles_to_grid(p, order, Transfer::flip, gradients, 1e-3, g);

  // The exact integral, p grad w_i over the block, by 16^3 points per particle domain.
  std::map<std::array<int, 3>, Vec3> exact;
  const int M = 16;
  const double dv = V / (M * M * M);
  for (const Vec3& xp : p.x)
    for (int a = 0; a < M; ++a)
      for (int b = 0; b < M; ++b)
        for (int c = 0; c < M; ++c) {
          const Vec3 x = xp + spacing * (Vec3(a + 0.5, b + 0.5, c + 0.5) / M - Vec3::Constant(0.5));
          const auto s = quadratic_stencil(x, g.origin, g.inv_h);
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
              for (int k = 0; k < 3; ++k) {
                const std::array<int, 3> node{s.base.x() + i, s.base.y() + j, s.base.z() + k};
                auto [it, fresh] = exact.try_emplace(node, Vec3::Zero());
                it->second += dv * pressure(x) * s.gradient(i, j, k);
              }
        }
  double scale = 0;
  for (const auto& [node, f] : exact) scale = std::max(scale, f.norm());
  int compared = 0;
  double worst = 0;
  for_each_active_node(g, [&](int i, int j, int k, std::size_t idx) {
    const auto it = exact.find({i, j, k});
    const Vec3 want = it == exact.end() ? Vec3::Zero() : it->second;
    worst = std::max(worst, (g.force[idx] - want).norm() / scale);
    ++compared;
  });
  INFO(compared << " nodes, worst difference " << worst << " of the largest force " << scale);
  CHECK(compared > 100);
  // The midpoint rule's own error, O((spacing / M)^2 / h^2), is below 1e-3.
  CHECK(worst < 1e-3);

  // The point form, sum V p_p grad w_i(x_p), on the same particles: off at the cut nodes.
  Grid point(grid_of(h, 16), true);
  sort_particles(p, Kernel::quadratic, point, order);
  particles_to_grid(p, order, Transfer::flip, Kernel::quadratic, 1e-3, point);
  double point_worst = 0;
  for_each_active_node(point, [&](int i, int j, int k, std::size_t idx) {
    const auto it = exact.find({i, j, k});
    const Vec3 want = it == exact.end() ? Vec3::Zero() : it->second;
    point_worst = std::max(point_worst, (point.force[idx] - want).norm() / scale);
  });
  INFO("point form: worst difference " << point_worst);
  CHECK(point_worst > 10 * worst);
}

TEST_CASE("domain transfers keep mass, momentum and APIC's angular momentum",
          "[transfers][domain]") {
  // As the point transfers (test_transfer.cpp): the domain weights are a partition of unity
  // with D = sum_i wbar_i (x_i - x_p)(x_i - x_p)^T = (h^2 / 4 + l^2 / 12) I, so the APIC round
  // trip keeps angular momentum (Jiang et al. 2015, section 5.3).
  for (Transfer tr : {Transfer::apic, Transfer::pic}) {
    Particles p = test::random_cloud(3000, tr == Transfer::apic, 7);
    Grid g(test::unit_grid(16), false);
    ParticleOrder ord;
    sort_particles(p, Kernel::quadratic, g, ord, kDomainReach);
    const std::vector<Vec3> no_gradient(p.size(), Vec3::Zero());
    domain_particles_to_grid(p, ord, tr, no_gradient, 0, g);
    const test::GridTotals before = test::grid_totals_of_momentum(g);
    double mass = 0;
    Vec3 mom = Vec3::Zero();
    for (std::size_t q = 0; q < p.size(); ++q) mass += p.mass(q), mom += p.mass(q) * p.v[q];
    CHECK(before.mass == Approx(mass).epsilon(1e-13));
    CHECK((before.momentum - mom).norm() < 1e-12 * mom.norm());
    grid_update(g);
    domain_grid_to_particles(g, tr, 0, 0, p);
    Vec3 back = Vec3::Zero();
    for (std::size_t q = 0; q < p.size(); ++q) back += p.mass(q) * p.v[q];
    CHECK((back - before.momentum).norm() < 1e-12 * mom.norm());
    domain_particles_to_grid(p, ord, tr, no_gradient, 0, g);
    const double drift =
        (test::grid_totals_of_momentum(g).angular - before.angular).norm() / before.angular.norm();
    INFO(static_cast<int>(tr) << ": angular momentum drift " << drift);
    if (tr == Transfer::apic)
      CHECK(drift < 1e-12 + test::kStoredEps);
    else
      CHECK(drift > 1e-3);
  }
}
