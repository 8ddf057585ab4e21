// Particle <-> grid transfers keep mass, linear momentum and (APIC) angular momentum.
#include <omp.h>

#include <algorithm>
#include <catch2/catch.hpp>
#include <numeric>
#include <random>
#include <stdexcept>
#include <tuple>

#include "engine/core/radix_sort.h"
#include "engine/core/shares.h"
#include "engine/step/grid.h"
#include "engine/step/kernels.h"
#include "engine/step/transfer.h"
#include "support/helpers.h"
#include "transfers/cloud.h"

using namespace mpm;
using mpm::test::grid_totals_of_momentum;
using mpm::test::GridTotals;
using mpm::test::random_cloud;
using mpm::test::unit_grid;

namespace {

const Kernel kAllKernels[] = {Kernel::linear, Kernel::quadratic, Kernel::cubic};

}  // namespace

TEST_CASE("P2G keeps mass and linear momentum to round-off", "[transfers]") {
  for (Kernel kernel : kAllKernels)
  for (Transfer tr : {Transfer::apic, Transfer::pic}) {
    Particles p = random_cloud(2000, tr == Transfer::apic, 1);
    Grid g(unit_grid(16), false);
    ParticleOrder ord;
    sort_particles(p, kernel, g, ord);
    particles_to_grid(p, ord, tr, kernel, 0, g);
    const GridTotals t = grid_totals_of_momentum(g);
    double mass = 0;
    Vec3 mom = Vec3::Zero();
    for (std::size_t q = 0; q < p.size(); ++q) mass += p.mass(q), mom += p.mass(q) * p.v[q];
    CHECK(t.mass == Approx(mass).epsilon(1e-13));
    CHECK((t.momentum - mom).norm() < 1e-12 * mom.norm() + 1e-12);
  }
}

TEST_CASE("P2G then G2P keeps linear momentum", "[transfers]") {
  for (Kernel kernel : kAllKernels)
  for (Transfer tr : {Transfer::apic, Transfer::pic}) {
    Particles p = random_cloud(2000, tr == Transfer::apic, 2);
    Grid g(unit_grid(16), false);
    ParticleOrder ord;
    sort_particles(p, kernel, g, ord);
    particles_to_grid(p, ord, tr, kernel, 0, g);
    const Vec3 grid_mom = grid_totals_of_momentum(g).momentum;
    grid_update(g);
    grid_to_particles(g, tr, kernel, 0, 0, p);
    Vec3 mom = Vec3::Zero();
    for (std::size_t q = 0; q < p.size(); ++q) mom += p.mass(q) * p.v[q];
    CHECK((mom - grid_mom).norm() < 1e-12 * grid_mom.norm() + 1e-12);
  }
}

TEST_CASE("grid_update's block speeds are those of the nodes with mass it leaves", "[transfers]") {
  // The contact search bounds closing speeds by them (contact.cpp GridSpeed); grid_update sets
  // them in its own pass, block_speeds in one of its own: both as a loop over the nodes says.
  Particles p = random_cloud(3000, true, 4);
  Grid g(unit_grid(16), false);
  ParticleOrder ord;
  sort_particles(p, Kernel::quadratic, g, ord);
  particles_to_grid(p, ord, Transfer::apic, Kernel::quadratic, 0, g);
  Grid copy = g;
  BlockSpeeds fused;
  grid_update(g, Vec3(0, -0.01, 0), &fused);
  grid_update(copy, Vec3(0, -0.01, 0));
  const BlockSpeeds after = block_speeds(copy);
  REQUIRE(fused.block.size() == g.active_blocks());
  CHECK(fused.block == after.block);
  CHECK(fused.fastest == after.fastest);
  Real fastest = 0;
  int moving = 0;
  for (std::size_t b = 0; b < g.active_blocks(); ++b) {
    std::array<Real, 6> most{};
    for (std::size_t i = b * Grid::kBlockNodes; i < (b + 1) * Grid::kBlockNodes; ++i)
      if (g.mass[i] > 0)
        for (int a = 0; a < 3; ++a) {
          most[2 * a] = std::max(most[2 * a], g.velocity[i][a]);
          most[2 * a + 1] = std::max(most[2 * a + 1], -g.velocity[i][a]);
          fastest = std::max(fastest, g.velocity[i].norm());
        }
    CHECK(fused.block[b] == most);
    moving += most[3] > 0;  // gravity: every block with mass moves down
  }
  CHECK(moving > 0);
  CHECK(fused.fastest == Approx(fastest).epsilon(1e-14));
}

