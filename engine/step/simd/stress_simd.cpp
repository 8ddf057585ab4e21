#include "engine/step/simd/stress_simd.h"

#include <algorithm>
#include <cstdint>

#include "materials/corotated.h"

// Compiled once per instruction set, one chosen at run time (as transfer_simd.cpp).
#ifndef HWY_DISABLED_TARGETS
#define HWY_DISABLED_TARGETS (HWY_SSSE3 | HWY_AVX3_DL)
#endif
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "engine/step/simd/stress_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "engine/step/simd/corotated-inl.h"

HWY_BEFORE_NAMESPACE();
namespace mpm::simd {
namespace HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;
using DF = hn::ScalableTag<float>;
constexpr std::size_t kLanes = HWY_LANES(float);  ///< Lanes of a full vector on this target.

/// Fixed corotated over particles [q0, q0 + count), count <= kLanes, one lane each (the last
/// particle repeated in unused lanes, which are not written back). Returns the fallbacks.
std::size_t corotated_batch(const materials::FixedCorotated& model, const StoredMat3* F,
                            std::size_t count, Real volume0, StoredMat3* out) {
  const DF d;
  alignas(64) float in[9][kLanes], res[9][kLanes];
  for (std::size_t l = 0; l < kLanes; ++l) {
    const StoredReal* f = F[std::min(l, count - 1)].data();
    for (int e = 0; e < 9; ++e) in[e][l] = static_cast<float>(f[e]);
  }
  hn::Vec<DF> fv[9], tau[9];
  for (int e = 0; e < 9; ++e) fv[e] = hn::Load(d, in[e]);
  const auto bad = corotated::neg_v0_tau(d, fv, hn::Set(d, static_cast<float>(2 * model.mu)),
                                         hn::Set(d, static_cast<float>(model.lambda)),
                                         hn::Set(d, static_cast<float>(-volume0)), tau);
  for (int e = 0; e < 9; ++e) hn::Store(tau[e], d, res[e]);
  for (std::size_t l = 0; l < count; ++l) {
    StoredReal* o = out[l].data();
    for (int e = 0; e < 9; ++e) o[e] = static_cast<StoredReal>(res[e][l]);
  }
  if (hn::AllFalse(d, bad)) return 0;
  alignas(64) std::uint8_t bits[(kLanes + 7) / 8 + 8] = {};
  hn::StoreMaskBits(d, bad, bits);
  std::size_t fallbacks = 0;
  for (std::size_t l = 0; l < count; ++l)
    if (bits[l / 8] >> (l % 8) & 1) {
      out[l] = to_stored(-volume0 * model.kirchhoff(to_real(F[l])));
      ++fallbacks;
    }
  return fallbacks;
}

}  // namespace

std::size_t CorotatedStressImpl(Real mu, Real lambda, const StoredMat3* F, std::size_t n,
                                Real volume0, StoredMat3* out) {
  const materials::FixedCorotated model{mu, lambda};
  const std::ptrdiff_t batches = static_cast<std::ptrdiff_t>((n + kLanes - 1) / kLanes);
  std::size_t fallbacks = 0;
#pragma omp parallel for schedule(static) reduction(+ : fallbacks) if (n >= kParallelMinItems)
  for (std::ptrdiff_t b = 0; b < batches; ++b) {
    const std::size_t q0 = static_cast<std::size_t>(b) * kLanes;
    fallbacks += corotated_batch(model, F + q0, std::min(kLanes, n - q0), volume0, out + q0);
  }
  return fallbacks;
}

}  // namespace HWY_NAMESPACE
}  // namespace mpm::simd
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace mpm::simd {

HWY_EXPORT(CorotatedStressImpl);

bool supports_stress(const BatchModel& model) {
  return model.kind == BatchModel::Kind::fixed_corotated;
}

std::size_t stress(const BatchModel& model, std::span<const StoredMat3> F, Real volume0,
                   std::span<StoredMat3> out) {
  if (F.empty()) return 0;
  return HWY_DYNAMIC_DISPATCH(CorotatedStressImpl)(model.mu, model.lambda, F.data(), F.size(),
                                                   volume0, out.data());
}

}  // namespace mpm::simd
#endif  // HWY_ONCE
