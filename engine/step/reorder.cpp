#include "engine/step/reorder.h"

#include <algorithm>
#include <utility>

namespace mpm {

namespace {

/// Smallest piece a range's cycle walk is cut into where dest allows: the threads share the
/// pieces, and a piece's particles stay in a core's cache while its cycles are walked.
constexpr std::size_t kReorderPiece = 4096;

/// Which arrays the cycle walk moves (those no dead array of the same type can take).
struct CycleFields {
  bool x = false, v = false, F = false;
};

/// Applies the permutation `dest` (new index of each particle) to particles [begin, end) of
/// range r, which `dest` maps onto themselves, by following its cycles; `dest` becomes the
/// identity there. Moves the arrays `f` names and the range's material state.
void apply_cycles(const ReorderRange& r, std::size_t begin, std::size_t end, CycleFields f,
                  std::vector<std::uint32_t>& dest, Particles& p) {
  const std::size_t s = r.count > 0 ? r.state.size() / r.count : 0;
  for (std::size_t q = begin; q < end; ++q) {
    while (dest[q] != q) {
      const std::uint32_t d = dest[q];
      if (f.x) std::swap(p.x[q], p.x[d]);
      if (f.F) std::swap(p.F[q], p.F[d]);
      if (f.v) std::swap(p.v[q], p.v[d]);
      if (s > 0)
        std::swap_ranges(r.state.begin() + (q - r.first) * s,
                         r.state.begin() + (q - r.first + 1) * s,
                         r.state.begin() + (d - r.first) * s);
      std::swap(dest[q], dest[d]);
    }
  }
}

/// to[dest[q]] = from[q] for every particle, in parallel; then `from` holds the result and
/// `to` what `from` held.
template <class T>
void permute_into(const std::vector<std::uint32_t>& dest, std::vector<T>& from,
                  std::vector<T>& to) {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(from.size());
  to.resize(from.size());
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < n; ++q) to[dest[q]] = from[q];
  from.swap(to);
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
  // Arrays with a dead array of their type beside them move out of place, in parallel, and
  // swap buffers with it: between the transfers v and C are dead (grid_to_particles
  // overwrites them) unless FLIP blends the old v (it keeps no C), and the sorted order is
  // spent. The rest follow the cycles below.
  permute_into(dest, p.id, order.order);
  CycleFields cycle;
  if (move_velocity)
    cycle.x = cycle.v = true;
  else
    permute_into(dest, p.x, p.v);
  if (p.C.size() == n)
    permute_into(dest, p.F, p.C);
  else
    cycle.F = true;
  const bool states = std::any_of(ranges.begin(), ranges.end(),
                                  [](const ReorderRange& r) { return !r.state.empty(); });
  if (!cycle.x && !cycle.F && !states) return;
  // In place by following the cycles: swapping q with dest[q] puts q's particle in its place
  // and brings the one from there to q, until q holds its own. A cycle never leaves its
  // range, nor a piece [b, c) that dest maps onto itself (a cut c with dest[q] < c for every
  // q < c of the range), so the pieces are walked in parallel. Where the cuts fall does not
  // change the result.
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
    apply_cycles(ranges[pieces[i].range], pieces[i].begin, pieces[i].end, cycle, dest, p);
}

}  // namespace mpm
