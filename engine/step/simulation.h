#pragma once
/// \file A simulation built from a scene: particles, grid, materials and the list of stages.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "engine/core/particles.h"
#include "engine/scene/scene_desc.h"
#include "engine/step/colliders.h"
#include "engine/step/contact.h"
#include "engine/step/domain_quadrature.h"
#include "engine/step/exchange.h"
#include "engine/step/grid.h"
#include "engine/step/split_gather.h"
#include "engine/step/transfer.h"
#include "engine/step/walls.h"
#include "materials/registry.h"

namespace mpm {

/// One object after sampling: a contiguous range of particles.
struct ObjectInfo {
  std::string name;       ///< From the scene.
  std::string material;   ///< Material name.
  std::size_t first = 0;  ///< First particle index.
  std::size_t count = 0;  ///< Number of particles.
  Real mass = 0;          ///< Total mass, kg.
  Real density = 0;       ///< Reference density, kg/m^3.
};

/// A contiguous particle range and the material that acts on it.
struct MaterialRange {
  std::size_t first = 0;                    ///< First particle index.
  std::size_t count = 0;                    ///< Number of particles.
  std::unique_ptr<MaterialGroup> material;  ///< Built by the registry.
};

/// A named step of the substep, with the time it has taken so far.
struct Stage {
  std::string name;               ///< Name in reports, e.g. "particles_to_grid".
  std::function<void(Real)> run;  ///< Runs the stage for a substep of dt.
  double seconds = 0;             ///< Accumulated wall time.
};

/// Everything one run needs, built once from a validated scene.
///
/// The substep is the list of stages(): only the stages the scene calls for are in it.
class Simulation {
 public:
  /// Samples every object's mesh and builds particles, grid, materials and stages.
  /// Throws SceneError for a mesh that cannot be used or an object outside the grid.
  static std::unique_ptr<Simulation> create(const SceneDesc& scene,
                                            const MaterialRegistry& registry);

  /// Largest substep allowed now: the CFL bound (if cfl is set) capped by the fixed dt.
  Real stable_dt() const;
  /// stable_dt(), timed: with cfl its seconds are the "cfl_bound" entry of stage_seconds().
  /// The run calls it before every adaptive substep.
  Real timed_stable_dt();
  /// cfl h / (c + |v|max): the CFL bound for CFL number `cfl`, with c the largest wave speed
  /// any material reports at the current F, s.
  Real cfl_bound(Real cfl) const;
  /// Advances by one substep of `dt` seconds, running every stage in order.
  void substep(Real dt);

  /// Particle state. Non-const access counts as a change of state (range_elastic_energies()).
  Particles& particles() {
    ++state_;
    return particles_;
  }
  /// Particle state.
  const Particles& particles() const { return particles_; }
  /// Grid state.
  const Grid& grid() const { return grid_; }
  /// The objects, in scene order.
  const std::vector<ObjectInfo>& objects() const { return objects_; }
  /// The material of each particle range.
  const std::vector<MaterialRange>& materials() const { return materials_; }
  /// The material of each particle range (for restoring checkpointed state).
  std::vector<MaterialRange>& materials() {
    ++state_;
    return materials_;
  }
  /// The stages of a substep, in order.
  const std::vector<Stage>& stages() const { return stages_; }
  /// Seconds spent so far in each stage, in order, after "cfl_bound" (the wave-speed bound of
  /// the adaptive dt, timed_stable_dt()) when the scene sets cfl, and "huge_pages" (the heap
  /// advised once, after the first substep): every timed part of a substep.
  std::vector<std::pair<std::string, double>> stage_seconds() const;
  /// The scene this simulation was built from.
  const SceneDesc& scene() const { return scene_; }

  /// Simulated time, s.
  Real time() const { return time_; }
  /// Sets the simulated time (the driver snaps it to frame times).
  void set_time(Real t) { time_ = t; }
  /// Substeps taken so far.
  std::size_t substeps() const { return substeps_; }
  /// Sets the substep count (when restoring a checkpoint).
  void set_substeps(std::size_t n) { substeps_ = n; }
  /// The contact impulses kept between substeps (checkpointed, so a resumed run continues
  /// bit for bit).
  ContactMemory& contact_memory() { return contact_memory_; }
  /// The contact impulses kept between substeps.
  const ContactMemory& contact_memory() const { return contact_memory_; }
  /// What advection saw in the last substep (non-finite positions, clamps, top speed).
  const AdvectStats& last_advect() const { return last_advect_; }
  /// The far particles' gather beside the contact stage (split_gather.h): how often it ran.
  const SplitGather& split_gather() const { return split_gather_; }
  /// The same, to change when it splits (tests).
  SplitGather& split_gather() { return split_gather_; }
  /// Total energy, J: kinetic + elastic + gravitational (relative to the grid origin).
  Real total_energy() const;
  /// Index of the first particle with a non-finite position, velocity or F, or size().
  std::size_t first_nonfinite_particle() const;
  /// Index of the fastest particle.
  std::size_t fastest_particle() const;
  /// The object particle `q` belongs to.
  const ObjectInfo& object_of(std::size_t q) const { return objects_[particles_.object[q]]; }
  /// The solid colliders (mesh, sphere and vdb walls), in scene order.
  const std::vector<Collider>& colliders() const { return colliders_; }
  /// Work done on the bodies by moving walls and colliders since the start, J.
  Real wall_work() const { return wall_work_; }
  /// Particles clamped back into the grid interior, over the whole run.
  std::size_t clamped_particles() const { return clamped_total_; }
  /// Largest particle speed, m/s.
  Real max_speed() const;
  /// Total kinetic energy, J.
  Real kinetic_energy() const;

