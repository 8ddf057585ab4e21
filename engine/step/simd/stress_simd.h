#pragma once
/// \file The stress of the models the engine runs in float SIMD lanes (Highway, run-time
/// dispatch), one particle per lane, for material groups whose MaterialGroup::batch_model
/// names one.

#include <cstddef>
#include <span>

#include "engine/core/math.h"
#include "materials/material.h"

namespace mpm::simd {

/// True if the engine has a lane kernel for `model` (every BatchModel kind but none and group:
/// a group's own kernel is called through MaterialGroup::lane_stress).
bool supports_stress(const BatchModel& model);

/// Writes -V0 tau of `model` for each F into `out`, as MaterialGroup::compute_stress does, in
/// float lanes (engine/step/simd/materials-inl.h); F is the group's range, so snow's Jp is
/// model.state[q]. Particles whose rotation the float quaternion cannot give to float accuracy
/// (fixed corotated and snow: the scalar path's svd_rv cases, near-singular, or inverted with
/// sigma_2 ~ |sigma_3|) are computed by the scalar double model (kirchhoff). Returns how many
/// were. Bit-identical for any thread count (each particle's lane depends on it alone).
std::size_t stress(const BatchModel& model, std::span<const StoredMat3> F, Real volume0,
                   std::span<StoredMat3> out);

/// The Kirchhoff stress tau of `model` at F in double, for a particle of plastic state `state`
/// (snow's Jp): the lanes' reference, and what they fall back to.
Mat3 kirchhoff(const BatchModel& model, const Mat3& F, Real state);

/// True if `model` has a return map in lanes (snow, sand, inviscid water).
bool supports_projection(const BatchModel& model);

/// The plasticity stage of `model`'s group in float lanes (water's F = J^(1/3) I in double
/// lanes): projects each F of the group's range and updates its plastic `state` (snow's Jp,
/// sand's volume correction; water has none), as the group's apply_plasticity does in double.
/// Particles the lanes cannot project to float accuracy (inverted, or nearly singular) take the
/// scalar double projection (project_scalar). Returns how many did. Bit-identical for any thread
/// count.
std::size_t project(const BatchModel& model, std::span<StoredMat3> F, std::span<Real> state);

/// True if `model` has its largest wave speed in lanes (snow, whose hardening takes an exp per
/// particle).
bool supports_wave_speed(const BatchModel& model);

/// The largest wave speed of `model`'s group (F: the group's range; snow's Jp model.state), as
/// MaterialGroup::max_wave_speed computes it, in double lanes: the exp of hn::Exp (within a few
/// units of the last place of std::exp), one square root of the largest square. The same for
/// any thread count.
Real max_wave_speed(const BatchModel& model, std::span<const StoredMat3> F);

/// The scalar double return map of `model` (snow, sand, water) on one particle's F and state.
void project_scalar(const BatchModel& model, StoredMat3& F, Real& state);

}  // namespace mpm::simd
