#pragma once
/// \file The one list of per-particle fields: what moves with a particle between ranks (and
/// what a checkpoint would have to hold). Material state is per group, handled beside it.

#include "engine/core/particles.h"

namespace mpm::parallel {

/// Calls fn(field) for every per-particle array of `p` (a Particles or const Particles), in a
/// fixed order: object, id, x, v, F, and C when `apic` (APIC and MLS keep C). The stress
/// array is scratch, recomputed every substep, and not listed.
template <class P, class Fn>
void visit_particle_fields(P& p, bool apic, Fn&& fn) {
  fn(p.object);
  fn(p.id);
  fn(p.x);
  fn(p.v);
  fn(p.F);
  if (apic) fn(p.C);
}

}  // namespace mpm::parallel
