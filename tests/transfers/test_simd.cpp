// The float SIMD transfers agree with the scalar double reference to float rounding, and MLS
// conserves what APIC conserves.
#include <omp.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "engine/step/grid.h"
#include "engine/step/kernels.h"
#include "engine/step/reorder.h"
#include "engine/step/simd/stress_simd.h"
#include "engine/step/simd/transfer_simd.h"
#include "engine/step/transfer.h"
#include "materials/corotated.h"
#include "materials/elastic_group.h"

using namespace mpm;

namespace {

/// Unit round-off of float, 2^-24.
constexpr double kU = 1.0 / (1 << 24);

/// Particles at x with random velocity, C and stress and F near I; one object.
Particles random_state(const std::vector<Vec3>& x, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  Particles p;
  p.object_mass.push_back(1e-3);
  p.object_volume0.push_back(1e-4);
  for (const Vec3& xp : x) {
    p.x.push_back(xp);
    p.v.emplace_back(u(rng), u(rng), u(rng));
    p.object.push_back(0);
    StoredMat3 C, S, F;
    for (int a = 0; a < 9; ++a) {
      C.data()[a] = static_cast<StoredReal>(u(rng));
      S.data()[a] = static_cast<StoredReal>(u(rng));
      F.data()[a] = static_cast<StoredReal>((a % 4 == 0 ? 1 : 0) + 0.2 * u(rng));
    }
    p.C.push_back(C);
    p.stress.push_back(S);
    p.F.push_back(F);
  }
  return p;
}

/// 3000 particles in a 16^3 grid with random velocity, C, stress and F near I; one object.
Particles cloud(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> pos(0.3, 0.7);
  std::vector<Vec3> x;
  for (int i = 0; i < 3000; ++i) x.emplace_back(pos(rng), pos(rng), pos(rng));
  return random_state(x, seed + 1);
}

GridDesc grid16() {
  GridDesc d;
  d.dims = Vec3i::Constant(16);
  d.buffer = 2;
  return d;
}

/// Lattice spacing and first corner of halves_lattice.
constexpr double kLatticeH = 0.0125, kLatticeStart = -0.05;

/// A 24^3 grid of cells kLatticeH shifted by j h / 8, 3 cells below halves_lattice: (x -
/// origin) / h of the lattice lands on, or one rounding away from, a cell's half or a node,
/// where the quadratic and linear/cubic stencil bases change.
GridDesc shifted_grid(int j) {
  const double h = kLatticeH;
  GridDesc gd;
  gd.dims = Vec3i::Constant(24);
  gd.buffer = 2;
  gd.origin = Vec3::Constant(kLatticeStart - 3 * h - h / 4 - j * h / 8);
  gd.max = gd.origin + Vec3::Constant(24 * h);
  return gd;
}

/// 8 particles per cell (h / 2 apart, as the sampler places them) in `cells`^3 cells.
std::vector<Vec3> halves_lattice(int cells) {
  std::vector<Vec3> x;
  for (int a = 0; a < cells; ++a)
    for (int b = 0; b < cells; ++b)
      for (int c = 0; c < cells; ++c) {
        const Vec3 corner = Vec3::Constant(kLatticeStart) + Vec3(a, b, c) * kLatticeH;
        for (int s = 0; s < 8; ++s)
          x.push_back(corner +
                      (Vec3(s / 4, (s / 2) % 2, s % 2) + Vec3::Constant(0.5)) / 2 * kLatticeH);
      }
  return x;
}

/// Per stored node, the sum over particles of the absolute values of every term the scatter
/// adds (mass: m w; momentum component e: |w a_e|, |w i c0_e|, ..., |grad w S|), computed from
/// the scalar stencil: the scale the rounding error of a sum is bounded against.
template <Kernel K>
void absolute_sums(const Particles& p, Transfer tr, Real dt, const Grid& g, std::vector<double>& am,
                   std::vector<Vec3>& av) {
  constexpr int N = KernelTraits<K>::kNodes;
  am.assign(g.mass.size(), 0);
  av.assign(g.mass.size(), Vec3::Zero());
  const Vec3 inv_D = KernelTraits<K>::kInvDScale * g.inv_h.cwiseProduct(g.inv_h);
  for (std::size_t q = 0; q < p.size(); ++q) {
    const auto s = make_stencil<K>(p.x[q], g.origin, g.inv_h);
    std::size_t nodes[N * N * N];
    g.stencil_indices<N>(s.base, nodes);
    const Real m = p.mass(q);
    Mat3 Q = tr == Transfer::pic ? Mat3::Zero() : Mat3(m * to_real(p.C[q]));
    if (tr == Transfer::mls) Q += dt * to_real(p.stress[q]) * inv_D.asDiagonal();
    const Mat3 S = tr == Transfer::mls ? Mat3::Zero() : Mat3(dt * to_real(p.stress[q]));
    int n = 0;
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j)
        for (int k = 0; k < N; ++k, ++n) {
          const Real w = s.weight(i, j, k);
          const Vec3 gw = s.gradient(i, j, k).cwiseAbs();
          const Vec3 off =
              (g.position(s.base.x() + i, s.base.y() + j, s.base.z() + k) - p.x[q]).cwiseAbs();
          am[nodes[n]] += m * w;
          av[nodes[n]] += w * (m * p.v[q].cwiseAbs() + Q.cwiseAbs() * off) + S.cwiseAbs() * gw;
        }
  }
}

