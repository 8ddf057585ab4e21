#pragma once
/// \file Rotation-variant SVD and polar decomposition of 3x3 matrices.
///
/// Follows McAdams, Selle, Tamstorf, Teran, Sifakis 2011, "Computing the singular value
/// decomposition of 3x3 matrices with minimal branching and elementary floating point
/// operations" (UW-Madison TR1690): (1) Jacobi eigen-iteration on the symmetric F^T F gives V;
/// (2) the columns of B = F V are sorted by length; (3) a Givens QR of B gives U and the
/// singular values. Exact Givens angles are used in place of the paper's approximate
/// quaternion ones, since this runs in double precision.

#include <cmath>
#include <utility>

#include "engine/math.h"

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

/// Rotation R of the polar decomposition F = R S, with R = U V^T from svd_rv.
inline Mat3 polar_rotation(const Mat3& F) {
  Mat3 U, V;
  Vec3 sigma;
  svd_rv(F, U, sigma, V);
  return U * V.transpose();
}

}  // namespace mpm
