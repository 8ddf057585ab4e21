#pragma once
/// \file What every frame writer takes: one frame's particles as views, nothing copied.

#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>

#include "engine/core/math.h"

namespace mpm {

/// One frame's particles as views into arrays the caller owns; every span has the same length.
struct FrameView {
  std::span<const Vec3> position;            ///< Position, m.
  std::span<const Vec3> velocity;            ///< Velocity, m/s.
  std::span<const std::uint32_t> object_id;  ///< Index of the object each particle belongs to.
  std::span<const Real> J;                   ///< Volume ratio det F.
  double time = 0;                           ///< Simulation time, s.
  int frame = 0;                             ///< Frame number; 0 is the initial state.
  std::span<const std::uint32_t> particle_id;  ///< Stable particle id (Particles::id).

  /// Number of particles.
  std::size_t size() const { return position.size(); }
};

/// Throws std::invalid_argument unless all five spans of `view` have the same length.
inline void check_frame_view(const FrameView& view) {
  const std::size_t n = view.position.size();
  if (view.velocity.size() != n || view.object_id.size() != n || view.J.size() != n ||
      view.particle_id.size() != n)
    throw std::invalid_argument(
        "frame view has spans of unequal length: position " + std::to_string(n) + ", velocity " +
        std::to_string(view.velocity.size()) + ", object_id " +
        std::to_string(view.object_id.size()) + ", J " + std::to_string(view.J.size()) +
        ", particle_id " + std::to_string(view.particle_id.size()));
}

}  // namespace mpm