/// Puts p in the order `ord` sorted it into, as the reorder stage does (ids numbered first).
void reorder_as(ParticleOrder& ord, Particles& p) {
  p.id.resize(p.size());
  std::iota(p.id.begin(), p.id.end(), 0u);
  const ReorderRange all{0, p.size(), {}};
  reorder_particles({&all, 1}, false, ord, p);
}

/// Calls f(cell_order, kernel, transfer) on every instruction set this CPU runs, for particles
/// in memory order and in cell order, and every kernel and transfer the SIMD path takes (MLS
/// needs a kernel wider than linear).
template <class F>
void for_each_case(F&& f) {
  simd::for_each_target([&](const char* target) {
    for (bool cell_order : {false, true})
      for (Kernel kernel : {Kernel::linear, Kernel::quadratic, Kernel::cubic})
        for (Transfer tr : {Transfer::apic, Transfer::pic, Transfer::mls}) {
          if (tr == Transfer::mls && kernel == Kernel::linear) continue;
          INFO("target " << target << " kernel " << static_cast<int>(kernel) << " transfer "
                         << static_cast<int>(tr) << " cell order " << cell_order);
          f(cell_order, kernel, tr);
        }
  });
}

/// Scatters p with the scalar and the SIMD path on the grid `gd` (after putting p in cell
/// order if asked) and checks that every node agrees to float rounding.
void check_scatter_agrees(Particles p, const GridDesc& gd, bool cell_order, Kernel kernel,
                          Transfer tr) {
  const Real dt = 1e-3;
  Grid a(gd, false), b(gd, false);
  ParticleOrder ord;
  if (cell_order) {
    sort_particles(p, kernel, a, ord);
    reorder_as(ord, p);
  }
  sort_particles(p, kernel, a, ord);
  sort_particles(p, kernel, b, ord);
  particles_to_grid(p, ord, tr, kernel, dt, a, TransferPath::scalar);
  particles_to_grid(p, ord, tr, kernel, dt, b, TransferPath::simd);
  std::vector<double> am;
  std::vector<Vec3> av;
  dispatch_kernel(kernel, [&]<Kernel K>() { absolute_sums<K>(p, tr, dt, a, am, av); });
  // Bound: each term is a product of at most 3 float-rounded weights with a
  // float-rounded factor and up to 7 chained FMAs (at most 12 roundings: 12 u of the
  // term), and a node's terms from a run of cells along z are summed in float before
  // the grid adds them (the window of particles_to_grid: a node lies in the stencils of
  // N cells of a run, n_cell <= 40 particles each in these clouds (the densest, 3000 particles
  // over about 260 cells): at most 3 * 40 = 120 more roundings of the partial sum for the
  // quadratic kernel, 160 for the cubic). Double rounding of the scalar reference is
  // negligible. So |simd - scalar| <= (12 + 40 N) u sum |terms| per node.
  const double bound = (12 + 40 * kernel_nodes(kernel)) * kU;
  std::size_t bad = 0;
  double worst = 0;
  for (std::size_t n = 0; n < a.mass.size(); ++n) {
    worst = std::max(worst, std::abs(a.mass[n] - b.mass[n]) / (am[n] + 1e-300));
    bad += std::abs(a.mass[n] - b.mass[n]) > bound * am[n];
    for (int e = 0; e < 3; ++e)
      bad += std::abs(a.velocity[n][e] - b.velocity[n][e]) > bound * av[n][e];
  }
  INFO("worst mass error / sum |terms| " << worst / kU << " u");
  CHECK(bad == 0);
  CHECK(worst > 0);  // the paths really differ: the SIMD one ran
}

