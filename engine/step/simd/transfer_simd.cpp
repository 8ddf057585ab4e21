#include "engine/step/simd/transfer_simd.h"

#include <algorithm>
#include <cassert>
#include <cstdint>
#include <stdexcept>
#include <type_traits>

// Highway compiles this file once per instruction set (foreach_target) and picks one at run
// time (HWY_DYNAMIC_DISPATCH), so the default build runs AVX-512 on Zen 4 and SSE4 elsewhere.
// SSSE3 and AVX3_DL add nothing to this float code over SSE4 and AVX3: not compiled.
#ifndef HWY_DISABLED_TARGETS
#define HWY_DISABLED_TARGETS (HWY_SSSE3 | HWY_AVX3_DL)
#endif
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "engine/step/simd/transfer_simd.cpp"
#include <hwy/cache_control.h>
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "engine/step/simd/materials-inl.h"
#include "engine/step/simd/stress_simd.h"

HWY_BEFORE_NAMESPACE();
namespace mpm::simd {
namespace HWY_NAMESPACE {
#if HWY_TARGET == HWY_SCALAR
// One lane cannot hold a stencil's 1D weights: on a CPU without SSE4 the scalar path runs.
void ScatterImpl(const Particles&, const ParticleOrder&, Transfer, Kernel, Real,
                 std::span<const BatchModel>, Grid&) {}
void GatherImpl(const Grid&, Transfer, Kernel, Real, Particles&, AdvectStats*) {}
void GatherRangeImpl(const Grid&, Transfer, Kernel, Real, Particles&, std::size_t, std::size_t,
                     AdvectStats*) {}
std::size_t CellKeysImpl(const Particles&, Kernel, const Grid&, const Vec3i&, const Vec3i&,
                         std::size_t, std::size_t, std::uint32_t*, std::int32_t*) {
  return 0;
}
const char* TargetImpl() {
  return nullptr;
}
#else
namespace {

namespace hn = hwy::HWY_NAMESPACE;
using DF = hn::ScalableTag<float>;
using DI = hn::RebindToSigned<DF>;
using VF = hn::Vec<DF>;
using VI = hn::Vec<DI>;
constexpr std::size_t kLanes = HWY_LANES(float);  ///< Lanes of a full vector on this target.
static_assert(kGatherAlign % kLanes == 0, "gather_range's ranges start on a lane set");

/// Rounds a grid value to float storage if the grid stores float (grid.precision: float).
inline Real store_node(Real v, bool float_nodes) {
  return float_nodes ? static_cast<Real>(static_cast<float>(v)) : v;
}

/// 1D weights and their derivatives (per cell) of kernel K at d = fx - base, one lane per
/// particle, in float or double lanes: the vector form of KernelTraits<K>::weights.
template <Kernel K, class D, class V = hn::Vec<D> >
void lane_weights(D d, V x, V* w, V* dw) {
  using VF = V;
  using T = hn::TFromD<D>;
  const VF one = hn::Set(d, 1.0f), half = hn::Set(d, 0.5f);
  if constexpr (K == Kernel::linear) {
    w[0] = hn::Sub(one, x);
    w[1] = x;
    dw[0] = hn::Neg(one);
    dw[1] = one;
  } else if constexpr (K == Kernel::quadratic) {
    const VF a = hn::Sub(hn::Set(d, 1.5f), x), b = hn::Sub(x, one), c = hn::Sub(x, half);
    w[0] = hn::Mul(half, hn::Mul(a, a));
    w[1] = hn::NegMulAdd(b, b, hn::Set(d, 0.75f));
    w[2] = hn::Mul(half, hn::Mul(c, c));
    dw[0] = hn::Neg(a);
    dw[1] = hn::Mul(hn::Set(d, -2.0f), b);
    dw[2] = c;
  } else {
    const VF a = hn::Sub(hn::Set(d, 2.0f), x), b = hn::Sub(x, one);  // c = a, e = b
    const VF sixth = hn::Set(d, static_cast<T>(1.0 / 6)),
             two3 = hn::Set(d, static_cast<T>(2.0 / 3));
    const VF a2 = hn::Mul(a, a), b2 = hn::Mul(b, b);
    w[0] = hn::Mul(hn::Mul(a2, a), sixth);
    w[1] = hn::Add(hn::Sub(hn::Mul(half, hn::Mul(b2, b)), b2), two3);
    w[2] = hn::Add(hn::Sub(hn::Mul(half, hn::Mul(a2, a)), a2), two3);
    w[3] = hn::Mul(hn::Mul(b2, b), sixth);
    const VF onehalf = hn::Set(d, 1.5f), two = hn::Set(d, 2.0f);
    dw[0] = hn::Neg(hn::Mul(half, a2));
    dw[1] = hn::Sub(hn::Mul(onehalf, b2), hn::Mul(two, b));
    dw[2] = hn::Neg(hn::Sub(hn::Mul(onehalf, a2), hn::Mul(two, a)));
    dw[3] = hn::Mul(half, b2);
  }
}

/// The stencil of kernel K along axis `a` for the positions x (m) in double lanes, as
/// KernelTraits<K>::base and make_stencil compute it: sets `base` to the base node and
/// `corner` to the offset of the base node from the particle, x_base - x (m); returns
/// fx - base (cells), from which the caller takes the weights.
template <Kernel K, class DD, class VD = hn::Vec<DD> >
VD stencil_lanes(DD dd, VD x, const Grid& g, int a, VD& corner, VD& base) {
  constexpr double kShift = K == Kernel::quadratic ? 0.5 : 0.0;
  constexpr double kFirst = K == Kernel::cubic ? -1.0 : 0.0;
  const VD fx = hn::Mul(hn::Sub(x, hn::Set(dd, g.origin[a])), hn::Set(dd, g.inv_h[a]));
  base = hn::Add(hn::Floor(hn::Sub(fx, hn::Set(dd, kShift))), hn::Set(dd, kFirst));
  corner = hn::Sub(hn::MulAdd(base, hn::Set(dd, g.h[a]), hn::Set(dd, g.origin[a])), x);
  return hn::Sub(fx, base);
}

using DD = hn::ScalableTag<double>;  ///< Double lanes: kHalves vectors per float vector.
using VD = hn::Vec<DD>;
constexpr std::size_t kHalves = HWY_LANES(float) / HWY_LANES(double);

/// The double lanes of one batch, h[0] the first (kHalves vectors), rounded to float (or
/// int) and joined into one vector in registers. Stored as one whole vector, they can be
/// loaded whole at once: a load that spans several narrower stores waits until they all reach
/// the cache.
template <class D>
HWY_INLINE hn::Vec<D> join_lanes(D d, const VD* h) {
  if constexpr (kHalves == 1) {
    return hn::DemoteTo(d, h[0]);
  } else {  // kHalves == 2
    const hn::Half<D> dh;
    return hn::Combine(d, hn::DemoteTo(dh, h[1]), hn::DemoteTo(dh, h[0]));
  }
}

/// The kLanes float 3x3 matrices at `m` (consecutive, column-major), one per lane:
/// out[3 c + r] holds M(r, c) of every lane. Two rounds of three-way deinterleaving, in
/// registers but for one 576-byte pass through the stack written and read as whole vectors:
/// M's columns are triples (rows of the first round), each row's columns the second.
/// (Float storage only: a double build never calls it, see kFloatMatrices.)
template <class T>
HWY_INLINE void load_matrices(const T* m, VF out[9]) {
  if constexpr (std::is_same_v<T, float>) {
    const DF d;
    alignas(64) float rows[3][3 * kLanes];
    for (std::size_t t = 0; t < 3; ++t) {
      VF r0, r1, r2;
      hn::LoadInterleaved3(d, m + 3 * kLanes * t, r0, r1, r2);
      hn::Store(r0, d, rows[0] + kLanes * t);
      hn::Store(r1, d, rows[1] + kLanes * t);
      hn::Store(r2, d, rows[2] + kLanes * t);
    }
    for (int r = 0; r < 3; ++r) hn::LoadInterleaved3(d, rows[r], out[r], out[3 + r], out[6 + r]);
  }
}

/// The inverse of load_matrices: stores lane l's matrix (in[3 c + r] = M(r, c)) at m + 9 l.
template <class T>
HWY_INLINE void store_matrices(const VF in[9], T* m) {
  if constexpr (std::is_same_v<T, float>) {
    const DF d;
    alignas(64) float rows[3][3 * kLanes];
    for (int r = 0; r < 3; ++r) hn::StoreInterleaved3(in[r], in[3 + r], in[6 + r], d, rows[r]);
    for (std::size_t t = 0; t < 3; ++t)
      hn::StoreInterleaved3(hn::Load(d, rows[0] + kLanes * t), hn::Load(d, rows[1] + kLanes * t),
                            hn::Load(d, rows[2] + kLanes * t), d, m + 3 * kLanes * t);
  }
}

/// Lane l of in[k] (k < N) to out[N l + k], for the N = 2, 3, 4 weights of a kernel.
template <int N>
void store_interleaved(const float (*in)[kLanes], float* out) {
  const DF d;
  if constexpr (N == 2)
    hn::StoreInterleaved2(hn::Load(d, in[0]), hn::Load(d, in[1]), d, out);
  else if constexpr (N == 3)
    hn::StoreInterleaved3(hn::Load(d, in[0]), hn::Load(d, in[1]), hn::Load(d, in[2]), d, out);
  else
    hn::StoreInterleaved4(hn::Load(d, in[0]), hn::Load(d, in[1]), hn::Load(d, in[2]),
                          hn::Load(d, in[3]), d, out);
}

/// True if the stored matrices are float, so load_matrices and store_matrices apply.
constexpr bool kFloatMatrices = std::is_same_v<StoredReal, float>;

/// The scatter's particles order[b0, b0 + count) (count <= kLanes) as kLanes in a row, so that
/// a batch loads their x, v, F and C as whole vectors (LoadInterleaved3, load_matrices) wherever
/// they lie: the particle arrays themselves when they are kLanes consecutive particles, else
/// copies of each lane's (the last particle repeated in unused lanes). Between reorders most
/// batches are not consecutive: a particle that has crossed a cell face since the last reorder
/// breaks its batch (3 % of two_cubes' batches were consecutive as it fell).
class BatchParticles {
 public:
  const Vec3* x;             ///< kLanes positions, m.
  const Vec3* v;             ///< kLanes velocities, m/s.
  const StoredMat3* F;       ///< kLanes deformation gradients.
  const StoredMat3* C;       ///< kLanes affine velocities, 1/s (with `affine` only).
  std::uint32_t object = 0;  ///< Lane 0's object.
  bool one_object = true;    ///< Whether every lane's object is lane 0's.

