#pragma once
/// \file Scalar, vector and matrix types shared by the engine and every material.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace mpm {

/// Floating-point type of all arithmetic, of the grid, and of particle positions and velocities.
using Real = double;
/// A 3-vector of Real.
using Vec3 = Eigen::Matrix<Real, 3, 1>;
/// A 3x3 matrix of Real (deformation gradients, stresses, affine velocity).
using Mat3 = Eigen::Matrix<Real, 3, 3>;
#ifdef MPM_DOUBLE_PARTICLES
/// Floating-point type of the per-particle matrices (F, C, stress): double in this build.
using StoredReal = double;
#else
/// Floating-point type of the per-particle matrices (F, C, stress): float unless the build sets
/// MPM_DOUBLE_PARTICLES=ON. Arithmetic is always in Real; only storage is narrowed.
using StoredReal = float;
#endif
/// A 3x3 matrix as stored per particle.
using StoredMat3 = Eigen::Matrix<StoredReal, 3, 3>;
/// Name of StoredReal, for reports ("float" or "double").
inline constexpr const char* kStoredPrecision = sizeof(StoredReal) == 4 ? "float" : "double";

/// A stored matrix widened to Real for arithmetic.
inline Mat3 to_real(const StoredMat3& m) { return m.cast<Real>(); }
/// A matrix rounded to the stored precision.
inline StoredMat3 to_stored(const Mat3& m) { return m.cast<StoredReal>(); }

/// A 3-vector of integer grid indices.
using Vec3i = Eigen::Vector3i;
/// A 2-vector of integers (image sizes).
using Vec2i = Eigen::Vector2i;

/// Loops shorter than this run on one thread: for small scenes the cost of waking threads
/// (and of waiting for one the OS has descheduled) outweighs the work.
inline constexpr long kParallelMinItems = 8192;

}  // namespace mpm
