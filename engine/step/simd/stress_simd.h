#pragma once
/// \file The stress of the models the engine runs in float SIMD lanes (Highway, run-time
/// dispatch), one particle per lane, for material groups whose MaterialGroup::batch_model
/// names one.

#include <cstddef>
#include <span>

#include "engine/core/math.h"
#include "materials/material.h"

namespace mpm::simd {

/// True if this machine's SIMD path has a stress kernel for `model` (today: fixed corotated).
bool supports_stress(const BatchModel& model);

/// Writes -V0 tau of `model` for each F into `out`, as MaterialGroup::compute_stress does, in
/// float lanes (engine/step/simd/corotated-inl.h). Particles whose rotation the float
/// quaternion cannot give to float accuracy (the scalar path's svd_rv cases: near-singular, or
/// inverted with sigma_2 ~ |sigma_3|) are computed by the scalar double model. Returns how many
/// were. Bit-identical for any thread count (each particle's lane depends on it alone).
std::size_t stress(const BatchModel& model, std::span<const StoredMat3> F, Real volume0,
                   std::span<StoredMat3> out);

}  // namespace mpm::simd