TEST_CASE("APIC round trip keeps angular momentum, PIC does not", "[transfers]") {
  // Jiang et al. 2015, section 5.3: with APIC, G2P then P2G leaves the grid's angular
  // momentum sum_i x_i x m_i v_i unchanged. PIC drops the particles' spin.
  auto drift = [](Transfer tr, Kernel kernel) {
    Particles p = random_cloud(3000, tr == Transfer::apic, 3);
    Grid g(unit_grid(16), false);
    ParticleOrder ord;
    sort_particles(p, kernel, g, ord);
    particles_to_grid(p, ord, tr, kernel, 0, g);
    const Vec3 before = grid_totals_of_momentum(g).angular;
    grid_update(g);
    grid_to_particles(g, tr, kernel, 0, 0, p);
    particles_to_grid(p, ord, tr, kernel, 0, g);
    const Vec3 after = grid_totals_of_momentum(g).angular;
    return (after - before).norm() / before.norm();
  };
  for (Kernel kernel : kAllKernels) {
    INFO("kernel " << static_cast<int>(kernel));
    // Round-off, plus the one rounding of C to StoredReal between G2P and P2G: it moves at
    // most eps / 2 of the part of L that C carries, a fraction of L (nothing in double).
    CHECK(drift(Transfer::apic, kernel) < 1e-12 + test::kStoredEps);
    CHECK(drift(Transfer::pic, kernel) > 1e-3);
  }
}

TEST_CASE("P2G gives the same grid for 1 and 2 threads", "[transfers]") {
  // 20000 particles: above kParallelMinItems, so two threads really scatter at once. APIC
  // scatters the stress as an impulse into the momentum, FLIP into the force array.
  Particles p = random_cloud(20000, true, 4);
  for (auto& S : p.stress) S = StoredMat3::Random();
  for (Kernel kernel : kAllKernels)
  for (Transfer tr : {Transfer::apic, Transfer::flip}) {
    auto scatter = [&](int threads) {
      omp_set_num_threads(threads);
      Grid g(unit_grid(16), tr == Transfer::flip);
      ParticleOrder ord;
      sort_particles(p, kernel, g, ord);
      particles_to_grid(p, ord, tr, kernel, 1e-3, g);
      return g;
    };
    const int threads = omp_get_max_threads();
    const Grid a = scatter(1), b = scatter(2);
    omp_set_num_threads(threads);
    CHECK(a.mass == b.mass);
    CHECK(a.velocity == b.velocity);
    CHECK(a.force == b.force);
    CHECK(a.force.empty() == (tr != Transfer::flip));
  }
}

TEST_CASE("for_each_slab runs every slab once, each odd one after the even ones beside it",
          "[transfers]") {
  for (int slabs : {1, 2, 5, 16}) {
    ParticleOrder ord;
    ord.order.resize(64 * slabs);
    for (int s = 0; s <= slabs; ++s) ord.slab_start.push_back(64 * s);
    for (long parallel_from : {0L, 1L << 30}) {
      // The slabs in the order they finished, each under the lock of one critical section.
      std::vector<int> finished;
      std::vector<int> started_after(slabs, -1);  // how many had finished when it started
      const auto run = [&](int s) {
#pragma omp critical
        started_after[s] = static_cast<int>(finished.size());
        // Some work, so that slabs overlap on two threads.
        volatile double sink = 0;
        for (int i = 0; i < 20000 * (s % 3 + 1); ++i) sink = sink + i;
#pragma omp critical
        finished.push_back(s);
      };
      for_each_slab(ord, run, parallel_from);
      REQUIRE(static_cast<int>(finished.size()) == slabs);
      std::vector<int> at(slabs);
      for (int k = 0; k < slabs; ++k) at[finished[k]] = k;
      std::vector<int> sorted = finished;
      std::sort(sorted.begin(), sorted.end());
      for (int s = 0; s < slabs; ++s) CHECK(sorted[s] == s);
      for (int s = 1; s < slabs; s += 2) {
        CHECK(at[s - 1] < started_after[s]);
        if (s + 1 < slabs) CHECK(at[s + 1] < started_after[s]);
      }
    }
  }
}

