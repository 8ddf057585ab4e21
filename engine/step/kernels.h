#pragma once
/// \file B-spline interpolation weights: linear, quadratic and cubic (Steffen, Kirby, Berzins
/// 2008, "Analysis and reduction of quadrature errors in the material point method", eq. 9-11;
/// Jiang et al. 2016 course notes, section 9.1; Stomakhin et al. 2013, eq. 8 for quadratic).

#include <cmath>

#include "engine/core/math.h"
#include "engine/scene/scene_desc.h"

namespace mpm {

/// Weights and gradients of the N x N x N grid nodes around one particle.
template <int N>
struct Stencil {
  static constexpr int kNodes = N;  ///< Nodes per axis.
  Vec3i base;     ///< Index of the first of the N nodes per axis.
  Real w[3][N];   ///< w[axis][k]: 1D weight of node base + k.
  Real dw[3][N];  ///< dw[axis][k]: d(w)/dx of node base + k, 1/m.

  /// Full weight of node (i, j, k).
  Real weight(int i, int j, int k) const { return w[0][i] * w[1][j] * w[2][k]; }
  /// Gradient of the full weight of node (i, j, k), 1/m.
  Vec3 gradient(int i, int j, int k) const {
    return {dw[0][i] * w[1][j] * w[2][k], w[0][i] * dw[1][j] * w[2][k],
            w[0][i] * w[1][j] * dw[2][k]};
  }
};

/// The kernel's stencil size, first node, weights and APIC inertia D (Jiang et al. 2015,
/// "The affine particle-in-cell method", section 5.3).
template <Kernel K>
struct KernelTraits;

/// floor(y) as an int for |y| < 2^31: std::floor's value in three instructions (std::floor is
/// a long sequence on the baseline x86-64 target, which has no rounding instruction; the sort
/// takes it for every particle in every substep).
inline int floor_int(Real y) {
  const int t = static_cast<int>(y);
  return t - (y < t);
}

/// Linear hat: N(d) = 1 - |d| for |d| < 1. Two nodes per axis.
template <>
struct KernelTraits<Kernel::linear> {
  static constexpr int kNodes = 2;  ///< Nodes per axis.
  /// D is not a constant multiple of I for the linear kernel: APIC takes C = sum v_i grad w^T,
  /// which equals B D^-1 for multilinear weights (Jiang et al. 2015, section 5.3).
  static constexpr Real kInvDScale = 0;
  /// First node of the stencil for grid coordinate fx.
  static int base(Real fx) { return floor_int(fx); }
  /// 1D weights and derivatives (per cell) at d = fx - base, d in [0, 1).
  static void weights(Real d, Real* w, Real* dw) {
    w[0] = 1 - d;
    w[1] = d;
    dw[0] = -1;
    dw[1] = 1;
  }
};

/// Quadratic B-spline: N(d) = 3/4 - d^2 for |d| < 1/2, (3/2 - |d|)^2 / 2 for 1/2 <= |d| < 3/2.
template <>
struct KernelTraits<Kernel::quadratic> {
  static constexpr int kNodes = 3;       ///< Nodes per axis.
  static constexpr Real kInvDScale = 4;  ///< D^-1 = 4 / h^2 (Jiang et al. 2015, eq. after 17).
  /// First node of the stencil for grid coordinate fx.
  static int base(Real fx) { return floor_int(fx - Real(0.5)); }
  /// 1D weights and derivatives (per cell) at d = fx - base, d in [0.5, 1.5).
  static void weights(Real d, Real* w, Real* dw) {
    w[0] = Real(0.5) * (Real(1.5) - d) * (Real(1.5) - d);
    w[1] = Real(0.75) - (d - 1) * (d - 1);
    w[2] = Real(0.5) * (d - Real(0.5)) * (d - Real(0.5));
    dw[0] = d - Real(1.5);
    dw[1] = -2 * (d - 1);
    dw[2] = d - Real(0.5);
  }
};

/// Cubic B-spline: N(d) = |d|^3 / 2 - d^2 + 2/3 for |d| < 1, (2 - |d|)^3 / 6 for 1 <= |d| < 2.
template <>
struct KernelTraits<Kernel::cubic> {
  static constexpr int kNodes = 4;       ///< Nodes per axis.
  static constexpr Real kInvDScale = 3;  ///< D^-1 = 3 / h^2 (Jiang et al. 2015, section 5.3).
  /// First node of the stencil for grid coordinate fx.
  static int base(Real fx) { return floor_int(fx) - 1; }
  /// 1D weights and derivatives (per cell) at d = fx - base, d in [1, 2).
  static void weights(Real d, Real* w, Real* dw) {
    const Real a = 2 - d;  // distance to node 0 is d in [1, 2): outer piece
    const Real b = d - 1;  // distance to node 1, in [0, 1): inner piece
    const Real c = 2 - d;  // distance to node 2, in (0, 1]: inner piece
    const Real e = d - 1;  // node 3 at distance 3 - d in (1, 2]: outer piece (2 - (3 - d))
    w[0] = a * a * a / 6;
    w[1] = Real(0.5) * b * b * b - b * b + Real(2) / 3;
    w[2] = Real(0.5) * c * c * c - c * c + Real(2) / 3;
    w[3] = e * e * e / 6;
    // d/dfx of N(fx - node): node 0, 1 lie below the particle, node 2, 3 above.
    dw[0] = -Real(0.5) * a * a;
    dw[1] = Real(1.5) * b * b - 2 * b;
    dw[2] = -(Real(1.5) * c * c - 2 * c);
    dw[3] = Real(0.5) * e * e;
  }
};

/// The stencil of kernel K for a particle at `x` on a grid with nodes at origin + i * h.
template <Kernel K>
inline Stencil<KernelTraits<K>::kNodes> make_stencil(const Vec3& x, const Vec3& origin,
                                                     const Vec3& inv_h) {
  using Traits = KernelTraits<K>;
  Stencil<Traits::kNodes> s;
  for (int a = 0; a < 3; ++a) {
    const Real fx = (x[a] - origin[a]) * inv_h[a];
    const int b = Traits::base(fx);
    s.base[a] = b;
    Traits::weights(fx - b, s.w[a], s.dw[a]);
    for (int k = 0; k < Traits::kNodes; ++k) s.dw[a][k] *= inv_h[a];
  }
  return s;
}

/// First stencil node per axis of kernel K for a particle at `x`.
template <Kernel K>
inline Vec3i stencil_base(const Vec3& x, const Vec3& origin, const Vec3& inv_h) {
  Vec3i b;
  for (int a = 0; a < 3; ++a) b[a] = KernelTraits<K>::base((x[a] - origin[a]) * inv_h[a]);
  return b;
}

/// Nodes per axis of kernel `k`.
constexpr int kernel_nodes(Kernel k) {
  return k == Kernel::linear ? 2 : k == Kernel::quadratic ? 3 : 4;
}

/// The quadratic B-spline stencil (the default kernel).
inline Stencil<3> quadratic_stencil(const Vec3& x, const Vec3& origin, const Vec3& inv_h) {
  return make_stencil<Kernel::quadratic>(x, origin, inv_h);
}

/// Calls f.template operator()<K>() with kernel `k` as a compile-time constant.
template <class Fn>
decltype(auto) dispatch_kernel(Kernel k, Fn&& f) {
  switch (k) {
    case Kernel::linear: return f.template operator()<Kernel::linear>();
    case Kernel::cubic: return f.template operator()<Kernel::cubic>();
    default: return f.template operator()<Kernel::quadratic>();
  }
}

}  // namespace mpm
