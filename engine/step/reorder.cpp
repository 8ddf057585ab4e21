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
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t q = order.order[k];
    dest[q] = static_cast<std::uint32_t>(next[p.object[q]]++);
    order.order[k] = dest[q];
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
  const std::size_t cells = order.counts.size() - 1;
  std::size_t k = 0;
  for (std::size_t c = 0; c < cells; ++c)
    for (; k < order.counts[c]; ++k) keys[order.order[k]] = static_cast<std::uint32_t>(c);
}

}  // namespace mpm