  /// The particles order[b0, b0 + count) of `p`; C only if `affine`.
  BatchParticles(const Particles& p, const ParticleOrder& ord, std::size_t b0, std::size_t count,
                 bool affine) {
    const std::uint32_t* at = ord.order.data() + b0;
    object = p.object[at[0]];
    const hn::RebindToUnsigned<DF> du;
    if (count == kLanes && hn::AllTrue(du, hn::Eq(hn::LoadU(du, at), hn::Iota(du, at[0])))) {
      x = &p.x[at[0]], v = &p.v[at[0]], F = &p.F[at[0]], C = affine ? &p.C[at[0]] : nullptr;
      one_object =
          hn::AllTrue(du, hn::Eq(hn::LoadU(du, p.object.data() + at[0]), hn::Set(du, object)));
      return;
    }
    for (std::size_t l = 0; l < kLanes; ++l) {
      const std::uint32_t q = at[std::min(l, count - 1)];
      x_[l] = p.x[q];
      v_[l] = p.v[q];
      F_[l] = p.F[q];
      if (affine) C_[l] = p.C[q];
      one_object &= p.object[q] == object;
    }
    x = x_, v = v_, F = F_, C = affine ? C_ : nullptr;
  }
  BatchParticles(const BatchParticles&) = delete;  ///< The pointers may point into it.
  BatchParticles& operator=(const BatchParticles&) = delete;

