// Every built-in model the engine runs in float SIMD lanes, one particle per lane: the stress
// (-V0 tau) of fixed corotated, snow, Neo-Hookean, Tait water and Drucker-Prager sand, and the
// return maps of snow and sand. Highway per-target code, included inside HWY_NAMESPACE by each
// file compiled with foreach_target (stress_simd.cpp, and the scatter in transfer_simd.cpp).
// neg_v0_tau and project are the one switch from BatchModel::Kind to lane kernel.

// Include guard that toggles once per target (Highway's convention for -inl.h headers).
#if defined(MPM_SIMD_MATERIALS_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef MPM_SIMD_MATERIALS_INL_H_
#undef MPM_SIMD_MATERIALS_INL_H_
#else
#define MPM_SIMD_MATERIALS_INL_H_
#endif

#include <hwy/contrib/math/math-inl.h>
#include <hwy/highway.h>

#include <cmath>
#include <cstdint>

#include "engine/step/simd/corotated-inl.h"
#include "materials/material.h"
#include "materials/neo_hookean.h"
#include "materials/sand.h"
#include "materials/water.h"

HWY_BEFORE_NAMESPACE();
namespace mpm::simd {
namespace HWY_NAMESPACE {
namespace lanes {

namespace hn = hwy::HWY_NAMESPACE;

/// Per-lane parameters of a stress kernel: what lane_params gives for each kind.
constexpr int kParams = 4;

/// The parameter that holds the particle's plastic state (snow's Jp).
constexpr int kStateParam = 3;

/// The kParams per-lane values of `m` for one particle whose plastic state is `state` (snow's
/// Jp; unused by the others): corotated 2 mu, lambda; snow 2 mu0, lambda0, xi, Jp;
/// Neo-Hookean mu, lambda; water K, gamma; sand mu, lambda.
inline void lane_params(const BatchModel& m, Real state, float out[kParams]) {
  using K = BatchModel::Kind;
  const bool twice = m.kind == K::fixed_corotated || m.kind == K::snow;
  out[0] = static_cast<float>(m.kind == K::water ? m.bulk_modulus : (twice ? 2 : 1) * m.mu);
  out[1] = static_cast<float>(m.kind == K::water ? m.gamma : m.lambda);
  out[2] = static_cast<float>(m.hardening);
  out[kStateParam] = static_cast<float>(state);
}

/// The eigen-decomposition of the symmetric matrix with entries a00 .. a12, per lane: its
/// eigenvalues in `l` and a proper rotation whose columns are the eigenvectors in `v`
/// (column-major), unsorted. Cyclic Jacobi with the rotations of materials/svd.h's
/// symmetric_eigen (Press et al., "Numerical Recipes", section 11.1), swept until every lane's
/// off-diagonal part has fallen below float round-off, at most 6 sweeps (Jacobi converges
/// quadratically: 3 to 4 sweeps reach float accuracy from any start). A lane that has
/// converged is left alone by the later sweeps, so its result does not depend on the others.
template <class D, class V = hn::Vec<D>>
void symmetric_eigen(D d, V a00, V a11, V a22, V a01, V a02, V a12, V l[3], V v[9]) {
  const V zero = hn::Zero(d), one = hn::Set(d, 1.0f), two = hn::Set(d, 2.0f);
  for (int e = 0; e < 9; ++e) v[e] = e % 4 == 0 ? one : zero;
  auto active = hn::Eq(zero, zero);
  // One rotation in the (p, q) plane that zeroes apq; r is the third index.
  const auto rotate = [&](V& app, V& aqq, V& apq, V& arp, V& arq, int p, int q) {
    const V b = apq, dd = hn::Sub(aqq, app), ad = hn::Abs(dd);
    const V r = hn::Sqrt(hn::MulAdd(dd, dd, hn::Mul(hn::Set(d, 4.0f), hn::Mul(b, b))));
    const V sb = hn::IfThenElse(hn::Lt(dd, zero), hn::Mul(hn::Neg(two), b), hn::Mul(two, b));
    const V rad = hn::Add(r, ad);
    const auto none = hn::Or(hn::Eq(r, zero), hn::Not(active));  // diagonal, or converged
    const V safe = hn::IfThenElse(none, one, rad);
    const V inv_h =
        hn::Div(one, hn::Sqrt(hn::Mul(two, hn::Mul(hn::IfThenElse(none, one, r), safe))));
    const V c = hn::IfThenElse(none, one, hn::Mul(rad, inv_h));
    const V s = hn::IfThenElse(none, zero, hn::Mul(sb, inv_h));
    const V t = hn::IfThenElse(none, zero, hn::Div(sb, safe));
    app = hn::NegMulAdd(t, b, app);
    aqq = hn::MulAdd(t, b, aqq);
    apq = hn::IfThenElse(active, zero, apq);
    const V rp = arp, rq = arq;
    arp = hn::MulSub(c, rp, hn::Mul(s, rq));
    arq = hn::MulAdd(s, rp, hn::Mul(c, rq));
    for (int k = 0; k < 3; ++k) {
      const V vp = v[3 * p + k], vq = v[3 * q + k];
      v[3 * p + k] = hn::MulSub(c, vp, hn::Mul(s, vq));
      v[3 * q + k] = hn::MulAdd(s, vp, hn::Mul(c, vq));
    }
  };
  const V scale = hn::MulAdd(a00, a00, hn::MulAdd(a11, a11, hn::Mul(a22, a22)));
  const V tol = hn::Mul(hn::Set(d, 1e-14f), scale);
  for (int sweep = 0; sweep < 6; ++sweep) {
    const V off = hn::MulAdd(a01, a01, hn::MulAdd(a02, a02, hn::Mul(a12, a12)));
    active = hn::Gt(off, tol);
    if (hn::AllFalse(d, active)) break;
    rotate(a00, a11, a01, a02, a12, 0, 1);
    rotate(a00, a22, a02, a01, a12, 0, 2);
    rotate(a11, a22, a12, a01, a02, 1, 2);
  }
  l[0] = a00, l[1] = a11, l[2] = a22;
}

/// The lanes set in `m` among the first `count`, as bits (lane l: bit l).
template <class D>
std::uint64_t mask_bits(D d, hn::Mask<D> m, std::size_t count) {
  if (hn::AllFalse(d, m)) return 0;
  alignas(8) std::uint8_t bits[8] = {};
  hn::StoreMaskBits(d, m, bits);
  std::uint64_t out = 0;
  for (int b = 0; b < 8; ++b) out |= std::uint64_t{bits[b]} << (8 * b);
  return count >= 64 ? out : out & ((std::uint64_t{1} << count) - 1);
}

/// det F, F column-major (f[3 c + r] = F(r, c)).
template <class D, class V = hn::Vec<D>>
V determinant(D, const V f[9]) {
  const V k0 = hn::MulSub(f[4], f[8], hn::Mul(f[5], f[7]));
  const V k1 = hn::MulSub(f[5], f[6], hn::Mul(f[3], f[8]));
  const V k2 = hn::MulSub(f[3], f[7], hn::Mul(f[4], f[6]));
  return hn::MulAdd(f[0], k0, hn::MulAdd(f[1], k1, hn::Mul(f[2], k2)));
}

/// Row a of F dotted with row b (F F^T), or column a with column b (F^T F) when `columns`.
template <bool columns, class V>
V gram(const V f[9], int a, int b) {
  const auto at = [&](int i, int k) { return columns ? f[3 * i + k] : f[3 * k + i]; };
  return hn::MulAdd(at(a, 0), at(b, 0),
                    hn::MulAdd(at(a, 1), at(b, 1), hn::Mul(at(a, 2), at(b, 2))));
}

/// -V0 tau = -V0 (mu F F^T + g'(J) J I) of Neo-Hookean (materials/neo_hookean.h: Bonet and
/// Wood eq. 6.27, g'(J) J = lambda log J - mu, continued linearly in g' below kJMin).
template <class D, class V = hn::Vec<D>>
void neo_hookean(D d, const V f[9], V mu, V lambda, V neg_v0, V out[9]) {
  const V J = determinant(d, f);
  const V k = hn::Set(d, static_cast<float>(materials::NeoHookean::kJMin));
  const V log_k = hn::Set(d, static_cast<float>(std::log(materials::NeoHookean::kJMin)));
  const V above = hn::MulSub(lambda, hn::Log(d, hn::Max(J, k)), mu);
  // (g'(k) + g''(k) (J - k)) J below kJMin.
  const V dg = hn::Div(hn::MulSub(lambda, log_k, mu), k);
  const V d2g = hn::Div(hn::Sub(hn::Add(lambda, mu), hn::Mul(lambda, log_k)), hn::Mul(k, k));
  const V below = hn::Mul(hn::MulAdd(d2g, hn::Sub(J, k), dg), J);
  const V bulk = hn::Mul(neg_v0, hn::IfThenElse(hn::Lt(J, k), below, above));
  const V a = hn::Mul(neg_v0, mu);
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) {
      const V t = hn::Mul(a, gram<false>(f, r, c));
      out[3 * c + r] = r == c ? hn::Add(t, bulk) : t;
    }
}

/// -V0 tau = V0 p(J) J I of Tait water (materials/water.h), p = K / gamma (J^-gamma - 1) with
/// J held at kJMin and above.
template <class D, class V = hn::Vec<D>>
void water(D d, const V f[9], V K, V gamma, V neg_v0, V out[9]) {
  const V J = determinant(d, f);
  const V Jc = hn::Max(J, hn::Set(d, static_cast<float>(materials::TaitWater::kJMin)));
  const V pow = hn::Exp(d, hn::Mul(hn::Neg(gamma), hn::Log(d, Jc)));
  const V p = hn::Mul(hn::Div(K, gamma), hn::Sub(pow, hn::Set(d, 1.0f)));
  const V diag = hn::Neg(hn::Mul(neg_v0, hn::Mul(p, J)));
  for (int e = 0; e < 9; ++e) out[e] = e % 4 == 0 ? diag : hn::Zero(d);
}

/// -V0 tau = -V0 U (2 mu eps + lambda tr(eps) I) U^T of sand's St. Venant-Kirchhoff on the
/// Hencky strain (Klar et al. 2016, section 7), with U and Sigma^2 the eigen-decomposition of
/// F F^T and eps = log Sigma (Sigma floored at kSigmaMin), as materials/sand.h.
template <class D, class V = hn::Vec<D>>
void sand(D d, const V f[9], V mu, V lambda, V neg_v0, V out[9]) {
  V s2[3], u[9];
  symmetric_eigen(d, gram<false>(f, 0, 0), gram<false>(f, 1, 1), gram<false>(f, 2, 2),
                  gram<false>(f, 0, 1), gram<false>(f, 0, 2), gram<false>(f, 1, 2), s2, u);
  const float floor = static_cast<float>(materials::DruckerPragerSand::kSigmaMin);
  const V floor2 = hn::Set(d, floor * floor), half = hn::Set(d, 0.5f);
  V eps[3];
  for (int i = 0; i < 3; ++i) eps[i] = hn::Mul(half, hn::Log(d, hn::Max(s2[i], floor2)));
  const V bulk = hn::Mul(lambda, hn::Add(eps[0], hn::Add(eps[1], eps[2])));
  V t[3];
  for (int i = 0; i < 3; ++i) t[i] = hn::Mul(neg_v0, hn::MulAdd(hn::Add(mu, mu), eps[i], bulk));
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) {
      const auto U = [&](int row, int i) { return u[3 * i + row]; };
      out[3 * c + r] = hn::MulAdd(
          hn::Mul(t[0], U(r, 0)), U(c, 0),
          hn::MulAdd(hn::Mul(t[1], U(r, 1)), U(c, 1), hn::Mul(hn::Mul(t[2], U(r, 2)), U(c, 2))));
    }
}

/// -V0 tau of a lane batch of kind `kind`, per-lane parameters `p` (lane_params) and volumes
/// `neg_v0` (-V0). Returns the lanes to redo in double (only fixed corotated and snow have
/// any: corotated::neg_v0_tau's fallbacks).
template <class D, class V = hn::Vec<D>>
hn::Mask<D> neg_v0_tau(BatchModel::Kind kind, D d, const V f[9], const V p[kParams], V neg_v0,
                       V out[9]) {
  using K = BatchModel::Kind;
  switch (kind) {
    case K::fixed_corotated:
      return corotated::neg_v0_tau(d, f, p[0], p[1], neg_v0, out);
    case K::snow: {
      // Stomakhin et al. 2013, eq. 3: mu, lambda scaled by exp(xi (1 - Jp)).
      const V h = hn::Exp(d, hn::Mul(p[2], hn::Sub(hn::Set(d, 1.0f), p[kStateParam])));
      return corotated::neg_v0_tau(d, f, hn::Mul(p[0], h), hn::Mul(p[1], h), neg_v0, out);
    }
    case K::neo_hookean:
      neo_hookean(d, f, p[0], p[1], neg_v0, out);
      break;
    case K::water:
      water(d, f, p[0], p[1], neg_v0, out);
      break;
    case K::sand:
      sand(d, f, p[0], p[1], neg_v0, out);
      break;
    case K::none:
    case K::group:  // a virtual call per batch, made by the caller (transfer_simd.cpp)
      break;
  }
  return hn::FirstN(d, 0);
}

/// The change F V diag(d) V^T of F V diag(1 + d) V^T, per lane, into `df` (zero where `m` is
/// not set). A return map moves F by a small d, so the change's float error is far below F's
/// own rounding: F + df, added in F's storage, comes out as if computed in double and rounded
/// once (runs on 1 and 2 ranks, whose inputs differ by round-off, then stay as close as with
/// the double map), and d = 0 leaves F exactly.
template <class D, class V = hn::Vec<D>, class M = hn::Mask<D>>
void change(M m, const V f[9], const V v[9], const V d[3], V df[9]) {
  // F V, then times diag(d) V^T.
  V fv[9];
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r)
      fv[3 * c + r] = hn::MulAdd(
          f[r], v[3 * c], hn::MulAdd(f[3 + r], v[3 * c + 1], hn::Mul(f[6 + r], v[3 * c + 2])));
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) {
      const V x = hn::MulAdd(hn::Mul(fv[r], d[0]), v[c],
                             hn::MulAdd(hn::Mul(fv[3 + r], d[1]), v[3 + c],
                                        hn::Mul(hn::Mul(fv[6 + r], d[2]), v[6 + c])));
      df[3 * c + r] = hn::IfThenElseZero(m, x);
    }
}

