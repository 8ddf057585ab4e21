#pragma once
/// \file The interface every constitutive model implements, and the parameter table it declares.

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include "engine/core/math.h"

namespace mpm {

/// One scalar parameter a material reads from an object's scene keys.
struct ParamSpec {
  std::string name;         ///< Scene key, e.g. "E".
  std::string unit;         ///< Unit for docs and `mpm materials`, e.g. "Pa"; empty if dimensionless.
  std::string description;  ///< One-line meaning.
  bool required = false;    ///< True if the scene must give it; otherwise default_value is used.
  double default_value = 0; ///< Value used when the key is absent (or a typical value if required).
  double min = -1e300;      ///< Smallest valid value.
  double max = 1e300;       ///< Largest valid value.
  bool min_exclusive = false;  ///< True if min itself is invalid.
  bool max_exclusive = false;  ///< True if max itself is invalid.
};

/// "(0, 0.5)", ">= 1", "any" ...: a range as text, for messages and `mpm materials`.
inline std::string range_text(double lo, double hi, bool lo_open, bool hi_open) {
  auto num = [](double v) {
    std::ostringstream s;
    s << v;
    return s.str();
  };
  const bool has_lo = lo > -1e299, has_hi = hi < 1e299;
  if (has_lo && has_hi)
    return std::string(lo_open ? "(" : "[") + num(lo) + ", " + num(hi) + (hi_open ? ")" : "]");
  if (has_lo) return std::string(lo_open ? "> " : ">= ") + num(lo);
  if (has_hi) return std::string(hi_open ? "< " : "<= ") + num(hi);
  return "any";
}

/// Parameter values after validation, keyed by ParamSpec::name. Used only while building.
using ParamValues = std::map<std::string, double>;

/// Per-object facts a material group needs besides its own parameters.
struct GroupInfo {
  GroupInfo() = default;
  /// The facts of a group of `count` particles of density `density`; `x` and `seed` as below.
  GroupInfo(double density, std::size_t count, std::span<const Vec3> x = {}, std::uint64_t seed = 1)
      : density(density), count(count), x(x), seed(seed) {}

  double density = 0;  ///< Reference mass density rho0, kg/m^3.
  std::size_t count = 0;  ///< Number of particles in the group's range.
  /// Positions of the group's particles as sampled (empty when a group is rebuilt to take
  /// restored state, e.g. after particle migration).
  std::span<const Vec3> x;
  std::uint64_t seed = 1;  ///< The scene's simulation.seed, for seeded initial state.
};

class MaterialGroup;

/// Particles per batch of MaterialGroup::lane_stress, whatever the engine's vector width.
inline constexpr std::size_t kStressLanes = 16;

/// One batch of MaterialGroup::lane_stress: up to kStressLanes particles of one group, one per
/// lane, entries lane-major so that a loop over the lanes vectorises (F[e][l] is entry e of
/// lane l's F, column-major: e = 3 column + row).
struct StressLanes {
  alignas(64) float F[9][kStressLanes];    ///< Each lane's deformation gradient.
  alignas(64) float tau[9][kStressLanes];  ///< Out: each lane's -V0 tau, Pa m^3.
  std::uint32_t index[kStressLanes];       ///< Each lane's particle, from the group's first.
  std::size_t count = 0;                   ///< Lanes in use; the others hold copies of lane 0.
};

/// A model the engine can also run in float SIMD lanes (engine/step/simd/stress_simd.h), named
/// with its parameters, so the engine's kernels need no virtual call per particle: its stress,
/// folded into the SIMD scatter, and for snow and sand its return map.
struct BatchModel {
  /// The models with a SIMD kernel.
  /// group: the group's own lane_stress (a plugin's), called once per batch.
  enum class Kind { none, fixed_corotated, snow, neo_hookean, water, sand, group };
  Kind kind = Kind::none;  ///< none: the engine calls compute_stress.
  Real mu = 0;      ///< Shear modulus (corotated, Neo-Hookean, sand; snow's before hardening), Pa.
  Real lambda = 0;  ///< First Lamé parameter (as mu), Pa.
  Real bulk_modulus = 0;           ///< Water's K, Pa.
  Real gamma = 0;                  ///< Water's Tait exponent.
  Real hardening = 0;              ///< Snow's xi: mu and lambda scale by exp(xi (1 - Jp)).
  Real critical_compression = 0;   ///< Snow's theta_c: singular values >= 1 - theta_c.
  Real critical_stretch = 0;       ///< Snow's theta_s: singular values <= 1 + theta_s.
  Real min_Jp = 0;                 ///< Snow's smallest Jp.
  Real rho0 = 0;                   ///< Snow's rest density, for its wave speed, kg/m^3.
  Real alpha = 0;                  ///< Sand's cone slope.
  Real apex_trace = 0;             ///< Sand's tr(eps) at the cone's apex.
  bool volume_correction = false;  ///< Sand's volume correction on.
  /// The group's per-particle plastic state (snow's Jp, which its stress reads), from its first
  /// particle: MaterialGroup::state(). Null for the others.
  const Real* state = nullptr;
  std::size_t first = 0;                 ///< The group's first particle index (set by the engine).
  const MaterialGroup* group = nullptr;  ///< Kind group: the group whose lane_stress runs.
};

/// A material applied to one contiguous range of particles.
///
/// The engine calls each method once per group per stage with spans of that range, so the
/// virtual call is paid once per group, never per particle.
class MaterialGroup {
 public:
  virtual ~MaterialGroup() = default;

