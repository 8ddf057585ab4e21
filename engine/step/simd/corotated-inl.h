// The fixed-corotated Kirchhoff stress in float SIMD lanes, one particle per lane: Highway
// per-target code, included inside HWY_NAMESPACE by each file compiled with foreach_target
// (engine/step/simd/stress_simd.cpp, and particles_to_grid's scatter in transfer_simd.cpp).

// Include guard that toggles once per target (Highway's convention for -inl.h headers).
#if defined(MPM_SIMD_COROTATED_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef MPM_SIMD_COROTATED_INL_H_
#undef MPM_SIMD_COROTATED_INL_H_
#else
#define MPM_SIMD_COROTATED_INL_H_
#endif

#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace mpm::simd {
namespace HWY_NAMESPACE {
namespace corotated {

namespace hn = hwy::HWY_NAMESPACE;

/// -V0 tau of the fixed-corotated model, tau = 2 mu (F - R) F^T + lambda (J - 1) J I
/// (Stomakhin et al. 2012, eq. 4; references.md), for one particle per lane, in float.
/// `f` holds F column-major (f[3 c + r] = F(r, c)); `two_mu`, `lambda` and `neg_v0` (-V0, m^3)
/// may differ per lane; `out` receives -V0 tau (Pa m^3), column-major.
///
/// R is the same rotation as the scalar path's (materials/svd.h, polar_rotation_quaternion):
/// Horn's quaternion (Horn 1987, section 4) from the largest root of K's characteristic
/// polynomial (Theobald 2005) by Halley's method, run on all lanes until every lane has met the
/// scalar path's stopping rule, then the adjugate column with the largest diagonal, chosen per
/// lane with blends. Returns the lanes where that path's accuracy test (P'(lambda) > 2 |F|^3,
/// Halley converged, lambda finite) fails: the caller recomputes those in double with the
/// scalar model, as the scalar path falls back to svd_rv. So an inverted F (det F < 0) gets
/// the proper rotation maximising tr(R^T F), as in the scalar path. Long because it is one
/// inlined chain of lane arithmetic (K, Halley's iteration, the rotation, the stress) whose
/// intermediate vectors stay in registers; split, they would be passed through memory.
template <class D, class V = hn::Vec<D>>
hn::Mask<D> neg_v0_tau(D d, const V f[9], V two_mu, V lambda, V neg_v0, V out[9]) {
  const auto F = [&](int r, int c) { return f[3 * c + r]; };
  // J = det F by the first column's cofactors.
  const V k0 = hn::MulSub(F(1, 1), F(2, 2), hn::Mul(F(2, 1), F(1, 2)));
  const V k1 = hn::MulSub(F(2, 1), F(0, 2), hn::Mul(F(0, 1), F(2, 2)));
  const V k2 = hn::MulSub(F(0, 1), F(1, 2), hn::Mul(F(1, 1), F(0, 2)));
  const V J = hn::MulAdd(F(0, 0), k0, hn::MulAdd(F(1, 0), k1, hn::Mul(F(2, 0), k2)));
  // Invariants of F: the Gram matrix of its columns, |F|^2 and the polynomial's coefficients
  // c2 = -2 |F|^2, c1 = -8 det F, c0 = 2 |F^T F|^2 - |F|^4.
  const auto dot = [&](int a, int b) {
    return hn::MulAdd(F(0, a), F(0, b), hn::MulAdd(F(1, a), F(1, b), hn::Mul(F(2, a), F(2, b))));
  };
  const V c00 = dot(0, 0), c11 = dot(1, 1), c22 = dot(2, 2);
  const V c01 = dot(0, 1), c02 = dot(0, 2), c12 = dot(1, 2);
  const V n2 = hn::Add(c00, hn::Add(c11, c22));
  const V two = hn::Set(d, 2.0f);
  const V c2 = hn::Mul(hn::Set(d, -2.0f), n2), c1 = hn::Mul(hn::Set(d, -8.0f), J);
  const V diag2 = hn::MulAdd(c00, c00, hn::MulAdd(c11, c11, hn::Mul(c22, c22)));
  const V off2 = hn::MulAdd(c01, c01, hn::MulAdd(c02, c02, hn::Mul(c12, c12)));
  const V c0 = hn::MulSub(two, hn::MulAdd(two, off2, diag2), hn::Mul(n2, n2));
  // Halley's method from sqrt(3) |F| (monotone from above, see polar_rotation_quaternion).
  // The stopping rule is the scalar one with float's round-off: (P''/2P')^2 step^3 below
  // 2^-22 lambda.
  V l = hn::Sqrt(hn::Mul(hn::Set(d, 3.0f), n2)), dp = hn::Zero(d);
  const V tol = hn::Set(d, 4.0f / (1 << 22)), four = hn::Set(d, 4.0f), twelve = hn::Set(d, 12.0f),
          two_c2 = hn::Add(c2, c2);
  auto active = hn::Eq(l, l);  // every lane with a finite |F|^2
  bool converged = false;
  for (int it = 0; it < 32 && !converged; ++it) {
    const V l2 = hn::Mul(l, l);
    const V p = hn::MulAdd(hn::Add(l2, c2), l2, hn::MulAdd(c1, l, c0));
    const V dpi = hn::MulAdd(hn::MulAdd(four, l2, two_c2), l, c1);
    const V ddp = hn::MulAdd(twelve, l2, two_c2);
    const V step =
        hn::Div(hn::Mul(two, hn::Mul(p, dpi)), hn::MulSub(two, hn::Mul(dpi, dpi), hn::Mul(p, ddp)));
    l = hn::IfThenElse(active, hn::Sub(l, step), l);
    dp = hn::IfThenElse(active, dpi, dp);
    const V err = hn::Mul(hn::Mul(ddp, ddp), hn::Mul(step, hn::Mul(step, step)));
    active = hn::And(active, hn::Gt(err, hn::Mul(tol, hn::Mul(hn::Mul(dpi, dpi), l))));
    converged = hn::AllFalse(d, active);
  }
  // Lanes the scalar path would hand to svd_rv, or whose Halley run did not converge.
  const V n6 = hn::Mul(n2, hn::Mul(n2, n2));
  const auto ok = hn::AndNot(
      active, hn::And(hn::Gt(dp, hn::Zero(d)),
                      hn::And(hn::Gt(hn::Mul(dp, dp), hn::Mul(four, n6)), hn::Eq(l, l))));

  // K - lambda I and the columns of its adjugate (as in polar_rotation_quaternion).
  const V tr = hn::Add(F(0, 0), hn::Add(F(1, 1), F(2, 2)));
  const V a00 = hn::Sub(tr, l);
  const V a11 = hn::Sub(hn::Sub(hn::Sub(F(0, 0), F(1, 1)), F(2, 2)), l);
  const V a22 = hn::Sub(hn::Sub(hn::Sub(F(1, 1), F(0, 0)), F(2, 2)), l);
  const V a33 = hn::Sub(hn::Sub(hn::Sub(F(2, 2), F(0, 0)), F(1, 1)), l);
  const V a01 = hn::Sub(F(2, 1), F(1, 2)), a02 = hn::Sub(F(0, 2), F(2, 0));
  const V a03 = hn::Sub(F(1, 0), F(0, 1)), a12 = hn::Add(F(0, 1), F(1, 0));
  const V a13 = hn::Add(F(0, 2), F(2, 0)), a23 = hn::Add(F(1, 2), F(2, 1));
  const auto det2 = [](V a, V b, V c, V e) { return hn::MulSub(a, b, hn::Mul(c, e)); };
  const V s0 = det2(a00, a11, a01, a01), s1 = det2(a00, a12, a01, a02);
  const V s2 = det2(a00, a13, a01, a03), s3 = det2(a01, a12, a11, a02);
  const V s4 = det2(a01, a13, a11, a03), s5 = det2(a02, a13, a12, a03);
  const V d1 = det2(a02, a23, a03, a22), d2 = det2(a02, a33, a03, a23);
  const V d3 = det2(a12, a23, a13, a22), d4 = det2(a12, a33, a13, a23);
  const V d5 = det2(a22, a33, a23, a23);
  // x y - z w + u v, the three-term sums of the adjugate entries.
  const auto sum3 = [](V x, V y, V z, V w, V u, V v) {
    return hn::MulAdd(u, v, hn::MulSub(x, y, hn::Mul(z, w)));
  };
  const V m00 = sum3(a11, d5, a12, d4, a13, d3);
  const V m01 = hn::Neg(sum3(a01, d5, a02, d4, a03, d3));
  const V m02 = sum3(a13, s5, a23, s4, a33, s3);
  const V m03 = hn::Neg(sum3(a12, s5, a22, s4, a23, s3));
  const V m11 = sum3(a00, d5, a02, d2, a03, d1);
  const V m12 = hn::Neg(sum3(a03, s5, a23, s2, a33, s1));
  const V m13 = sum3(a02, s5, a22, s2, a23, s1);
  const V m22 = sum3(a03, s4, a13, s2, a33, s0);
  const V m23 = hn::Neg(sum3(a02, s4, a12, s2, a23, s0));
  const V m33 = sum3(a02, s3, a12, s1, a22, s0);
  // The column with the largest |diagonal| (ties keep the earlier column, as the scalar path).
  V w = m00, x = m01, y = m02, z = m03, best = hn::Abs(m00);
  auto pick = [&](V diag, V cw, V cx, V cy, V cz) {
    const auto m = hn::Gt(hn::Abs(diag), best);
    w = hn::IfThenElse(m, cw, w), x = hn::IfThenElse(m, cx, x);
    y = hn::IfThenElse(m, cy, y), z = hn::IfThenElse(m, cz, z);
    best = hn::IfThenElse(m, hn::Abs(diag), best);
  };
  pick(m11, m01, m11, m12, m13);
  pick(m22, m02, m12, m22, m23);
  pick(m33, m03, m13, m23, m33);
  // R(q) for the unnormalised q, divided by |q|^2.
  const V ww = hn::Mul(w, w), xx = hn::Mul(x, x), yy = hn::Mul(y, y), zz = hn::Mul(z, z);
  const V s = hn::Div(hn::Set(d, 1.0f), hn::Add(hn::Add(ww, xx), hn::Add(yy, zz)));
  const V s2x = hn::Add(s, s);
  V R[9];  // column-major
  R[0] = hn::Mul(hn::Sub(hn::Add(ww, xx), hn::Add(yy, zz)), s);
  R[4] = hn::Mul(hn::Sub(hn::Add(ww, yy), hn::Add(xx, zz)), s);
  R[8] = hn::Mul(hn::Sub(hn::Add(ww, zz), hn::Add(xx, yy)), s);
  R[3] = hn::Mul(hn::MulSub(x, y, hn::Mul(w, z)), s2x);  // R(0, 1)
  R[1] = hn::Mul(hn::MulAdd(x, y, hn::Mul(w, z)), s2x);  // R(1, 0)
  R[6] = hn::Mul(hn::MulAdd(x, z, hn::Mul(w, y)), s2x);  // R(0, 2)
  R[2] = hn::Mul(hn::MulSub(x, z, hn::Mul(w, y)), s2x);  // R(2, 0)
  R[7] = hn::Mul(hn::MulSub(y, z, hn::Mul(w, x)), s2x);  // R(1, 2)
  R[5] = hn::Mul(hn::MulAdd(y, z, hn::Mul(w, x)), s2x);  // R(2, 1)
  // tau = 2 mu (F - R) F^T + lambda (J - 1) J I, times -V0.
  V A[9];
  for (int e = 0; e < 9; ++e) A[e] = hn::Sub(f[e], R[e]);
  const V a = hn::Mul(two_mu, neg_v0);
  const V b = hn::Mul(hn::Mul(lambda, neg_v0), hn::MulSub(J, J, J));  // lambda (J - 1) J (-V0)
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) {
      // ((F - R) F^T)(r, c) = sum_k A(r, k) F(c, k)
      const V t =
          hn::MulAdd(A[r], F(c, 0), hn::MulAdd(A[3 + r], F(c, 1), hn::Mul(A[6 + r], F(c, 2))));
      out[3 * c + r] = r == c ? hn::MulAdd(a, t, b) : hn::Mul(a, t);
    }
  return hn::Not(ok);
}

}  // namespace corotated
}  // namespace HWY_NAMESPACE
}  // namespace mpm::simd
HWY_AFTER_NAMESPACE();

#endif  // include guard
