#pragma once
/// \file Contact of the particles with the walls and colliders (simulation.contact:
/// particles), solved on the grid velocities at the contact points: the same answer wherever
/// a wall lies between the node rows.
///
/// A wall's reaction enters the grid where the material touches it: at each particle within
/// reach of a wall, at the particle's projection on the wall (its contact point), as a
/// Lagrange multiplier (an impulse) that makes the grid velocity there obey the wall's
/// condition. The impulse's weights over the contact point's stencil are the boundary term
/// that the particles' own quadrature of the stress divergence calls for: the force a mirror
/// image of the body behind the wall would put on each node (ghost particles; contact.cpp,
/// ghost_weights), so that a body at rest on a wall is in balance node by node wherever the
/// wall lies between the node rows. This is the weak form's boundary term (the traction
/// integrated against the shape functions at the contact, not at the nodes nearest the
/// wall): frictional contact on the material particles, posed on the grid's velocities
/// (Li et al. 2021, "BFEMP: interpenetration-free MPM-FEM coupling with barrier contact",
/// arXiv:2108.03349, which reduces to separable frictional boundaries for MPM; M. Li,
/// "Physics-Based Simulation", lecture 28.2, "Frictional contact on material particles").
/// Here the constraint is solved directly, not through a barrier: projected Jacobi
/// iterations on accumulated normal impulses (Erleben 2007, "Velocity-based shock
/// propagation for multibody dynamics animation", ACM TOG 26(2)), each contact's step scaled
/// by its row sum of W M^-1 W^T, so that a body pressing on a wall as a whole is solved in
/// one iteration, accelerated by Chebyshev's semi-iteration (Wang 2015, "A Chebyshev
/// semi-iterative approach for accelerating projective and position-based dynamics", ACM TOG
/// 34(6), its recurrence of weights, with the projections after each extrapolation), and
/// warm-started from each particle's impulse of the last substep (ContactMemory). Friction is
/// Coulomb's bound on the impulses gathered at the nodes, with the capacity (mu times the normal
/// impulse) pooled over each wall and object (contact.cpp says why; docs/accuracy.md, "Walls
/// between the node rows", what it measures). A particle still a gap g away is held back to -g / dt
/// (speculative contacts, as in Jolt Physics), so nothing passes a wall between two substeps.
///
/// A particle's radius, where the gap is measured from, is half its spacing, except on the
/// surface of an elastic body (one whose material has no plasticity, so it keeps its rest
/// shape): there a particle within 3/4 of the spacing of the surface at rest is the ball of its
/// depth below that surface, deformed by its F (its support along the wall's normal n is
/// depth |F^T n|). The union of those balls is the body's own smooth surface, where balls of
/// half the spacing leave a bumpy one: dips of up to half the spacing between particles, over
/// which a ball rolling on its particles hops and loses energy (docs/accuracy.md).

#include <cstdint>
#include <span>
#include <vector>

#include "engine/core/particles.h"
#include "engine/scene/scene_desc.h"
#include "engine/step/colliders.h"
#include "engine/step/grid.h"
#include "engine/step/kernels.h"
#include "engine/step/walls.h"

namespace mpm {

/// The deepest a particle of an elastic body may lie below its surface at rest and still
/// have its depth as its contact radius, in half spacings (3/4 of the spacing): deeper ones,
/// and the second row of a body sampled on a lattice (1.5 spacings deep), keep half the spacing.
constexpr Real kRestDepthCap = 1.5;

/// How a run's contact solves went (mpm bench reports it), summed over the substeps whose solve
/// had contacts.
struct ContactSolveStats {
  long solves = 0;      ///< Solves with contacts.
  long iterations = 0;  ///< Their iterations, summed.
  /// Their residuals, summed: the largest violation of a touching contact's normal condition
  /// at the start of the last iteration (velocity into the wall, or off it where the contact
  /// pushes or is held), m/s.
  Real residual = 0;
};

/// What the contact solve keeps between substeps: each particle's normal impulse on each wall
/// it touched, which the next substep's solve starts from (warm starting, as Box2D and Jolt
/// Physics do; Catto 2005, "Iterative dynamics with temporal coherence", GDC). A body resting
/// on a wall then starts each solve at its last answer, and the few iterations refine it
/// instead of finding the whole weight again (docs/accuracy.md: without it, the pool at rest
/// drifts by the part left unsolved in every substep).
struct ContactMemory {
  std::vector<std::uint32_t> ids;      ///< Particle id of each kept impulse, by patch then id.
  std::vector<std::uint32_t> patches;  ///< Its patch (wall and object).
  std::vector<Real> impulses;          ///< Its normal impulse there, N s.
  Real dt = 0;                         ///< The substep those impulses were found in, s.
  ContactSolveStats stats;             ///< The solves so far (not written to checkpoints).

