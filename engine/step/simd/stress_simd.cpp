#include "engine/step/simd/stress_simd.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "materials/corotated.h"
#include "materials/neo_hookean.h"
#include "materials/sand.h"
#include "materials/snow.h"
#include "materials/water.h"

// Compiled once per instruction set, one chosen at run time (as transfer_simd.cpp).
#ifndef HWY_DISABLED_TARGETS
#define HWY_DISABLED_TARGETS (HWY_SSSE3 | HWY_AVX3_DL)
#endif
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "engine/step/simd/stress_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "engine/step/simd/materials-inl.h"

HWY_BEFORE_NAMESPACE();
namespace mpm::simd {
namespace HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;
using DF = hn::ScalableTag<float>;
using VF = hn::Vec<DF>;
constexpr std::size_t kLanes = HWY_LANES(float);  ///< Lanes of a full vector on this target.

/// Loads F of particles [0, count), count <= kLanes, one lane each (the last particle repeated
/// in unused lanes, which are not written back).
void load_lanes(const StoredMat3* F, std::size_t count, VF f[9]) {
  const DF d;
  alignas(64) float in[9][kLanes];
  for (std::size_t l = 0; l < kLanes; ++l) {
    const StoredReal* m = F[std::min(l, count - 1)].data();
    for (int e = 0; e < 9; ++e) in[e][l] = static_cast<float>(m[e]);
  }
  for (int e = 0; e < 9; ++e) f[e] = hn::Load(d, in[e]);
}

/// -V0 tau of `model` over particles [0, count), count <= kLanes, of plastic state `state`
/// (null: none). Returns the fallbacks.
std::size_t stress_batch(const BatchModel& model, const StoredMat3* F, const Real* state,
                         std::size_t count, Real volume0, StoredMat3* out) {
  const DF d;
  alignas(64) float prm[lanes::kParams][kLanes], res[9][kLanes];
  for (std::size_t l = 0; l < kLanes; ++l) {
    float one[lanes::kParams];
    lanes::lane_params(model, state ? state[std::min(l, count - 1)] : 1, one);
    for (int k = 0; k < lanes::kParams; ++k) prm[k][l] = one[k];
  }
  VF f[9], p[lanes::kParams], tau[9];
  load_lanes(F, count, f);
  for (int k = 0; k < lanes::kParams; ++k) p[k] = hn::Load(d, prm[k]);
  const auto bad =
      lanes::neg_v0_tau(model.kind, d, f, p, hn::Set(d, static_cast<float>(-volume0)), tau);
  for (int e = 0; e < 9; ++e) hn::Store(tau[e], d, res[e]);
  for (std::size_t l = 0; l < count; ++l) {
    StoredReal* o = out[l].data();
    for (int e = 0; e < 9; ++e) o[e] = static_cast<StoredReal>(res[e][l]);
  }
  const std::uint64_t redo = lanes::mask_bits(d, bad, count);
  for (std::size_t l = 0; l < count; ++l)
    if (redo >> l & 1)
      out[l] = to_stored(-volume0 * kirchhoff(model, to_real(F[l]), state ? state[l] : 1));
  return static_cast<std::size_t>(__builtin_popcountll(redo));
}

/// det F of double lanes `a` (column-major: a[3 c + r] = F(r, c)), in the order of Eigen's 3x3
/// determinant, as the scalar path computes it (not lanes::determinant, whose fused MulSub
/// rounds differently).
template <class VD>
HWY_INLINE VD determinant(const VD a[9]) {
  const auto cofactor = [](VD p, VD q, VD r, VD s) {
    return hn::Sub(hn::Mul(p, q), hn::Mul(r, s));
  };
  return hn::Add(hn::Sub(hn::Mul(a[0], cofactor(a[4], a[8], a[7], a[5])),
                         hn::Mul(a[3], cofactor(a[1], a[8], a[7], a[2]))),
                 hn::Mul(a[6], cofactor(a[1], a[5], a[4], a[2])));
}

/// Water's return map over particles [0, count), count <= kLanes: F = J^(1/3) I in double
/// lanes. J is det F in the order of Eigen's 3x3 determinant, as the scalar path computes it
/// (not lanes::determinant, whose fused MulSub rounds differently); the root is exp(log J / 3)
/// and one Newton step, within a unit of the last place of double before F's one rounding to
/// its storage. Particles with J <= 0 take the scalar map (std::cbrt). Returns those fallbacks.
std::size_t project_water_batch(StoredMat3* F, std::size_t count) {
  using DD = hn::ScalableTag<double>;
  const DD dd;
  constexpr std::size_t kDoubles = HWY_LANES(double);
  alignas(64) double m[9][kLanes], root[kLanes];
  for (std::size_t l = 0; l < kLanes; ++l) {
    const StoredReal* f = F[std::min(l, count - 1)].data();
    for (int e = 0; e < 9; ++e) m[e][l] = static_cast<double>(f[e]);
  }
  std::uint64_t redo = 0;
  for (std::size_t h = 0; h < kLanes; h += kDoubles) {
    hn::Vec<DD> a[9];  // column-major: a[3 c + r] = F(r, c)
    for (int e = 0; e < 9; ++e) a[e] = hn::Load(dd, m[e] + h);
    const hn::Vec<DD> J = determinant(a);
    const auto bad = hn::Not(hn::Gt(J, hn::Zero(dd)));  // also NaN
    const hn::Vec<DD> Jsafe = hn::IfThenElse(bad, hn::Set(dd, 1.0), J);
    hn::Vec<DD> x = hn::Exp(dd, hn::Mul(hn::Log(dd, Jsafe), hn::Set(dd, 1.0 / 3)));
    x = hn::Sub(x, hn::Div(hn::Sub(x, hn::Div(Jsafe, hn::Mul(x, x))), hn::Set(dd, 3.0)));
    hn::Store(x, dd, root + h);
    redo |= lanes::mask_bits(dd, bad, kDoubles) << h;
  }
  if (count < 64) redo &= (std::uint64_t{1} << count) - 1;
  for (std::size_t l = 0; l < count; ++l) {
    if (redo >> l & 1) {
      F[l] = to_stored(materials::TaitWater::project(to_real(F[l])));
      continue;
    }
    StoredReal* o = F[l].data();
    for (int e = 0; e < 9; ++e) o[e] = e % 4 == 0 ? static_cast<StoredReal>(root[l]) : 0;
  }
  return static_cast<std::size_t>(__builtin_popcountll(redo));
}

/// The return map of `model` over particles [0, count), count <= kLanes, and their `state`.
/// Returns the fallbacks.
std::size_t project_batch(const BatchModel& model, StoredMat3* F, Real* state, std::size_t count) {
  if (model.kind == BatchModel::Kind::water) return project_water_batch(F, count);
  const DF d;
  VF f[9];
  load_lanes(F, count, f);
  alignas(64) float st[kLanes], res[9][kLanes];
  for (std::size_t l = 0; l < kLanes; ++l)
    st[l] = static_cast<float>(state[std::min(l, count - 1)]);
  VF delta, df[9];  // snow: Jp's relative change; sand: the new volume correction
  hn::Mask<DF> changed, bad;
  const bool snow = model.kind == BatchModel::Kind::snow;
  if (snow) {
    const VF one = hn::Set(d, 1.0f);
    bad = lanes::snow_project(
        d, f, hn::Sub(one, hn::Set(d, static_cast<float>(model.critical_compression))),
        hn::Add(one, hn::Set(d, static_cast<float>(model.critical_stretch))), delta, changed, df);
  } else {
    bad = lanes::sand_project(d, f, hn::Load(d, st), model, delta, changed, df);
  }
  hn::Store(delta, d, st);
  for (int e = 0; e < 9; ++e) hn::Store(df[e], d, res[e]);
  const std::uint64_t moved = lanes::mask_bits(d, changed, count),
                      redo = lanes::mask_bits(d, bad, count);
  for (std::size_t l = 0; l < count; ++l) {
    if (redo >> l & 1) {
      project_scalar(model, F[l], state[l]);
      continue;
    }
    // The state in double, as the scalar path keeps it: snow raises every Jp to min_Jp.
    const bool kept = !(moved >> l & 1);
    if (snow)
      state[l] = std::max(kept ? state[l] : state[l] + state[l] * st[l], model.min_Jp);
    else if (!kept && model.volume_correction)  // sand: the new volume correction
      state[l] = st[l];
    if (kept) continue;
    StoredReal* o = F[l].data();  // F plus the change, in F's storage
    for (int e = 0; e < 9; ++e) o[e] = static_cast<StoredReal>(o[e] + res[e][l]);
  }
  return static_cast<std::size_t>(__builtin_popcountll(redo));
}

/// Snow's squared wave speed, (lambda h + 2 mu h) max(|det F| Jp, 1e-6) / rho0 with the
/// hardening h = exp(xi (1 - Jp)) (materials::SnowGroup::wave_speed before its square root), over
/// particles [0, count), count <= kLanes, in double lanes; the largest of them and `top`.
/// hn::Exp is within a few units of the last place of std::exp.
Real snow_wave_speed2_batch(const BatchModel& model, const StoredMat3* F, const Real* Jp,
                            std::size_t count, Real top) {
  using DD = hn::ScalableTag<double>;
  const DD dd;
  using VD = hn::Vec<DD>;
  constexpr std::size_t kDoubles = HWY_LANES(double);
  alignas(64) double m[9][kLanes], jp[kLanes];
  for (std::size_t l = 0; l < kLanes; ++l) {  // unused lanes repeat the last particle
    const std::size_t q = std::min(l, count - 1);
    const StoredReal* f = F[q].data();
    for (int e = 0; e < 9; ++e) m[e][l] = static_cast<double>(f[e]);
    jp[l] = Jp[q];
  }
  const VD one = hn::Set(dd, 1.0), two = hn::Set(dd, 2.0), least = hn::Set(dd, 1e-6);
  const VD xi = hn::Set(dd, model.hardening), mu = hn::Set(dd, model.mu),
           lambda = hn::Set(dd, model.lambda), rho0 = hn::Set(dd, model.rho0);
  VD most = hn::Set(dd, top);
  for (std::size_t h = 0; h < kLanes; h += kDoubles) {
    VD a[9];
    for (int e = 0; e < 9; ++e) a[e] = hn::Load(dd, m[e] + h);
    const VD j = hn::Load(dd, jp + h);
    const VD hard = hn::Exp(dd, hn::Mul(xi, hn::Sub(one, j)));
    const VD J = hn::Max(hn::Mul(hn::Abs(determinant(a)), j), least);
    const VD c2 =
        hn::Div(hn::Mul(hn::Add(hn::Mul(lambda, hard), hn::Mul(two, hn::Mul(mu, hard))), J), rho0);
    most = hn::IfThenElse(hn::Lt(most, c2), c2, most);  // std::max(most, c2)
  }
  return hn::GetLane(hn::MaxOfLanes(dd, most));
}

}  // namespace

