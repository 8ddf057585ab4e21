#pragma once
/// \file Checks that need the built simulation: warnings about likely mistakes, and the
/// summary `mpm validate` prints.

#include <string>
#include <vector>

#include "engine/step/simulation.h"

namespace mpm {

/// Legal but likely wrong: overlapping objects, an object starting inside a wall, a fixed dt
/// above the CFL bound, fewer than two particles per cell per axis, a huge particle count. One
/// line each.
std::vector<std::string> scene_warnings(Simulation& sim);

/// A few lines: objects and particle counts, grid, time step, stages.
std::string scene_summary(Simulation& sim);

/// Physical memory of this machine, bytes.
double physical_memory_bytes();

}  // namespace mpm