/// Gathers p from g with the scalar and the SIMD path and checks that v, C and F agree to float
/// rounding.
void check_gather_agrees(const Grid& g, Transfer tr, Kernel kernel, Real dt, Particles a) {
  Particles b = a;
  grid_to_particles(g, tr, kernel, 0, dt, a, TransferPath::scalar);
  grid_to_particles(g, tr, kernel, 0, dt, b, TransferPath::simd);
  double vmax = 0;
  for (const Vec3& v : g.velocity) vmax = std::max(vmax, v.cwiseAbs().maxCoeff());
  // v = sum_i w_i v_i with weights summing to 1: node velocities rounded to float (u / 2),
  // weights rounded (u), products of three (2 u), a chain of 2 N + 2 <= 10 FMAs: at most
  // 16 u of sum w |v_i| <= vmax. C = B D^-1 multiplies by |corner| + N h <= (N + 1) h and
  // 1/D = 4 / h^2 (linear: C = grad v, |grad w| <= 2 / h per axis, 3 axes): at most
  // 16 u vmax (N + 1) 4 / h. F = F + dt G F is rounded to float by both paths (1 ulp of
  // |F| <= 1.6: 2 u |F| apart at most) plus dt 3 |dG| |F|.
  const double h = g.h.x(), N = kernel_nodes(kernel);
  const double dv = 16 * kU * vmax, dC = 16 * kU * vmax * (N + 1) * 4 / h;
  std::size_t bad = 0;
  double seen = 0;
  for (std::size_t q = 0; q < a.size(); ++q) {
    seen = std::max(seen, (a.v[q] - b.v[q]).cwiseAbs().maxCoeff());
    bad += (a.v[q] - b.v[q]).cwiseAbs().maxCoeff() > dv;
    if (tr != Transfer::pic) bad += (to_real(a.C[q]) - to_real(b.C[q])).cwiseAbs().maxCoeff() > dC;
    const double fmax = to_real(a.F[q]).cwiseAbs().maxCoeff();
    bad += (to_real(a.F[q]) - to_real(b.F[q])).cwiseAbs().maxCoeff() >
           2 * kU * fmax + dt * 3 * dC * fmax;
  }
  INFO("largest velocity difference " << seen << " (bound " << dv << ")");
  CHECK(bad == 0);
  CHECK(seen > 0);
}

}  // namespace

TEST_CASE("force_target runs each instruction set's code, and refuses one it cannot",
          "[transfers][simd]") {
  // mpm bench --simd AVX2 times the AVX2 code on an AVX-512 machine this way.
  const char* best = simd::target_name();
  std::vector<std::string> names;
  simd::for_each_target([&](const char* n) { names.push_back(n); });
  for (const std::string& n : names) {
    CHECK(simd::force_target(n));
    CHECK(simd::target_name() == n);
  }
  if (!names.empty()) {
    CHECK(simd::force_target(""));
    CHECK(simd::target_name() == best);
    CHECK(simd::force_target(names.back()));
  }
  CHECK_FALSE(simd::force_target("AVX9"));
  CHECK(simd::target_name() == best);  // the normal choice again
}