Real SnowWaveSpeedImpl(const BatchModel& model, const StoredMat3* F, const Real* Jp,
                       std::size_t n) {
  const std::ptrdiff_t batches = static_cast<std::ptrdiff_t>((n + kLanes - 1) / kLanes);
  Real top = 0;
#pragma omp parallel for schedule(static) reduction(max : top) if (n >= kParallelMinItems)
  for (std::ptrdiff_t b = 0; b < batches; ++b) {
    const std::size_t q0 = static_cast<std::size_t>(b) * kLanes;
    top = snow_wave_speed2_batch(model, F + q0, Jp + q0, std::min(kLanes, n - q0), top);
  }
  return std::sqrt(top);  // the largest root is the root of the largest square
}

std::size_t StressImpl(const BatchModel& model, const StoredMat3* F, std::size_t n, Real volume0,
                       StoredMat3* out) {
  const std::ptrdiff_t batches = static_cast<std::ptrdiff_t>((n + kLanes - 1) / kLanes);
  std::size_t fallbacks = 0;
#pragma omp parallel for schedule(static) reduction(+ : fallbacks) if (n >= kParallelMinItems)
  for (std::ptrdiff_t b = 0; b < batches; ++b) {
    const std::size_t q0 = static_cast<std::size_t>(b) * kLanes;
    fallbacks += stress_batch(model, F + q0, model.state ? model.state + q0 : nullptr,
                              std::min(kLanes, n - q0), volume0, out + q0);
  }
  return fallbacks;
}