/// Snow's clamp of the elastic singular values to [lo, hi] (Stomakhin et al. 2013, section 7;
/// materials/snow.h, SnowPlasticity::project) of the lanes' F, as the change `df`. The common case,
/// every singular value inside with det F > 0, is found without a decomposition (C = F^T F with C -
/// lo^2 I and hi^2 I - C positive definite); for the others F^T F = V Sigma^2 V^T gives F_e = F V
/// diag(clamp(Sigma) / Sigma) V^T (U = F V Sigma^-1), and `growth` receives det Sigma / det
/// clamp(Sigma) - 1, Jp's relative change (0 where F is kept), formed from the small per-value
/// changes so that Jp can be updated in double. Sets `changed` to the lanes whose F changed and
/// returns the lanes to redo in double (det F <= 0, or a singular value below 0.01).
template <class D, class V = hn::Vec<D>, class M = hn::Mask<D>>
M snow_project(D d, const V f[9], V lo, V hi, V& growth, M& changed, V df[9]) {
  const V c00 = gram<true>(f, 0, 0), c11 = gram<true>(f, 1, 1), c22 = gram<true>(f, 2, 2);
  const V c01 = gram<true>(f, 0, 1), c02 = gram<true>(f, 0, 2), c12 = gram<true>(f, 1, 2);
  const V zero = hn::Zero(d);
  // Sylvester's criterion on C + k I for k = -lo^2 (sign +1) and on -(C - hi^2 I).
  const auto positive = [&](V k, V sign) {
    const V a = hn::Mul(sign, hn::Add(c00, k)), b = hn::Mul(sign, hn::Add(c11, k));
    const V c = hn::Mul(sign, hn::Add(c22, k));
    const V x = hn::Mul(sign, c01), y = hn::Mul(sign, c02), z = hn::Mul(sign, c12);
    const V m2 = hn::MulSub(a, b, hn::Mul(x, x));
    const V det = hn::Add(hn::Sub(hn::Mul(a, hn::MulSub(b, c, hn::Mul(z, z))),
                                  hn::Mul(x, hn::MulSub(x, c, hn::Mul(z, y)))),
                          hn::Mul(y, hn::MulSub(x, z, hn::Mul(b, y))));
    return hn::And(hn::Gt(a, zero), hn::And(hn::Gt(m2, zero), hn::Gt(det, zero)));
  };
  const V one = hn::Set(d, 1.0f);
  const V J = determinant(d, f);
  const auto inside =
      hn::And(hn::Gt(J, zero), hn::And(positive(hn::Neg(hn::Mul(lo, lo)), one),
                                       positive(hn::Neg(hn::Mul(hi, hi)), hn::Neg(one))));
  changed = hn::Not(inside);
  growth = zero;
  if (hn::AllTrue(d, inside)) {
    for (int e = 0; e < 9; ++e) df[e] = zero;
    return hn::FirstN(d, 0);
  }
  V s2[3], v[9];
  symmetric_eigen(d, c00, c11, c22, c01, c02, c12, s2, v);
  V dc[3], q[3];  // clamp(sigma) / sigma - 1, and sigma / clamp(sigma) - 1
  for (int i = 0; i < 3; ++i) {
    const V s = hn::Sqrt(hn::Max(s2[i], zero));
    const V c = hn::Min(hn::Max(s, lo), hi);
    dc[i] = hn::Div(hn::Sub(c, s), hn::Max(s, hn::Set(d, 1e-30f)));
    q[i] = hn::Div(hn::Sub(s, c), c);
  }
  // (1 + q0)(1 + q1)(1 + q2) - 1, without the cancellation of forming the product first.
  const V q01 = hn::Mul(q[0], q[1]);
  const V g = hn::Add(hn::Add(hn::Add(q[0], q[1]), q[2]),
                      hn::MulAdd(q01, q[2], hn::Add(q01, hn::Mul(q[2], hn::Add(q[0], q[1])))));
  const auto bad = hn::And(
      changed,
      hn::Or(hn::Le(J, zero), hn::Lt(hn::Min(s2[0], hn::Min(s2[1], s2[2])), hn::Set(d, 1e-4f))));
  changed = hn::AndNot(bad, changed);
  growth = hn::IfThenElse(changed, g, zero);
  change<D>(changed, f, v, dc, df);
  return bad;
}

