#pragma once
/// \file The domain decomposition of a run over MPI ranks: slabs of grid block layers along
/// the grid's longest axis, the halo exchange of the nodes next to a slab boundary, particle
/// migration, and the gather to rank 0 for each frame's checks and output (docs/distributed.md).

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "engine/core/math.h"
#include "engine/step/exchange.h"

namespace mpm::parallel {

/// Rank r owns the grid's block layers [first_layer[r], first_layer[r + 1]) along `axis` (a
/// layer is one 4-node block thick), and the particles whose stencil base node lies there.
struct Slabs {
  int axis = 0;                  ///< 0, 1 or 2.
  std::vector<int> first_layer;  ///< ranks + 1 bounds, strictly increasing.
  /// The rank owning block layer `layer` (layers outside the grid go to the end ranks).
  int owner_of_layer(int layer) const;
};

/// Slab bounds balancing particle counts: with `per_layer[l]` particles whose stencil base lies
/// in layer l, rank r starts at the layer whose count before it is nearest r N / ranks (of
/// the first to reach it and the one before), kept at least one layer after rank r - 1's
/// start and leaving one layer for each later rank.
/// Needs ranks <= per_layer.size().
Slabs balanced_slabs(const std::vector<std::uint64_t>& per_layer, int ranks, int axis);

/// What the decomposition did over a run, for report.yaml (filled on rank 0 at each frame).
struct DomainStats {
  int ranks = 1;                         ///< Number of ranks.
  std::vector<std::uint64_t> particles;  ///< Particles per rank in the last frame.
  double imbalance_max = 1;              ///< Largest max/mean particles over the frames.
  double imbalance_mean = 1;             ///< Mean of max/mean over the frames.
  std::vector<double> comm_seconds;      ///< Seconds in MPI per rank.
  std::vector<std::uint64_t> bytes;      ///< Bytes each rank sent.
  std::uint64_t substeps = 0;            ///< Substeps over which `bytes` was counted.
  std::uint64_t halo_bytes = 0;          ///< Of `bytes`, halo exchanges summed over ranks.
  int frames = 0;                        ///< Frames distributed.
};

/// The run's split over ranks. Every method is collective: all ranks call it in the same order.
class Domain final : public RankExchange {
 public:
  /// The decomposition of `sim` over parallel::ranks() ranks (more than one). Throws SceneError
  /// (at grid.dims) when the grid's longest axis has fewer block layers than there are ranks.
  static std::shared_ptr<Domain> create(const Simulation& sim);

  /// Stage halo_blocks, after the sort: each rank sends the list of its active blocks in the
  /// next rank's first layer (its ghost blocks) to that rank, which activates them too.
  void share_ghost_blocks(Grid& grid) override;
  /// Stage halo_sum, after particles_to_grid: ghost nodes' mass, momentum (and FLIP's force)
  /// go to their owner, which adds them in block order; the sender then zeroes its ghosts, so
  /// only the owner updates a node and counts wall work on it.
  void add_ghost_sums(Grid& grid) override;
  /// Stage halo_velocity, before contact and grid_to_particles: the owner sends the mass and
  /// velocity (and FLIP's velocity before forces) of those nodes back to the ghosts.
  void return_ghost_velocities(Grid& grid) override;
  /// Stage contact: every rank's contacts (`local`, found on its own particles) and the
  /// nodes they reach go to rank 0, which solves them as one set (solve_contact,
  /// engine/step/contact.h); every rank then takes the new velocity of each node it stores.
  /// Rank 0 starts from and keeps the normal impulses in `memory`. Returns the walls' work on
  /// rank 0, 0 on the others.
  Real solve_contact(const ContactSettings& settings, Real dt, ContactState& local, Grid& g,
                     ContactMemory& memory) override;
  /// Stage migrate, after advect: particles whose stencil base left the slab go to its owner.
  void migrate(Simulation& sim) override;
  /// The advection statistics over all ranks (sum of counts, largest speed).
  AdvectStats combine(const AdvectStats& local) const override;

  /// At the start of a run every rank holds the whole state (built or restored the same way):
  /// ranks other than 0 drop their particles, so the state is as after collect().
  void keep_root_only(Simulation& sim);
  /// Frame start: balanced slabs from the particle count per block layer summed over the
  /// ranks (one reduction of a layer-sized array), then every particle goes to its new owner
  /// by the migration exchange. Works wherever the particles are (all on rank 0 after
  /// collect(), or spread over slabs). Called every frame, after the frame's gather.
  void distribute(Simulation& sim);
  /// Frame end: every particle, material state, wall work and clamp count goes to rank 0, in
  /// rank order per object, so rank 0 checks and writes the frame as a one-rank run does.
  void collect(Simulation& sim);
  /// Frame end without the gather: only collect()'s totals (wall work, clamp count on rank 0)
  /// and counters, when no observer reads every particle on rank 0.
  void collect_counters(Simulation& sim);

  /// Why a compute stage failed on this rank ("" if none): its later compute stages are then
  /// skipped, its exchanges still run, and run_frames stops every rank after the substep.
  const std::string& failure() const override { return failure_; }
  /// Records this rank's first failure as "rank N, `why`" (a later one is dropped).
  void set_failure(const std::string& why) override;
  /// parallel::max_all.
  double max_all(double x) const override;
  /// parallel::test_failure_requested.
  bool test_failure_requested() const override;
  /// parallel::test_failure_point.
  void test_failure_point(std::size_t substeps) const override;

  /// The current slabs.
  const Slabs& slabs() const { return slabs_; }
  /// The counters so far (complete on rank 0 after collect()).
  const DomainStats& stats() const { return stats_; }

 private:
  void exchange(Simulation& sim, const std::vector<int>& dest);
  std::vector<int> owners(const Simulation& sim) const;
  Slabs slabs_;
  DomainStats stats_;
  std::vector<std::size_t> send_slots_;  // storage slots of this rank's ghost blocks
  std::vector<std::size_t> recv_slots_;  // storage slots of the previous rank's ghost blocks
  std::string failure_;
  double imbalance_sum_ = 0;
  std::uint64_t halo_local_ = 0;  // halo bytes this rank sent
};

/// The domain `sim` was split with (Simulation::set_domain), or nullptr for a one-rank run.
Domain* domain_of(const Simulation& sim);

}  // namespace mpm::parallel
