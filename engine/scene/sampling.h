#pragma once
/// \file Filling a closed mesh with particles.

#include <cstdint>
#include <vector>

#include "engine/scene/mesh.h"
#include "engine/scene/scene_desc.h"

namespace mpm {

/// Samples `per_cell` points in every grid cell that overlaps the mesh and keeps those inside.
///
/// If per_cell is a cube n^3 the points are stratified: one per sub-cell, jittered inside it,
/// or at its centre when `regular` (a lattice); otherwise uniformly random in the cell. Random numbers come from a counter-based hash of
/// (seed, stream, cell, sample), so the result depends only on those, not on thread count.
/// Points come out in cell order (x slowest).
std::vector<Vec3> sample_inside(const TriangleMesh& mesh, const GridDesc& grid, int per_cell, bool regular,
                                std::uint64_t seed, std::uint64_t stream);

/// A uniform double in [0, 1) from a 64-bit key (splitmix64 finaliser).
double hash_uniform(std::uint64_t key);

}  // namespace mpm