TEST_CASE("the stress impulse scattered with the momentum equals the force applied after",
          "[transfers]") {
  // PIC folds dt f_i into the momentum; FLIP scatters f_i and applies it after grid_update.
  // Both give v_i + dt f_i / m_i on every node, up to round-off.
  Particles p = random_cloud(3000, false, 5);
  for (auto& S : p.stress) S = StoredMat3::Random();
  const Real dt = 1e-3;
  for (Kernel kernel : kAllKernels) {
    Grid impulse(unit_grid(16), false), force(unit_grid(16), true);
    ParticleOrder ord;
    sort_particles(p, kernel, impulse, ord);
    sort_particles(p, kernel, force, ord);
    particles_to_grid(p, ord, Transfer::pic, kernel, dt, impulse);
    particles_to_grid(p, ord, Transfer::flip, kernel, dt, force);
    grid_update(impulse);
    grid_update(force);
    apply_stress_forces(dt, force);
    REQUIRE(impulse.velocity.size() == force.velocity.size());  // the same blocks, same slots
    double diff = 0, scale = 0;
    for (std::size_t i = 0; i < impulse.velocity.size(); ++i) {
      diff = std::max(diff, (impulse.velocity[i] - force.velocity[i]).norm());
      scale = std::max(scale, (force.velocity[i] - force.velocity_old[i]).norm());
    }
    INFO("kernel " << static_cast<int>(kernel) << ": largest dt f / m " << scale);
    CHECK(scale > 0);  // the stress really moved the nodes
    CHECK(diff <= 1e-12 * scale + 1e-13);
  }
}

namespace {

/// Checks `ord` against the stable sort by stencil base cell (ties by index) of kernel K,
/// the blocks of every stencil widened by `reach` nodes active, and slabs that start on
/// x-planes of cells.
template <Kernel K>
void check_sorted(const Particles& p, const Grid& g, const ParticleOrder& ord, int reach) {
  constexpr int N = KernelTraits<K>::kNodes;
  const std::size_t n = p.size();
  std::vector<Vec3i> base(n);
  for (std::size_t i = 0; i < n; ++i) base[i] = stencil_base<K>(p.x[i], g.origin, g.inv_h);
  const auto lex = [](const Vec3i& a, const Vec3i& b) {
    return std::tie(a.x(), a.y(), a.z()) < std::tie(b.x(), b.y(), b.z());
  };
  std::vector<std::uint32_t> expected(n);
  for (std::size_t i = 0; i < n; ++i) expected[i] = static_cast<std::uint32_t>(i);
  std::stable_sort(expected.begin(), expected.end(),
                   [&](std::uint32_t a, std::uint32_t b) { return lex(base[a], base[b]); });
  REQUIRE(ord.order == expected);
  std::size_t inactive = 0;
  for (std::size_t i = 0; i < n; ++i) {
    CHECK(ord.cell_base(ord.keys[i]) == base[i]);
    for (int a = -reach; a < N + reach; ++a)
      for (int b = -reach; b < N + reach; ++b)
        for (int c = -reach; c < N + reach; ++c) {
          const Vec3i node = base[i] + Vec3i(a, b, c);
          inactive += g.slot[g.page(node.x() >> Grid::kBlockBits, node.y() >> Grid::kBlockBits,
                                    node.z() >> Grid::kBlockBits)] < 0;
        }
  }
  CHECK(inactive == 0);
  REQUIRE(ord.slab_start.front() == 0);
  REQUIRE(ord.slab_start.back() == n);
  for (std::size_t s = 1; s + 1 < ord.slab_start.size(); ++s) {
    const std::size_t q = ord.slab_start[s];
    CHECK(ord.slab_start[s - 1] <= q);
    if (q > 0 && q < n) CHECK(base[ord.order[q - 1]].x() < base[ord.order[q]].x());
  }
}

}  // namespace

