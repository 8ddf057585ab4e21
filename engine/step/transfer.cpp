#include "engine/step/transfer.h"

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <limits>
#include <span>
#include <stdexcept>
#include <utility>

#include "engine/core/radix_sort.h"
#include "engine/step/kernels.h"
#include "engine/step/simd/transfer_simd.h"

namespace mpm {

namespace {

/// Smallest slab width (cells along x) so that slabs two apart never write the same node: a
/// particle whose stencil base lies in slab s, cells [X_s, X_s+1), writes nodes from
/// X_s - r to X_s+1 - 1 + (N - 1) + r < X_s+2 - r when X_s+2 - X_s+1 >= N - 1 + 2 r, with r
/// the nodes a scatter reaches beyond the stencil on each side.
int slab_width(Kernel k, int reach) {
  return std::max(2, kernel_nodes(k) - 1 + 2 * reach);
}

/// Slabs per substep when the box is wide enough: an even number, so that each colour's
/// slabs (kSlabs / 2 of about equal particle counts) share out evenly over 2, 4 or 8 threads.
/// A constant, not the thread count, so the sums are the same for any count.
constexpr int kSlabs = 16;

/// The blocks holding the nodes of the stencil from `base`, widened by `reach` nodes on each
/// side: the first block and the last (each at most one more per axis,
/// Grid::stencil_indices).
template <Kernel K>
std::pair<Vec3i, Vec3i> stencil_blocks(const Vec3i& base, int reach) {
  constexpr int N = KernelTraits<K>::kNodes, B = Grid::kBlockBits;
  const Vec3i first = base - Vec3i::Constant(reach);
  const Vec3i last = base + Vec3i::Constant(N - 1 + reach);
  return {Vec3i(first.x() >> B, first.y() >> B, first.z() >> B),
          Vec3i(last.x() >> B, last.y() >> B, last.z() >> B)};
}

/// Marks the blocks [first, last] for storage (Grid::activate_blocks). Threads may mark the
/// same block: the store is atomic, and they all store 0.
void mark_blocks(const std::pair<Vec3i, Vec3i>& blocks, Grid& grid) {
  const auto& [first, last] = blocks;
  for (int bi = first.x(); bi <= last.x(); ++bi)
    for (int bj = first.y(); bj <= last.y(); ++bj)
      for (int bk = first.z(); bk <= last.z(); ++bk)
        std::atomic_ref<std::int32_t>(grid.slot[grid.page(bi, bj, bk)])
            .store(0, std::memory_order_relaxed);
}

/// The stable counting sort by key (`keys_of(first, last)` sets ord.keys of particles
/// [first, last), each below `cells`), for a box of at most two cells per particle: lists in
/// `order` each cell's particles by index, cells in key order, and marks the blocks of every
/// occupied cell's stencil. In parallel: each thread keys and counts the cells of its own
/// contiguous chunk of particles, and thread t's particles of cell c go after those of the
/// threads before it, so `order` is the serial sort's for any thread count. Each thread's
/// counts cover only the cells from its least key to its greatest: the particles lie in cell
/// order since the last reorder, so a chunk's cells are about its share of the box, and the
/// passes over the counts divide among the threads instead of each thread passing over the
/// whole box.
template <Kernel K, class KeysOf>
void counting_sort(std::size_t cells, KeysOf&& keys_of, int reach, ParticleOrder& ord, Grid& grid) {
  const std::size_t n = ord.order.size();
  std::vector<std::uint32_t>& keys = ord.keys;
  std::vector<std::uint32_t>& at = ord.scratch;
  std::vector<std::uint32_t>& start = ord.counts;
  start.resize(cells + 1);
  start[0] = 0;
  // Each thread's counts cover the whole box: no more threads than keep them within two
  // counts per particle.
  const int threads =
      static_cast<int>(std::clamp<std::size_t>(2 * n / cells, 1, omp_get_max_threads()));
  // Sized here, on the calling thread: allocated inside the team by whichever thread came
  // first, the buffer could come from that thread's malloc arena, which returns freed memory
  // to the system less readily (jello 4M's peak then varied between 148 and 160 B/particle).
  at.resize(static_cast<std::size_t>(threads) * cells);
  std::vector<std::uint32_t> range_count(threads);
  // Per thread, its least key and one past its greatest (its counts' window).
  std::vector<std::size_t> low(threads), high(threads);
#pragma omp parallel num_threads(threads) if (n >= kParallelMinItems)
  {
    const std::size_t team = static_cast<std::size_t>(omp_get_num_threads());
    const std::size_t t = static_cast<std::size_t>(omp_get_thread_num());
    const std::size_t first = n * t / team, last = n * (t + 1) / team;
    std::uint32_t* mine = at.data() + t * cells;
    keys_of(first, last);
    std::uint32_t least = ~0u, greatest = 0;
    for (std::size_t i = first; i < last; ++i) {
      least = std::min(least, keys[i]);
      greatest = std::max(greatest, keys[i]);
    }
    low[t] = first < last ? least : 0;
    high[t] = first < last ? std::size_t{greatest} + 1 : 0;
    std::fill(mine + low[t], mine + high[t], 0u);
    for (std::size_t i = first; i < last; ++i) ++mine[keys[i]];
    // at[t][c] becomes where thread t's first particle of cell c goes; start[c] is where cell
    // c starts: an exclusive sum over the cells, and within a cell over the threads whose
    // windows hold it, each thread summing its own range of cells, then starting its range
    // after the ones before.
    const std::size_t c0 = cells * t / team, c1 = cells * (t + 1) / team;
#pragma omp barrier
    const auto in_window = [&](std::size_t u, std::size_t c) { return c >= low[u] && c < high[u]; };
    std::uint32_t end = 0;
    for (std::size_t c = c0; c < c1; ++c)
      for (std::size_t u = 0; u < team; ++u)
        if (in_window(u, c)) end += at[u * cells + c];
    range_count[t] = end;
#pragma omp barrier
    end = 0;
    for (std::size_t u = 0; u < t; ++u) end += range_count[u];
    for (std::size_t c = c0; c < c1; ++c) {
      for (std::size_t u = 0; u < team; ++u)
        if (in_window(u, c)) end += std::exchange(at[u * cells + c], end);
      start[c + 1] = end;
    }
#pragma omp barrier
    for (std::size_t i = first; i < last; ++i)
      ord.order[mine[keys[i]]++] = static_cast<std::uint32_t>(i);
  }
  // The occupied cells mark their blocks, in parallel over x-planes of cells.
  const Vec3i ext = ord.ext;
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (int x = 0; x < ext.x(); ++x) {
    std::size_t c = static_cast<std::size_t>(x) * ext.y() * ext.z();
    for (int y = 0; y < ext.y(); ++y)
      for (int z = 0; z < ext.z(); ++z, ++c)
        if (start[c + 1] != start[c])
          mark_blocks(stencil_blocks<K>(ord.lo + Vec3i(x, y, z), reach), grid);
  }
}

/// The same order as counting_sort by least-significant-digit radix passes (each a stable
/// counting sort on up to 11 bits of the key, radix_order): time in proportion to the
/// particles, where counting_sort's passes over the cells would cost more (a sparse box).
void radix_sort(std::size_t cells, ParticleOrder& ord) {
  const std::vector<std::uint32_t>& keys = ord.keys;
  radix_order(
      ord.order.size(), static_cast<int>(std::bit_width(cells - 1)),
      [&](std::uint32_t i) { return keys[i]; }, ord.order, ord.scratch);
}

/// The keys of a sparse box, and the marks of the blocks each stencil (widened by `reach`)
/// touches. Each thread keys its own contiguous part a chunk at a time: keys and bases in
/// double lanes if `lanes` (simd::cell_keys, which needs the keys below 2^31), the rest one by
/// one, then the marks of each stencil whose blocks differ from the particle's before it. A
/// stencil that spans at most two blocks per axis (`narrow`) sets one byte of ord.spans, its
/// first block's, naming the axes along which it reaches the next block; activate_blocks
/// widens it, so no loop runs over the blocks per particle.
template <Kernel K, class Key>
void key_sparse(const Particles& p, bool lanes, const Key& key, int reach, Grid& grid,
                ParticleOrder& ord) {
  const std::size_t n = p.size();
  const long count = static_cast<long>(n);
  std::vector<std::uint32_t>& keys = ord.keys;
  const bool narrow = KernelTraits<K>::kNodes + 2 * reach <= Grid::kBlockEdge + 1;
  if (narrow) ord.spans.resize(grid.slot.size());
#pragma omp parallel if (count >= kParallelMinItems)
  {
    const std::size_t team = static_cast<std::size_t>(omp_get_num_threads());
    const std::size_t t = static_cast<std::size_t>(omp_get_thread_num());
    constexpr std::size_t kChunk = 256;
    std::int32_t bases[3 * kChunk];
    std::pair<Vec3i, Vec3i> marked(Vec3i::Zero(), -Vec3i::Ones());
    std::uint64_t marked_span = 0;
    for (std::size_t c0 = n * t / team, last = n * (t + 1) / team; c0 < last; c0 += kChunk) {
      const std::size_t c1 = std::min(last, c0 + kChunk);
      std::size_t i = c0;
      if (lanes) i += simd::cell_keys(p, K, grid, ord.lo, ord.ext, c0, c1, keys.data(), bases);
      for (; i < c1; ++i) {
        const Vec3i base = stencil_base<K>(p.x[i], grid.origin, grid.inv_h);
        keys[i] = key(base);
        for (int a = 0; a < 3; ++a) bases[3 * (i - c0) + a] = base[a];
      }
      for (i = c0; i < c1; ++i) {
        const std::int32_t* b = bases + 3 * (i - c0);
        const std::pair<Vec3i, Vec3i> blocks = stencil_blocks<K>(Vec3i(b[0], b[1], b[2]), reach);
        if (!narrow) {
          if (blocks != marked) mark_blocks(blocks, grid);
          marked = blocks;
          continue;
        }
        const auto& [first, end] = blocks;
        const std::size_t pg = grid.page(first.x(), first.y(), first.z());
        const auto span = static_cast<std::uint8_t>(
            8 | (end.x() > first.x()) | (end.y() > first.y()) << 1 | (end.z() > first.z()) << 2);
        const std::uint64_t mark = pg << 4 | span;
        if (mark != marked_span)
          std::atomic_ref<std::uint8_t>(ord.spans[pg]).fetch_or(span, std::memory_order_relaxed);
        marked_span = mark;
      }
    }
  }
}

/// Sorts by the base cell of kernel K's stencil (dispatched once, not per particle), activates
/// the blocks the stencils touch and places the slabs.
template <Kernel K>
void sort_by_cell(const Particles& p, Grid& grid, ParticleOrder& ord, int reach) {
  const std::size_t n = p.size();
  const Vec3 origin = grid.origin, inv_h = grid.inv_h;
  // Bounds of the stencil bases: the active nodes are [lo, hi + N - 1]. The base is a
  // non-decreasing function of each coordinate, so the bounds are the bases of the smallest
  // and largest coordinates: a min/max pass with no floor per particle.
  Real lx = std::numeric_limits<Real>::max(), ly = lx, lz = lx, hx = -lx, hy = hx, hz = hx;
  const std::ptrdiff_t count = static_cast<std::ptrdiff_t>(n);
#pragma omp parallel for schedule(static) reduction(min : lx, ly, lz) \
    reduction(max : hx, hy, hz) if (count >= kParallelMinItems)
  for (std::ptrdiff_t i = 0; i < count; ++i) {
    const Vec3& x = p.x[i];
    lx = std::min(lx, x.x()), ly = std::min(ly, x.y()), lz = std::min(lz, x.z());
    hx = std::max(hx, x.x()), hy = std::max(hy, x.y()), hz = std::max(hz, x.z());
  }
  const Vec3i lo = stencil_base<K>(Vec3(lx, ly, lz), origin, inv_h);
  const Vec3i hi = stencil_base<K>(Vec3(hx, hy, hz), origin, inv_h);
  const Vec3i ext = hi - lo + Vec3i::Ones();
  ord.lo = lo, ord.ext = ext;

  // Keys: base cells inside the active box, x slowest, z fastest.
  const std::size_t cells = static_cast<std::size_t>(ext.x()) * ext.y() * ext.z();
  const auto key = [&](const Vec3i& base) {
    const Vec3i k = base - lo;
    return static_cast<std::uint32_t>(
        (static_cast<std::size_t>(k.x()) * ext.y() + k.y()) * ext.z() + k.z());
  };
  const auto key_of = [&](std::size_t i) { return key(stencil_base<K>(p.x[i], origin, inv_h)); };
  std::vector<std::uint32_t>& keys = ord.keys;  // reused: no allocation per substep
  keys.resize(n);
  grid.release_blocks();
  if (cells <= 2 * n) {
    // The keys in double lanes where there is a SIMD target (the same values), the rest one
    // by one: one at a time, the floors and products took half the sort's time.
    const auto keys_of = [&](std::size_t first, std::size_t last) {
      first += simd::cell_keys(p, K, grid, lo, ext, first, last, keys.data());
      for (std::size_t i = first; i < last; ++i) keys[i] = key_of(i);
    };
    counting_sort<K>(cells, keys_of, reach, ord, grid);
  } else {
    // A box of more than two cells per particle (a body broken into dust): passes over the
    // cells would cost more than the particles. The radix sort orders the keys.
    key_sparse<K>(p, cells < (std::size_t{1} << 31), key, reach, grid, ord);
    radix_sort(cells, ord);
    ord.counts.clear();  // no cell offsets: scatters find a cell's run by its keys
  }
  const Vec3i top = hi + Vec3i::Constant(KernelTraits<K>::kNodes - 1 + reach);
  const Vec3i bottom = lo - Vec3i::Constant(reach);
  constexpr int B = Grid::kBlockBits;
  grid.activate_blocks(Vec3i(bottom.x() >> B, bottom.y() >> B, bottom.z() >> B),
                       Vec3i(top.x() >> B, top.y() >> B, top.z() >> B), ord.spans);

  // Slab boundaries at x-planes of cells, each slab at least `width` planes thick, placed
  // where the count of particles before them is nearest above s n / slabs: the slabs of a
  // colour hold about the same number of particles, so threads finish a colour together.
  const auto start_of_plane = [&](int x) {  // particles in the planes before x
    const std::uint32_t first = key(lo + Vec3i(x, 0, 0));
    return static_cast<std::size_t>(
        std::partition_point(ord.order.begin(), ord.order.end(),
                             [&](std::uint32_t i) { return keys[i] < first; }) -
        ord.order.begin());
  };
  const int width = slab_width(K, reach);
  const int slabs = std::max(1, std::min(kSlabs, ext.x() / width) & ~1);
  ord.slab_start.assign(1, 0);
  for (int s = 1, x = 0; s < slabs; ++s) {
    const int latest = ext.x() - (slabs - s) * width;  // room for the slabs after this one
    int next = x + width;
    while (next < latest && start_of_plane(next) < n * s / slabs) ++next;
    ord.slab_start.push_back(start_of_plane(next));
    x = next;
  }
  ord.slab_start.push_back(n);
}

}  // namespace

void sort_particles(const Particles& p, Kernel kernel, Grid& grid, ParticleOrder& ord, int reach) {
  ord.order.resize(p.size());
  if (p.size() == 0) {
    grid.release_blocks();
    grid.activate_blocks(Vec3i::Zero(), -Vec3i::Ones());
    ord.slab_start.assign(1, 0);
    return;
  }
  dispatch_kernel(kernel, [&]<Kernel K>() { sort_by_cell<K>(p, grid, ord, reach); });
}

namespace {

/// The sums over the N^3 nodes of one stencil base cell, accumulated for all the particles
/// of that cell before one write to the grid (kForce: FLIP's separate force).
template <int N, bool kForce>
struct CellSums {
  static constexpr int kNodes = N * N * N;  ///< Nodes of the stencil.
  Real mass[kNodes] = {};                   ///< Mass per node.
  Vec3 momentum[kNodes];                    ///< Momentum (with the impulse unless kForce).
  Vec3 force[kForce ? kNodes : 1];          ///< Stress force (FLIP only).
  CellSums() {
    for (Vec3& v : momentum) v.setZero();
    for (Vec3& f : force) f.setZero();
  }
};

/// Adds particle q, whose stencil is `s`, to its cell's sums. With kImpulse the stress force
/// enters the momentum as the impulse dt f; otherwise (FLIP, which needs the velocity before
/// forces) it is summed apart. With kMls the stress is folded into the affine term instead
/// (Hu et al. 2018, eq. 29: Q = m C + dt (-V0 tau) D^-1) and no force is scattered.
template <Kernel K, bool kApic, bool kImpulse, bool kMls = false>
void scatter_particle(const Particles& p, std::uint32_t q, Real dt, const Grid& g,
                      const Stencil<KernelTraits<K>::kNodes>& s,
                      CellSums<KernelTraits<K>::kNodes, !kImpulse>& sums) {
  constexpr int N = KernelTraits<K>::kNodes;
  const Real m = p.mass(q);
  // Momentum at node (i, j, k): m v + Q (corner + (i, j, k) h) = a + i c0 + j c1 + k c2.
  Vec3 a = m * p.v[q];
  Mat3 c = Mat3::Zero();
  if constexpr (kApic) {
    Mat3 mC = m * to_real(p.C[q]);
    if constexpr (kMls)
      mC += (dt * KernelTraits<K>::kInvDScale) * to_real(p.stress[q]) *
            g.inv_h.cwiseProduct(g.inv_h).asDiagonal();
    a += mC * (g.position(s.base.x(), s.base.y(), s.base.z()) - p.x[q]);
    c = mC * g.h.asDiagonal();
  }
  const Mat3 S = kMls ? Mat3::Zero() : Mat3((kImpulse ? dt : Real(1)) * to_real(p.stress[q]));
  // Weights are products w0[i] w1[j] w2[k]. Per (i, j) row, with w01 = w0[i] w1[j]:
  //   momentum  w2[k] w01 a_ij + k w2[k] w01 c2,    a_ij = a + i c0 + j c1,
  //   force     w2[k] (dw0[i] w1[j] S0 + w0[i] dw1[j] S1) + dw2[k] w01 S2   (S grad w).
  int n = 0;
  for (int i = 0; i < N; ++i)
    for (int j = 0; j < N; ++j) {
      const Real w01 = s.w[0][i] * s.w[1][j];
      const Vec3 mom = w01 * (a + i * c.col(0) + j * c.col(1));
      const Vec3 mom_k = w01 * c.col(2);
      const Vec3 f_w = s.dw[0][i] * s.w[1][j] * S.col(0) + s.w[0][i] * s.dw[1][j] * S.col(1);
      const Vec3 f_dw = w01 * S.col(2);
      const Real m01 = w01 * m;
      for (int k = 0; k < N; ++k, ++n) {
        const Real w2 = s.w[2][k], dw2 = s.dw[2][k];
        sums.mass[n] += m01 * w2;
        Vec3 dp = w2 * mom;
        if constexpr (kApic) dp += (k * w2) * mom_k;
        const Vec3 f = kMls ? Vec3::Zero() : Vec3(w2 * f_w + dw2 * f_dw);
        if constexpr (kImpulse) {
          sums.momentum[n] += dp + f;
        } else {
          sums.momentum[n] += dp;
          sums.force[n] += f;
        }
      }
    }
}

/// Scatters the sorted particles order[begin, end): each run of particles sharing a stencil
/// base cell is summed locally, then added to the grid's nodes once.
template <Kernel K, bool kApic, bool kImpulse, bool kMls>
void scatter_range(const Particles& p, const ParticleOrder& ord, std::size_t begin,
                   std::size_t end, Real dt, Grid& g) {
  constexpr int N = KernelTraits<K>::kNodes;
  using Sums = CellSums<N, !kImpulse>;
  for (std::size_t q = begin; q < end;) {
    const std::uint32_t cell = ord.keys[ord.order[q]];
    Sums sums;
    Vec3i base;
    for (; q < end && ord.keys[ord.order[q]] == cell; ++q) {
      const std::uint32_t i = ord.order[q];
      const auto s = make_stencil<K>(p.x[i], g.origin, g.inv_h);
      base = s.base;
      scatter_particle<K, kApic, kImpulse, kMls>(p, i, dt, g, s, sums);
    }
    std::size_t nodes[Sums::kNodes];
    g.stencil_indices<N>(base, nodes);
    for (int n = 0; n < Sums::kNodes; ++n) {
      g.mass[nodes[n]] += sums.mass[n];
      g.velocity[nodes[n]] += sums.momentum[n];
      if constexpr (!kImpulse) g.force[nodes[n]] += sums.force[n];
      if (g.float_nodes) {  // grid.precision: float rounds every stored sum
        g.mass[nodes[n]] = static_cast<float>(g.mass[nodes[n]]);
        g.velocity[nodes[n]] = g.velocity[nodes[n]].template cast<float>().template cast<Real>();
        if constexpr (!kImpulse) g.force[nodes[n]] = g.force[nodes[n]].template cast<float>().template cast<Real>();
      }
    }
  }
}

template <Kernel K, bool kApic, bool kImpulse, bool kMls = false>
void scatter_all(const Particles& p, const ParticleOrder& ord, Real dt, Grid& g) {
  for_each_slab(ord, [&](int s) {
    scatter_range<K, kApic, kImpulse, kMls>(p, ord, ord.slab_start[s], ord.slab_start[s + 1], dt,
                                            g);
  });
}

}  // namespace

void clear_node_sums(Grid& g) {
  // The node arrays hold exactly the active blocks; clear all of them, padding included (a
  // slot may have held another block before).
  const std::ptrdiff_t nodes = static_cast<std::ptrdiff_t>(g.mass.size());
#pragma omp parallel for schedule(static) if (nodes >= kParallelMinItems)
  for (std::ptrdiff_t i = 0; i < nodes; ++i) {
    g.mass[i] = 0;
    g.velocity[i].setZero();
    if (g.flip) g.force[i].setZero();
  }
}

void particles_to_grid(const Particles& p, const ParticleOrder& ord, Transfer transfer,
                       Kernel kernel, Real dt, Grid& g, TransferPath path,
                       std::span<const BatchModel> fold) {
  clear_node_sums(g);
  const bool simd_path = path == TransferPath::simd && simd::supports(transfer, kernel, g);
  if (simd_path) return simd::scatter(p, ord, transfer, kernel, dt, g, fold);
  if (!fold.empty())  // the caller did not compute these particles' stress
    throw std::logic_error("particles_to_grid: stress folded into a scatter the SIMD path cannot run");
  dispatch_kernel(kernel, [&]<Kernel K>() {
    switch (transfer) {
      case Transfer::apic: scatter_all<K, true, true>(p, ord, dt, g); break;
      case Transfer::pic: scatter_all<K, false, true>(p, ord, dt, g); break;
      case Transfer::flip: scatter_all<K, false, false>(p, ord, dt, g); break;
      case Transfer::mls:
        if constexpr (K != Kernel::linear) scatter_all<K, true, true, true>(p, ord, dt, g);
        break;  // the loader refuses mls with the linear kernel
    }
  });
}

namespace {

template <Kernel K, Transfer kTransfer>
void gather_all(const Grid& g, Real flip_blend, Real dt, Particles& p) {
  constexpr int N = KernelTraits<K>::kNodes;
  constexpr int kStencil = N * N * N;
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(p.size());
  constexpr bool kAffine = kTransfer == Transfer::apic || kTransfer == Transfer::mls;
  const Vec3 inv_D = KernelTraits<K>::kInvDScale * g.inv_h.cwiseProduct(g.inv_h);
  const bool fl = g.float_nodes;
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < n; ++q) {
    const auto s = make_stencil<K>(p.x[q], g.origin, g.inv_h);
    std::size_t nodes[kStencil];
    g.template stencil_indices<N>(s.base, nodes);
    // Weights are products w0[i] w1[j] w2[k]: sum each (i, j) row over k first (r: with w2,
    // dw2 and k w2), then the rows. Columns of `sums`: v, grad v (3), sum w v (i, j, k)^T (3).
    Eigen::Matrix<Real, 3, 7> sums = Eigen::Matrix<Real, 3, 7>::Zero();
    Vec3 dv = Vec3::Zero();  // FLIP: sum w (v - v_old)
    int c = 0;
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j) {
        Vec3 r0 = Vec3::Zero(), r1 = Vec3::Zero(), r2 = Vec3::Zero(), rd = Vec3::Zero();
        for (int k = 0; k < N; ++k, ++c) {
          const Vec3 vi = fl ? Vec3(g.velocity[nodes[c]].template cast<float>().template cast<Real>())
                             : g.velocity[nodes[c]];
          r0 += s.w[2][k] * vi;
          r1 += s.dw[2][k] * vi;
          if constexpr (kAffine) r2 += (k * s.w[2][k]) * vi;
          if constexpr (kTransfer == Transfer::flip)
            rd += s.w[2][k] * (vi - g.velocity_old[nodes[c]]);
        }
        const Real w01 = s.w[0][i] * s.w[1][j];
        sums.col(0) += w01 * r0;
        sums.col(1) += (s.dw[0][i] * s.w[1][j]) * r0;
        sums.col(2) += (s.w[0][i] * s.dw[1][j]) * r0;
        sums.col(3) += w01 * r1;
        if constexpr (kAffine) {
          sums.col(4) += (i * w01) * r0;
          sums.col(5) += (j * w01) * r0;
          sums.col(6) += w01 * r2;
        }
        if constexpr (kTransfer == Transfer::flip) dv += w01 * rd;
      }
    const Vec3 v = sums.col(0);
    if constexpr (kTransfer == Transfer::flip)
      p.v[q] = flip_blend * (p.v[q] + dv) + (1 - flip_blend) * v;
    else
      p.v[q] = v;
    Mat3 grad_v = sums.template middleCols<3>(1);
    if constexpr (kAffine) {
      if constexpr (K == Kernel::linear) p.C[q] = to_stored(grad_v);
      else {
        // B = sum w v (x_i - x_p)^T = v (corner)^T + sum w v (i, j, k)^T diag(h).
        const Vec3 corner = g.position(s.base.x(), s.base.y(), s.base.z()) - p.x[q];
        const Mat3 B = v * corner.transpose() + sums.template rightCols<3>() * g.h.asDiagonal();
        const Mat3 C = B * inv_D.asDiagonal();
        p.C[q] = to_stored(C);
        if constexpr (kTransfer == Transfer::mls) grad_v = C;  // Hu et al. 2018, eq. 17
      }
    }
    // F <- (I + dt grad v) F (Stomakhin et al. 2013, eq. 7 with the elastic part only).
    p.F[q] = to_stored((Mat3::Identity() + dt * grad_v) * to_real(p.F[q]));
  }
}

}  // namespace

