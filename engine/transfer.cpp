#include "engine/transfer.h"

#include <algorithm>
#include <cmath>

#include "engine/kernels.h"

namespace mpm {

namespace {

Vec3i stencil_base(const Vec3& x, const Grid& g) {
  Vec3i b;
  for (int a = 0; a < 3; ++a)
    b[a] = static_cast<int>(std::floor((x[a] - g.origin[a]) * g.inv_h[a] - Real(0.5)));
  return b;
}

}  // namespace

void sort_particles(const Particles& p, Grid& grid, ParticleOrder& ord) {
  const std::size_t n = p.size();
  ord.order.resize(n);
  if (n == 0) {
    grid.active = NodeRange{};
    ord.slab_start.assign(1, 0);
    return;
  }
  // Bounds of the stencil bases: the active nodes are [lo, hi + 2].
  Vec3i lo = Vec3i::Constant(1 << 30), hi = Vec3i::Constant(-(1 << 30));
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3i b = stencil_base(p.x[i], grid);
    lo = lo.cwiseMin(b);
    hi = hi.cwiseMax(b);
  }
  const Vec3i ext = hi - lo + Vec3i::Ones();
  grid.active.lo = lo;
  grid.active.hi = hi + Vec3i::Constant(2);

  // Counting sort by base cell inside the active box (x slowest).
  const std::size_t cells = static_cast<std::size_t>(ext.x()) * ext.y() * ext.z();
  ord.counts.assign(cells + 1, 0);
  auto key = [&](std::size_t i) {
    const Vec3i b = stencil_base(p.x[i], grid) - lo;
    return (static_cast<std::size_t>(b.x()) * ext.y() + b.y()) * ext.z() + b.z();
  };
  std::vector<std::uint32_t>& keys = ord.keys;  // reused: no allocation per substep
  keys.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    keys[i] = static_cast<std::uint32_t>(key(i));
    ++ord.counts[keys[i] + 1];
  }
  for (std::size_t c = 1; c <= cells; ++c) ord.counts[c] += ord.counts[c - 1];
  const int slabs = (ext.x() + ParticleOrder::kSlabWidth - 1) / ParticleOrder::kSlabWidth;
  ord.slab_start.resize(slabs + 1);
  const std::size_t plane = static_cast<std::size_t>(ext.y()) * ext.z();
  for (int s = 0; s <= slabs; ++s) {
    const std::size_t x = std::min<std::size_t>(s * ParticleOrder::kSlabWidth, ext.x());
    ord.slab_start[s] = ord.counts[x * plane];
  }
  for (std::size_t i = 0; i < n; ++i) ord.order[ord.counts[keys[i]]++] = static_cast<std::uint32_t>(i);
}

namespace {

template <bool kApic>
void scatter_particle(const Particles& p, std::uint32_t q, Grid& g) {
  const Stencil s = quadratic_stencil(p.x[q], g.origin, g.inv_h);
  const Real m = p.mass[q];
  const Vec3 mv = m * p.v[q];
  Mat3 mC = Mat3::Zero();
  if constexpr (kApic) mC = m * p.C[q];
  const Mat3& S = p.stress[q];
  const Vec3 corner = g.position(s.base.x(), s.base.y(), s.base.z()) - p.x[q];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) {
        const std::size_t idx = g.index(s.base.x() + i, s.base.y() + j, s.base.z() + k);
        const Real w = s.weight(i, j, k);
        g.mass[idx] += w * m;
        if constexpr (kApic) {
          const Vec3 dpos = corner + Vec3(i, j, k).cwiseProduct(g.h);
          g.velocity[idx] += w * (mv + mC * dpos);
        } else {
          g.velocity[idx] += w * mv;
        }
        g.force[idx] += S * s.gradient(i, j, k);
      }
}

template <bool kApic>
void scatter_all(const Particles& p, const ParticleOrder& ord, Grid& g) {
  const int slabs = static_cast<int>(ord.slab_start.size()) - 1;
  for (int color = 0; color < 2; ++color) {
#pragma omp parallel for schedule(dynamic, 1) if (ord.order.size() >= kParallelMinItems)
    for (int s = color; s < slabs; s += 2)
      for (std::size_t q = ord.slab_start[s]; q < ord.slab_start[s + 1]; ++q)
        scatter_particle<kApic>(p, ord.order[q], g);
  }
}

}  // namespace

