#include "engine/step/split_gather.h"

#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <exception>

#include "engine/core/idle_help.h"
#include "engine/core/shares.h"
#include "engine/step/simd/transfer_simd.h"

namespace mpm {

namespace {

/// Adds `part`'s counts to `whole` and raises its speed to part's.
void combine(const AdvectStats& part, AdvectStats& whole) {
  whole.clamped += part.clamped;
  whole.nonfinite += part.nonfinite;
  whole.max_speed = std::max(whole.max_speed, part.max_speed);
}

/// The chunks of `split` whose mark is `near`, in order.
std::vector<std::uint32_t> chunks_marked(const SplitGather& split, char near) {
  std::vector<std::uint32_t> chunks;
  for (std::size_t k = 0; k < split.near.size(); ++k)
    if (split.near[k] == near) chunks.push_back(static_cast<std::uint32_t>(k));
  return chunks;
}

/// Gathers the chunks `chunks` on the team, handed out by Shares (this thread first runs
/// `first`, if any), and adds the advection to split.advect.
void gather_chunks(const std::vector<std::uint32_t>& chunks, const std::function<void()>& first,
                   Transfer transfer, Kernel kernel, Real dt, const Grid& g, Particles& p,
                   SplitGather& split) {
  constexpr std::size_t C = simd::kGatherAlign;
  std::exception_ptr error;
  const bool par = p.size() >= static_cast<std::size_t>(kParallelMinItems);
  // Each thread first takes the chunks of its own share of the particles, the one whose slabs
  // it scattered (Shares, as for_each_slab hands them out), four at a time, then the others'
  // last ones: the chunks of thread 0's share that it has not reached when the contact ends go
  // to the others.
  Shares shares(chunks.size(), omp_get_max_threads(), 4);
  IdleTeam::reset();
#pragma omp parallel if (par)
  {
    if (first && omp_get_thread_num() == 0) {
      try {
        first();
      } catch (...) {
        error = std::current_exception();
      }
    }
    AdvectStats mine;
    std::size_t i = 0, end = 0;
    while (shares.next(i, end))
      for (std::size_t j = i; j < end; ++j) {
        const std::size_t q0 = chunks[j] * C;
        simd::gather_range(g, transfer, kernel, dt, p, q0, std::min(p.size(), q0 + C), &mine);
      }
#pragma omp critical(mpm_split_gather)
    combine(mine, split.advect);
    // Done: `first`'s loops may give this thread a part (idle_help.h) until the team ends.
    IdleTeam::arrive();
  }
  IdleTeam::reset();
  if (error) std::rethrow_exception(error);
}

}  // namespace

bool gather_beside(const ContactPass& contact, const std::vector<WallPlane>& planes,
                   const std::vector<Collider>& colliders, const BufferLayers& layers,
                   Transfer transfer, Kernel kernel, Real time, Real dt, const Grid& grid,
                   Particles& particles, SplitGather& split) {
  constexpr std::size_t C = simd::kGatherAlign;
  if (omp_get_max_threads() < 2 || static_cast<long>(particles.size()) < kParallelMinItems)
    return false;
  split.near = contact_chunks(planes, colliders, layers, kernel, time, particles, grid, C);
  const std::vector<std::uint32_t> far = chunks_marked(split, 0);
  if (2 * far.size() < split.near.size()) return false;
  split.advect = {};
  split.pending = true;
  ++split.runs;
  const std::vector<IndexRange> search = marked_ranges(split.near, C, particles.size());
  simd::prepare_gather(grid, kernel);
  gather_chunks(
      far, [&] { contact(&search); }, transfer, kernel, dt, grid, particles, split);
  return true;
}

void gather_rest(const Grid& grid, Transfer transfer, Kernel kernel, Real dt, Particles& particles,
                 SplitGather& split, AdvectStats* advect) {
  simd::prepare_gather(grid, kernel);  // the contact's and the domain boundary's nodes changed
  gather_chunks(chunks_marked(split, 1), {}, transfer, kernel, dt, grid, particles, split);
  split.pending = false;
  if (advect) *advect = split.advect;
}

}  // namespace mpm
