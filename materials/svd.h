#pragma once
/// \file Rotation-variant SVD and polar decomposition of 3x3 matrices.

#include <Eigen/SVD>

#include "engine/math.h"

namespace mpm {

/// F = U diag(sigma) V^T with U, V proper rotations (det = +1); sigma(2) may be negative
/// when det F < 0. This is the "rotation variant" SVD of Irving et al. 2004, which the
/// fixed-corotated model needs to stay defined for inverted elements (Stomakhin et al. 2012).
inline void svd_rv(const Mat3& F, Mat3& U, Vec3& sigma, Mat3& V) {
  Eigen::JacobiSVD<Mat3> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  U = svd.matrixU();
  V = svd.matrixV();
  sigma = svd.singularValues();
  if (U.determinant() < 0) {
    U.col(2) *= -1;
    sigma(2) *= -1;
  }
  if (V.determinant() < 0) {
    V.col(2) *= -1;
    sigma(2) *= -1;
  }
}

/// Rotation R of the polar decomposition F = R S, with R = U V^T from svd_rv.
inline Mat3 polar_rotation(const Mat3& F) {
  Mat3 U, V;
  Vec3 sigma;
  svd_rv(F, U, sigma, V);
  return U * V.transpose();
}

}  // namespace mpm
