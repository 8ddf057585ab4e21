#pragma once
/// \file MaterialGroup for any hyperelastic value-type model: one tight loop per stage.

#include <algorithm>
#include <concepts>
#include <cstddef>

#include "engine/core/reduce.h"
#include "materials/material.h"
#include "materials/particle_loop.h"

namespace mpm::materials {

/// -V0 tau of every particle of a value-type model (kirchhoff), into `out`.
template <class Model>
void model_stress(const Model& model, std::span<const StoredMat3> F, Real volume0,
                  std::span<StoredMat3> out) {
  for_each_particle(F.size(), [&](std::ptrdiff_t p) {
    out[p] = to_stored(-volume0 * model.kirchhoff(to_real(F[p])));
  });
}

/// The largest wave speed of a value-type model (wave_speed) over the particles, m/s.
template <class Model>
Real model_max_wave_speed(const Model& model, std::span<const StoredMat3> F, Real rho0) {
  return max_over_particles(
      F.size(), [&](std::ptrdiff_t p) { return model.wave_speed(to_real(F[p]), rho0); });
}

/// The elastic energy of a value-type model (energy) over the particles, J; the same for any
/// thread count (sum_chunks).
template <class Model>
Real model_elastic_energy(const Model& model, std::span<const StoredMat3> F, Real volume0) {
  return volume0 * sum_chunks(F.size(), [&](std::size_t p) { return model.energy(to_real(F[p])); });
}

/// Wraps a value-type model (energy, kirchhoff, wave_speed) as a MaterialGroup.
/// The loops are templated on Model, so the compiler inlines the model per particle.
template <class Model>
class ElasticGroup final : public MaterialGroup {
 public:
  /// A group of particles sharing `model`, with reference density `rho0`.
  ElasticGroup(const Model& model, Real rho0) : model_(model), rho0_(rho0) {}

  void compute_stress(std::span<const StoredMat3> F, Real volume0,
                      std::span<StoredMat3> out) const override {
    model_stress(model_, F, volume0, out);
  }

  Real max_wave_speed(std::span<const StoredMat3> F) const override {
    return model_max_wave_speed(model_, F, rho0_);
  }

  Real elastic_energy(std::span<const StoredMat3> F, Real volume0) const override {
    return model_elastic_energy(model_, F, volume0);
  }

  bool has_lane_stress() const override { return true; }

  /// The model's own lane kernel, `lane_kirchhoff(batch, volume0)`, if it has one (a model
  /// written for float lanes, as the stvk plugin's); else each lane in double through
  /// kirchhoff (the scalar default: inlined, no virtual call per particle).
  void lane_stress(StressLanes& batch, Real volume0) const override {
    if constexpr (requires(const Model& m) { m.lane_kirchhoff(batch, volume0); }) {
      model_.lane_kirchhoff(batch, volume0);
    } else {
      for (std::size_t l = 0; l < batch.count; ++l) {
        Mat3 F;
        for (int e = 0; e < 9; ++e) F.data()[e] = batch.F[e][l];
        const Mat3 tau = -volume0 * model_.kirchhoff(F);
        for (int e = 0; e < 9; ++e) batch.tau[e][l] = static_cast<float>(tau.data()[e]);
      }
    }
  }

  BatchModel batch_model() const override {
    if constexpr (requires(const Model& m) {
                    { m.batch() } -> std::same_as<BatchModel>;
                  })
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