void particles_to_grid(const Particles& p, const ParticleOrder& ord, Transfer transfer,
                       Grid& g) {
  for_each_active_node(g, [&](int, int, int, std::size_t idx) {
    g.mass[idx] = 0;
    g.velocity[idx].setZero();
    g.force[idx].setZero();
  });
  if (transfer == Transfer::apic) scatter_all<true>(p, ord, g);
  else scatter_all<false>(p, ord, g);
}

namespace {

template <Transfer kTransfer>
void gather_all(const Grid& g, Real flip_blend, Particles& p) {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(p.size());
  // D^-1 = 4 / h^2 per axis for quadratic B-splines (Jiang et al. 2015, section 5.3).
  const Vec3 inv_D = 4 * g.inv_h.cwiseProduct(g.inv_h);
  // Columns of K per node: w, grad w (3), w (x_i - x_p) (3). The sums over the 27 nodes are
  // then one small matrix product, which keeps the accumulators in registers.
  using NodeVel = Eigen::Matrix<Real, 3, 27>;
  using NodeKernel = Eigen::Matrix<Real, 27, 7>;
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < n; ++q) {
    const Stencil s = quadratic_stencil(p.x[q], g.origin, g.inv_h);
    const Vec3 corner = g.position(s.base.x(), s.base.y(), s.base.z()) - p.x[q];
    NodeVel vel, dvel;
    NodeKernel K;
    int c = 0;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k, ++c) {
          const std::size_t idx = g.index(s.base.x() + i, s.base.y() + j, s.base.z() + k);
          const Real w = s.weight(i, j, k);
          vel.col(c) = g.velocity[idx];
          if constexpr (kTransfer == Transfer::flip) dvel.col(c) = g.velocity[idx] - g.velocity_old[idx];
          K(c, 0) = w;
          K.block<1, 3>(c, 1) = s.gradient(i, j, k).transpose();
          K.block<1, 3>(c, 4) = w * (corner + Vec3(i, j, k).cwiseProduct(g.h)).transpose();
        }
    const Eigen::Matrix<Real, 3, 7> sums = vel.lazyProduct(K);
    const Vec3 v = sums.col(0);
    if constexpr (kTransfer == Transfer::flip)
      p.v[q] = flip_blend * (p.v[q] + dvel * K.col(0)) + (1 - flip_blend) * v;
    else
      p.v[q] = v;
    if constexpr (kTransfer == Transfer::apic) p.C[q] = sums.rightCols<3>() * inv_D.asDiagonal();
    p.grad_v[q] = sums.middleCols<3>(1);
  }
}

}  // namespace

void grid_to_particles(const Grid& g, Transfer transfer, Real flip_blend, Particles& p) {
  switch (transfer) {
    case Transfer::apic: gather_all<Transfer::apic>(g, flip_blend, p); break;
    case Transfer::pic: gather_all<Transfer::pic>(g, flip_blend, p); break;
    case Transfer::flip: gather_all<Transfer::flip>(g, flip_blend, p); break;
  }
}

void update_deformation(Real dt, Particles& p) {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(p.size());
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < n; ++q)
    p.F[q] = (Mat3::Identity() + dt * p.grad_v[q]) * p.F[q];
}

AdvectStats advect_particles(Real dt, const Grid& g, Particles& p) {
  const Vec3 lo = g.origin + g.buffer * g.h;
  const Vec3 hi = g.origin + (g.nodes - Vec3i::Ones() - Vec3i::Constant(g.buffer)).cast<Real>()
                                 .cwiseProduct(g.h);
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(p.size());
  std::size_t clamped = 0, nonfinite = 0;
  Real v2 = 0;
#pragma omp parallel for schedule(static) reduction(+ : clamped, nonfinite) reduction(max : v2) \
    if (n >= kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < n; ++q) {
    v2 = std::max(v2, p.v[q].squaredNorm());
    const Vec3 x = p.x[q] + dt * p.v[q];
    if (!x.allFinite()) {
      ++nonfinite;
      continue;
    }
    const Vec3 c = x.cwiseMax(lo).cwiseMin(hi);
    if (c != x) ++clamped;
    p.x[q] = c;
  }
  return {clamped, nonfinite, std::sqrt(v2)};
}

}  // namespace mpm
