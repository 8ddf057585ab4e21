#include "engine/step/domain_quadrature.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "engine/step/kernels.h"

namespace mpm {

namespace {

/// A fit is well posed where its particles' weighted spread, the smallest eigenvalue of
/// their position covariance, exceeds this fraction of h^2 times (heaviest node's weight /
/// this node's)^2: a node at the edge of the body, holding little weight, needs its
/// particles spread more widely (the 1D model's rule, scripts/pool_1d/schemes.py).
constexpr Real kFitSpread = 1e-6;

/// Runs f(q) for every particle q in `order`, slab by slab (for_each_slab), so that two
/// particles that run at once never write the same node.
template <class Fn>
void for_each_by_slab(const ParticleOrder& order, Fn&& f) {
  for_each_slab(order, [&](int s) {
    for (std::size_t at = order.slab_start[s]; at < order.slab_start[s + 1]; ++at)
      f(order.order[at]);
  });
}

/// Sums particle q's moments into its 27 nodes: sum w, sum w d (3), sum w d d^T (6: xx yy zz
/// xy xz yz), sum w v, sum w v d (3), with d = x_p - x_i.
void add_moments(const Vec3& x, Real value, const Grid& g, NodeFits& fits) {
  const auto s = quadratic_stencil(x, g.origin, g.inv_h);
  std::size_t nodes[27];
  g.stencil_indices<3>(s.base, nodes);
  Real d[3][3];  // d[axis][node]: x_p - x_i along the axis
  const Vec3 corner = x - g.position(s.base.x(), s.base.y(), s.base.z());
  for (int a = 0; a < 3; ++a)
    for (int k = 0; k < 3; ++k) d[a][k] = corner[a] - k * g.h[a];
  int c = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k, ++c) {
        const Real w = s.weight(i, j, k), dx = d[0][i], dy = d[1][j], dz = d[2][k];
        const Real wv = w * value;
        auto& m = fits.sums[nodes[c]];
        m[0] += w;
        m[1] += w * dx, m[2] += w * dy, m[3] += w * dz;
        m[4] += w * dx * dx, m[5] += w * dy * dy, m[6] += w * dz * dz;
        m[7] += w * dx * dy, m[8] += w * dx * dz, m[9] += w * dy * dz;
        m[10] += wv;
        m[11] += wv * dx, m[12] += wv * dy, m[13] += wv * dz;
      }
}

/// Solves one node's fit from its moments, in place: m[0..3] becomes (a, b). Returns whether
/// it is well posed (see kFitSpread); `heaviest` is the largest sum of weights of any node.
bool solve_fit(std::array<Real, 14>& m, Real heaviest, Real h2) {
  const Real w = m[0];
  if (!(w > 0)) return false;
  const Vec3 mean(m[1] / w, m[2] / w, m[3] / w);
  Mat3 cov;
  cov << m[4], m[7], m[8], m[7], m[5], m[9], m[8], m[9], m[6];
  cov = cov / w - mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Mat3> eig;
  eig.computeDirect(cov, Eigen::EigenvaluesOnly);
  const Real ratio = heaviest / w;
  if (!(eig.eigenvalues()[0] > kFitSpread * h2 * ratio * ratio)) return false;
  const Real vmean = m[10] / w;
  // b = cov^-1 (sum w v d / w - mean(v) mean(d)); a = mean(v) - b . mean(d).
  const Vec3 rhs = Vec3(m[11], m[12], m[13]) / w - vmean * mean;
  const Vec3 b = cov.ldlt().solve(rhs);
  m[0] = vmean - b.dot(mean);
  m[1] = b.x(), m[2] = b.y(), m[3] = b.z();
  return true;
}

}  // namespace

