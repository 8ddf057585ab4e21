#pragma once
/// \file The stress integrated over each particle's domain (simulation.quadrature: domain).
///
/// The point form f_i = sum_p V_p sigma_p grad w_i(x_p) is a one-point quadrature of
/// -integral sigma grad w_i. Where a free surface cuts a node's B-spline (the top of a pool)
/// that quadrature sets the top particles' pressure wrongly, by a fraction of rho g h that
/// depends on where the surface lies between the node rows (docs/accuracy.md, "The pool's top
/// layer"). Here each particle's domain is a cube of its current volume (the domain follows
/// the deformation's volume, as in cpGIMP; GIMP: Bardenhagen and Kober 2004, "The generalized
/// interpolation material point method", CMES 5), its stress is linear over the domain,
/// sigma_p - (grad p_p . (x - x_p)) I, and the quadratic B-spline's gradient is integrated
/// exactly over it (GIMP's domain-averaged weights and gradients, with a linear rather than a
/// constant stress). The pressure's gradient comes from per-node weighted linear least-squares fits of
/// the particles' pressures (as the Taylor least-squares reconstruction of Wobbes et al.
/// 2020). Mass, momentum and the gather use the same domain-averaged weights, so that a
/// node's inertia comes from the particles its force does.

#include <array>
#include <span>
#include <vector>

#include "engine/core/math.h"
#include "engine/core/particles.h"
#include "engine/step/grid.h"
#include "engine/step/transfer.h"

namespace mpm {

/// The quadratic B-spline averaged over a particle's domain along one axis, for the four
/// nodes from `base`. With the domain [x_p - l/2, x_p + l/2] and node i at x_i:
/// n = mean of N_i, s = mean of dN_i/dx, q = mean of (x - x_p) N_i, m = mean of
/// (x - x_p) dN_i/dx.
struct DomainAxis {
  int base = 0;  ///< First of the four nodes.
  Real n[4];     ///< Domain mean of the weight.
  Real s[4];     ///< Domain mean of the weight's derivative, 1/m.
  Real q[4];     ///< Domain mean of (x - x_p) times the weight, m.
  Real m[4];     ///< Domain mean of (x - x_p) times the weight's derivative.
};

/// One axis of the domain stencil of a particle at grid coordinate fx (cells from the
/// origin) whose domain is `cells` cells wide (in (0, 1]), on cells of `h` metres.
DomainAxis domain_axis(Real fx, Real cells, Real h);

/// The quadratic B-spline's antiderivatives in cell units, N1(r) = int_-inf^r N and
/// N2(r) = int_-inf^r N1 (exposed for the tests).
Real bspline_integral(Real r);
/// N2(r) = int_-inf^r N1 (see bspline_integral).
Real bspline_second_integral(Real r);

/// Buffers of the per-node fits, kept between substeps (no allocation per substep).
struct NodeFits {
  std::vector<std::array<Real, 14>> sums;  ///< Per node: moments, then the fit (a, b).
  std::vector<unsigned char> ok;           ///< Per node: the fit is well posed.
};

/// Fits at every node with particles a + b . (x - x_i) to the particles' `values` by
/// least squares with their quadratic weights w_ip, and gives each particle the fits' blend
/// sum_i w_ip (a_i + b_i . (x_p - x_i)) / sum_i w_ip (in `value`, if not empty) and
/// sum_i w_ip b_i / sum_i w_ip (in `gradient`, if not empty), over the nodes whose particles
/// spread in every direction (others are left out; with none, 0). Exact for a linear field.
void fit_linear(const Particles& p, const ParticleOrder& order, const Grid& grid,
                std::span<const Real> values, NodeFits& fits, std::span<Real> value,
                std::span<Vec3> gradient);

/// Each particle's pressure, p = tr(-V0 tau) / (3 V) from Particles::stress, V = V0 det F.
void particle_pressures(const Particles& p, std::span<Real> pressure);

/// A particle's domain stencil: the domain means per axis and APIC's inertia over the domain.
struct DomainStencil {
  DomainAxis axis[3];  ///< The domain means along x, y and z.
  Vec3 inv_d;          ///< D^-1 per axis, D = sum_i wbar_i (x_i - x_p)^2 = h^2 / 4 + l^2 / 12.
  /// The first of the 4 x 4 x 4 nodes.
  Vec3i base() const { return {axis[0].base, axis[1].base, axis[2].base}; }
  /// Domain mean of the weight of node (i, j, k) from base.
  Real weight(int i, int j, int k) const { return axis[0].n[i] * axis[1].n[j] * axis[2].n[k]; }
  /// Domain mean of the gradient of that weight, 1/m.
  Vec3 gradient(int i, int j, int k) const {
    return {axis[0].s[i] * axis[1].n[j] * axis[2].n[k], axis[0].n[i] * axis[1].s[j] * axis[2].n[k],
            axis[0].n[i] * axis[1].n[j] * axis[2].s[k]};
  }
};

/// The domain stencil of a particle at `x` whose domain is a cube of `volume` (its side at
/// most a cell, at least 0.05 of one).
DomainStencil domain_stencil(const Vec3& x, Real volume, const Grid& grid);

/// Nodes the domain stencil reaches beyond the quadratic stencil on each side (the sort's
/// `reach`).
inline constexpr int kDomainReach = 1;

/// Clears the nodes, then scatters mass and momentum with the domain weights (with APIC's
/// and MLS's affine term m C (x_i - x_p)), and the stress force integrated over each domain
/// with the pressure gradient `pressure_gradient` (Pa/m): dt f_i into the momentum (PIC,
/// APIC, MLS), or f_i into grid.force (FLIP). The order must come from sort_particles with
/// reach kDomainReach.
void domain_particles_to_grid(const Particles& p, const ParticleOrder& order, Transfer transfer,
                              std::span<const Vec3> pressure_gradient, Real dt, Grid& grid);

/// Gathers velocity (and APIC's and MLS's C = B D^-1) with the domain weights and updates
/// F <- (I + dt L) F, L = sum_i v_i grad wbar_i^T (C for MLS), without advecting.
void domain_grid_to_particles(const Grid& grid, Transfer transfer, Real flip_blend, Real dt,
                              Particles& p);

/// Replaces each particle's volume change over the substep by its nodal least-squares blend
/// (a J-bar, after the F-bar of de Souza Neto et al. 1996, with the average taken by the
/// fits): `j_old` holds det F before the F update; F is scaled by the cube root of the
/// fitted J over its own.
void smooth_volume_change(const ParticleOrder& order, const Grid& grid, std::span<const Real> j_old,
                          NodeFits& fits, std::vector<Real>& scratch, Particles& p);

}  // namespace mpm
