#pragma once
/// \file Particle state, stored as a structure of arrays with named fields.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "engine/core/math.h"

namespace mpm {

/// All particles of a simulation. Particles of one object are contiguous and share one mass
/// and one reference volume, kept per object.
struct Particles {
  std::vector<Vec3> x;                 ///< Position, m.
  std::vector<Vec3> v;                 ///< Velocity, m/s.
  std::vector<StoredMat3> F;           ///< Deformation gradient (elastic part for plastic materials).
  std::vector<StoredMat3> C;           ///< APIC affine velocity, 1/s (empty unless transfer is apic).
  std::vector<std::uint32_t> object;   ///< Index of the object the particle belongs to.
  std::vector<std::uint32_t> id;       ///< Stable id: the particle's index when sampled. The
                                       ///< reorder stage moves particles in memory; frames are
                                       ///< written in id order and carry it.
  std::vector<StoredMat3> stress;      ///< Scratch: -V0 tau, written by compute_stress.
  std::vector<Real> object_mass;       ///< Mass of one particle, per object, kg.
  std::vector<Real> object_volume0;    ///< Reference volume V0 of one particle, per object, m^3.

  /// Number of particles.
  std::size_t size() const { return x.size(); }
  /// Mass of particle q, kg.
  Real mass(std::size_t q) const { return object_mass[object[q]]; }
  /// Reference volume of particle q, m^3.
  Real volume0(std::size_t q) const { return object_volume0[object[q]]; }
};

}  // namespace mpm