namespace {

/// The quadratic B-spline and its antiderivatives at r (cell units): N, N1 = int_-inf^r N,
/// N2 = int_-inf^r N1.
struct SplineTerms {
  Real n, n1, n2;
};

SplineTerms spline_terms(Real r) {
  // On r <= 0, then N(r) = N(-r), N1(r) = 1 - N1(-r), N2(r) = r + N2(-r) above 0.
  const bool above = r > 0;
  const Real t = above ? -r : r;
  SplineTerms a{0, 0, 0};
  if (t > Real(-0.5)) {
    const Real v = t + Real(0.5);  // int_-0.5^t (3/4 - u^2) du = 3/4 v - (t^3 + 1/8) / 3
    a.n = Real(0.75) - t * t;
    a.n1 = Real(1) / 6 + Real(0.75) * v - (t * t * t + Real(0.125)) / 3;
    a.n2 = Real(1) / 24 + v / 8 + Real(0.375) * v * v - (t * t * t * t - Real(0.0625)) / 12;
  } else if (t > Real(-1.5)) {
    const Real u = t + Real(1.5);
    a.n = Real(0.5) * u * u;
    a.n1 = a.n * u / 3;
    a.n2 = a.n1 * u / 4;
  }
  if (above) a.n1 = 1 - a.n1, a.n2 = r + a.n2;
  return a;
}

}  // namespace

Real bspline_integral(Real r) {
  return spline_terms(r).n1;
}

Real bspline_second_integral(Real r) {
  return spline_terms(r).n2;
}

DomainAxis domain_axis(Real fx, Real cells, Real h) {
  DomainAxis a;
  const Real lo = fx - cells / 2, inv = 1 / cells;
  a.base = floor_int(lo - Real(0.5));
  for (int k = 0; k < 4; ++k) {
    const Real ra = lo - (a.base + k);
    const SplineTerms sa = spline_terms(ra), sb = spline_terms(ra + cells);
    a.n[k] = (sb.n1 - sa.n1) * inv;
    a.s[k] = (sb.n - sa.n) * inv / h;
    a.m[k] = Real(0.5) * (sa.n + sb.n) - a.n[k];
    a.q[k] = h * (Real(0.5) * (sa.n1 + sb.n1) - (sb.n2 - sa.n2) * inv);
  }
  return a;
}

void fit_linear(const Particles& p, const ParticleOrder& order, const Grid& g,
                std::span<const Real> values, NodeFits& fits, std::span<Real> value,
                std::span<Vec3> gradient) {
  fits.sums.assign(g.mass.size(), {});
  fits.ok.assign(g.mass.size(), 0);
  for_each_by_slab(order, [&](std::uint32_t q) { add_moments(p.x[q], values[q], g, fits); });
  Real heaviest = 0;
  for (const auto& m : fits.sums) heaviest = std::max(heaviest, m[0]);
  const Real h2 = g.h.minCoeff() * g.h.minCoeff();
  const std::ptrdiff_t nodes = static_cast<std::ptrdiff_t>(fits.sums.size());
#pragma omp parallel for schedule(static) if (nodes >= kParallelMinItems)
  for (std::ptrdiff_t i = 0; i < nodes; ++i) fits.ok[i] = solve_fit(fits.sums[i], heaviest, h2);
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(p.size());
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < n; ++q) {
    const auto s = quadratic_stencil(p.x[q], g.origin, g.inv_h);
    std::size_t nodes27[27];
    g.stencil_indices<3>(s.base, nodes27);
    Real wsum = 0, v = 0;
    Vec3 b = Vec3::Zero();
    int c = 0;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k, ++c) {
          if (!fits.ok[nodes27[c]]) continue;
          const auto& m = fits.sums[nodes27[c]];
          const Real w = s.weight(i, j, k);
          const Vec3 bi(m[1], m[2], m[3]);
          const Vec3 d = p.x[q] - g.position(s.base.x() + i, s.base.y() + j, s.base.z() + k);
          wsum += w;
          v += w * (m[0] + bi.dot(d));
          b += w * bi;
        }
    const Real inv = wsum > 0 ? 1 / wsum : 0;
    if (!value.empty()) value[q] = wsum > 0 ? v * inv : values[q];
    if (!gradient.empty()) gradient[q] = b * inv;
  }
}