  /// Replaces the entries by the positive `impulses` of the contacts of particles `id` on
  /// `patches` (one per particle and patch: a particle in a corner, or on two walls that
  /// coincide, keeps one for each wall), put in order of patch and id.
  void keep(const std::vector<std::uint32_t>& id, const std::vector<std::uint32_t>& patches,
            const std::vector<Real>& impulses, Real dt);
};

/// Settings of the contact solve (the scene's defaults: simulation.contact_iterations and
/// contact_spectral_radius).
struct ContactSettings {
  /// Most projected Jacobi iterations per substep.
  int iterations = SimulationDesc{}.contact_iterations;
  Real tolerance = 1e-3;  ///< Stop when the largest node velocity change falls by this factor.
  /// The spectral radius that Chebyshev's acceleration assumes of the Jacobi steps (0: none).
  /// Twelve accelerated iterations leave a smaller violation than 24 plain ones
  /// (docs/accuracy.md, "The contact solve, accelerated").
  Real spectral_radius = SimulationDesc{}.contact_spectral_radius;
};

/// The contact solve's per-substep state (kept between substeps so its buffers are reused).
/// Contacts are indexed in the order they were found; the nodes their stencils touch get
/// compact indices in first-touch order.
struct ContactState {
  std::vector<std::uint32_t> particle;  ///< Particle of each contact.
  std::vector<std::uint32_t> id;        ///< Its particle's id.
  std::vector<Vec3> point;              ///< Contact point: the particle projected on the wall.
  std::vector<Vec3> normal;             ///< Wall normal at the particle (into the free side).
  std::vector<Vec3> wall_velocity;      ///< Wall velocity at the particle, m/s.
  std::vector<Real> gap;                ///< Distance to the wall less the particle's radius, m.
  std::vector<Boundary> boundary;       ///< The wall's condition.
  std::vector<Real> friction;           ///< The wall's Coulomb coefficient.
  std::vector<std::uint32_t> patch;     ///< Wall index times objects plus object index.
  std::vector<Real> count;  ///< Particles each contact stands for (set by solve_contact).
  std::size_t patches = 0;              ///< Walls times objects.
  std::vector<Real> normal_impulse;     ///< Accumulated normal impulse on the grid, N s.
  std::vector<Real> inv_k;              ///< 1 / (row sum of W M^-1 W^T), kg.
  int stencil = 0;                      ///< Nodes per contact (kernel nodes per axis cubed).
  std::vector<std::uint32_t> nodes;     ///< Compact node index, `stencil` per contact.
  std::vector<Real> weights;            ///< Stencil weights, `stencil` per contact.
  std::vector<Vec3> node_velocity;      ///< Velocity of each compact node, m/s.
  std::vector<Real> node_inv_mass;      ///< 1 / mass of each compact node (0 if massless).
  std::vector<std::uint64_t> node_key;  ///< Grid-wide index (i nodes.y + j) nodes.z + k.
  std::vector<std::size_t> storage;     ///< Grid storage index of each compact node (node 0:
                                        ///< none, for stencil nodes without mass).
  std::vector<std::int32_t> compact;    ///< Scratch per grid storage slot, -1 between uses.
  /// Scratch kept between substeps, so that a solve of many contacts takes no fresh pages (a
  /// buffer over glibc's mmap threshold, 32 MiB, would be mapped, faulted in and zeroed anew
  /// every substep): each candidate's stencil nodes as grid storage indices (gather_stencils),
  /// and the merged stencils' weights and nodes (merge_shared_stencils, copied back into
  /// weights and nodes).
  std::vector<std::size_t> stencil_storage;
  std::vector<Real> spare_weights;         ///< Scratch, see stencil_storage.
  std::vector<std::uint32_t> spare_nodes;  ///< Scratch, see stencil_storage.
  /// The weights the stress scatter uses, which the ghost weights follow.
  enum class ForceWeights {
    gradient,  ///< The kernel's gradient (PIC, FLIP, APIC).
    mls,       ///< MLS's D^-1 w (x_i - x_p) (transfer mls).
    domain,    ///< The gradient averaged over the particle's domain (quadrature domain).
  } force_weights = ForceWeights::gradient;
  std::vector<Real> rest_depth;  ///< By particle id: the depth below its elastic body's surface
                                 ///< at rest, m, or -1 (half the spacing); empty: all -1.
                                 ///< Set once at creation; clear() keeps it.
  std::size_t size() const { return particle.size(); }  ///< Number of contacts.
  /// Drops every contact and node (the scratch buffers stay).
  void clear();
};

/// Particles [first, last).
struct IndexRange {
  std::size_t first = 0;  ///< The first particle.
  std::size_t last = 0;   ///< One past the last.
};

/// Finds the particles within reach of each plane wall and collider at time `time` (a
/// particle's reach is its radius, half its spacing, plus one cell: no particle moves a cell
/// in a substep), with the wall's normal, velocity at time + dt and condition, and their
/// stencils' nodes and weights; `state` then holds the contacts and their nodes' velocities.
/// Only the particles of `search` are looked at (all if it is null): the caller vouches that
/// no other is within reach (contact_chunks). `speeds`, if given, are the grid's block speeds
/// as grid_update left them, and the caller vouches that no velocity has changed since; else
/// they are made from the grid.
void find_contacts(const std::vector<WallPlane>& planes, const std::vector<Collider>& colliders,
                   Kernel kernel, Real time, Real dt, const Particles& particles, const Grid& grid,
                   ContactState& state, const std::vector<IndexRange>* search = nullptr,
                   const BlockSpeeds* speeds = nullptr);

/// Solves the walls' conditions at the contacts on `state`'s node velocities (sorted by wall
/// and particle id first, and those sharing a stencil and wall merged): sticky, the
/// velocity relative to the wall is zero; slip and separate, the normal part may only point
/// away, with Coulomb friction. Starts from the normal impulses in `memory` and keeps the new
/// ones there. Returns the work (J) the moving walls did on the grid: the impulses times the
/// walls' velocities.
Real solve_contact(const ContactSettings& settings, Real dt, ContactState& state,
                   ContactMemory& memory);

/// Writes `state`'s node velocities back to the grid nodes they came from.
void write_contact_velocities(const ContactState& state, Grid& grid);

/// find_contacts, solve_contact and write_contact_velocities on one rank. Returns the work of
/// the moving walls.
Real apply_contact(const std::vector<WallPlane>& planes, const std::vector<Collider>& colliders,
                   const ContactSettings& settings, Kernel kernel, Real time, Real dt,
                   const Particles& particles, Grid& grid, ContactState& state,
                   ContactMemory& memory, const std::vector<IndexRange>* search = nullptr,
                   const BlockSpeeds* speeds = nullptr);

/// For each run of `chunk` consecutive particles (the last one shorter), whether the contact
/// at time `time` or the domain boundary (its `layers`) may involve it: 1 where find_contacts
/// may find one of its particles, or where a node of one of its particles' stencils may lie in
/// a contact's stencil or in the layers; 0 where none can, so its particles gather the same
/// velocities before the contact solve as after it. Bounds: a contact's point lies on its wall
/// (or within two reaches of a collider's bounds, with a cell to spare), a particle's reach is
/// at most the widest radius plus a cell, and two stencils of kernel width N cells share a
/// node only within N cells per axis (widened by a part in 10^6 against rounding).
std::vector<char> contact_chunks(const std::vector<WallPlane>& planes,
                                 const std::vector<Collider>& colliders, const BufferLayers& layers,
                                 Kernel kernel, Real time, const Particles& particles,
                                 const Grid& grid, std::size_t chunk);

/// The particle ranges of the chunks `near` marks (contact_chunks), consecutive ones joined.
std::vector<IndexRange> marked_ranges(const std::vector<char>& near, std::size_t chunk,
                                      std::size_t particles);

}  // namespace mpm