TEST_CASE("SIMD and scalar particle-to-grid give the same grid to float rounding",
          "[transfers][simd]") {
  if (!simd::target_name()) {  // a CPU without SSE4: only the scalar path exists
    WARN("no SIMD target on this CPU");
    return;
  }
  // Every instruction set (AVX-512 scatters by planes of the stencil, narrower ones by nodes),
  // with particles in memory order as sampled and in cell order as the reorder leaves them
  // (batches of consecutive particles of one object: mass and model set once per batch).
  for_each_case([&](bool cell_order, Kernel kernel, Transfer tr) {
    check_scatter_agrees(cloud(7), grid16(), cell_order, kernel, tr);
  });
}

TEST_CASE("SIMD and scalar particle-to-grid agree for particles on cells' halves and nodes",
          "[transfers][simd]") {
  if (!simd::target_name()) {
    WARN("no SIMD target on this CPU");
    return;
  }
  // A regular lattice on grids shifted by j h / 8 (shifted_grid, halves_lattice). The SIMD
  // stencil must round as the scalar sort does: a fused multiply-add the source does not
  // write (GCC contracts one on FMA targets unless -ffp-contract=off) moved such a base by a
  // cell, and the scatter then wrote outside the blocks the sort activated (the grid at
  // offset 2/8 of scenes/validation/hydrostatic_water.yaml hung with MLS).
  for (int j = 0; j < 8; ++j) {
    const GridDesc gd = shifted_grid(j);
    const Particles p = random_state(halves_lattice(12), 3);
    INFO("grid origin at " << j << "/8 of a cell");
    for_each_case([&](bool cell_order, Kernel kernel, Transfer tr) {
      check_scatter_agrees(p, gd, cell_order, kernel, tr);
    });
  }
}

TEST_CASE("SIMD sort keys and bases are the scalar sort's, on cells' halves and nodes too",
          "[transfers][simd][sort]") {
  if (!simd::target_name()) {
    WARN("no SIMD target on this CPU");
    return;
  }
  // The lattice on grids shifted by j h / 8 (shifted_grid, halves_lattice), plus a few random
  // particles so that the count is not a multiple of any lane width: every key, whole lane
  // sets in lanes and the rest by the caller, must be the stencil base's key the scalar sort
  // computes.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0, 12 * kLatticeH);
  for (int j = 0; j < 8; ++j) {
    const Grid g(shifted_grid(j), false);
    Particles p;
    p.x = halves_lattice(6);
    for (int k = 0; k < 13; ++k)
      p.x.push_back(Vec3::Constant(kLatticeStart) + Vec3(u(rng), u(rng), u(rng)));
    const Vec3i lo(1, 2, 3), ext(30, 29, 28);
    simd::for_each_target([&](const char* target) {
      for (Kernel kernel : {Kernel::linear, Kernel::quadratic, Kernel::cubic}) {
        INFO("grid origin at " << j << "/8 of a cell, target " << target << ", kernel "
                               << static_cast<int>(kernel));
        std::vector<std::uint32_t> keys(p.size(), ~0u);
        std::vector<std::int32_t> bases(3 * p.size(), -7);
        const std::size_t first = 3;  // not on a lane set's start
        const std::size_t done =
            simd::cell_keys(p, kernel, g, lo, ext, first, p.size(), keys.data(), bases.data());
        CHECK(done >= p.size() - first - 16);
        std::size_t wrong = 0, wrong_base = 0;
        for (std::size_t q = first; q < first + done; ++q) {
          Vec3i b;
          dispatch_kernel(kernel,
                          [&]<Kernel K>() { b = stencil_base<K>(p.x[q], g.origin, g.inv_h); });
          const Vec3i k = b - lo;
          wrong +=
              keys[q] != static_cast<std::uint32_t>((k.x() * ext.y() + k.y()) * ext.z() + k.z());
          for (int a = 0; a < 3; ++a) wrong_base += bases[3 * (q - first) + a] != b[a];
        }
        CHECK(wrong == 0);
        CHECK(wrong_base == 0);
        CHECK(bases[3 * done] == -7);   // no base past what it did
        CHECK(keys[first - 1] == ~0u);  // nothing before `first` written
        if (first + done < p.size()) CHECK(keys[first + done] == ~0u);  // nor after what it did
      }
    });
  }
}

