#include "engine/step/reorder.h"

#include <algorithm>
#include <utility>

namespace mpm {

namespace {

/// Smallest piece a range's cycle walk is cut into where dest allows: the threads share the
/// pieces, and a piece's particles (52 to 124 bytes each) stay in a core's cache while its
/// cycles are walked.
constexpr std::size_t kReorderPiece = 4096;

/// Applies the permutation `dest` (new index of each particle) to particles [begin, end) of
/// range r, which `dest` maps onto themselves, by following its cycles; `dest` becomes the
/// identity there. Moves x, F, id, the state and, with `move_velocity`, v.
void apply_cycles(const ReorderRange& r, std::size_t begin, std::size_t end, bool move_velocity,
                  std::vector<std::uint32_t>& dest, Particles& p) {
  const std::size_t s = r.count > 0 ? r.state.size() / r.count : 0;
  for (std::size_t q = begin; q < end; ++q) {
    while (dest[q] != q) {
      const std::uint32_t d = dest[q];
      // The next step swaps q with dest[d]: start loading that particle now.
      const std::uint32_t next = dest[d];
      __builtin_prefetch(&p.x[next], 1);
      __builtin_prefetch(&p.F[next], 1);
      if (move_velocity) __builtin_prefetch(&p.v[next], 1);
      std::swap(p.x[q], p.x[d]);
      std::swap(p.F[q], p.F[d]);
      if (move_velocity) std::swap(p.v[q], p.v[d]);
      std::swap(p.id[q], p.id[d]);
      if (s > 0)
        std::swap_ranges(r.state.begin() + (q - r.first) * s,
                         r.state.begin() + (q - r.first + 1) * s,
                         r.state.begin() + (d - r.first) * s);
      std::swap(dest[q], dest[d]);
    }
  }
}

}  // namespace

void reorder_particles(std::span<const ReorderRange> ranges, bool move_velocity,
                       ParticleOrder& order, Particles& p) {
  const std::size_t n = p.size();
  if (n == 0) return;
  // dest[q]: the new index of particle q. Walking the sorted order and handing out the next
  // free index of q's range keeps each range's particles in cell order. It overwrites the cell
  // keys: the order is spent.
  std::vector<std::uint32_t>& dest = order.keys;
  dest.resize(n);
  std::vector<std::size_t> next(p.object_mass.size());
  for (const ReorderRange& r : ranges) next[p.object[r.first]] = r.first;
  {
    // Every range already in cell order (a slow scene: most reorders): the permutation is the
    // identity and nothing moves. The first particle out of place ends the check.
    std::vector<std::size_t> at = next;
    std::size_t k = 0;
    while (k < n && at[p.object[order.order[k]]]++ == order.order[k]) ++k;
    if (k == n) return;
  }
  // The walk in fixed chunks of the sorted order, in parallel: each chunk starts each object's
  // count where the chunks before it left it (a prefix sum over chunks per object), so dest is
  // the serial walk's for any thread count.
  constexpr std::size_t kChunk = std::size_t{1} << 16;
  const std::size_t objects = next.size(), chunks = (n + kChunk - 1) / kChunk;
  std::vector<std::size_t> start(chunks * objects, 0);
  const std::ptrdiff_t nchunks = static_cast<std::ptrdiff_t>(chunks);
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (std::ptrdiff_t c = 0; c < nchunks; ++c)
    for (std::size_t k = c * kChunk; k < std::min(n, (c + 1) * kChunk); ++k)
      ++start[c * objects + p.object[order.order[k]]];
  for (std::size_t o = 0; o < objects; ++o)
    for (std::size_t c = 0, at = next[o]; c < chunks; ++c)
      at += std::exchange(start[c * objects + o], at);
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (std::ptrdiff_t c = 0; c < nchunks; ++c) {
    std::size_t* at = start.data() + c * objects;
    for (std::size_t k = c * kChunk; k < std::min(n, (c + 1) * kChunk); ++k) {
      const std::uint32_t q = order.order[k];
      dest[q] = static_cast<std::uint32_t>(at[p.object[q]]++);
    }
  }
  // Apply the permutation in place by following its cycles: swapping q with dest[q] puts q's
  // particle in its place and brings the one from there to q, until q holds its own. A cycle
  // never leaves its range, nor a piece [b, c) that dest maps onto itself (a cut c with
  // dest[q] < c for every q < c of the range: found close to any index, since particles move
  // only to nearby cells), so the pieces are walked in parallel. Where the cuts fall does
  // not change the result.
  struct Piece {
    std::size_t range, begin, end;
  };
  std::vector<Piece> pieces;
  for (std::size_t r = 0; r < ranges.size(); ++r) {
    const std::size_t first = ranges[r].first, last = first + ranges[r].count;
    std::size_t begin = first, reach = first;  // reach: the largest dest[q] of the range so far
    for (std::size_t q = first; q < last;) {
      reach = std::max<std::size_t>(reach, dest[q++]);
      if (q - begin >= kReorderPiece && reach < q) {
        pieces.push_back({r, begin, q});
        begin = q;
      }
    }
    if (begin < last) pieces.push_back({r, begin, last});
  }
  const std::ptrdiff_t npieces = static_cast<std::ptrdiff_t>(pieces.size());
#pragma omp parallel for schedule(dynamic, 1) if (n >= kParallelMinItems)
  for (std::ptrdiff_t i = 0; i < npieces; ++i)
    apply_cycles(ranges[pieces[i].range], pieces[i].begin, pieces[i].end, move_velocity, dest, p);
}

}  // namespace mpm