void particle_pressures(const Particles& p, std::span<Real> pressure) {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(p.size());
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < n; ++q) {
    const Real volume = p.volume0(q) * to_real(p.F[q]).determinant();
    pressure[q] = to_real(p.stress[q]).trace() / (3 * volume);
  }
}

DomainStencil domain_stencil(const Vec3& x, Real volume, const Grid& g) {
  DomainStencil d;
  const Real side = std::cbrt(std::max(volume, Real(0)));
  for (int a = 0; a < 3; ++a) {  // at most a cell wide: four nodes per axis
    // A crushed, inverted or non-finite volume (a run going wrong) takes the narrowest domain,
    // so the stencil stays on the grid until the run's checks stop it.
    const Real wide = side * g.inv_h[a];
    const Real cells = wide >= Real(0.05) ? std::min(wide, Real(1)) : Real(0.05);
    d.axis[a] = domain_axis((x[a] - g.origin[a]) * g.inv_h[a], cells, g.h[a]);
    const Real l = cells * g.h[a];
    d.inv_d[a] = 1 / (g.h[a] * g.h[a] / 4 + l * l / 12);
  }
  return d;
}

namespace {

/// Scatters particle q's mass, momentum and stress force (times `impulse`: dt, or 1 for FLIP's
/// force array) with its domain weights (domain_particles_to_grid).
void scatter_domain_particle(const Particles& p, std::uint32_t q, bool affine, Real impulse,
                             std::span<const Vec3> pressure_gradient, Grid& g) {
  const Real volume = p.volume0(q) * to_real(p.F[q]).determinant(), m = p.mass(q);
  const DomainStencil d = domain_stencil(p.x[q], volume, g);
  const DomainAxis &x = d.axis[0], &y = d.axis[1], &z = d.axis[2];
  const Mat3 S = impulse * to_real(p.stress[q]);
  const Vec3 G = impulse * volume * pressure_gradient[q];
  // Momentum at node (i, j, k): w (m v + m C (x_i - x_p)) = w (a + i c0 + j c1 + k c2).
  const Mat3 mC = affine ? Mat3(m * to_real(p.C[q])) : Mat3::Zero();
  const Vec3 a = m * p.v[q] + mC * (g.position(x.base, y.base, z.base) - p.x[q]);
  const Mat3 c = mC * g.h.asDiagonal();
  std::size_t nodes[64];
  g.stencil_indices<4>(d.base(), nodes);
  // The force, -integral of sigma grad w_i over the domain with sigma = sigma_p -
  // (G . (x - x_p)) I, is S grad + sum_a G_a T_a, T_ab = mean of (x_a - x_pa) dw_i / dx_b: a
  // product of one mean per axis (m on the diagonal, q times s off it). Per (i, j) row it
  // is nz[k] fn + sz[k] fs + qz[k] fq + mz[k] fm.
  int c3 = 0;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      const Real nn = x.n[i] * y.n[j], sn = x.s[i] * y.n[j], ns = x.n[i] * y.s[j];
      const Vec3 fn = S.col(0) * sn + S.col(1) * ns +
                      Vec3(G.x() * x.m[i] * y.n[j] + G.y() * x.s[i] * y.q[j],
                           G.y() * x.n[i] * y.m[j] + G.x() * x.q[i] * y.s[j], 0);
      const Vec3 fs = S.col(2) * nn + Vec3(0, 0, G.x() * x.q[i] * y.n[j] + G.y() * x.n[i] * y.q[j]);
      const Vec3 fq(G.z() * sn, G.z() * ns, 0), fm(0, 0, G.z() * nn);
      const Vec3 mom = a + i * c.col(0) + j * c.col(1);
      for (int k = 0; k < 4; ++k, ++c3) {
        const Real w = nn * z.n[k];
        const Vec3 f = z.n[k] * fn + z.s[k] * fs + z.q[k] * fq + z.m[k] * fm;
        g.mass[nodes[c3]] += w * m;
        g.velocity[nodes[c3]] += w * (mom + k * c.col(2));
        if (g.flip)
          g.force[nodes[c3]] += f;
        else
          g.velocity[nodes[c3]] += f;
      }
    }
}

}  // namespace