 private:
  alignas(64) Vec3 x_[kLanes];
  alignas(64) Vec3 v_[kLanes];
  alignas(64) StoredMat3 F_[kLanes];
  alignas(64) StoredMat3 C_[kLanes];
};

/// The matrices m[0, count) (count <= kLanes, the last repeated in unused lanes) in float
/// lanes: out[3 c + r] holds M(r, c) of every lane. kLanes float matrices load as whole vectors
/// (load_matrices), others lane by lane.
HWY_INLINE void load_matrix_lanes(const StoredMat3* m, std::size_t count, VF out[9]) {
  if constexpr (kFloatMatrices)
    if (count == kLanes) return load_matrices(m[0].data(), out);
  alignas(64) float in[9][kLanes];
  for (std::size_t l = 0; l < kLanes; ++l) {
    const StoredReal* M = m[std::min(l, count - 1)].data();
    for (int e = 0; e < 9; ++e) in[e][l] = static_cast<float>(M[e]);
  }
  for (int e = 0; e < 9; ++e) out[e] = hn::Load(DF(), in[e]);
}

/// -V0 tau of the kLanes particles order[b0, b0 + kLanes) (clamped to `end`), for the scatter:
/// computed in lanes for the objects whose model `fold` names (the stress folded into the
/// scatter, so it is never stored), read from p.stress for the others.
struct StressBatch {
  std::size_t b0 = 0, b1 = 0;        ///< The batch is order[b0, b1).
  alignas(64) float tau[9][kLanes];  ///< -V0 tau per lane, column-major.
};

/// The model `fold` names for object o (kind none: its stress is in p.stress).
inline const BatchModel* folded(std::span<const BatchModel> fold, std::uint32_t o) {
  return o < fold.size() && fold[o].kind != BatchModel::Kind::none ? &fold[o] : nullptr;
}

/// The plastic state the stress of particle pi of model m reads (snow's Jp), or 1.
inline Real lane_state(const BatchModel& m, std::uint32_t pi) {
  return m.state ? m.state[pi - m.first] : 1;
}

/// The lanes `lanes` of the batch at order[b0, ...) whose model is a group's own lane kernel
/// (kind group, a plugin's): one MaterialGroup::lane_stress call per group among them.
void group_stress(const Particles& p, const ParticleOrder& ord, std::span<const BatchModel> fold,
                  std::size_t b0, std::uint64_t lanes, StressBatch& sb) {
  static_assert(kLanes <= kStressLanes, "a batch fits one lane_stress call");
  while (lanes) {
    const std::uint32_t o = p.object[ord.order[b0 + __builtin_ctzll(lanes)]];
    const BatchModel& m = fold[o];
    StressLanes batch;
    std::size_t slot[kStressLanes];
    for (std::uint64_t rest = lanes; rest; rest &= rest - 1) {
      const std::size_t l = __builtin_ctzll(rest);
      const std::uint32_t pi = ord.order[b0 + l];
      if (p.object[pi] != o) continue;
      lanes &= ~(std::uint64_t{1} << l);
      for (int e = 0; e < 9; ++e) batch.F[e][batch.count] = static_cast<float>(p.F[pi].data()[e]);
      batch.index[batch.count] = static_cast<std::uint32_t>(pi - m.first);
      slot[batch.count++] = l;
    }
    for (std::size_t l = batch.count; l < kStressLanes; ++l) {
      for (int e = 0; e < 9; ++e) batch.F[e][l] = batch.F[e][0];
      batch.index[l] = batch.index[0];
    }
    m.group->lane_stress(batch, p.object_volume0[o]);
    for (std::size_t n = 0; n < batch.count; ++n)
      for (int e = 0; e < 9; ++e) sb.tau[e][slot[n]] = batch.tau[e][n];
  }
}

/// Fills `sb` with the stresses of order[b0, min(b0 + kLanes, end)), whose F `bp` holds; if
/// they belong to one object, its parameters are set once. Each model kind among the lanes
/// runs its lane kernel once over the batch (lanes::neg_v0_tau), kept in its own lanes.
void fill_stress(const Particles& p, const ParticleOrder& ord, std::span<const BatchModel> fold,
                 std::size_t b0, std::size_t end, const BatchParticles& bp, StressBatch& sb) {
  const DF d;
  const DI di;
  sb.b0 = b0;
  sb.b1 = std::min(end, b0 + kLanes);
  const std::size_t count = sb.b1 - b0;
  alignas(64) float prm[lanes::kParams][kLanes], nv0[kLanes];
  alignas(64) std::int32_t kind[kLanes];
  unsigned present = 0;  // bit k: some lane's model is of kind k
  const bool uniform = bp.one_object;
  const BatchModel* one = uniform ? folded(fold, bp.object) : nullptr;
  if (one) {  // particles of one object: its parameters set once
    float v[lanes::kParams];
    lanes::lane_params(*one, 1, v);
    for (int k = 0; k < lanes::kParams; ++k) hn::Store(hn::Set(d, v[k]), d, prm[k]);
    if (one->state)  // snow's Jp
      for (std::size_t l = 0; l < kLanes; ++l)
        prm[lanes::kStateParam][l] =
            static_cast<float>(one->state[ord.order[b0 + std::min(l, count - 1)] - one->first]);
    hn::Store(hn::Set(d, static_cast<float>(-p.object_volume0[bp.object])), d, nv0);
    present = 1u << static_cast<int>(one->kind);
  }
  for (std::size_t l = 0; l < kLanes && !uniform; ++l) {
    const std::uint32_t pi = ord.order[b0 + std::min(l, count - 1)];
    const std::uint32_t o = p.object[pi];
    const BatchModel* m = folded(fold, o);
    kind[l] = static_cast<std::int32_t>(m ? m->kind : BatchModel::Kind::none);
    if (m && l < count) present |= 1u << kind[l];
    float v[lanes::kParams] = {};
    if (m) lanes::lane_params(*m, lane_state(*m, pi), v);
    for (int k = 0; k < lanes::kParams; ++k) prm[k][l] = v[k];
    nv0[l] = static_cast<float>(-p.object_volume0[o]);
  }
  std::uint64_t bad = 0;
  if (present) {
    VF fv[9], tau[9], pv[lanes::kParams];
    load_matrix_lanes(bp.F, kLanes, fv);
    for (int k = 0; k < lanes::kParams; ++k) pv[k] = hn::Load(d, prm[k]);
    const VF v0 = hn::Load(d, nv0);
    hn::Mask<DF> redo = hn::FirstN(d, 0);
    for (int k = 0; present >> k; ++k) {
      if (!(present >> k & 1) || k == static_cast<int>(BatchModel::Kind::group)) continue;
      VF mine[9];  // one model: its stresses straight into tau (no copy)
      const auto m =
          lanes::neg_v0_tau(static_cast<BatchModel::Kind>(k), d, fv, pv, v0, uniform ? tau : mine);
      if (uniform) {
        redo = m;
        continue;
      }
      const auto lane = hn::RebindMask(d, hn::Eq(hn::Load(di, kind), hn::Set(di, k)));
      for (int e = 0; e < 9; ++e) tau[e] = hn::IfThenElse(lane, mine[e], tau[e]);
      redo = hn::Or(redo, hn::And(lane, m));
    }
    for (int e = 0; e < 9; ++e) hn::Store(tau[e], d, sb.tau[e]);
    bad = lanes::mask_bits(d, redo, count);
  }
  const bool groups = present >> static_cast<int>(BatchModel::Kind::group) & 1;
  if (uniform && present && bad == 0 && !groups) return;  // every lane computed
  std::uint64_t group_lanes = 0;
  for (std::size_t l = 0; l < count; ++l) {
    const std::uint32_t pi = ord.order[b0 + l];
    const std::uint32_t o = p.object[pi];
    const BatchModel* m = folded(fold, o);
    if (m && m->kind == BatchModel::Kind::group) {
      group_lanes |= std::uint64_t{1} << l;
      continue;
    }
    if (m && !(bad >> l & 1)) continue;
    // Not folded (the stress stage wrote p.stress), or a lane the float quaternion cannot
    // give to float accuracy: the scalar double model, as simd::stress does.
    const StoredMat3 t =
        m ? to_stored(-p.object_volume0[o] * kirchhoff(*m, to_real(p.F[pi]), lane_state(*m, pi)))
          : p.stress[pi];
    for (int e = 0; e < 9; ++e) sb.tau[e][l] = static_cast<float>(t.data()[e]);
  }
  if (group_lanes) group_stress(p, ord, fold, b0, group_lanes, sb);
}

/// What the scatter needs of the particles order[b0, b1) (kLanes of them, clamped to the
/// range's end), one row or one lane per particle: the 1D weights (from the double stencil,
/// rounded once), the stencil base, and the per-axis tables of the node momentum, computed
/// in lanes (one particle per lane) from the float-stored C and stress, so the per-particle
/// loop only loads them.
template <int N>
struct ScatterBatch {
  std::size_t b0 = 0, b1 = 0;  ///< The batch is order[b0, b1).
  /// w[axis][N l + k]: lane l's 1D weight of node base + k (N per lane, interleaved; padded
  /// so that a full vector loaded at N l stays inside).
  alignas(64) float w[3][(N + 1) * kLanes] = {};
  /// t[axis][e][N l + k], the momentum tables (rows as w): component e of the momentum at
  /// node (i, j, k) is t[0][e](i) wy wz + wx t[1][e](j) wz + wx wy t[2][e](k).
  alignas(64) float t[3][3][(N + 1) * kLanes] = {};
  alignas(64) std::int32_t base[3][kLanes];  ///< The stencil's first node per axis and lane.
  alignas(64) float m[kLanes];               ///< Particle mass, kg.
};

/// The scatter's stencil of a batch (base, 1D weights and derivatives per cell) from the
/// positions xs: the base, the corner offset and fx - base in double lanes as make_stencil
/// computes them, each rounded to float once, then the weights in float lanes from fx - base
/// (as the gather takes them).
template <Kernel K, int N = KernelTraits<K>::kNodes>
HWY_INLINE void scatter_stencil(const Grid& g, const double (*xs)[kLanes], float (*corner)[kLanes],
                                std::int32_t (*base)[kLanes], float (*wl)[N][kLanes],
                                float (*dwl)[N][kLanes]) {
  const DD dd;
  const DF d;
  const DI di;
  for (int a = 0; a < 3; ++a) {
    VD c[kHalves], b[kHalves], t[kHalves];
    for (std::size_t h = 0; h < kHalves; ++h)
      t[h] = stencil_lanes<K>(dd, hn::Load(dd, xs[a] + h * hn::Lanes(dd)), g, a, c[h], b[h]);
    hn::Store(join_lanes(d, c), d, corner[a]);
    hn::Store(join_lanes(di, b), di, base[a]);
    VF w[N], dw[N];
    lane_weights<K>(d, join_lanes(d, t), w, dw);
    const VF s = hn::Set(d, static_cast<float>(g.inv_h[a]));
    for (int k = 0; k < N; ++k) {
      hn::Store(w[k], d, wl[a][k]);
      hn::Store(hn::Mul(dw[k], s), d, dwl[a][k]);
    }
  }
}

/// Fills `pb` with order[b0, min(b0 + kLanes, end)); `sb` holds their stresses after. One
/// function: its lane arrays (weights, corners, velocities, C) live on its stack and in
/// registers between the stencil and the momentum tables.
template <Kernel K, Transfer T>
void fill_batch(const Particles& p, const ParticleOrder& ord, std::span<const BatchModel> fold,
                const Grid& g, Real dt, std::size_t b0, std::size_t end, StressBatch& sb,
                ScatterBatch<KernelTraits<K>::kNodes>& pb) {
  constexpr int N = KernelTraits<K>::kNodes;
  constexpr bool kAffine = T == Transfer::apic || T == Transfer::mls;
  const DF d;
  // The next batch's particles, requested now so that their loads below (one batch later) do
  // not wait for memory: the scatter's order only roughly follows memory order.
  for (std::size_t q = b0 + kLanes; q < std::min(end, b0 + 2 * kLanes); ++q) {
    const std::uint32_t pi = ord.order[q];
    hwy::Prefetch(&p.x[pi]);
    hwy::Prefetch(&p.v[pi]);
    hwy::Prefetch(&p.F[pi]);
    hwy::Prefetch(&p.object[pi]);
    if constexpr (kAffine) hwy::Prefetch(&p.C[pi]);
  }
  const BatchParticles bp(p, ord, b0, std::min(end, b0 + kLanes) - b0, kAffine);
  fill_stress(p, ord, fold, b0, end, bp, sb);
  pb.b0 = sb.b0;
  pb.b1 = sb.b1;
  const std::size_t count = pb.b1 - pb.b0;
  alignas(64) float corner[3][kLanes], vel[3][kLanes], cm[3][3][kLanes];
  alignas(64) float wl[3][N][kLanes], dwl[3][N][kLanes];
  alignas(64) double xs[3][kLanes];
  if constexpr (kAffine) {
    VF c[9];
    load_matrix_lanes(bp.C, kLanes, c);
    for (int e = 0; e < 3; ++e)
      for (int a = 0; a < 3; ++a) hn::Store(c[3 * a + e], d, cm[e][a]);
  }
  const DD dd;
  // x and v three axes at a time, as the gather loads x.
  {
    VD x[3][kHalves], v[3][kHalves];
    for (std::size_t h = 0; h < kHalves; ++h) {
      const std::size_t l = h * hn::Lanes(dd);
      hn::LoadInterleaved3(dd, bp.x[l].data(), x[0][h], x[1][h], x[2][h]);
      hn::LoadInterleaved3(dd, bp.v[l].data(), v[0][h], v[1][h], v[2][h]);
      for (int a = 0; a < 3; ++a) hn::Store(x[a][h], dd, xs[a] + l);
    }
    for (int a = 0; a < 3; ++a) hn::Store(join_lanes(d, v[a]), d, vel[a]);
  }
  if (bp.one_object) hn::Store(hn::Set(d, static_cast<float>(p.object_mass[bp.object])), d, pb.m);
  for (std::size_t l = 0; l < kLanes && !bp.one_object; ++l)
    pb.m[l] = static_cast<float>(p.mass(ord.order[b0 + std::min(l, count - 1)]));
  scatter_stencil<K>(g, xs, corner, pb.base, wl, dwl);
  // Momentum at node (i, j, k), with w = wx wy wz and grad w = (dwx wy wz, wx dwy wz, wx wy
  // dwz): w (m v + Q (x_base + (i, j, k) h - x_p)) + dt (-V0 tau) grad w
  //   = w (a + i c0 + j c1 + k c2) + s0 dwx wy wz + s1 wx dwy wz + s2 wx wy dwz,
  // Q = m C (APIC) or m C + dt (-V0 tau) D^-1 (MLS, Hu et al. 2018, eq. 29), a = m v + Q
  // (x_base - x_p), c_b = Q_.b h_b, s_b = dt (-V0 tau)_.b (no s for MLS, folded into Q).
  // Each term has one 1D factor that is not a weight, so per component e
  //   = X(i) wy wz + wx Y(j) wz + wx wy Z(k), X(i) = wx(i) (a + i c0) + dwx(i) s0,
  //     Y(j) = wy(j) j c1 + dwy(j) s1, Z(k) = wz(k) k c2 + dwz(k) s2:
  // N-entry tables per particle, computed here in lanes.
  const VF m = hn::Load(d, pb.m);
  const Vec3 inv_D = KernelTraits<K>::kInvDScale * g.inv_h.cwiseProduct(g.inv_h);
  alignas(64) float tl[3][N][kLanes];
  for (int e = 0; e < 3; ++e) {
    VF a = hn::Mul(m, hn::Load(d, vel[e]));
    VF c[3], s[3];
    for (int b = 0; b < 3; ++b) {
      const VF tau = hn::Load(d, sb.tau[3 * b + e]);  // column-major, as stored
      c[b] = hn::Zero(d);
      if constexpr (kAffine) {
        VF Q = hn::Mul(m, hn::Load(d, cm[e][b]));
        if constexpr (T == Transfer::mls)
          Q = hn::MulAdd(hn::Set(d, static_cast<float>(dt * inv_D[b])), tau, Q);
        a = hn::MulAdd(Q, hn::Load(d, corner[b]), a);
        c[b] = hn::Mul(Q, hn::Set(d, static_cast<float>(g.h[b])));
      }
      s[b] = T == Transfer::mls ? hn::Zero(d) : hn::Mul(hn::Set(d, static_cast<float>(dt)), tau);
    }
    for (int b = 0; b < 3; ++b)
      for (int k = 0; k < N; ++k) {
        const VF u = b == 0 ? hn::MulAdd(hn::Set(d, static_cast<float>(k)), c[0], a)
                            : hn::Mul(hn::Set(d, static_cast<float>(k)), c[b]);
        hn::Store(hn::MulAdd(hn::Load(d, wl[b][k]), u, hn::Mul(hn::Load(d, dwl[b][k]), s[b])), d,
                  tl[b][k]);
      }
    for (int b = 0; b < 3; ++b) store_interleaved<N>(tl[b], pb.t[b][e]);
  }
  // From one lane per particle to N consecutive floats per particle, by interleaved stores.
  for (int a = 0; a < 3; ++a) store_interleaved<N>(wl[a], pb.w[a]);
}

/// Scatters order[begin, end) (the grid cleared): one lane per stencil node. For each
/// particle the node values are sums of products of three 1D factors (weights and the
/// per-axis momentum tables of ScatterBatch, made kLanes particles at a time), each looked up
/// per lane from an N-entry row.
///
/// Node layout in lanes: with at least N^2 lanes (AVX-512), one vector per plane i, node
/// (i, j, k) in lane j N + k. The (j, k) products are then formed once per particle and each
/// plane adds them times its x factors, broadcast: momentum e at (i, j, k) is
/// X_e(i) A + wx(i) B_e with A = wy wz and B_e = Y_e(j) wz + wy Z_e(k). With fewer lanes,
/// node n = (i N + j) N + k sits in lane n of NV vectors and takes all three factors by lookup.
/// With one lane fewer than N^2 (the quadratic kernel on AVX2: 8 lanes, 9 nodes a plane),
/// planes still: each plane's last node (i, N - 1, N - 1) goes to a tail vector instead, whose
/// lane i sums it from the particle's x rows as loaded, times the scalars A and B_e there
/// (eight lookups a particle, not the 48 of the node layout).
///
/// Long because it is the SIMD scatter's hot loop: the window's sums (acc) and its lane tables
/// stay in registers across the loop over particles and the slide along z; split into
/// functions they would be passed through memory.
template <Kernel K, Transfer T>
void scatter_range(const Particles& p, const ParticleOrder& ord, std::size_t begin, std::size_t end,
                   Real dt, std::span<const BatchModel> fold, Grid& g) {
  using Traits = KernelTraits<K>;
  constexpr int N = Traits::kNodes, kNodes = N * N * N;
  constexpr bool kTail = kLanes + 1 == static_cast<std::size_t>(N * N);
  constexpr bool kPlanes = kLanes >= static_cast<std::size_t>(N * N) || kTail;
  constexpr int NV = kPlanes ? N : static_cast<int>((kNodes + kLanes - 1) / kLanes);
  constexpr int NA = NV + (kTail ? 1 : 0);  // accumulator vectors per component
  constexpr int kSlots = NA * static_cast<int>(kLanes);
  const DF d;
  const DI di;
  // Per lane: the node's (i, j, k) as table indices (padding lanes: 0, summed but never
  // written); the lane of each node; and the lanes kept when the window slides along z
  // (below), where lane n takes lane n + 1's sums except in the new plane k = N - 1 and
  // padding, which start at zero.
  alignas(64) std::int32_t ti[kSlots], tj[kSlots], tk[kSlots], keep_bits[kSlots];
  alignas(64) std::int32_t rotate[kLanes];
  int lane_of[kNodes];
  for (int n = 0; n < NV * static_cast<int>(kLanes); ++n) {
    const int r = n % static_cast<int>(kLanes);
    const bool valid = kPlanes ? r < N * N : n < kNodes;
    const int i = kPlanes ? n / static_cast<int>(kLanes) : n / (N * N);
    const int jk = valid ? (kPlanes ? r : n % (N * N)) : 0;
    ti[n] = valid ? i : 0, tj[n] = jk / N, tk[n] = jk % N;
    keep_bits[n] = valid && jk % N != N - 1 ? -1 : 0;
    if (valid) lane_of[i * N * N + jk] = n;
  }
  if constexpr (kTail)  // node (i, N - 1, N - 1): the tail vector's lane i
    for (int i = 0; i < N; ++i) lane_of[(i + 1) * N * N - 1] = NV * static_cast<int>(kLanes) + i;
  for (std::size_t t = 0; t < kLanes; ++t) rotate[t] = static_cast<std::int32_t>((t + 1) % kLanes);
  const auto rot = hn::SetTableIndices(d, rotate);
  const auto last_lane = hn::RebindMask(
      d, hn::Eq(hn::Iota(di, 0), hn::Set(di, static_cast<std::int32_t>(kLanes - 1))));
  hn::Mask<DF> keep[NV];
  for (int v = 0; v < NV; ++v)
    keep[v] = hn::RebindMask(d, hn::Ne(hn::Load(di, keep_bits + v * kLanes), hn::Zero(di)));
  const bool fl = g.float_nodes;
  VF acc[4][NA];  // mass, momentum x, y, z per node, summed over the window's cells
  alignas(64) float out[4][kSlots];
  const auto spill = [&] {
    for (int a = 0; a < 4; ++a)
      for (int v = 0; v < NA; ++v) hn::Store(acc[a][v], d, out[a] + v * kLanes);
  };
  // Adds the window's sums of stencil nodes c * stride (numbered (i N + j) N + k), c < count,
  // to the grid at storage indices at[c], from `out` (where spill stores the sums).
  const auto add_nodes = [&fl, &g, &lane_of, &out](const std::size_t* at, int count, int stride) {
    for (int c = 0; c < count; ++c) {
      const std::size_t x = at[c];
      const int n = lane_of[c * stride];
      g.mass[x] = store_node(g.mass[x] + out[0][n], fl);
      for (int e = 0; e < 3; ++e)
        g.velocity[x][e] = store_node(g.velocity[x][e] + out[1 + e][n], fl);
    }
  };
  const auto flush_all = [&](const Vec3i& base) {
    spill();
    std::size_t at[kNodes];
    g.stencil_indices<N>(base, at);
    add_nodes(at, kNodes, 1);
  };
  StressBatch sb;
  ScatterBatch<N> pb;
  // The window: the sums of the particles of a run of cells along z, on the stencil of the
  // run's current cell `base`. Particles arrive sorted by cell (z fastest), so the next cell is
  // usually base + (0, 0, 1): the window then writes its plane k = 0, which no later cell of
  // the run touches, and slides (each node's sums move to lane k - 1, the new plane starts at
  // zero) instead of writing all N^3 nodes per cell.
  Vec3i base = Vec3i::Zero();
  bool open = false;
  // The cell of the run that starts at q. With the counting sort's offsets it is the next cell
  // whose run is not empty (only the slab's first is looked up by key): a key looked up through
  // `order` waits for memory, early in each cell's work.
  const bool offsets = !ord.counts.empty();
  std::uint32_t cell = 0;
  for (std::size_t q = begin; q < end;) {
    if (offsets && q > begin)
      for (++cell; ord.counts[cell + 1] == q;) ++cell;
    else
      cell = ord.keys[ord.order[q]];
    assert(cell == ord.keys[ord.order[q]]);
    if (q >= pb.b1) fill_batch<K, T>(p, ord, fold, g, dt, q, end, sb, pb);
    // The window sits on the sort's cell, whose blocks are active, whatever the lanes computed
    // (they agree: the lanes round as the sort does, tests/transfers/test_simd.cpp).
    const Vec3i next = ord.cell_base(cell);
    assert(next == Vec3i(pb.base[0][q - pb.b0], pb.base[1][q - pb.b0], pb.base[2][q - pb.b0]));
    if (open && next == base + Vec3i(0, 0, 1)) {
      spill();
      std::size_t at[N * N];
      for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j)
          at[N * i + j] = g.node_index(base.x() + i, base.y() + j, base.z());
      add_nodes(at, N * N, N);  // nodes (i, j, 0): c = i N + j
      for (auto& a : acc) {
        VF r[NV];
        for (int v = 0; v < NV; ++v) r[v] = hn::TableLookupLanes(a[v], rot);
        if constexpr (kTail) {  // plane v's lane kLanes - 1 takes its node (v, N - 1, N - 1)
          alignas(64) float tail[kLanes];
          hn::Store(a[NV], d, tail);
          for (int v = 0; v < NV; ++v) r[v] = hn::IfThenElse(last_lane, hn::Set(d, tail[v]), r[v]);
          a[NV] = hn::Zero(d);
        }
        for (int v = 0; v < NV; ++v)  // node layout: lane kLanes - 1 takes the next vector's 0
          a[v] = hn::IfThenElseZero(
              keep[v], !kPlanes && v + 1 < NV ? hn::IfThenElse(last_lane, r[v + 1], r[v]) : r[v]);
      }
    } else {
      if (open) flush_all(base);
      for (auto& a : acc)
        for (VF& v : a) v = hn::Zero(d);
    }
    base = next;
    open = true;
    // The end of the cell's run: its offset, else by scanning the keys.
    std::size_t cell_end = q + 1;
    if (offsets)
      cell_end = std::min<std::size_t>(end, ord.counts[cell + 1]);
    else
      while (cell_end < end && ord.keys[ord.order[cell_end]] == cell) ++cell_end;
    for (; q < cell_end; ++q) {
      if (q >= pb.b1) fill_batch<K, T>(p, ord, fold, g, dt, q, end, sb, pb);
      const std::size_t l = q - pb.b0;
      // Lanes 0 to N - 1 of a row hold the particle's weights and tables (the rest, its
      // neighbours', are never looked up).
      const auto row = [&](const float* r) { return hn::LoadU(d, r + N * l); };
      if constexpr (kPlanes) {
        const auto Ij = hn::SetTableIndices(d, tj), Ik = hn::SetTableIndices(d, tk);
        const VF wy = hn::TableLookupLanes(row(pb.w[1]), Ij);
        const VF wz = hn::TableLookupLanes(row(pb.w[2]), Ik);
        const VF A = hn::Mul(wy, wz), mA = hn::Mul(hn::Set(d, pb.m[l]), A);
        VF B[3];
        for (int e = 0; e < 3; ++e)
          B[e] = hn::MulAdd(hn::TableLookupLanes(row(pb.t[1][e]), Ij), wz,
                            hn::Mul(wy, hn::TableLookupLanes(row(pb.t[2][e]), Ik)));
        for (int i = 0; i < N; ++i) {
          const VF wx = hn::Set(d, pb.w[0][N * l + i]);
          acc[0][i] = hn::MulAdd(wx, mA, acc[0][i]);
          for (int e = 0; e < 3; ++e)
            acc[1 + e][i] = hn::MulAdd(hn::Set(d, pb.t[0][e][N * l + i]), A,
                                       hn::MulAdd(wx, B[e], acc[1 + e][i]));
        }
        if constexpr (kTail) {  // lane i: node (i, N - 1, N - 1), as a plane's lane computes it
          const auto last = [&](const float* r) { return hn::Set(d, r[N * l + N - 1]); };
          const VF wy2 = last(pb.w[1]), wz2 = last(pb.w[2]), A2 = hn::Mul(wy2, wz2);
          const VF wx = row(pb.w[0]);
          acc[0][NV] = hn::MulAdd(wx, hn::Mul(hn::Set(d, pb.m[l]), A2), acc[0][NV]);
          for (int e = 0; e < 3; ++e) {
            const VF B2 = hn::MulAdd(last(pb.t[1][e]), wz2, hn::Mul(wy2, last(pb.t[2][e])));
            acc[1 + e][NV] = hn::MulAdd(row(pb.t[0][e]), A2, hn::MulAdd(wx, B2, acc[1 + e][NV]));
          }
        }
      } else {
        VF W[3], X[3][3];
        for (int b = 0; b < 3; ++b) {
          W[b] = row(pb.w[b]);
          for (int e = 0; e < 3; ++e) X[b][e] = row(pb.t[b][e]);
        }
        const VF mv = hn::Set(d, pb.m[l]);
        for (int v = 0; v < NV; ++v) {
          const auto Ii = hn::SetTableIndices(d, ti + v * kLanes);
          const auto Ij = hn::SetTableIndices(d, tj + v * kLanes);
          const auto Ik = hn::SetTableIndices(d, tk + v * kLanes);
          const VF wx = hn::TableLookupLanes(W[0], Ii), wy = hn::TableLookupLanes(W[1], Ij),
                   wz = hn::TableLookupLanes(W[2], Ik);
          const VF wyz = hn::Mul(wy, wz), wxz = hn::Mul(wx, wz), wxy = hn::Mul(wx, wy);
          acc[0][v] = hn::MulAdd(mv, hn::Mul(wx, wyz), acc[0][v]);
          for (int e = 0; e < 3; ++e) {
            VF sum = hn::MulAdd(hn::TableLookupLanes(X[0][e], Ii), wyz, acc[1 + e][v]);
            sum = hn::MulAdd(hn::TableLookupLanes(X[1][e], Ij), wxz, sum);
            acc[1 + e][v] = hn::MulAdd(hn::TableLookupLanes(X[2][e], Ik), wxy, sum);
          }
        }
      }
    }
  }
  if (open) flush_all(base);
}

template <Kernel K, Transfer T>
void scatter_all(const Particles& p, const ParticleOrder& ord, Real dt,
                 std::span<const BatchModel> fold, Grid& g) {
  for_each_slab(ord, [&](int s) {
    scatter_range<K, T>(p, ord, ord.slab_start[s], ord.slab_start[s + 1], dt, fold, g);
  });
}

/// The stencil of particles [q0, q0 + count) (count <= kLanes, the last particle repeated in
/// unused lanes) per axis and lane: the base node, the distance fx - base (cells) and the
/// corner offset x_base - x (m), computed in double and rounded to float once.
template <Kernel K>
HWY_INLINE void gather_stencil(const Grid& g, const Particles& p, std::size_t q0, std::size_t count,
                               float (*dist)[kLanes], float (*corner)[kLanes],
                               std::int32_t (*base)[kLanes]) {
  using Traits = KernelTraits<K>;
  if (count == kLanes) {
    // A full batch: positions loaded three axes at a time into double lanes, the stencil
    // base, the distance to it and the corner offset computed there (as the scalar lines
    // below), each rounded to float once.
    const DD dd;
    const DF d;
    const DI di;
    VD x[3][kHalves];
    for (std::size_t h = 0; h < kHalves; ++h)
      hn::LoadInterleaved3(dd, p.x[q0 + h * hn::Lanes(dd)].data(), x[0][h], x[1][h], x[2][h]);
    for (int a = 0; a < 3; ++a) {
      VD c[kHalves], b[kHalves], t[kHalves];
      for (std::size_t h = 0; h < kHalves; ++h)
        t[h] = stencil_lanes<K>(dd, x[a][h], g, a, c[h], b[h]);
      hn::Store(join_lanes(d, t), d, dist[a]);
      hn::Store(join_lanes(d, c), d, corner[a]);
      hn::Store(join_lanes(di, b), di, base[a]);
    }
  } else {
    for (std::size_t l = 0; l < kLanes; ++l) {
      const std::size_t q = q0 + std::min(l, count - 1);
      for (int a = 0; a < 3; ++a) {
        const Real fx = (p.x[q][a] - g.origin[a]) * g.inv_h[a];
        base[a][l] = Traits::base(fx);
        dist[a][l] = static_cast<float>(fx - base[a][l]);
        corner[a][l] = static_cast<float>(g.origin[a] + base[a][l] * g.h[a] - p.x[q][a]);
      }
    }
  }
}

/// Writes lanes [0, count) of the gather's results to particles [q0, q0 + count): F from
/// out[0, 9), C from out[9, 18) (affine transfers only), v from out[18, 21), each column-major.
template <bool kAffine>
HWY_INLINE void store_gathered(const float (*out)[kLanes], std::size_t q0, std::size_t count,
                               Particles& p) {
  [[maybe_unused]] const DF d;
  if constexpr (kFloatMatrices)
    if (count == kLanes) {
      VF m[9];
      for (int e = 0; e < 9; ++e) m[e] = hn::Load(d, out[e]);
      store_matrices(m, p.F[q0].data());
      if constexpr (kAffine) {
        for (int e = 0; e < 9; ++e) m[e] = hn::Load(d, out[9 + e]);
        store_matrices(m, p.C[q0].data());
      }
    }
  if (!kFloatMatrices || count < kLanes)
    for (std::size_t l = 0; l < count; ++l) {
      const std::size_t q = q0 + l;
      StoredReal* F = p.F[q].data();
      for (int e = 0; e < 9; ++e) F[e] = static_cast<StoredReal>(out[e][l]);
      if constexpr (kAffine) {
        StoredReal* Cq = p.C[q].data();
        for (int e = 0; e < 9; ++e) Cq[e] = static_cast<StoredReal>(out[9 + e][l]);
      }
    }
  if (count == kLanes) {
    // Velocities widened to double in lanes and stored three axes at a time.
    const hn::ScalableTag<double> dd;
    const hn::Rebind<float, decltype(dd)> dh;
    for (std::size_t h = 0; h < kLanes; h += hn::Lanes(dd))
      hn::StoreInterleaved3(hn::PromoteTo(dd, hn::Load(dh, out[18] + h)),
                            hn::PromoteTo(dd, hn::Load(dh, out[19] + h)),
                            hn::PromoteTo(dd, hn::Load(dh, out[20] + h)), dd, p.v[q0 + h].data());
  } else {
    for (std::size_t l = 0; l < count; ++l) p.v[q0 + l] = Vec3(out[18][l], out[19][l], out[20][l]);
  }
}

/// Gathers particles [q0, q0 + count), count <= kLanes, one lane each (the last lane's
/// particle repeated in unused lanes, which are not written back). Their new velocities are
/// also left in `v` (one row per axis), where advect_batch takes them instead of reloading
/// the particles' v it has just stored. Long because it is the SIMD gather's hot kernel: its
/// cells' masks, the lanes' row offsets and the stencil's sums are vectors shared from one
/// job to the next; split into functions they would be passed through memory. Its jobs, in
/// order: the stencil (gather_stencil), the lanes' distinct cells, their rows of velocity_f,
/// weights, the node values, the stencil sums, C, F (load_matrix_lanes) and its update, then
/// the stores (store_gathered).
template <Kernel K, Transfer T>
void gather_batch(const Grid& g, Real dt, std::size_t q0, std::size_t count, Particles& p,
                  float (*v)[kLanes]) {
  using Traits = KernelTraits<K>;
  constexpr int N = Traits::kNodes;
  constexpr bool kAffine = T == Transfer::apic || T == Transfer::mls;
  constexpr bool kGrad = T != Transfer::mls;  // MLS updates F with C, not with grad w
  const DF d;
  const DI di;
  alignas(64) float dist[3][kLanes], corner[3][kLanes];
  alignas(64) std::int32_t base[3][kLanes];
  gather_stencil<K>(g, p, q0, count, dist, corner, base);
  hwy::Prefetch(&p.F[q0]);  // loaded after the sums
  // The distinct stencil cells of the lanes: with at most kMaxCells of them, each cell's node
  // velocities are loaded once and spread to its lanes by blends, instead of gathered lane by
  // lane. The values are the same either way. The reorder stage keeps a cell's particles
  // together, but between reorders the particles that cross a cell face interleave with those
  // that stay, so lanes are grouped by cell, not by runs of equal neighbours (two cells in
  // alternating lanes are two cells, not sixteen runs). 99 % of jello's batches and about 80 %
  // of two_cubes' span three or fewer; those blend with the count of cells known to the
  // compiler. A batch of more than kMaxCells (snow blown into dust: about 1.9 particles a cell)
  // gathers by index. With 16 lanes (AVX-512), blending up to 8 cells instead of 3 made
  // two_cubes' gather 17 % faster and snowball_paper's no slower; with 8 lanes, 3 was best on
  // the dust (docs/performance.md, thirtieth and thirty-third sessions).
  constexpr int kMaxCells = kLanes >= 16 ? static_cast<int>(kLanes / 2) : 3;
  std::size_t cell_lane[kMaxCells] = {};  // a lane of each cell
  hn::Mask<DF> in_cell[kMaxCells];
  int cells = 0;
  {
    const VI bx = hn::Load(di, base[0]), by = hn::Load(di, base[1]), bz = hn::Load(di, base[2]);
    auto left = hn::Eq(bx, bx);  // the lanes of no cell yet
    while (!hn::AllFalse(di, left)) {
      if (cells == kMaxCells) {
        ++cells;  // too many: gathered lane by lane
        break;
      }
      const std::size_t l = hn::FindKnownFirstTrue(di, left);
      const auto same =
          hn::And(hn::And(hn::Eq(bx, hn::Set(di, base[0][l])), hn::Eq(by, hn::Set(di, base[1][l]))),
                  hn::Eq(bz, hn::Set(di, base[2][l])));
      in_cell[cells] = hn::RebindMask(d, same);
      cell_lane[cells++] = l;
      left = hn::AndNot(same, left);
    }
  }
  const bool few = cells <= kMaxCells;
  std::uint32_t cell_rows[kMaxCells][N * N];  // each cell's rows of velocity_f
  if (few)
    for (int r = 0; r < cells; ++r) {
      const std::size_t l = cell_lane[r];
      g.stencil_rows<N>(Vec3i(base[0][l], base[1][l], base[2][l]), cell_rows[r]);
    }
  // Offset in velocity_f of row (i, j) of each lane's stencil, as Grid::stencil_rows computes
  // it: the slot of the row's block times row_block_floats(N), plus the row's offset in the
  // block and the stencil's z offset there. A stencil spans at most two blocks along x and y
  // (block b0 or b0 + 1: `up`), so the slots of the four blocks are gathered from the page
  // table once per batch and chosen per row by blends. A block the lane's stencil does not reach is
  // clamped into the domain and never chosen. Only for more than kMaxCells cells.
  VI off[2][N], slots[2][2], zoff;
  hn::Mask<DI> up[2][N];
  if (!few) {
    const std::int32_t stride[3] = {g.blocks.y() * g.blocks.z(), g.blocks.z(), 1};
    const VI mask = hn::Set(di, Grid::kBlockEdge - 1);
    VI page[2][2];
    for (int a = 0; a < 2; ++a) {
      const VI b = hn::Load(di, base[a]);
      const VI b0 = hn::ShiftRight<Grid::kBlockBits>(b);
      const VI last = hn::Set(di, g.blocks[a] - 1);
      for (int h = 0; h < 2; ++h)
        page[a][h] = hn::Mul(hn::Min(hn::Add(b0, hn::Set(di, h)), last), hn::Set(di, stride[a]));
      for (int t = 0; t < N; ++t) {
        const VI s = hn::Add(hn::And(b, mask), hn::Set(di, t));  // offset from block b0
        up[a][t] = hn::Gt(s, mask);
        const int row = 3 * Grid::row_nodes(N) * (a == 0 ? Grid::kBlockEdge : 1);
        off[a][t] = hn::Mul(hn::And(s, mask), hn::Set(di, row));
      }
    }
    const VI bz = hn::Load(di, base[2]);
    zoff = hn::Mul(hn::And(bz, mask), hn::Set(di, 3));
    const VI pz = hn::ShiftRight<Grid::kBlockBits>(bz);
    for (int x = 0; x < 2; ++x)
      for (int y = 0; y < 2; ++y)
        slots[x][y] = hn::Mul(
            hn::GatherIndex(di, g.slot.data(), hn::Add(hn::Add(page[0][x], page[1][y]), pz)),
            hn::Set(di, Grid::row_block_floats(N)));
  }
  // The 1D weights, their derivatives and t w_t (for the index moments) per axis and node, kept
  // in memory as the sums' operands: with 16 vector registers (AVX2) only the running sums
  // stay in registers.
  alignas(64) float w[3][N][kLanes], dw[3][N][kLanes], tw[3][N][kLanes];
  for (int a = 0; a < 3; ++a) {
    VF wa[N], dwa[N];
    lane_weights<K>(d, hn::Load(d, dist[a]), wa, dwa);
    const VF s = hn::Set(d, static_cast<float>(g.inv_h[a]));
    for (int t = 0; t < N; ++t) {
      hn::Store(wa[t], d, w[a][t]);
      hn::Store(hn::Mul(dwa[t], s), d, dw[a][t]);
      hn::Store(hn::Mul(hn::Set(d, static_cast<float>(t)), wa[t]), d, tw[a][t]);
    }
  }
  // The stencil's node velocities per component, node and lane. With at most kMaxCells cells
  // each cell's value is broadcast and blended into its lanes; else gathered lane by lane:
  // (x, y) pairs as one 64-bit value per lane (half the gathers' elements of two 32-bit
  // gathers), then split into x and y lanes, and z on its own.
  const float* vf = g.velocity_f.data();
  alignas(64) float nv[3][N * N * N][kLanes];
  const auto load_nodes = [&](auto kc) {
    // 1 to 3: that many cells; 0: more, blended with the count read at run time up to
    // kMaxCells (`few`), else gathered by index.
    constexpr int ncells = decltype(kc)::value;
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j) {
        const int n0 = (i * N + j) * N;
        if (ncells > 0 || few) {
          // Known to the compiler for one to three cells; four to kMaxCells counted at run time.
          const int count = ncells > 0 ? ncells : cells;
          const float* row[kMaxCells] = {};  // each cell's row (i, j)
          for (int r = 0; r < count; ++r) row[r] = vf + cell_rows[r][N * i + j];
          for (int k = 0; k < N; ++k)
            for (int e = 0; e < 3; ++e) {
              VF v = hn::Set(d, row[0][3 * k + e]);
              for (int r = 1; r < count; ++r)
                v = hn::IfThenElse(in_cell[r], hn::Set(d, row[r][3 * k + e]), v);
              hn::Store(v, d, nv[e][n0 + k]);
            }
        } else {
          const hn::Repartition<std::uint64_t, DF> du64;
          const hn::Repartition<std::int64_t, DF> di64;
          const hn::Half<DI> dih;
          const std::uint64_t* vel_xy = reinterpret_cast<const std::uint64_t*>(vf);
          const VI sij =
              hn::IfThenElse(up[1][j], hn::IfThenElse(up[0][i], slots[1][1], slots[0][1]),
                             hn::IfThenElse(up[0][i], slots[1][0], slots[0][0]));
          const VI rij = hn::Add(hn::Add(sij, zoff), hn::Add(off[0][i], off[1][j]));
          for (int k = 0; k < N; ++k) {
            const VI vi = hn::Add(rij, hn::Set(di, 3 * k));  // node (i, j, k)'s x
            const auto pair = [&](auto half) {  // byte offsets: a pair starts at any float
              return hn::BitCast(
                  d, hn::GatherOffset(du64, vel_xy, hn::ShiftLeft<2>(hn::PromoteTo(di64, half))));
            };
            const VF lo = pair(hn::LowerHalf(dih, vi)), hi = pair(hn::UpperHalf(dih, vi));
            hn::Store(hn::ConcatEven(d, hi, lo), d, nv[0][n0 + k]);
            hn::Store(hn::ConcatOdd(d, hi, lo), d, nv[1][n0 + k]);
            hn::Store(hn::GatherIndex(d, vf + 2, vi), d, nv[2][n0 + k]);
          }
        }
      }
  };
  if (cells == 1)
    load_nodes(std::integral_constant<int, 1>{});
  else if (cells == 2)
    load_nodes(std::integral_constant<int, 2>{});
  else if (cells == 3)
    load_nodes(std::integral_constant<int, 3>{});
  else
    load_nodes(std::integral_constant<int, 0>{});
  // Per component, the stencil's sums of v, grad v (column a: d/dx_a) and the index moments
  // sum w v (i, j, k) for B, separably: over k for each (i, j) (r), then over j for each i
  // (t), then over i (s), so that 15 running sums are live at a time.
  alignas(64) float sums[3][7][kLanes];  // v; grad v along x, y, z; moments i, j, k
  for (int e = 0; e < 3; ++e) {
    VF s[7];
    for (VF& x : s) x = hn::Zero(d);
    for (int i = 0; i < N; ++i) {
      VF t[5];  // sum over j of: w r0, dw r0, w r1, j w r0, w r2
      for (VF& x : t) x = hn::Zero(d);
      for (int j = 0; j < N; ++j) {
        VF r0 = hn::Zero(d), r1 = hn::Zero(d), r2 = hn::Zero(d);  // over k: w v, dw v, k w v
        for (int k = 0; k < N; ++k) {
          const VF v = hn::Load(d, nv[e][(i * N + j) * N + k]);
          r0 = hn::MulAdd(hn::Load(d, w[2][k]), v, r0);
          if constexpr (kGrad) r1 = hn::MulAdd(hn::Load(d, dw[2][k]), v, r1);
          if constexpr (kAffine)  // k = 0 adds 0 v
            if (k > 0) r2 = hn::MulAdd(hn::Load(d, tw[2][k]), v, r2);
        }
        const VF wj = hn::Load(d, w[1][j]);
        t[0] = hn::MulAdd(wj, r0, t[0]);
        if constexpr (kGrad) {
          t[1] = hn::MulAdd(hn::Load(d, dw[1][j]), r0, t[1]);
          t[2] = hn::MulAdd(wj, r1, t[2]);
        }
        if constexpr (kAffine) {
          if (j > 0) t[3] = hn::MulAdd(hn::Load(d, tw[1][j]), r0, t[3]);
          t[4] = hn::MulAdd(wj, r2, t[4]);
        }
      }
      const VF wi = hn::Load(d, w[0][i]);
      s[0] = hn::MulAdd(wi, t[0], s[0]);
      if constexpr (kGrad) {
        s[1] = hn::MulAdd(hn::Load(d, dw[0][i]), t[0], s[1]);
        s[2] = hn::MulAdd(wi, t[1], s[2]);
        s[3] = hn::MulAdd(wi, t[2], s[3]);
      }
      if constexpr (kAffine) {
        if (i > 0) s[4] = hn::MulAdd(hn::Load(d, tw[0][i]), t[0], s[4]);
        s[5] = hn::MulAdd(wi, t[3], s[5]);
        s[6] = hn::MulAdd(wi, t[4], s[6]);
      }
    }
    for (int c = 0; c < 7; ++c) hn::Store(s[c], d, sums[e][c]);
  }
  VF sv[3], sg[3][3], sb[3][3];
  for (int e = 0; e < 3; ++e) {
    sv[e] = hn::Load(d, sums[e][0]);
    for (int a = 0; a < 3; ++a) {
      sg[e][a] = hn::Load(d, sums[e][1 + a]);
      sb[e][a] = hn::Load(d, sums[e][4 + a]);
    }
  }
  VF Fin[9];  // F in lanes: Fin[e] holds entry e (column-major) of each lane's F
  load_matrix_lanes(&p.F[q0], count, Fin);
  // C = B D^-1 with B = v corner^T + sum w v (i, j, k)^T diag(h) (Jiang et al. 2015, eq. 8-10);
  // the linear kernel takes C = grad v (section 5.3).
  VF C[3][3];
  if constexpr (kAffine) {
    const Vec3 inv_D = Traits::kInvDScale * g.inv_h.cwiseProduct(g.inv_h);
    for (int a = 0; a < 3; ++a) {
      const VF ca = hn::Load(d, corner[a]);
      const VF ha = hn::Set(d, static_cast<float>(g.h[a]));
      const VF da = hn::Set(d, static_cast<float>(inv_D[a]));
      for (int e = 0; e < 3; ++e)
        C[e][a] = K == Kernel::linear ? sg[e][a]
                                      : hn::Mul(hn::MulAdd(sv[e], ca, hn::Mul(sb[e][a], ha)), da);
    }
  }
  // F <- (I + dt G) F with G = grad v (Stomakhin et al. 2013, eq. 7), or G = C for MLS (Hu et
  // al. 2018, eq. 17).
  const VF vdt = hn::Set(d, static_cast<float>(dt));
  alignas(64) float out[9 + 9 + 3][kLanes];
  for (int col = 0; col < 3; ++col)
    for (int r = 0; r < 3; ++r) {
      const VF f = Fin[3 * col + r];
      VF gf = hn::Zero(d);
      for (int k = 0; k < 3; ++k) {
        const VF G = kGrad ? sg[r][k] : C[r][k];
        gf = hn::MulAdd(G, Fin[3 * col + k], gf);
      }
      hn::Store(hn::MulAdd(vdt, gf, f), d, out[3 * col + r]);
    }
  if constexpr (kAffine)
    for (int col = 0; col < 3; ++col)
      for (int r = 0; r < 3; ++r) hn::Store(C[r][col], d, out[9 + 3 * col + r]);
  for (int e = 0; e < 3; ++e) {
    hn::Store(sv[e], d, out[18 + e]);
    hn::Store(sv[e], d, v[e]);
  }
  store_gathered<kAffine>(out, q0, count, p);
}

/// Advects particles [q0, q0 + count) with their new velocities: advect_particle, in double
/// lanes for a full batch, where x + dt v is one fused multiply-add on targets that have one
/// (AVX2, AVX-512), so a position may differ from advect_particle's in its last bit. A full
/// batch takes v from gather_batch's float rows `v` (widened to double, as store_gathered
/// widens them), not from the particles' v just stored.
void advect_batch(const AdvectBox& box, Real dt, std::size_t q0, std::size_t count,
                  const float (*v_rows)[kLanes], Particles& p, std::size_t& clamped,
                  std::size_t& nonfinite, Real& v2) {
  if (count < kLanes) {
    for (std::size_t q = q0; q < q0 + count; ++q)
      advect_particle(box, dt, p.v[q], p.x[q], clamped, nonfinite, v2);
    return;
  }
  const hn::ScalableTag<double> dd;
  using VD = hn::Vec<decltype(dd)>;
  const VD vdt = hn::Set(dd, dt);
  VD top = hn::Set(dd, v2);
  for (std::size_t h = 0; h < kLanes; h += hn::Lanes(dd)) {
    const hn::Rebind<float, decltype(dd)> dh;
    VD x[3], v[3];
    hn::LoadInterleaved3(dd, p.x[q0 + h].data(), x[0], x[1], x[2]);
    for (int a = 0; a < 3; ++a) v[a] = hn::PromoteTo(dd, hn::Load(dh, v_rows[a] + h));
    const VD s = hn::MulAdd(v[2], v[2], hn::MulAdd(v[1], v[1], hn::Mul(v[0], v[0])));
    top = hn::IfThenElse(hn::Lt(top, s), s, top);  // std::max(top, s): a NaN speed is not kept
    VD moved[3], c[3];
    auto finite = hn::IsFinite(hn::Zero(dd));
    auto moved_out = hn::Lt(hn::Zero(dd), hn::Zero(dd));
    for (int a = 0; a < 3; ++a) {
      moved[a] = hn::MulAdd(vdt, v[a], x[a]);
      finite = hn::And(finite, hn::IsFinite(moved[a]));
      c[a] = hn::Min(hn::Max(moved[a], hn::Set(dd, box.lo[a])), hn::Set(dd, box.hi[a]));
      moved_out = hn::Or(moved_out, hn::Ne(c[a], moved[a]));
    }
    nonfinite += hn::CountTrue(dd, hn::Not(finite));
    clamped += hn::CountTrue(dd, hn::And(finite, moved_out));
    hn::StoreInterleaved3(hn::IfThenElse(finite, c[0], x[0]), hn::IfThenElse(finite, c[1], x[1]),
                          hn::IfThenElse(finite, c[2], x[2]), dd, p.x[q0 + h].data());
  }
  v2 = hn::GetLane(hn::MaxOfLanes(dd, top));
}

/// Gathers (and with `advect` advects) particles [first, last) on the calling thread, in the
/// lane sets gather_all makes of them (`first` a multiple of kLanes), adding the advection's
/// counts and speed to `advect`.
template <Kernel K, Transfer T>
void gather_range(const Grid& g, Real dt, Particles& p, std::size_t first, std::size_t last,
                  AdvectStats* advect) {
  const AdvectBox box(g);
  std::size_t clamped = 0, nonfinite = 0;
  Real v2 = 0;
  for (std::size_t q0 = first; q0 < last; q0 += kLanes) {
    const std::size_t count = std::min(kLanes, last - q0);
    alignas(64) float v[3][kLanes];
    gather_batch<K, T>(g, dt, q0, count, p, v);
    if (advect) advect_batch(box, dt, q0, count, v, p, clamped, nonfinite, v2);
  }
  if (!advect) return;
  advect->clamped += clamped;
  advect->nonfinite += nonfinite;
  advect->max_speed = std::max(advect->max_speed, std::sqrt(v2));
}

template <Kernel K, Transfer T>
void gather_all(const Grid& g, Real dt, Particles& p, AdvectStats* advect) {
  const std::size_t n = p.size();
  const std::ptrdiff_t batches = static_cast<std::ptrdiff_t>((n + kLanes - 1) / kLanes);
  const AdvectBox box(g);
  std::size_t clamped = 0, nonfinite = 0;
  Real v2 = 0;
  // Handed out by Shares, 16 lane sets at a time: each thread first gathers its own part of
  // the particles, whose nodes its scatter left in its caches, then what is left of the
  // other's. Every particle's values are its own, so they do not depend on the schedule.
  const bool par = n >= kParallelMinItems;
  Shares shares(static_cast<std::size_t>(batches), par ? omp_get_max_threads() : 1, 16);
#pragma omp parallel reduction(+ : clamped, nonfinite) reduction(max : v2) if (par)
  {
    std::size_t first = 0, last = 0;
    while (shares.next(first, last))
      for (std::size_t b = first; b < last; ++b) {
        const std::size_t q0 = b * kLanes;
        const std::size_t count = std::min(kLanes, n - q0);
        alignas(64) float v[3][kLanes];
        gather_batch<K, T>(g, dt, q0, count, p, v);
        if (advect) advect_batch(box, dt, q0, count, v, p, clamped, nonfinite, v2);
      }
  }
  if (advect) *advect = {clamped, nonfinite, std::sqrt(v2)};
}

/// cell_keys with kernel K: the keys of whole lane sets of particles from `first`.
template <Kernel K>
std::size_t cell_keys(const Particles& p, const Grid& g, const Vec3i& lo, const Vec3i& ext,
                      std::size_t first, std::size_t last, std::uint32_t* keys,
                      std::int32_t* bases) {
  const DD dd;
  const hn::Rebind<std::int32_t, DD> di32;
  const std::size_t L = hn::Lanes(dd), end = first + (last - first) / L * L;
  for (std::size_t q = first; q < end; q += L) {
    VD x[3], corner, base[3];
    hn::LoadInterleaved3(dd, p.x[q].data(), x[0], x[1], x[2]);
    for (int a = 0; a < 3; ++a) stencil_lanes<K>(dd, x[a], g, a, corner, base[a]);
    if (bases)
      hn::StoreInterleaved3(hn::DemoteTo(di32, base[0]), hn::DemoteTo(di32, base[1]),
                            hn::DemoteTo(di32, base[2]), di32, bases + 3 * (q - first));
    for (int a = 0; a < 3; ++a)  // small integers: exact in double
      base[a] = hn::Sub(base[a], hn::Set(dd, lo[a]));
    // (k_x ext_y + k_y) ext_z + k_z, below 2^31 (cells <= 2 n): exact in double.
    const VD key = hn::Add(
        hn::Mul(hn::Add(hn::Mul(base[0], hn::Set(dd, ext.y())), base[1]), hn::Set(dd, ext.z())),
        base[2]);
    hn::StoreU(hn::DemoteTo(di32, key), di32, reinterpret_cast<std::int32_t*>(keys + q));
  }
  return end - first;
}

/// Calls f.template operator()<K, T>() for the transfers the SIMD path handles.
template <class Fn>
void dispatch(Transfer t, Kernel k, Fn&& f) {
  dispatch_kernel(k, [&]<Kernel K>() {
    switch (t) {
      case Transfer::apic:
        f.template operator()<K, Transfer::apic>();
        break;
      case Transfer::pic:
        f.template operator()<K, Transfer::pic>();
        break;
      case Transfer::mls:
        if constexpr (K != Kernel::linear)
          f.template operator()<K, Transfer::mls>();
        else
          throw std::invalid_argument("MLS needs the quadratic or cubic kernel");
        break;
      case Transfer::flip:
        throw std::invalid_argument("the SIMD transfers do not handle FLIP");
    }
  });
}

}  // namespace

