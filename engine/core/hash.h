#pragma once
/// \file The one 64-bit hash of the engine and its materials: seeded particle sampling
/// (engine/scene/sampling.cpp) and snow's hardness field (materials/snow.h). Installed for
/// plugins with math.h.

#include <cstdint>

namespace mpm {

/// The splitmix64 finaliser of z + increment (Steele, Lea, Flood 2014): a well-mixed 64-bit
/// hash of z.
constexpr std::uint64_t splitmix64(std::uint64_t z,
                                   std::uint64_t increment = 0x9e3779b97f4a7c15ull) {
  z += increment;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

/// A uniform number in [0, 1) from the top 53 bits of the 64-bit hash `bits`.
constexpr double unit_from_bits(std::uint64_t bits) {
  return static_cast<double>(bits >> 11) * 0x1.0p-53;
}

}  // namespace mpm