TEST_CASE("SIMD and scalar grid-to-particle give the same v, C and F to float rounding",
          "[transfers][simd]") {
  if (!simd::target_name()) {  // a CPU without SSE4: only the scalar path exists
    WARN("no SIMD target on this CPU");
    return;
  }
  const Real dt = 1e-3;
  // In memory order as sampled (a batch's 16 lanes in as many cells: the lanes gather), in
  // cell order as the reorder stage leaves it (about 11 particles per cell here: a batch
  // spans two or three cells, whose node velocities are loaded once per cell), and in cell
  // order with each 32 particles' halves interleaved (lanes alternate between cells, as where
  // particles cross a cell face between reorders: still loaded once per cell), or each 64
  // particles' quarters (a batch then spans four to nine cells: blended, the count known at
  // run time, up to half of 16 lanes; gathered by index beyond that, and beyond three cells on
  // narrower targets).
  for_each_case([&](bool cell_order, Kernel kernel, Transfer tr) {
    for (const std::uint32_t ways : {1u, 2u, 4u}) {
      if (ways > 1 && !cell_order) continue;
      INFO("interleaved " << ways << " ways");
      Particles a = cloud(8);
      Grid g(grid16(), false);
      ParticleOrder ord;
      sort_particles(a, kernel, g, ord);
      particles_to_grid(a, ord, tr, kernel, dt, g, TransferPath::scalar);
      grid_update(g);
      if (cell_order) reorder_as(ord, a);
      if (ways > 1) {
        const std::uint32_t group = 16 * ways;
        ParticleOrder mixed;
        for (std::uint32_t q = 0; q < a.size(); ++q) {
          const std::uint32_t first = q / group * group, k = q % group;
          const bool whole = first + group <= a.size();  // the last, partial group stays
          mixed.order.push_back(whole ? first + (k % ways) * 16 + k / ways : q);
        }
        reorder_as(mixed, a);
      }
      check_gather_agrees(g, tr, kernel, dt, a);
    }
  });
}

TEST_CASE("SIMD transfers give the same results for 1 and 2 threads", "[transfers][simd]") {
  Particles p0 = cloud(9);
  for (int r = 0; r < 3; ++r) {  // 12000 particles: above kParallelMinItems
    const Particles more = cloud(10 + r);
    p0.x.insert(p0.x.end(), more.x.begin(), more.x.end());
    p0.v.insert(p0.v.end(), more.v.begin(), more.v.end());
    p0.C.insert(p0.C.end(), more.C.begin(), more.C.end());
    p0.F.insert(p0.F.end(), more.F.begin(), more.F.end());
    p0.stress.insert(p0.stress.end(), more.stress.begin(), more.stress.end());
    p0.object.insert(p0.object.end(), more.object.begin(), more.object.end());
  }
  for (Transfer tr : {Transfer::apic, Transfer::mls}) {
    auto run = [&](int threads) {
      omp_set_num_threads(threads);
      Particles p = p0;
      Grid g(grid16(), false);
      ParticleOrder ord;
      sort_particles(p, Kernel::quadratic, g, ord);
      particles_to_grid(p, ord, tr, Kernel::quadratic, 1e-3, g, TransferPath::simd);
      const std::vector<Vec3> mom = g.velocity;
      grid_update(g);
      grid_to_particles(g, tr, Kernel::quadratic, 0, 1e-3, p, TransferPath::simd);
      return std::pair{mom, p};
    };
    const int threads = omp_get_max_threads();
    const auto [ga, pa] = run(1);
    const auto [gb, pb] = run(2);
    omp_set_num_threads(threads);
    CHECK(ga == gb);
    CHECK(pa.v == pb.v);
    CHECK(pa.C == pb.C);
    CHECK(pa.F == pb.F);
  }
}