void domain_particles_to_grid(const Particles& p, const ParticleOrder& order, Transfer transfer,
                              std::span<const Vec3> pressure_gradient, Real dt, Grid& g) {
  clear_node_sums(g);
  const bool affine = transfer == Transfer::apic || transfer == Transfer::mls;
  const Real impulse = g.flip ? 1 : dt;  // FLIP keeps the force apart
  for_each_by_slab(order, [&](std::uint32_t q) {
    scatter_domain_particle(p, q, affine, impulse, pressure_gradient, g);
  });
}

void domain_grid_to_particles(const Grid& g, Transfer transfer, Real flip_blend, Real dt,
                              Particles& p) {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(p.size());
  const bool affine = transfer == Transfer::apic || transfer == Transfer::mls;
  const bool flip = transfer == Transfer::flip;
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < n; ++q) {
    const Mat3 F = to_real(p.F[q]);
    const DomainStencil d = domain_stencil(p.x[q], p.volume0(q) * F.determinant(), g);
    const DomainAxis &x = d.axis[0], &y = d.axis[1], &z = d.axis[2];
    std::size_t nodes[64];
    g.stencil_indices<4>(d.base(), nodes);
    // Per (i, j) row, sums over k first: r0 = sum wz v, r1 = sum sz v, r2 = sum k wz v.
    Vec3 v = Vec3::Zero(), dv = Vec3::Zero();
    Mat3 grad_v = Mat3::Zero(), ijk = Mat3::Zero();  // ijk: sum w v (i, j, k)^T
    int c = 0;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        Vec3 r0 = Vec3::Zero(), r1 = Vec3::Zero(), r2 = Vec3::Zero(), rd = Vec3::Zero();
        for (int k = 0; k < 4; ++k, ++c) {
          const Vec3& vi = g.velocity[nodes[c]];
          r0 += z.n[k] * vi;
          r1 += z.s[k] * vi;
          r2 += (k * z.n[k]) * vi;
          if (flip) rd += z.n[k] * (vi - g.velocity_old[nodes[c]]);
        }
        const Real nn = x.n[i] * y.n[j];
        v += nn * r0;
        dv += nn * rd;
        grad_v.col(0) += (x.s[i] * y.n[j]) * r0;
        grad_v.col(1) += (x.n[i] * y.s[j]) * r0;
        grad_v.col(2) += nn * r1;
        ijk.col(0) += (i * nn) * r0;
        ijk.col(1) += (j * nn) * r0;
        ijk.col(2) += nn * r2;
      }
    p.v[q] = flip ? Vec3(flip_blend * (p.v[q] + dv) + (1 - flip_blend) * v) : v;
    if (affine) {
      // B = sum w v (x_i - x_p)^T = v (corner)^T + sum w v (i, j, k)^T diag(h); C = B D^-1
      // (Jiang et al. 2015, eq. 8-10).
      const Vec3 corner = g.position(x.base, y.base, z.base) - p.x[q];
      const Mat3 C = (v * corner.transpose() + ijk * g.h.asDiagonal()) * d.inv_d.asDiagonal();
      p.C[q] = to_stored(C);
      if (transfer == Transfer::mls) grad_v = C;  // Hu et al. 2018, eq. 17
    }
    p.F[q] = to_stored((Mat3::Identity() + dt * grad_v) * F);
  }
}

void smooth_volume_change(const ParticleOrder& order, const Grid& grid, std::span<const Real> j_old,
                          NodeFits& fits, std::vector<Real>& scratch, Particles& p) {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(p.size());
  scratch.resize(2 * p.size());
  const std::span<Real> change(scratch.data(), p.size()),
      fitted(scratch.data() + p.size(), p.size());
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < n; ++q) change[q] = to_real(p.F[q]).determinant() / j_old[q];
  fit_linear(p, order, grid, change, fits, fitted, {});
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < n; ++q)
    if (fitted[q] > 0 && change[q] > 0)
      p.F[q] = to_stored(to_real(p.F[q]) * std::cbrt(fitted[q] / change[q]));
}

}  // namespace mpm
