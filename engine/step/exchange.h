#pragma once
/// \file What a substep needs from a run split over MPI ranks. engine/parallel/domain.h
/// implements it; a one-rank run has none (a null pointer), and its stage list holds no
/// exchange stage. The interface keeps the step layer below the parallel one.

#include <cstddef>
#include <string>

#include "engine/core/math.h"

namespace mpm {

class Simulation;
struct Grid;
struct AdvectStats;
struct ContactSettings;
struct ContactMemory;
struct ContactState;

/// The exchanges and reductions of a substep over ranks. Every call is collective: all ranks
/// make it in the same order (parallel::Domain documents each).
class RankExchange {
 public:
  virtual ~RankExchange() = default;
  /// Stage halo_blocks: activate the ghost blocks the next rank's particles reach.
  virtual void share_ghost_blocks(Grid& grid) = 0;
  /// Stage halo_sum: ghost nodes' sums go to their owner.
  virtual void add_ghost_sums(Grid& grid) = 0;
  /// Stage halo_velocity: owners send node mass and velocity back to the ghosts.
  virtual void return_ghost_velocities(Grid& grid) = 0;
  /// Stage contact_solve: every rank's contacts solved as one set, from and into `memory`
  /// (rank 0's); returns the walls' work.
  virtual Real solve_contact(const ContactSettings& settings, Real dt, ContactState& local,
                             Grid& grid, ContactMemory& memory) = 0;
  /// Stage migrate: particles that left the slab go to its owner.
  virtual void migrate(Simulation& sim) = 0;
  /// The advection statistics over all ranks.
  virtual AdvectStats combine(const AdvectStats& local) const = 0;
  /// The largest of `x` over all ranks.
  virtual double max_all(double x) const = 0;
  /// Why a compute stage failed on this rank ("" if none).
  virtual const std::string& failure() const = 0;
  /// Records this rank's first failure, prefixed with the rank.
  virtual void set_failure(const std::string& why) = 0;
  /// True when the environment asks for a test failure (tests/parallel).
  virtual bool test_failure_requested() const = 0;
  /// Throws on the rank and substep the environment names (tests/parallel).
  virtual void test_failure_point(std::size_t substeps) const = 0;
};

}  // namespace mpm