/// Sand's return map onto the Drucker-Prager cone on the Hencky strain (Klar et al. 2016,
/// section 7.3, its three cases; materials/sand.h, DruckerPragerSand::project) of the lanes' F,
/// as the change `df`, for volume corrections `vc`: F^T F = V Sigma^2 V^T, eps = log Sigma, and a
/// projected eps' gives F V diag(exp(eps') / Sigma) V^T. Where F changed (`changed`), `gained`
/// is the new volume correction: eps' keeps the trace of eps + vc/3 I in cases I and III, so
/// vc is used up exactly, and case II keeps what lies beyond the apex. Returns the lanes to
/// redo in double (det F <= 0, or Sigma at the kSigmaMin floor).
template <class D, class V = hn::Vec<D>, class M = hn::Mask<D>>
M sand_project(D d, const V f[9], V vc, const BatchModel& m, V& gained, M& changed, V df[9]) {
  V s2[3], v[9];
  symmetric_eigen(d, gram<true>(f, 0, 0), gram<true>(f, 1, 1), gram<true>(f, 2, 2),
                  gram<true>(f, 0, 1), gram<true>(f, 0, 2), gram<true>(f, 1, 2), s2, v);
  const V zero = hn::Zero(d), half = hn::Set(d, 0.5f), third = hn::Set(d, 1.0f / 3);
  const float floor = static_cast<float>(materials::DruckerPragerSand::kSigmaMin);
  const auto bad = hn::Or(hn::Le(determinant(d, f), zero),
                          hn::Le(hn::Min(s2[0], hn::Min(s2[1], s2[2])), hn::Set(d, floor * floor)));
  V e[3];
  for (int i = 0; i < 3; ++i)
    e[i] = hn::Mul(half, hn::Log(d, hn::Max(s2[i], hn::Set(d, floor * floor))));
  const auto corrected = m.volume_correction ? hn::Ne(vc, zero) : hn::FirstN(d, 0);
  const V shift = hn::IfThenElse(corrected, hn::Mul(vc, third), zero);
  V ec[3];
  for (int i = 0; i < 3; ++i) ec[i] = hn::Add(e[i], shift);
  const V tr = hn::Add(ec[0], hn::Add(ec[1], ec[2]));
  const V apex = hn::Set(d, static_cast<float>(m.apex_trace));
  V dev[3];
  for (int i = 0; i < 3; ++i) dev[i] = hn::NegMulAdd(tr, third, ec[i]);
  const V dev_norm =
      hn::Sqrt(hn::MulAdd(dev[0], dev[0], hn::MulAdd(dev[1], dev[1], hn::Mul(dev[2], dev[2]))));
  const V k = hn::Set(d, static_cast<float>((3 * m.lambda + 2 * m.mu) / (2 * m.mu) * m.alpha));
  const V dgamma = hn::MulAdd(k, hn::Sub(tr, apex), dev_norm);
  const auto to_apex = hn::Ge(tr, apex);  // case II
  const auto inside =
      hn::AndNot(to_apex, hn::Or(hn::Le(dgamma, zero), hn::Eq(dev_norm, zero)));  // case I
  const V shorten =
      hn::Div(dgamma, hn::IfThenElse(hn::Eq(dev_norm, zero), hn::Set(d, 1.0f), dev_norm));
  V out[3];
  for (int i = 0; i < 3; ++i)
    out[i] = hn::IfThenElse(to_apex, hn::Mul(apex, third),
                            hn::IfThenElse(inside, ec[i], hn::NegMulAdd(shorten, dev[i], ec[i])));
  changed = hn::AndNot(bad, hn::Or(hn::Not(inside), corrected));
  gained = m.volume_correction ? hn::IfThenElse(hn::And(changed, to_apex), hn::Sub(tr, apex), zero)
                               : zero;
  V dc[3];
  for (int i = 0; i < 3; ++i) dc[i] = hn::Expm1(d, hn::Sub(out[i], e[i]));  // exp(eps') / Sigma - 1
  change<D>(changed, f, v, dc, df);
  return bad;
}

}  // namespace lanes
}  // namespace HWY_NAMESPACE
}  // namespace mpm::simd
HWY_AFTER_NAMESPACE();

#endif  // include guard