void grid_to_particles(const Grid& g, Transfer transfer, Kernel kernel, Real flip_blend,
                       Real dt, Particles& p, TransferPath path, AdvectStats* advect) {
  if (path == TransferPath::simd && simd::supports(transfer, kernel, g))
    return simd::gather(g, transfer, kernel, dt, p, advect);
  dispatch_kernel(kernel, [&]<Kernel K>() {
    switch (transfer) {
      case Transfer::mls:
        if constexpr (K != Kernel::linear) gather_all<K, Transfer::mls>(g, flip_blend, dt, p);
        break;  // the loader refuses mls with the linear kernel
      case Transfer::apic: gather_all<K, Transfer::apic>(g, flip_blend, dt, p); break;
      case Transfer::pic: gather_all<K, Transfer::pic>(g, flip_blend, dt, p); break;
      case Transfer::flip: gather_all<K, Transfer::flip>(g, flip_blend, dt, p); break;
    }
  });
  if (advect) *advect = advect_particles(dt, g, p);
}

AdvectStats advect_particles(Real dt, const Grid& g, Particles& p) {
  const AdvectBox box(g);
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(p.size());
  std::size_t clamped = 0, nonfinite = 0;
  Real v2 = 0;
#pragma omp parallel for schedule(static) reduction(+ : clamped, nonfinite) reduction(max : v2) \
    if (n >= kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < n; ++q)
    advect_particle(box, dt, p.v[q], p.x[q], clamped, nonfinite, v2);
  return {clamped, nonfinite, std::sqrt(v2)};
}

}  // namespace mpm