TEST_CASE(
    "The sort is the stable sort by cell, on dense boxes and on sparse ones, in cell "
    "order or not",
    "[transfers]") {
  // Each cloud starts in the cell order of the quadratic kernel; then some particles move by
  // up to 3 cells along an axis, or all move anywhere.
  struct Cloud {
    int cells;          ///< Grid cells per axis.
    std::size_t count;  ///< Particles.
    double lo, hi;      ///< Where they are spread, a fraction of the grid per axis.
  };
  const Cloud clouds[] = {
      {16, 3000, 0.3, 0.7},      // 2^3 cells of the box per particle: the counting sort
      {12, 100, 0.2, 0.8},       // about 700 cells, 10 bits: the radix sort in one pass
      {96, 3000, 0.05, 0.95},    // about 200 per particle, 20 bits: two passes
      {200, 3000, 0.05, 0.95},   // 180^3 cells, 23 bits: three passes
      {200, 20000, 0.05, 0.95},  // the same on the threads, each keying its own part
  };
  std::mt19937 rng(11);
  for (const Cloud& cloud : clouds)
    for (const int moved : {0, 20, 150, -1}) {  // -1: every particle anywhere
      INFO(cloud.cells << "^3 grid, " << cloud.count << " particles, moved " << moved);
      Particles p = random_cloud(cloud.count, false, 5);
      for (Vec3& x : p.x)
        x = (x - Vec3::Constant(0.3)) / 0.4 * (cloud.hi - cloud.lo) + Vec3::Constant(cloud.lo);
      Grid g(unit_grid(cloud.cells), false);
      ParticleOrder ord;
      sort_particles(p, Kernel::quadratic, g, ord);
      const std::vector<Vec3> x = p.x;
      for (std::size_t q = 0; q < p.size(); ++q) p.x[q] = x[ord.order[q]];  // in cell order
      std::uniform_int_distribution<std::size_t> which(0, p.size() - 1);
      std::uniform_int_distribution<int> axis(0, 2), cells_by(-3, 3);
      std::uniform_real_distribution<double> anywhere(0.2, 0.8);
      if (moved < 0)
        for (Vec3& y : p.x) y = Vec3(anywhere(rng), anywhere(rng), anywhere(rng));
      for (int m = 0; m < moved; ++m) {
        Vec3& y = p.x[which(rng)];
        const int a = axis(rng);
        y[a] = std::clamp(y[a] + cells_by(rng) * g.h[a], 0.2, 0.8);
      }
      for (Kernel kernel : kAllKernels)
        for (int reach : {0, 1}) {  // the cubic kernel with reach 1 spans three blocks per axis
          INFO("kernel " << static_cast<int>(kernel) << ", reach " << reach);
          sort_particles(p, kernel, g, ord, reach);
          dispatch_kernel(kernel, [&]<Kernel K>() { check_sorted<K>(p, g, ord, reach); });
        }
    }
}

TEST_CASE("grid_update with gravity folded in gives the two stages' velocities, bit for bit",
          "[transfers]") {
  // A cloud's sums leave nodes with and without mass in its blocks; the folded pass must match
  // grid_update then apply_gravity at every stored node, with float nodes as well.
  const Vec3 gravity(0.3, -9.81, 0.7);
  const Real dt = 1.3e-3;
  for (bool float_nodes : {false, true}) {
    INFO("float nodes " << float_nodes);
    Particles p = random_cloud(3000, true, 7);
    GridDesc desc = unit_grid(16);
    desc.float_nodes = float_nodes;
    Grid two(desc, false);
    ParticleOrder ord;
    sort_particles(p, Kernel::quadratic, two, ord);
    particles_to_grid(p, ord, Transfer::apic, Kernel::quadratic, dt, two);
    Grid folded = two;
    grid_update(two);
    apply_gravity(dt, gravity, two);
    grid_update(folded, dt * gravity);
    std::size_t with_mass = 0, without = 0;
    for (std::size_t i = 0; i < two.mass.size(); ++i) {
      (two.mass[i] > 0 ? with_mass : without) += 1;
      REQUIRE(folded.velocity[i] == two.velocity[i]);
    }
    CHECK(with_mass > 0);
    CHECK(without > 0);
  }
  Grid flip(unit_grid(8), true);
  CHECK_THROWS_AS(grid_update(flip, Vec3(0, -1, 0)), std::logic_error);
}

TEST_CASE("Shares hands out every item once, each share to its owner first", "[transfers]") {
  // One thread: its own share in grains, then the other's from the back, half of what is left.
  Shares one(10, 2, 3);
  std::vector<std::pair<std::size_t, std::size_t>> taken;
  for (std::size_t first = 0, last = 0; one.next(0, first, last);) taken.emplace_back(first, last);
  using R = std::vector<std::pair<std::size_t, std::size_t>>;
  CHECK(taken == R{{0, 3}, {3, 5}, {7, 10}, {5, 7}});
  CHECK_THROWS_AS(Shares(std::size_t{1} << 33, 2, 1), std::length_error);
  // Teams of 1 to 3 threads on 3 shares: each item once; in each share, the owner's items come
  // first and in order, the other threads' after them.
  const int threads = omp_get_max_threads();
  for (int team : {1, 2, 3}) {
    INFO("threads " << team);
    omp_set_num_threads(team);
    const std::size_t n = 5000;
    Shares shares(n, 3, 7);
    std::vector<int> owner(n, -1);
    std::vector<std::vector<std::pair<std::size_t, std::size_t>>> claims(3);
#pragma omp parallel
    {
      const int t = omp_get_thread_num();
      for (std::size_t first = 0, last = 0; shares.next(first, last);) {
        for (std::size_t i = first; i < last; ++i) owner[i] = owner[i] == -1 ? t : -2;
        claims[static_cast<std::size_t>(t)].emplace_back(first, last);
        volatile double sink = 0;  // some work, so that the threads overlap
        for (int i = 0; i < 2000; ++i) sink = sink + i;
      }
    }
    REQUIRE(std::count_if(owner.begin(), owner.end(), [](int o) { return o < 0; }) == 0);
    for (int s = 0; s < 3; ++s) {
      const std::size_t lo = s * n / 3, hi = (s + 1) * n / 3;
      std::size_t next = lo;  // the owner's claims in its share: in order from its start
      if (s < team)
        for (const auto& [first, last] : claims[static_cast<std::size_t>(s)])
          if (first >= lo && first < hi) {
            CHECK(first == next);
            next = last;
          }
      std::size_t misplaced = 0;  // the owner's items after another thread's, or the reverse
      for (std::size_t i = lo; i < hi; ++i) misplaced += (i < next) != (owner[i] == s);
      CHECK(misplaced == 0);
    }
  }
  omp_set_num_threads(threads);
}