TEST_CASE("MLS keeps mass, momentum and angular momentum through a transfer like APIC",
          "[transfers][mls]") {
  // With zero stress MLS's transfer is APIC's (Hu et al. 2018, section 4): P2G keeps mass and
  // momentum, and G2P then P2G keeps the grid's angular momentum. With stress, the folded
  // term m C + dt (-V0 tau) D^-1 adds no net momentum: sum_i w_ip (x_i - x_p) = 0.
  for (Kernel kernel : {Kernel::quadratic, Kernel::cubic})
    for (TransferPath path : {TransferPath::scalar, TransferPath::simd}) {
      Particles p = cloud(11);
      const double tol = path == TransferPath::simd ? 1e-5 : 1e-11;  // float lanes: see above
      Grid g(grid16(), false);
      ParticleOrder ord;
      sort_particles(p, kernel, g, ord);
      particles_to_grid(p, ord, Transfer::mls, kernel, 1e-3, g, path);
      double m = 0, gm = 0;
      Vec3 mom = Vec3::Zero(), gmom = Vec3::Zero(), L0 = Vec3::Zero();
      for (std::size_t q = 0; q < p.size(); ++q) m += p.mass(q), mom += p.mass(q) * p.v[q];
      for (std::size_t n = 0; n < g.mass.size(); ++n) gm += g.mass[n], gmom += g.velocity[n];
      CHECK(gm == Approx(m).epsilon(tol));
      CHECK((gmom - mom).norm() < tol * mom.norm());
      for (auto& S : p.stress) S.setZero();
      particles_to_grid(p, ord, Transfer::mls, kernel, 1e-3, g, path);
      auto angular = [&] {
        Vec3 L = Vec3::Zero();
        for (std::size_t b = 0; b < g.active_blocks(); ++b)
          for (int n = 0; n < Grid::kBlockNodes; ++n) {
            const Vec3i o = g.block_first[b];
            const Vec3 x = g.position(o.x() + (n >> 4), o.y() + ((n >> 2) & 3), o.z() + (n & 3));
            L += x.cross(g.velocity[b * Grid::kBlockNodes + n]);
          }
        return L;
      };
      L0 = angular();
      grid_update(g);
      grid_to_particles(g, Transfer::mls, kernel, 0, 0, p, path);
      particles_to_grid(p, ord, Transfer::mls, kernel, 0, g, path);
      CHECK((angular() - L0).norm() < (tol + 2 * kU) * L0.norm());
    }
}

namespace {

/// cloud(seed) with a second object: object 1 every third particle; or, with `one_object`,
/// object 0 alone, in cell order (batches of one object: the model set once per batch).
Particles two_object_cloud(unsigned seed, bool one_object) {
  Particles p = cloud(seed);
  p.object_mass.push_back(2e-3);
  p.object_volume0.push_back(2e-4);
  if (one_object) {
    Grid g(grid16(), false);
    ParticleOrder ord;
    sort_particles(p, Kernel::quadratic, g, ord);
    reorder_as(ord, p);
  } else {
    for (std::size_t q = 0; q < p.size(); q += 3) p.object[q] = 1;
  }
  return p;
}

/// Scatters `ref`, whose stored stress holds object 0's, into `a`, and `p` with object 0's
/// stress folded in by `model` into `b`; p's stored stress of object 0 is set to garbage
/// first, which the fold must not read.
void scatter_stored_and_folded(const Particles& ref, Particles p, const BatchModel& model,
                               Transfer tr, Grid& a, Grid& b) {
  for (std::size_t q = 0; q < p.size(); ++q)
    if (p.object[q] == 0) p.stress[q].setConstant(1e30f);
  ParticleOrder ord;
  sort_particles(p, Kernel::quadratic, a, ord);
  sort_particles(p, Kernel::quadratic, b, ord);
  particles_to_grid(ref, ord, tr, Kernel::quadratic, 1e-3, a, TransferPath::simd);
  const std::vector<BatchModel> fold{model, BatchModel{}};
  particles_to_grid(p, ord, tr, Kernel::quadratic, 1e-3, b, TransferPath::simd, fold);
}

}  // namespace

