#pragma once
/// \file Particle state, stored as a structure of arrays with named fields.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "engine/math.h"

namespace mpm {

/// All particles of a simulation. Particles of one object are contiguous.
struct Particles {
  std::vector<Vec3> x;                 ///< Position, m.
  std::vector<Vec3> v;                 ///< Velocity, m/s.
  std::vector<Mat3> F;                 ///< Deformation gradient (elastic part for plastic materials).
  std::vector<Mat3> C;                 ///< APIC affine velocity, 1/s (empty unless transfer is apic).
  std::vector<Real> mass;              ///< Mass, kg.
  std::vector<Real> volume0;           ///< Reference volume V0, m^3.
  std::vector<std::uint32_t> object;   ///< Index of the object the particle belongs to.
  std::vector<Mat3> stress;            ///< Scratch: -V0 tau, written by compute_stress.

  /// Number of particles.
  std::size_t size() const { return x.size(); }
};

}  // namespace mpm
