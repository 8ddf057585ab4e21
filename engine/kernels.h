#pragma once
/// \file Quadratic B-spline interpolation weights (Stomakhin et al. 2013, eq. 8 and its
/// derivative; Jiang et al. 2016 course notes, section 9.1).

#include <cmath>

#include "engine/math.h"

namespace mpm {

/// Weights and gradients of the 3x3x3 grid nodes around one particle.
struct Stencil {
  Vec3i base;     ///< Index of the first of the three nodes per axis.
  Real w[3][3];   ///< w[axis][k]: 1D weight of node base + k.
  Real dw[3][3];  ///< dw[axis][k]: d(w)/dx of node base + k, 1/m.

  /// Full weight of node (i, j, k).
  Real weight(int i, int j, int k) const { return w[0][i] * w[1][j] * w[2][k]; }
  /// Gradient of the full weight of node (i, j, k), 1/m.
  Vec3 gradient(int i, int j, int k) const {
    return {dw[0][i] * w[1][j] * w[2][k], w[0][i] * dw[1][j] * w[2][k],
            w[0][i] * w[1][j] * dw[2][k]};
  }
};

/// The quadratic B-spline stencil of a particle at `x` on a grid with nodes at
/// origin + i * h. N(d) = 3/4 - d^2 for |d| < 1/2, (3/2 - |d|)^2 / 2 for 1/2 <= |d| < 3/2.
inline Stencil quadratic_stencil(const Vec3& x, const Vec3& origin, const Vec3& inv_h) {
  Stencil s;
  for (int a = 0; a < 3; ++a) {
    const Real fx = (x[a] - origin[a]) * inv_h[a];
    const int b = static_cast<int>(std::floor(fx - Real(0.5)));
    const Real d = fx - b;  // distance to node b in cells, in [0.5, 1.5)
    s.base[a] = b;
    s.w[a][0] = Real(0.5) * (Real(1.5) - d) * (Real(1.5) - d);
    s.w[a][1] = Real(0.75) - (d - 1) * (d - 1);
    s.w[a][2] = Real(0.5) * (d - Real(0.5)) * (d - Real(0.5));
    s.dw[a][0] = (d - Real(1.5)) * inv_h[a];
    s.dw[a][1] = -2 * (d - 1) * inv_h[a];
    s.dw[a][2] = (d - Real(0.5)) * inv_h[a];
  }
  return s;
}

}  // namespace mpm
