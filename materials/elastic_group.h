#pragma once
/// \file MaterialGroup for any hyperelastic value-type model: one tight loop per stage.

#include <algorithm>
#include <concepts>
#include <cstddef>

#include "engine/core/reduce.h"
#include "materials/material.h"

namespace mpm::materials {

/// Wraps a value-type model (energy, kirchhoff, wave_speed) as a MaterialGroup.
/// The loops are templated on Model, so the compiler inlines the model per particle.
template <class Model>
class ElasticGroup final : public MaterialGroup {
 public:
  /// A group of particles sharing `model`, with reference density `rho0`.
  ElasticGroup(const Model& model, Real rho0) : model_(model), rho0_(rho0) {}

  void compute_stress(std::span<const StoredMat3> F, Real volume0,
                      std::span<StoredMat3> out) const override {
    const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(F.size());
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
    for (std::ptrdiff_t p = 0; p < n; ++p)
      out[p] = to_stored(-volume0 * model_.kirchhoff(to_real(F[p])));
  }

  Real max_wave_speed(std::span<const StoredMat3> F) const override {
    Real c = 0;
    const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(F.size());
#pragma omp parallel for schedule(static) reduction(max : c) if (n >= kParallelMinItems)
    for (std::ptrdiff_t p = 0; p < n; ++p) c = std::max(c, model_.wave_speed(to_real(F[p]), rho0_));
    return c;
  }

  Real elastic_energy(std::span<const StoredMat3> F, Real volume0) const override {
    return volume0 * sum_chunks(F.size(), [&](std::size_t p) { return model_.energy(to_real(F[p])); });
  }

  BatchModel batch_model() const override {
    if constexpr (requires(const Model& m) { { m.batch() } -> std::same_as<BatchModel>; })
      return model_.batch();
    else
      return {};
  }

  /// The wrapped model.
  const Model& model() const { return model_; }

 private:
  Model model_;
  Real rho0_;
};

}  // namespace mpm::materials