std::size_t ProjectImpl(const BatchModel& model, StoredMat3* F, Real* state, std::size_t n) {
  const std::ptrdiff_t batches = static_cast<std::ptrdiff_t>((n + kLanes - 1) / kLanes);
  std::size_t fallbacks = 0;
  // Guided: the particles that yield (and those the scalar fallback takes) lie together in
  // cell order, so equal parts are not equal work (frame 4 of snowball_paper: 1.59 s against
  // 1.70 s static, 1.75 s dynamic in runs of 32). Each batch is its own particles' only
  // writer, so the results do not depend on the schedule.
#pragma omp parallel for schedule(guided, 8) reduction(+ : fallbacks) if (n >= kParallelMinItems)
  for (std::ptrdiff_t b = 0; b < batches; ++b) {
    const std::size_t q0 = static_cast<std::size_t>(b) * kLanes;
    fallbacks +=
        project_batch(model, F + q0, state ? state + q0 : nullptr, std::min(kLanes, n - q0));
  }
  return fallbacks;
}

}  // namespace HWY_NAMESPACE
}  // namespace mpm::simd
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace mpm::simd {

HWY_EXPORT(StressImpl);
HWY_EXPORT(ProjectImpl);
HWY_EXPORT(SnowWaveSpeedImpl);

bool supports_stress(const BatchModel& model) {
  return model.kind != BatchModel::Kind::none && model.kind != BatchModel::Kind::group;
}

std::size_t stress(const BatchModel& model, std::span<const StoredMat3> F, Real volume0,
                   std::span<StoredMat3> out) {
  if (F.empty()) return 0;
  return HWY_DYNAMIC_DISPATCH(StressImpl)(model, F.data(), F.size(), volume0, out.data());
}

namespace {

/// Snow's plasticity as `model` describes it (its hardening and clamp).
materials::SnowPlasticity snow_plasticity(const BatchModel& model) {
  materials::SnowPlasticity plastic;
  plastic.critical_compression = model.critical_compression;
  plastic.critical_stretch = model.critical_stretch;
  plastic.hardening = model.hardening;
  plastic.min_Jp = model.min_Jp;
  return plastic;
}

}  // namespace

Mat3 kirchhoff(const BatchModel& model, const Mat3& F, Real state) {
  using K = BatchModel::Kind;
  switch (model.kind) {
    case K::fixed_corotated:
      return materials::FixedCorotated{model.mu, model.lambda}.kirchhoff(F);
    case K::snow: {
      const Real h = snow_plasticity(model).hardening_factor(state);
      return materials::FixedCorotated{model.mu * h, model.lambda * h}.kirchhoff(F);
    }
    case K::neo_hookean:
      return materials::NeoHookean{model.mu, model.lambda}.kirchhoff(F);
    case K::water:
      return materials::TaitWater{model.bulk_modulus, model.gamma}.kirchhoff(F);
    case K::sand:
      return materials::DruckerPragerSand{model.mu, model.lambda}.kirchhoff(F);
    case K::none:
    case K::group:
      break;
  }
  return Mat3::Zero();
}

bool supports_projection(const BatchModel& model) {
  using K = BatchModel::Kind;
  return model.kind == K::snow || model.kind == K::sand || model.kind == K::water;
}

std::size_t project(const BatchModel& model, std::span<StoredMat3> F, std::span<Real> state) {
  if (F.empty()) return 0;
  return HWY_DYNAMIC_DISPATCH(ProjectImpl)(model, F.data(), state.data(), F.size());
}

bool supports_wave_speed(const BatchModel& model) {
  return model.kind == BatchModel::Kind::snow;
}

Real max_wave_speed(const BatchModel& model, std::span<const StoredMat3> F) {
  if (F.empty()) return 0;
  return HWY_DYNAMIC_DISPATCH(SnowWaveSpeedImpl)(model, F.data(), model.state, F.size());
}

void project_scalar(const BatchModel& model, StoredMat3& F, Real& state) {
  if (model.kind == BatchModel::Kind::snow) {
    Mat3 Fe = to_real(F);
    if (snow_plasticity(model).project(Fe, state)) F = to_stored(Fe);
    return;
  }
  if (model.kind == BatchModel::Kind::water)
    F = to_stored(materials::TaitWater::project(to_real(F)));
  if (model.kind == BatchModel::Kind::sand)
    materials::project_sand(
        {model.mu, model.lambda, model.alpha, model.apex_trace, model.volume_correction}, F, state);
}

}  // namespace mpm::simd
#endif  // HWY_ONCE
