#pragma once
/// \file MaterialGroup for a plastic material: the loops over the particles, shared by every
/// plastic material (sand, snow); the material supplies what happens to one particle.

#include <cstddef>
#include <span>
#include <utility>
#include <vector>

#include "engine/core/reduce.h"
#include "materials/material.h"
#include "materials/particle_loop.h"

namespace mpm::materials {

/// A MaterialGroup whose particles each keep one plastic state value (sand's volume
/// correction, snow's Jp), for `Material` (CRTP: class Material : public
/// PlasticGroup<Material>) to supply per particle p:
///   elastic_model(p)       the value-type elastic model at p's state (kirchhoff, energy),
///   wave_speed(F, p)       the largest wave speed at deformation F (Mat3), m/s,
///   project(F, p)          the return mapping of p's F (StoredMat3&) and state.
/// Each stage is one for_each_particle (or a sum or maximum) over the group's range, templated
/// on Material so the per-particle parts are inlined.
template <class Material>
class PlasticGroup : public MaterialGroup {
 public:
  void compute_stress(std::span<const StoredMat3> F, Real volume0,
                      std::span<StoredMat3> out) const override {
    for_each_particle(F.size(), [&](std::ptrdiff_t p) {
      out[p] = to_stored(-volume0 * self().elastic_model(p).kirchhoff(to_real(F[p])));
    });
  }

  bool has_plasticity() const override { return true; }

  void apply_plasticity(std::span<StoredMat3> F) override {
    for_each_particle(F.size(), [&](std::ptrdiff_t p) { self().project(F[p], p); });
  }

  Real max_wave_speed(std::span<const StoredMat3> F) const override {
    return max_over_particles(
        F.size(), [&](std::ptrdiff_t p) { return self().wave_speed(to_real(F[p]), p); });
  }

  Real elastic_energy(std::span<const StoredMat3> F, Real volume0) const override {
    return volume0 * sum_chunks(F.size(), [&](std::size_t p) {
             return self().elastic_model(p).energy(to_real(F[p]));
           });
  }

  std::span<Real> state() override { return state_; }

 protected:
  /// A group whose particles start with the plastic state `state` (one value each).
  explicit PlasticGroup(std::vector<Real> state) : state_(std::move(state)) {}

  std::vector<Real> state_;  ///< The plastic state of each particle of the group.

 private:
  /// The material that supplies the per-particle parts.
  const Material& self() const { return static_cast<const Material&>(*this); }
  /// The material that supplies the per-particle parts.
  Material& self() { return static_cast<Material&>(*this); }
};

}  // namespace mpm::materials
