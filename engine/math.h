#pragma once
/// \file Scalar, vector and matrix types shared by the engine and every material.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace mpm {

/// Floating-point type of particle and grid state.
using Real = double;
/// A 3-vector of Real.
using Vec3 = Eigen::Matrix<Real, 3, 1>;
/// A 3x3 matrix of Real (deformation gradients, stresses, affine velocity).
using Mat3 = Eigen::Matrix<Real, 3, 3>;
/// A 3-vector of integer grid indices.
using Vec3i = Eigen::Vector3i;
/// A 2-vector of integers (image sizes).
using Vec2i = Eigen::Vector2i;

/// Loops shorter than this run on one thread: for small scenes the cost of waking threads
/// (and of waiting for one the OS has descheduled) outweighs the work.
inline constexpr long kParallelMinItems = 8192;

}  // namespace mpm