TEST_CASE(
    "SIMD particle-to-grid with each model's stress folded in equals the stress pass then the "
    "scatter",
    "[transfers][simd]") {
  if (!simd::target_name()) {
    WARN("no SIMD target on this CPU");
    return;
  }
  // Two objects: 0 folded (each model in turn), 1 not (its stress read from p.stress); or
  // object 0 alone (two_object_cloud).
  using K = BatchModel::Kind;
  std::vector<BatchModel> models;
  for (K kind : {K::fixed_corotated, K::snow, K::neo_hookean, K::water, K::sand}) {
    BatchModel m{kind, 3.8e5, 5.8e5};
    m.hardening = 10;                   // snow
    m.bulk_modulus = 1e5, m.gamma = 7;  // water
    models.push_back(m);
  }
  std::vector<Real> jp(3000);  // snow's Jp per particle
  for (std::size_t q = 0; q < jp.size(); ++q) jp[q] = 0.9 + 0.2 * std::sin(Real(q));
  simd::for_each_target([&](const char* target) {
    for (BatchModel model : models)
      for (bool one_object : {false, true})
        for (Transfer tr : {Transfer::apic, Transfer::pic, Transfer::mls}) {
          INFO("target " << target << " transfer " << static_cast<int>(tr) << " one object "
                         << one_object << " kind " << static_cast<int>(model.kind));
          if (model.kind == K::snow) model.state = jp.data();
          const Particles p = two_object_cloud(17, one_object);
          // Reference: object 0's stress from the separate SIMD stress pass, stored, then
          // scattered.
          Particles ref = p;
          for (std::size_t q = 0; q < p.size(); ++q)
            if (p.object[q] == 0) {
              BatchModel one = model;  // its state read from particle q's
              if (one.state) one.state += q;
              simd::stress(one, std::span<const StoredMat3>(&p.F[q], 1), p.object_volume0[0],
                           std::span<StoredMat3>(&ref.stress[q], 1));
            }
          Grid a(grid16(), false), b(grid16(), false);
          scatter_stored_and_folded(ref, p, model, tr, a, b);
          CHECK(a.mass == b.mass);
          CHECK(a.velocity == b.velocity);  // bit-identical: the same float stress, the same sums
        }
  });
}

TEST_CASE(
    "SIMD particle-to-grid with a group's own lane kernel (a plugin's) folded in equals "
    "its compute_stress pass then the scatter",
    "[transfers][simd]") {
  if (!simd::target_name()) {
    WARN("no SIMD target on this CPU");
    return;
  }
  // ElasticGroup's scalar default lane_stress: each lane in double, rounded to float, as
  // compute_stress rounds it to storage; so the grids agree to the bit in float storage.
  const materials::ElasticGroup<materials::FixedCorotated> group({3.8e5, 5.8e5}, 1000);
  BatchModel own;
  own.kind = BatchModel::Kind::group;
  own.group = &group;
  simd::for_each_target([&](const char* target) {
    for (bool one_object : {false, true}) {
      INFO("target " << target << " one object " << one_object);
      const Particles p = two_object_cloud(23, one_object);
      Particles ref = p;
      for (std::size_t q = 0; q < p.size(); ++q)
        if (p.object[q] == 0)
          group.compute_stress(std::span<const StoredMat3>(&p.F[q], 1), p.object_volume0[0],
                               std::span<StoredMat3>(&ref.stress[q], 1));
      Grid a(grid16(), false), b(grid16(), false);
      scatter_stored_and_folded(ref, p, own, Transfer::apic, a, b);
      CHECK(a.mass == b.mass);
      // In double storage the lanes see F rounded to float: equal to that rounding only.
      if constexpr (std::is_same_v<StoredReal, float>) CHECK(a.velocity == b.velocity);
    }
  });
}
