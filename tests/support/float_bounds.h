#pragma once
/// \file Bounds on what the float SIMD transfers (simulation.simd: true) may add to a whole
/// run's results, for the tests that check an exact property of the algorithm (free fall's
/// discrete trajectory, momentum conservation) on both paths: the scalar path keeps its double
/// round-off bound, the SIMD path takes these.
///
/// The one-transfer bounds are tests/transfers/test_simd.cpp's, with u = 2^-24 (float's unit
/// round-off): after a scatter each node's mass and momentum are within 52 u of the sum of
/// their terms' magnitudes; the float copy of the node velocities rounds them by u / 2; a
/// gather's v is within 16 u of sum w |v_i|. For a body whose terms share their sign (a
/// uniform motion, or the momentum scale sum m |v|), one substep therefore moves a particle's
/// velocity by at most kSubstepRel u |v|, kSubstepRel = 52 + 52 + 1/2 + 16 = 120.5 (mass and
/// momentum each, the copy, the gather), and the total momentum by at most kSubstepRel u of
/// sum m |v| (the scatter's sums and the gather's mass mismatch).
///
/// Over a run these per-substep errors add up. The bounds below sum them over the substeps
/// and do not compound them: a substep's transfer does not amplify the velocity error it
/// received (the scatter and the gather are weighted averages). In the worst case the error a
/// particle carries into the next substep is added to, which gives T (n + 1) / 2 kSubstepRel u
/// |v| for a position after n substeps of a time T: at n = 400 that is as large as the
/// g t dt / 2 the free-fall test exists to see, so it would test nothing. Round-to-nearest
/// errors of independent operands have zero mean and each node averages those of a few hundred
/// particles, so the carried error stays far below that; the tests show it: the measured free-
/// fall deviation is the same for n = 100, 200 and 400 (2e-8 to 4e-8 m, 50 times below
/// position_bound), which a compounding error would not be.

#include <cstddef>

namespace mpm::test {

/// Float's unit round-off, 2^-24.
inline constexpr double kFloatU = 1.0 / (1 << 24);
/// One substep's transfers move a velocity by at most this many u of its magnitude (above).
inline constexpr double kSubstepRel = 52 + 52 + 0.5 + 16;

/// Position error after a time `t` with speeds at most `speed`: dt kSubstepRel u |v| per
/// substep, summed over the substeps.
inline double simd_position_bound(double t, double speed) {
  return t * kSubstepRel * kFloatU * speed;
}

/// APIC's relative angular momentum drift on the SIMD path after `substeps`: the scalar
/// bound (test::apic_bound, storage rounding of C) plus the float transfers' kSubstepRel u of
/// sum m |r x v| per substep, which for a body spinning as a whole is its angular momentum.
inline double simd_apic_bound(std::size_t substeps, double stored_bound) {
  return stored_bound + static_cast<double>(substeps) * kSubstepRel * kFloatU;
}

/// Velocity error of one substep (the error a particle's speed may show at any time).
inline double simd_velocity_bound(double speed) { return kSubstepRel * kFloatU * speed; }

/// Drift of a closed system's total momentum after `substeps`, with `scale` = sum m |v|:
/// kSubstepRel u of the scale per substep (a worst case: nothing is assumed about signs).
inline double simd_momentum_bound(std::size_t substeps, double scale) {
  return static_cast<double>(substeps) * kSubstepRel * kFloatU * scale;
}

/// |F - I| (Frobenius) after `substeps` taking a time `t` of a uniform motion at speeds at
/// most `speed` on a grid of spacing `h` (quadratic kernel). grad v = sum v_i grad w_i with
/// node velocities within kSubstepRel u |v| of the uniform one and sum_i |d w_i / d x_a| <= 2 / h
/// per axis, so each entry of grad v is at most kSubstepRel u |v| 2 / h; F += dt grad v F adds
/// at most dt 3 of that per entry (F = I to this order, a row of 3 terms), and the rounding of
/// F to float storage at most u per entry per substep. Summed over the substeps, times 3 for
/// the Frobenius norm of 9 entries.
inline double simd_F_bound(std::size_t substeps, double t, double speed, double h) {
  return 3 * (t * 3 * kSubstepRel * kFloatU * speed * 2 / h +
              static_cast<double>(substeps) * kFloatU);
}

}  // namespace mpm::test