  /// Writes -V0 * tau (tau = P F^T, the Kirchhoff stress) for each particle into `out`;
  /// every particle of the group has the reference volume `volume0`.
  virtual void compute_stress(std::span<const StoredMat3> F, Real volume0,
                              std::span<StoredMat3> out) const = 0;

  /// True if the material changes F after the F update (plasticity).
  virtual bool has_plasticity() const { return false; }

  /// Projects F onto the elastic region, keeping the plastic part as group state.
  virtual void apply_plasticity(std::span<StoredMat3> F) {}

  /// Largest elastic wave speed (m/s) over the range, at the current density rho0 / J.
  virtual Real max_wave_speed(std::span<const StoredMat3> F) const = 0;

  /// Total elastic energy (J) stored in the range: sum of V0 * psi(F).
  virtual Real elastic_energy(std::span<const StoredMat3> F, Real volume0) const = 0;

  /// Per-particle state beyond F (e.g. plastic Jp), flat and particle-major (particle i's
  /// values at [i s, (i + 1) s) for s = size / count); empty if none. Checkpoints save and
  /// restore it through this view, so a resumed run continues bit for bit, and the reorder
  /// stage moves each particle's values with the particle.
  virtual std::span<Real> state() { return {}; }

  /// The model whose stress compute_stress computes, if the engine has a SIMD kernel for it
  /// (simulation.simd: true then runs that kernel, in float, in place of compute_stress); kind
  /// none (the default) if not, or if the group does more than the model (e.g. plasticity's
  /// rescaled moduli).
  virtual BatchModel batch_model() const { return {}; }

  /// The plasticity stage's call, given the substep `dt` (s) whose F update F holds; a group
  /// whose projection needs the rate of deformation (water's viscosity) overrides this one.
  /// The default calls apply_plasticity(F).
  virtual void apply_plasticity_step(std::span<StoredMat3> F, Real dt) { apply_plasticity(F); }

  /// Largest kinematic viscosity eta / rho (m^2/s) over the range, for the explicit viscous
  /// bound on dt; 0 (the default) for a material without viscosity.
  virtual Real max_kinematic_viscosity(std::span<const StoredMat3> F) const { return 0; }

  /// True if lane_stress is implemented: with simulation.simd the engine then folds this
  /// group's stress into the SIMD scatter, one call per batch of particles, and stores none.
  /// False (the default): compute_stress runs as its own pass.
  virtual bool has_lane_stress() const { return false; }

  /// Writes -V0 tau of the batch's particles (`batch.F`, every particle of reference volume
  /// `volume0`) into `batch.tau`, in float: the plugin entry to the SIMD scatter. Called from
  /// several threads at once. ElasticGroup implements it for every value-type model.
  virtual void lane_stress(StressLanes& batch, Real volume0) const {}
};

/// A registered material: its name, parameter table and factory.
struct MaterialInfo {
  std::string name;                  ///< Scene name, e.g. "corotated".
  std::string description;           ///< One line for `mpm materials`.
  std::string reference;             ///< Paper the model follows.
  std::vector<ParamSpec> params;     ///< Keys read from the object besides the engine's own.
  bool supports_inversion = true;    ///< True if stress stays finite for det F <= 0 and near 0.
  /// Builds a group for `info.count` particles from validated parameters.
  std::function<std::unique_ptr<MaterialGroup>(const ParamValues&, const GroupInfo&)> create;
};

/// Lamé parameters from Young's modulus and Poisson's ratio.
struct Lame {
  Real mu;      ///< Shear modulus, Pa.
  Real lambda;  ///< First Lamé parameter, Pa.
};

/// mu = E / (2 (1 + nu)), lambda = E nu / ((1 + nu)(1 - 2 nu)).
inline Lame lame_from_young(Real E, Real nu) {
  return {E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))};
}

/// The parameters every elastic model shares: Young's modulus and Poisson's ratio.
inline std::vector<ParamSpec> elastic_param_specs() {
  ParamSpec E{"E", "Pa", "Young's modulus", true, 1.0e4};
  E.min = 0;
  E.min_exclusive = true;
  ParamSpec nu{"nu", "", "Poisson's ratio", true, 0.3};
  nu.min = -1;
  nu.max = 0.5;
  nu.min_exclusive = nu.max_exclusive = true;
  return {E, nu};
}

/// Cofactor matrix J F^-T, computed without inverting F (defined for singular F).
inline Mat3 cofactor(const Mat3& F) {
  Mat3 c;
  c.col(0) = F.col(1).cross(F.col(2));
  c.col(1) = F.col(2).cross(F.col(0));
  c.col(2) = F.col(0).cross(F.col(1));
  return c;
}

}  // namespace mpm