TEST_CASE("The counting sort is the stable sort by cell on any team, in cell order or not",
          "[transfers]") {
  // A dense box (at most two cells per particle), enough particles for a team: shuffled, each
  // thread's keys span the box; in cell order (as after the reorder stage), a part of it.
  Particles p = random_cloud(30000, false, 7);
  const int threads = omp_get_max_threads();
  for (bool cell_order : {false, true}) {
    INFO("cell order " << cell_order);
    if (cell_order) {
      Grid g(unit_grid(16), false);
      ParticleOrder ord;
      sort_particles(p, Kernel::quadratic, g, ord);
      std::vector<Vec3> x(p.size());
      for (std::size_t i = 0; i < x.size(); ++i) x[i] = p.x[ord.order[i]];
      p.x = x;
    }
    for (int team : {1, 2, 3}) {
      INFO("threads " << team);
      omp_set_num_threads(team);
      Grid g(unit_grid(16), false);
      ParticleOrder ord;
      sort_particles(p, Kernel::quadratic, g, ord);
      REQUIRE(ord.counts.size() > 1);  // the counting sort's offsets: it ran
      std::vector<std::uint32_t> want(p.size());
      std::iota(want.begin(), want.end(), 0u);
      std::stable_sort(want.begin(), want.end(),
                       [&](std::uint32_t a, std::uint32_t b) { return ord.keys[a] < ord.keys[b]; });
      CHECK(ord.order == want);
      std::size_t wrong = 0;  // cell c's run starts after every particle of a smaller key
      for (std::size_t c = 0; c + 1 < ord.counts.size(); ++c)
        wrong += ord.counts[c] !=
                 static_cast<std::uint32_t>(std::count_if(ord.keys.begin(), ord.keys.end(),
                                                          [&](std::uint32_t k) { return k < c; }));
      CHECK(wrong == 0);
    }
  }
  omp_set_num_threads(threads);
}

TEST_CASE("radix_order is the stable sort by key", "[transfers]") {
  // Keys of one and of two radix passes, with many equal keys (whose indices must stay in
  // order): the sparse box's particle sort and the contacts' sort rely on the stable order.
  for (int bits : {9, 22}) {
    const std::size_t n = 30000;
    std::mt19937 rng(static_cast<unsigned>(bits));
    std::uniform_int_distribution<std::uint32_t> pick(0, (1u << bits) - 1);
    std::vector<std::uint32_t> keys(n);
    for (auto& k : keys) k = pick(rng) % (n / 3);  // about three indices a key, or more
    std::vector<std::uint32_t> expect(n);
    for (std::size_t i = 0; i < n; ++i) expect[i] = static_cast<std::uint32_t>(i);
    std::stable_sort(expect.begin(), expect.end(),
                     [&](std::uint32_t a, std::uint32_t b) { return keys[a] < keys[b]; });
    // One thread, and teams that split the indices into parts (each pass's counts per part).
    const int threads = omp_get_max_threads();
    for (int team : {1, 2, 3}) {
      INFO("bits " << bits << ", threads " << team);
      omp_set_num_threads(team);
      std::vector<std::uint32_t> order, scratch;
      radix_order(
          n, bits, [&](std::uint32_t i) { return keys[i]; }, order, scratch);
      CHECK(order == expect);
    }
    omp_set_num_threads(threads);
  }
}
