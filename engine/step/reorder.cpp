#include "engine/step/reorder.h"

#include <algorithm>
#include <utility>

namespace mpm {

void reorder_particles(std::span<const ReorderRange> ranges, ParticleOrder& order,
                       Particles& p) {
  const std::size_t n = p.size();
  if (n == 0) return;
  // dest[q]: the new index of particle q. Walking the sorted order and handing out the next
  // free index of q's range keeps each range's particles in cell order. It overwrites the cell
  // keys, rebuilt at the end.
  std::vector<std::uint32_t>& dest = order.keys;
  dest.resize(n);
  std::vector<std::size_t> next(p.object_mass.size());
  std::vector<std::size_t> range_of_object(p.object_mass.size());
  for (std::size_t r = 0; r < ranges.size(); ++r) {
    const std::uint32_t o = p.object[ranges[r].first];
    next[o] = ranges[r].first;
    range_of_object[o] = r;
  }
  {
    // Every range already in cell order (a slow scene: most reorders): the permutation is the
    // identity, nothing moves and the sort's keys stay valid. The first particle out of place
    // ends the check.
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
      order.order[k] = dest[q];
    }
  }
  // Apply the permutation in place by following its cycles: swapping q with dest[q] puts q's
  // particle in its place and brings the one from there to q, until q holds its own. The
  // order changes little between reorders, so most cycles are short and local.
  const bool apic = !p.C.empty();
  for (std::size_t q = 0; q < n; ++q) {
    while (dest[q] != q) {
      const std::uint32_t d = dest[q];
      // The next step swaps q with dest[d]: start loading that particle now.
      const std::uint32_t next = dest[d];
      __builtin_prefetch(&p.x[next], 1);
      __builtin_prefetch(&p.v[next], 1);
      __builtin_prefetch(&p.F[next], 1);
      if (apic) __builtin_prefetch(&p.C[next], 1);
      std::swap(p.x[q], p.x[d]);
      std::swap(p.v[q], p.v[d]);
      std::swap(p.F[q], p.F[d]);
      if (apic) std::swap(p.C[q], p.C[d]);
      std::swap(p.id[q], p.id[d]);
      const ReorderRange& r = ranges[range_of_object[p.object[q]]];
      if (!r.state.empty()) {
        const std::size_t s = r.state.size() / r.count;
        std::swap_ranges(r.state.begin() + (q - r.first) * s,
                         r.state.begin() + (q - r.first + 1) * s,
                         r.state.begin() + (d - r.first) * s);
      }
      std::swap(dest[q], dest[d]);
    }
  }
  // The cell keys of the new indices: sort position k lies in cell c for
  // counts[c - 1] <= k < counts[c] (counts[-1] = 0).
  std::vector<std::uint32_t>& keys = order.keys;
  const std::ptrdiff_t cells = static_cast<std::ptrdiff_t>(order.counts.size()) - 1;
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (std::ptrdiff_t c = 0; c < cells; ++c)
    for (std::size_t k = c > 0 ? order.counts[c - 1] : 0; k < order.counts[c]; ++k)
      keys[order.order[k]] = static_cast<std::uint32_t>(c);
}

}  // namespace mpm
