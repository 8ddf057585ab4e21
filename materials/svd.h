#pragma once
/// \file Rotation-variant SVD and polar decomposition of 3x3 matrices.
///
/// svd_rv follows McAdams, Selle, Tamstorf, Teran, Sifakis 2011, "Computing the singular value
/// decomposition of 3x3 matrices with minimal branching and elementary floating point
/// operations" (UW-Madison TR1690): (1) Jacobi eigen-iteration on the symmetric F^T F gives V;
/// (2) the columns of B = F V are sorted by length; (3) a Givens QR of B gives U and the
/// singular values. Exact Givens angles are used in place of the paper's approximate
/// quaternion ones, since this runs in double precision.
///
/// polar_rotation needs only R = U V^T, which is the proper rotation maximising tr(R^T F)
/// (the rotation-variant sign on sigma_3 is exactly the Kabsch/Umeyama correction). That
/// rotation is the top eigenvector of Horn's 4x4 quaternion matrix, found without any SVD;
/// see svd_detail::polar_rotation_quaternion.

#include <algorithm>
#include <cmath>
#include <utility>

#include "engine/core/math.h"

namespace mpm {

namespace svd_detail {

/// One Jacobi rotation in the (p, q) plane that zeroes S(p, q); accumulates it into V.
inline void jacobi_rotate(Mat3& S, Mat3& V, int p, int q) {
  const Real apq = S(p, q);
  if (apq == 0) return;
  const Real theta = (S(q, q) - S(p, p)) / (2 * apq);
  const Real t = (theta >= 0 ? 1 : -1) / (std::abs(theta) + std::sqrt(theta * theta + 1));
  const Real c = 1 / std::sqrt(t * t + 1), s = t * c;
  // S <- G^T S G with G the rotation [c s; -s c] in the (p, q) plane.
  for (int k = 0; k < 3; ++k) {
    const Real skp = S(k, p), skq = S(k, q);
    S(k, p) = c * skp - s * skq;
    S(k, q) = s * skp + c * skq;
  }
  for (int k = 0; k < 3; ++k) {
    const Real spk = S(p, k), sqk = S(q, k);
    S(p, k) = c * spk - s * sqk;
    S(q, k) = s * spk + c * sqk;
  }
  for (int k = 0; k < 3; ++k) {
    const Real vkp = V(k, p), vkq = V(k, q);
    V(k, p) = c * vkp - s * vkq;
    V(k, q) = s * vkp + c * vkq;
  }
}

/// Givens rotation that zeroes B(i, col) against B(j, col) (rows j < i); accumulates into U.
inline void givens_zero(Mat3& B, Mat3& U, int j, int i, int col) {
  const Real a = B(j, col), b = B(i, col);
  const Real r = std::sqrt(a * a + b * b);  // no overflow guard needed: |F| is moderate
  if (r == 0) return;
  const Real c = a / r, s = b / r;
  for (int k = 0; k < 3; ++k) {
    const Real bj = B(j, k), bi = B(i, k);
    B(j, k) = c * bj + s * bi;
    B(i, k) = -s * bj + c * bi;
  }
  for (int k = 0; k < 3; ++k) {
    const Real uj = U(k, j), ui = U(k, i);
    U(k, j) = c * uj + s * ui;
    U(k, i) = -s * uj + c * ui;
  }
}

}  // namespace svd_detail

/// F = U diag(sigma) V^T with U, V proper rotations (det = +1), sigma(0) >= sigma(1) >= 0 and
/// sigma(2) carrying the sign of det F. This "rotation variant" SVD (Irving et al. 2004) keeps
/// the fixed-corotated model defined for inverted elements (Stomakhin et al. 2012).
inline void svd_rv(const Mat3& F, Mat3& U, Vec3& sigma, Mat3& V) {
  using namespace svd_detail;
  // (1) Symmetric eigenproblem F^T F = V diag(lambda) V^T by cyclic Jacobi.
  Mat3 S = F.transpose() * F;
  V.setIdentity();
  const Real scale = S.diagonal().sum();
  for (int sweep = 0; sweep < 8; ++sweep) {
    const Real off = S(0, 1) * S(0, 1) + S(0, 2) * S(0, 2) + S(1, 2) * S(1, 2);
    if (off <= Real(1e-30) * scale * scale) break;
    jacobi_rotate(S, V, 0, 1);
    jacobi_rotate(S, V, 0, 2);
    jacobi_rotate(S, V, 1, 2);
  }
  // (2) Sort the columns of B = F V by decreasing length; swapping two columns negates one
  // so V stays a proper rotation.
  Mat3 B = F * V;
  Real n0 = B.col(0).squaredNorm(), n1 = B.col(1).squaredNorm(), n2 = B.col(2).squaredNorm();
  auto swap_cols = [&](int a, int b, Real& na, Real& nb) {
    B.col(a).swap(B.col(b));
    V.col(a).swap(V.col(b));
    B.col(b) *= -1;
    V.col(b) *= -1;
    std::swap(na, nb);
  };
  if (n0 < n1) swap_cols(0, 1, n0, n1);
  if (n0 < n2) swap_cols(0, 2, n0, n2);
  if (n1 < n2) swap_cols(1, 2, n1, n2);
  // (3) QR by Givens rotations: B = U R, R upper triangular and (B's columns being orthogonal)
  // diagonal up to round-off. R(0,0), R(1,1) >= 0; R(2,2) takes the sign of det F.
  U.setIdentity();
  givens_zero(B, U, 0, 1, 0);
  givens_zero(B, U, 0, 2, 0);
  givens_zero(B, U, 1, 2, 1);
  sigma = B.diagonal();
}

/// Rotation R of the polar decomposition F = R S, with R = U V^T from svd_rv (the reference
/// for polar_rotation, and its fallback near degenerate F).
inline Mat3 polar_rotation_svd(const Mat3& F) {
  Mat3 U, V;
  Vec3 sigma;
  svd_rv(F, U, sigma, V);
  return U * V.transpose();
}

namespace svd_detail {

/// The largest eigenvalue l = tr(R^T F) of Horn's matrix K below for the best rotation R
/// (J = det F), and n2 = |F|^2; false when l's eigenvector (and so R) is too ill-conditioned
/// to trust (F = 0, rank <= 1, or inverted with sigma_2 ~ |sigma_3|), or F is not finite: the
/// callers then fall back to svd_rv.
///
/// Horn 1987, "Closed-form solution of absolute orientation using unit quaternions" (JOSA A
/// 4(4), section 4): with R = R(q) for a quaternion q = (w, x, y, z), tr(R^T F) = q^T K q / q^T q
/// for the symmetric, traceless 4x4 matrix K below (Horn's N, written for tr(R^T F)), so the
/// best R comes from the eigenvector of K's largest eigenvalue lambda = sigma_1 + sigma_2 +
/// sigma_3 (sigma_3 signed as in svd_rv; K's other eigenvalues are sigma_1 - sigma_2 -
/// sigma_3, -sigma_1 + sigma_2 - sigma_3 and -sigma_1 - sigma_2 + sigma_3). As in Theobald
/// 2005, "Rapid calculation of RMSDs using a quaternion-based characteristic polynomial" (Acta
/// Cryst. A61), lambda is the largest root of det(K - lambda I) = lambda^4 + c2 lambda^2 +
/// c1 lambda + c0 and the eigenvector is a column of the adjugate of K - lambda I. Here
/// c2 = -2 |F|^2, c1 = -8 det F and c0 = det K = 2 |F^T F|^2 - |F|^4 (from the eigenvalues).
inline bool horn_largest_root(const Mat3& F, Real J, Real& l, Real& n2) {
  // Invariants of F and the characteristic polynomial of K.
  const Real c00 = F.col(0).squaredNorm(), c11 = F.col(1).squaredNorm(),
             c22 = F.col(2).squaredNorm();
  const Real c01 = F.col(0).dot(F.col(1)), c02 = F.col(0).dot(F.col(2)),
             c12 = F.col(1).dot(F.col(2));
  n2 = c00 + c11 + c22;  // |F|^2
  const Real c2 = -2 * n2, c1 = -8 * J;
  const Real c0 =
      2 * (c00 * c00 + c11 * c11 + c22 * c22 + 2 * (c01 * c01 + c02 * c02 + c12 * c12)) - n2 * n2;
  // Largest root by Halley's method from sqrt(3) |F| >= sigma_1 + sigma_2 + |sigma_3|. From
  // above the largest root of a polynomial with only real roots, Halley's step
  // 2 P P' / (2 P'^2 - P P'') never overshoots it (with x_i = 1 / (lambda - lambda_i), the step
  // is 2 sum x / ((sum x)^2 + sum x^2) <= 1 / max x), so lambda decreases monotonically to it.
  l = std::sqrt(3 * n2);
  Real dp = 0;
  int it = 0;
  for (; it < 32; ++it) {
    const Real l2 = l * l;
    const Real p = (l2 + c2) * l2 + c1 * l + c0;
    dp = (4 * l2 + 2 * c2) * l + c1;
    const Real ddp = 12 * l2 + 2 * c2;
    const Real step = 2 * p * dp / (2 * dp * dp - p * ddp);
    l -= step;
    // Halley's error after the step is at most about (P'' / 2P')^2 step^3: stop once that is
    // below round-off of lambda (also when step is 0, negative round-off or NaN).
    if (!(ddp * ddp * step * step * step > Real(4e-16) * dp * dp * l)) break;
  }
  // P'(lambda) is the product of the gaps from lambda to K's other eigenvalues, and the
  // round-off of lambda and q grows as it shrinks. Above 2 |F|^3 (near-rotations have about
  // 12 |F|^3) R is about as accurate as svd_rv's (measured against a long double SVD); below,
  // the caller falls back to svd_rv.
  return it < 32 && dp > 0 && dp * dp > 4 * n2 * n2 * n2;
}

/// R = argmax tr(R^T F) over proper rotations (J = det F) by the quaternion method; false
/// (R unset) when F is too close to a case where R is ill-determined or not unique (F = 0,
/// rank <= 1, or inverted with sigma_2 ~ |sigma_3|), or not finite: the eigenvector of
/// horn_largest_root's l.
inline bool polar_rotation_quaternion(const Mat3& F, Real J, Mat3& R) {
  Real l, n2;
  if (!horn_largest_root(F, J, l, n2)) return false;

  // K - lambda I.
  const Real a00 = F(0, 0) + F(1, 1) + F(2, 2) - l, a11 = F(0, 0) - F(1, 1) - F(2, 2) - l,
             a22 = -F(0, 0) + F(1, 1) - F(2, 2) - l, a33 = -F(0, 0) - F(1, 1) + F(2, 2) - l;
  const Real a01 = F(2, 1) - F(1, 2), a02 = F(0, 2) - F(2, 0), a03 = F(1, 0) - F(0, 1);
  const Real a12 = F(0, 1) + F(1, 0), a13 = F(0, 2) + F(2, 0), a23 = F(1, 2) + F(2, 1);
  // Its adjugate from 2x2 minors of rows (0, 1) and of rows (2, 3) (Laplace expansion). It is
  // P'(lambda) q q^T up to round-off, so its column with the largest diagonal entry is the
  // best-conditioned multiple of q.
  const Real s0 = a00 * a11 - a01 * a01, s1 = a00 * a12 - a01 * a02, s2 = a00 * a13 - a01 * a03;
  const Real s3 = a01 * a12 - a11 * a02, s4 = a01 * a13 - a11 * a03, s5 = a02 * a13 - a12 * a03;
  const Real d1 = a02 * a23 - a03 * a22, d2 = a02 * a33 - a03 * a23;
  const Real d3 = a12 * a23 - a13 * a22, d4 = a12 * a33 - a13 * a23, d5 = a22 * a33 - a23 * a23;
  const Real m00 = a11 * d5 - a12 * d4 + a13 * d3, m01 = -a01 * d5 + a02 * d4 - a03 * d3;
  const Real m02 = a13 * s5 - a23 * s4 + a33 * s3, m03 = -a12 * s5 + a22 * s4 - a23 * s3;
  const Real m11 = a00 * d5 - a02 * d2 + a03 * d1, m12 = -a03 * s5 + a23 * s2 - a33 * s1;
  const Real m13 = a02 * s5 - a22 * s2 + a23 * s1, m22 = a03 * s4 - a13 * s2 + a33 * s0;
  const Real m23 = -a02 * s4 + a12 * s2 - a23 * s0, m33 = a02 * s3 - a12 * s1 + a22 * s0;
  Real w = m00, x = m01, y = m02, z = m03, best = std::abs(m00);
  if (std::abs(m11) > best) w = m01, x = m11, y = m12, z = m13, best = std::abs(m11);
  if (std::abs(m22) > best) w = m02, x = m12, y = m22, z = m23, best = std::abs(m22);
  if (std::abs(m33) > best) w = m03, x = m13, y = m23, z = m33;
  // R(q) for the unnormalised q (the unit-quaternion matrix divided by |q|^2): orthogonal to
  // round-off, det +1.
  const Real ww = w * w, xx = x * x, yy = y * y, zz = z * z;
  const Real s = 1 / (ww + xx + yy + zz), s2x = 2 * s;
  R << (ww + xx - yy - zz) * s, (x * y - w * z) * s2x, (x * z + w * y) * s2x,  //
      (x * y + w * z) * s2x, (ww - xx + yy - zz) * s, (y * z - w * x) * s2x,   //
      (x * z - w * y) * s2x, (y * z + w * x) * s2x, (ww - xx - yy + zz) * s;
  return true;
}

}  // namespace svd_detail

/// Rotation R of the rotation-variant polar decomposition F = R S (R a proper rotation, S
/// symmetric; R = U V^T of svd_rv), and J = det F.
inline Mat3 polar_rotation(const Mat3& F, Real& J) {
  J = F.determinant();
  Mat3 R;
  if (!svd_detail::polar_rotation_quaternion(F, J, R)) R = polar_rotation_svd(F);
  return R;
}

/// |F - R|^2 = sum_i (sigma_i - 1)^2 for the rotation R of polar_rotation (sigma_3 signed),
/// and J = det F, without R: |F|^2 - 2 tr(R^T F) + 3 with tr(R^T F) = sigma_1 + sigma_2 +
/// sigma_3, the largest root of Horn's polynomial: no eigenvector and no R (about half the
/// cost of polar_rotation in two_cubes' energy check, docs/performance.md).
/// The subtraction loses about 1e-15 absolute against the (F - R) route.
inline Real distance_to_rotation_squared(const Mat3& F, Real& J) {
  J = F.determinant();
  Real l, n2;
  if (svd_detail::horn_largest_root(F, J, l, n2)) return std::max(Real(0), n2 - 2 * l + 3);
  Mat3 U, V;
  Vec3 sigma;
  svd_rv(F, U, sigma, V);
  return (sigma - Vec3::Ones()).squaredNorm();
}

/// Rotation R of the rotation-variant polar decomposition F = R S.
inline Mat3 polar_rotation(const Mat3& F) {
  Real J;
  return polar_rotation(F, J);
}

/// Rotation-variant polar decomposition F = R S: R = polar_rotation(F) and S = R^T F,
/// symmetrised. S's eigenvalues are svd_rv's sigma (the smallest negative if det F < 0).
inline void polar_decomposition(const Mat3& F, Mat3& R, Mat3& S) {
  Real J;
  R = polar_rotation(F, J);
  const Mat3 A = R.transpose() * F;
  S = 0.5 * (A + A.transpose());
}

namespace svd_detail {

/// One Jacobi rotation in the (p, q) plane of a symmetric matrix held as its diagonal entries
/// app, aqq and off-diagonal apq, arp = A(r, p), arq = A(r, q) (r the third index): the same
/// rotation as jacobi_rotate, with the symmetric update of Press et al., "Numerical Recipes",
/// section 11.1 (app -= t apq, aqq += t apq), and c, s with one division fewer: with
/// d = aqq - app and r = sqrt(d^2 + 4 apq^2), t = 2 apq sign(d) / (|d| + r),
/// c = (|d| + r) / h and s = 2 apq sign(d) / h for h = sqrt(2 r (r + |d|)).
inline void jacobi_rotate_symmetric(Real& app, Real& aqq, Real& apq, Real& arp, Real& arq, Mat3& V,
                                    int p, int q) {
  const Real b = apq;
  if (b == 0) return;
  const Real d = aqq - app, ad = std::abs(d);
  Real c, s, t;
  if (std::abs(b) <= Real(1e-4) * ad) {
    // Small angle (the rotations of the last sweep): the Taylor series t = x - x^3 + O(x^5),
    // x = apq / d, and c = 1 - t^2 / 2 + O(t^4) are exact to round-off for |x| <= 1e-4.
    const Real x = b / d;
    t = x - x * x * x;
    c = 1 - t * t / 2;
    s = t * c;
  } else {
    const Real r = std::sqrt(d * d + 4 * b * b);
    const Real sb = d < 0 ? -2 * b : 2 * b;
    const Real inv_h = 1 / std::sqrt(2 * r * (r + ad));
    c = (r + ad) * inv_h;
    s = sb * inv_h;
    t = sb / (r + ad);
  }
  app -= t * b;
  aqq += t * b;
  apq = 0;
  const Real rp = arp, rq = arq;
  arp = c * rp - s * rq;
  arq = s * rp + c * rq;
  for (int k = 0; k < 3; ++k) {
    const Real vp = V(k, p), vq = V(k, q);
    V(k, p) = c * vp - s * vq;
    V(k, q) = s * vp + c * vq;
  }
}

}  // namespace svd_detail

/// Eigen-decomposition S = V diag(lambda) V^T of a symmetric S by cyclic Jacobi (as step (1) of
/// svd_rv); V is a proper rotation, lambda unsorted.
inline void symmetric_eigen(const Mat3& S, Vec3& lambda, Mat3& V) {
  using svd_detail::jacobi_rotate_symmetric;
  Real a00 = S(0, 0), a11 = S(1, 1), a22 = S(2, 2), a01 = S(0, 1), a02 = S(0, 2), a12 = S(1, 2);
  V.setIdentity();
  const Real scale = S.squaredNorm();
  for (int sweep = 0; sweep < 8; ++sweep) {
    if (a01 * a01 + a02 * a02 + a12 * a12 <= Real(1e-30) * scale) break;
    jacobi_rotate_symmetric(a00, a11, a01, a02, a12, V, 0, 1);
    jacobi_rotate_symmetric(a00, a22, a02, a01, a12, V, 0, 2);
    jacobi_rotate_symmetric(a11, a22, a12, a01, a02, V, 1, 2);
  }
  lambda = Vec3(a00, a11, a22);
}

}  // namespace mpm