  /// The split over MPI ranks (engine/parallel/domain.h), or nullptr for a one-rank run.
  RankExchange* domain() const { return domain_.get(); }
  /// Splits the run with `domain` (nullptr: one rank) and rebuilds the stage list, which then
  /// holds the exchange stages (halo_blocks, halo_sum, halo_velocity, migrate).
  void set_domain(std::shared_ptr<RankExchange> domain);
  /// Replaces the particles with `p`, whose objects lie contiguous in scene order with
  /// `counts[o]` particles each, and object o's material state with `states[o]`
  /// (state_stride(o) values per particle); each material group is rebuilt for its new count.
  void replace_particles(Particles&& p, const std::vector<std::size_t>& counts,
                         std::vector<std::vector<Real>>&& states);
  /// Material state values per particle of object `o` (0 if its material keeps none).
  std::size_t state_stride(std::size_t o) const { return state_stride_[o]; }
  /// Sets the run totals kept across substeps (when ranks combine theirs).
  void set_totals(Real wall_work, std::size_t clamped) {
    wall_work_ = wall_work;
    clamped_total_ = clamped;
  }
  /// Total elastic energy stored in all materials, J.
  Real elastic_energy() const;
  /// Elastic energy of each material range, in materials() order, J. Computed once per state
  /// (a substep or a non-const access changes it), so the energy check and the summaries of a
  /// frame share one pass over the particles.
  const std::vector<Real>& range_elastic_energies() const;

 private:
  explicit Simulation(const SceneDesc& scene);
  /// Builds the substep's stage list from the scene (docs/architecture.md, "The substep").
  void build_stages();
  /// Appends compute stage `name`; with more than one rank its exception is kept in the
  /// domain and later compute stages are skipped.
  void add_stage(std::string name, std::function<void(Real)> fn);
  /// Appends exchange stage `name` (with more than one rank: runs even after a failure).
  void add_exchange(std::string name, std::function<void(Real)> fn);
  /// Chooses each group's stress path, appends the compute_stress stage when any group stores
  /// its stress, and returns true if the SIMD scatter computes some group's stress.
  bool add_stress_stage();
  /// Each group's model in SIMD lanes now (kind none: it has none), with its first particle
  /// and state; empty without simulation.simd.
  std::vector<BatchModel> lane_models() const;
  /// Appends the stages of walls, colliders and the domain boundary (simulation.contact).
  void add_boundary_stages();
  /// Appends the pressure fits and the scatter with the particles' domains.
  void add_domain_scatter_stages();
  /// Appends the gather with the particles' domains (MLS: its volume change smoothed), then
  /// advection.
  void add_domain_gather_stages();

  SceneDesc scene_;
  Particles particles_;
  Grid grid_;
  ParticleOrder order_;
  std::vector<ObjectInfo> objects_;
  std::vector<MaterialRange> materials_;
  std::vector<WallPlane> walls_;
  std::vector<Collider> colliders_;
  ContactState contact_;  // the contact solve's buffers, reused between substeps
  ContactMemory contact_memory_;  // the contact impulses, kept between substeps (rank 0's)
  SplitGather split_gather_;      // the far particles' gather, run beside the contact stage
  // The block speeds the grid update leaves for the contact search, where no stage between
  // them changes a velocity (else null, and the search makes its own).
  BlockSpeeds block_speeds_;
  BlockSpeeds* speeds_for_contact_ = nullptr;
  std::vector<Stage> stages_;
  double bound_seconds_ = 0;
  double huge_pages_seconds_ = -1;  // advise_heap_huge_pages' time; negative before it runs
  Real time_ = 0;
  std::size_t substeps_ = 0;
  AdvectStats last_advect_;
  // simulation.quadrature: domain only (empty otherwise): the per-node fits, each particle's
  // pressure and its gradient, det F before the F update, and the fits' scratch.
  NodeFits fits_;
  std::vector<Real> pressure_, j_old_, fit_scratch_;
  std::vector<Vec3> pressure_gradient_;
  std::size_t clamped_total_ = 0;
  Real wall_work_ = 0;
  std::size_t state_ = 0;                        // bumped by every change of state
  mutable std::size_t energy_state_ = SIZE_MAX;  // the state range_energy_ was computed for
  mutable std::vector<Real> range_energy_;       // cache of range_elastic_energies()
  std::shared_ptr<RankExchange> domain_;
  /// Builds object o's material group for a count of particles (replace_particles).
  std::vector<std::function<std::unique_ptr<MaterialGroup>(std::size_t)>> group_factories_;
  std::vector<std::size_t> state_stride_;
  bool stores_stress_ = false;
};

}  // namespace mpm
