#pragma once
/// \file The gather of the particles that no contact can reach, run beside the contact stage.
///
/// With contact at the particles, the contact stage is a chain of small steps over a few
/// thousand contacts (the search near the walls, the stencils, a dozen Jacobi iterations) that
/// two threads share poorly, and the gather after it is one large loop over every particle.
/// Most particles lie where neither the contact nor the domain boundary changes a node of their
/// stencils (contact_chunks): they gather the same velocities before the contact solve as after
/// it. So the contact runs on one thread while the others gather those particles, and the rest
/// are gathered after the domain boundary. Each particle gets the values the plain order gives
/// it (gather_range makes the same lane sets), so the frames are the same.

#include <functional>
#include <vector>

#include "engine/core/particles.h"
#include "engine/scene/scene_desc.h"
#include "engine/step/colliders.h"
#include "engine/step/contact.h"
#include "engine/step/grid.h"
#include "engine/step/transfer.h"
#include "engine/step/walls.h"

namespace mpm {

/// The fewest contacts the last substep's solve must have had for the next contact stage to be
/// split: below it the stage is too short to hide much of the gather, and the split's own cost
/// (the chunks' boxes, the float velocities filled twice, the solve on one thread) is not
/// repaid (snowball_paper's ~40 contacts a substep against two_cubes' ~1,000).
inline constexpr std::size_t kSplitMinContacts = 256;

/// The gather split around the contact stage (the SIMD path, on one process).
struct SplitGather {
  std::vector<char> near;  ///< Per chunk of simd::kGatherAlign particles: 1 if left for after.
  AdvectStats advect;      ///< What the advection of the chunks gathered so far saw.
  bool pending = false;    ///< gather_beside ran; gather_rest has the near chunks to gather.
  std::size_t runs = 0;    ///< Substeps gather_beside split so far.
  /// Split only after a substep whose solve had at least this many contacts (tests lower it).
  std::size_t min_contacts = kSplitMinContacts;
};

/// The contact stage as gather_beside runs it: given the particle ranges its search may look
/// at (the near chunks; null: all), it finds and solves the contacts and writes the node
/// velocities.
using ContactPass = std::function<void(const std::vector<IndexRange>* search)>;

/// Marks the chunks (contact_chunks at time `time`, with the domain boundary's `layers`), fills
/// the float node velocities (simd::prepare_gather), then runs `contact` on this thread while
/// the team's other threads gather and advect the far chunks; this thread joins them when
/// `contact` returns. An exception from `contact` is thrown again after the team is done.
/// Returns false, having run nothing, on one thread or where fewer than half the chunks are
/// far (most particles near a wall: the contact then gains more from the team's threads than
/// the far gather does beside it); the caller then runs the plain contact and gather.
bool gather_beside(const ContactPass& contact, const std::vector<WallPlane>& planes,
                   const std::vector<Collider>& colliders, const BufferLayers& layers,
                   Transfer transfer, Kernel kernel, Real time, Real dt, const Grid& grid,
                   Particles& particles, SplitGather& split);

/// Gathers and advects the chunks gather_beside left (in parallel, once the contact and the
/// domain boundary have set their nodes) and writes the whole advection's counts to `advect`.
void gather_rest(const Grid& grid, Transfer transfer, Kernel kernel, Real dt, Particles& particles,
                 SplitGather& split, AdvectStats* advect);

}  // namespace mpm
