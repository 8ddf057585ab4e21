#pragma once
/// \file An object's state at rest under its own weight (objects[i].initial_stress: gravity),
/// so that a pool or a layer starts in balance instead of falling into it.

#include <span>

#include "engine/core/math.h"
#include "materials/material.h"

namespace mpm {

/// Puts the particles `x`, `F` of one object (its material `group`, reference density
/// `density`, particle spacing `spacing`) in the state of a layer with a flat top at rest
/// under `gravity`, confined sideways: at depth d below the top, the stress along gravity is
/// the weight of the material above, sigma_gg = -rho g d, and F = I - (1 - lambda) u u^T
/// (uniaxial strain along the up direction u, the geostatic state of soil mechanics). lambda
/// is found per particle by bisection on the group's own stress, so every material, plugins
/// included, takes part. The particles stay where they were sampled, which is the reference
/// configuration the weight is measured in; the body then settles by its own compression
/// (rho g H / K of its height, 0.5 % for hydrostatic_water), with no more than that out of
/// balance. Throws std::runtime_error when gravity is zero or the material cannot hold the
/// weight of the layer (it would need lambda below kLowestStretch).
void settle_under_gravity(const Vec3& gravity, Real density, Real spacing,
                          const MaterialGroup& group, std::span<const Vec3> x,
                          std::span<StoredMat3> F);

/// The most compression settle_under_gravity accepts: lambda (= J) at least this.
constexpr Real kLowestStretch = 0.5;

}  // namespace mpm