void ScatterImpl(const Particles& p, const ParticleOrder& ord, Transfer t, Kernel k, Real dt,
                 std::span<const BatchModel> fold, Grid& g) {
  dispatch(t, k, [&]<Kernel K, Transfer T>() { scatter_all<K, T>(p, ord, dt, fold, g); });
}

void GatherImpl(const Grid& g, Transfer t, Kernel k, Real dt, Particles& p, AdvectStats* advect) {
  dispatch(t, k, [&]<Kernel K, Transfer T>() { gather_all<K, T>(g, dt, p, advect); });
}

void GatherRangeImpl(const Grid& g, Transfer t, Kernel k, Real dt, Particles& p, std::size_t first,
                     std::size_t last, AdvectStats* advect) {
  if (first % kLanes != 0) throw std::invalid_argument("gather_range: first not a lane multiple");
  dispatch(t, k,
           [&]<Kernel K, Transfer T>() { gather_range<K, T>(g, dt, p, first, last, advect); });
}

std::size_t CellKeysImpl(const Particles& p, Kernel kernel, const Grid& g, const Vec3i& lo,
                         const Vec3i& ext, std::size_t first, std::size_t last, std::uint32_t* keys,
                         std::int32_t* bases) {
  std::size_t done = 0;
  dispatch_kernel(
      kernel, [&]<Kernel K>() { done = cell_keys<K>(p, g, lo, ext, first, last, keys, bases); });
  return done;
}

const char* TargetImpl() {
  return hwy::TargetName(HWY_TARGET);
}
#endif  // HWY_TARGET == HWY_SCALAR

}  // namespace HWY_NAMESPACE
}  // namespace mpm::simd
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace mpm::simd {

HWY_EXPORT(ScatterImpl);
HWY_EXPORT(GatherImpl);
HWY_EXPORT(GatherRangeImpl);
HWY_EXPORT(CellKeysImpl);
HWY_EXPORT(TargetImpl);

bool supports(Transfer transfer, Kernel, const Grid& grid) {
  // velocity_f's offsets are 32-bit
  return target_name() != nullptr && transfer != Transfer::flip &&
         grid.mass.size() / Grid::kBlockNodes * Grid::row_block_floats(4) < (std::size_t{1} << 31);
}

void scatter(const Particles& p, const ParticleOrder& order, Transfer transfer, Kernel kernel,
             Real dt, Grid& grid, std::span<const BatchModel> fold) {
  HWY_DYNAMIC_DISPATCH(ScatterImpl)(p, order, transfer, kernel, dt, fold, grid);
}

void gather(const Grid& grid, Transfer transfer, Kernel kernel, Real dt, Particles& p,
            AdvectStats* advect) {
  prepare_gather(grid, kernel);
  HWY_DYNAMIC_DISPATCH(GatherImpl)(grid, transfer, kernel, dt, p, advect);
}

void prepare_gather(const Grid& grid, Kernel kernel) {
  // Node velocities in float for the lane gathers, in rows along z (Grid::velocity_f): row
  // (i, j) of a block holds its nodes (i, j, 0 to 3), then the first N - 1 of the next block
  // along z (zero where that block has no storage: no stencil reaches into it), so a
  // stencil's nodes along z are consecutive in memory wherever it starts.
  dispatch_kernel(kernel, [&]<Kernel K>() {
    constexpr int E = Grid::kBlockEdge, R = Grid::row_nodes(KernelTraits<K>::kNodes);
    constexpr int kBlockFloats = Grid::row_block_floats(KernelTraits<K>::kNodes);
    const std::ptrdiff_t nb = static_cast<std::ptrdiff_t>(grid.active_blocks());
    grid.velocity_f.resize(static_cast<std::size_t>(nb) * kBlockFloats);
#pragma omp parallel for schedule(static) if (nb * Grid::kBlockNodes >= kParallelMinItems)
    for (std::ptrdiff_t b = 0; b < nb; ++b) {
      const Vec3i o = grid.block_first[b] / E;
      const std::int32_t next =
          o.z() + 1 < grid.blocks.z() ? grid.slot[grid.page(o.x(), o.y(), o.z() + 1)] : -1;
      const double* own = grid.velocity[b * Grid::kBlockNodes].data();
      const double* after = next < 0 ? nullptr : grid.velocity[next * Grid::kBlockNodes].data();
      float* out = grid.velocity_f.data() + b * kBlockFloats;
      for (int ij = 0; ij < E * E; ++ij, out += 3 * R) {  // row (i, j): nodes ij E + k
        for (int c = 0; c < 3 * E; ++c) out[c] = static_cast<float>(own[3 * E * ij + c]);
        for (int c = 3 * E; c < 3 * R; ++c)
          out[c] = after ? static_cast<float>(after[3 * E * ij + c - 3 * E]) : 0.0f;
      }
    }
  });
}

void gather_range(const Grid& grid, Transfer transfer, Kernel kernel, Real dt, Particles& p,
                  std::size_t first, std::size_t last, AdvectStats* advect) {
  HWY_DYNAMIC_DISPATCH(GatherRangeImpl)(grid, transfer, kernel, dt, p, first, last, advect);
}

std::size_t cell_keys(const Particles& p, Kernel kernel, const Grid& grid, const Vec3i& lo,
                      const Vec3i& ext, std::size_t first, std::size_t last, std::uint32_t* keys,
                      std::int32_t* bases) {
  return HWY_DYNAMIC_DISPATCH(CellKeysImpl)(p, kernel, grid, lo, ext, first, last, keys, bases);
}

const char* target_name() {
  return HWY_DYNAMIC_DISPATCH(TargetImpl)();
}

bool force_target(const std::string& name) {
  hwy::SetSupportedTargetsForTest(0);  // the CPU's own list, whatever was forced before
  if (name.empty()) return true;
  for (const std::int64_t target : hwy::SupportedAndGeneratedTargets()) {
    if (name != hwy::TargetName(target)) continue;
    hwy::SetSupportedTargetsForTest(target);
    if (HWY_DYNAMIC_DISPATCH(TargetImpl)()) return true;
    hwy::SetSupportedTargetsForTest(0);
  }
  return false;
}

void for_each_target(const std::function<void(const char*)>& f) {
  struct Restore {  // the normal dispatch again, also when f throws
    ~Restore() { force_target(""); }
  } restore;
  for (const std::int64_t target : hwy::SupportedAndGeneratedTargets())
    if (force_target(hwy::TargetName(target))) f(hwy::TargetName(target));
}

}  // namespace mpm::simd
#endif  // HWY_ONCE
