// Validation cases with exact answers (docs/validation.md), each at its scene's settings or a
// stated refinement. Every bound below is derived in docs/validation.md from the reference
// formula and the scheme's known error, not fitted to the measured value.
#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
#include <sstream>

#include "engine/tools/validation/cases.h"
#include "materials/sand.h"
#include "materials/svd.h"
#include "support/float_bounds.h"
#include "support/helpers.h"

using namespace mpm;
using namespace mpm::validation;

namespace {

Outcome run(const std::string& name, std::vector<SceneOverride> overrides = {}) {
  const Case* c = find_case(name);
  REQUIRE(c != nullptr);
  Outcome o = run_case(*c, overrides);
  REQUIRE(o.status == "ok");
  return o;
}

}  // namespace

TEST_CASE("validation: free fall lands exactly g dt t / 2 below the exact parabola",
          "[validation]") {
  // Symplectic Euler with fixed dt: x_n = x0 + v0 t + g t^2 / 2 + g dt t / 2 (t = n dt). The
  // transfers reproduce a uniform velocity exactly, so only round-off separates the two: double
  // round-off on the scalar path, float rounding of the SIMD transfers on the default path
  // (tests/support/float_bounds.h; 1 s of flight at speeds up to |(2, 2 + 9.81)| < 12 m/s).
  for (const char* simd : {"false", "true"})
    for (double dt : {1e-3, 5e-4}) {
      const Outcome o = run("free_fall", {{"simulation.dt", std::to_string(dt)},
                                          {"simulation.simd", simd}});
      const Measure& m = o.measure("scheme_error");
      INFO("simd " << simd << ", dt " << dt << ": error " << m.value << " m, predicted " << m.exact
                   << " m");
      const double bound = std::string(simd) == "false" ? 1e-9 * (1 + 5.0)  // ~5 m of travel
                                                        : test::simd_position_bound(1.0, 12.0);
      CHECK(std::abs(m.value - m.exact) < bound);
    }
}

TEST_CASE("validation: resting column settles to the exact stress and height", "[validation]") {
  const Outcome o = run("resting_column");
  INFO("settled height error " << o.error << ", stress rms "
                               << o.measure("stress_rms_error").value);
  // The sticky floor fixes the nodes at y = 0, a first-order boundary error of about h / H
  // (0.1 here) in the settlement; the stress error is bounded by the same.
  CHECK(o.error < 0.1);
  CHECK(o.measure("stress_rms_error").value < 0.1);
}

TEST_CASE("validation: the free-free bar's period is within 1 % at L / h = 20", "[validation]") {
  const Outcome o = run("bar_vibration", {{"grid.dims", "[36, 18, 18]"}});
  INFO("period " << o.measure("period").value << " s against " << o.measure("period").exact);
  // Quadratic B-splines on a particle lattice converge at second order (see the study test);
  // at L / h = 20 the first mode is resolved by 40 cells per wavelength: 1 % is the accuracy
  // docs/accuracy.md recommends this resolution for.
  CHECK(o.error < 0.01);
  CHECK(o.measure("half_periods_seen").value >= 19);  // ten periods, none missed
  // Energy over ten periods: APIC dissipates only the unresolved modes of the initial field;
  // the first mode holds 8 / pi^2 = 81 % of it, so at most 19 % may go.
  CHECK(o.measure("energy_drift").value < 0);
  CHECK(o.measure("energy_drift").value > -(1 - 8 / (M_PI * M_PI)));
}

TEST_CASE("validation: colliding spheres keep momentum, dip in kinetic energy and separate",
          "[validation]") {
  // No walls or gravity: every stage conserves momentum, so only round-off remains: of sums of
  // ~4000 doubles on the scalar path (1500 substeps), of the SIMD transfers' float sums on the
  // default path (float_bounds.h: per substep 120.5 u of sum m |v|, which is twice the
  // momentum of one sphere, the drift's unit).
  const Outcome scalar = run("sphere_collision", {{"simulation.simd", "false"}});
  INFO("scalar momentum drift " << scalar.error);
  CHECK(scalar.error < 1e-11);
  const Outcome o = run("sphere_collision");
  INFO("momentum drift " << o.error << ", kinetic min " << o.measure("kinetic_min_ratio").value
                         << ", end " << o.measure("kinetic_end_ratio").value);
  CHECK(o.error < test::simd_momentum_bound(o.substeps, 2.0));
  CHECK(o.measure("kinetic_min_ratio").value < 0.5);  // most kinetic energy stored in contact
  CHECK(o.measure("kinetic_end_ratio").value > 0.3);  // and much of it given back
  CHECK(o.measure("separating_speed").value > 0);     // moving apart at the end
}

TEST_CASE("validation: a spinning cube keeps its angular momentum with APIC only",
          "[validation]") {
  // Jiang et al. 2015: exact up to round-off; on the scalar path that of double arithmetic
  // and C's storage, on the default SIMD path also the float transfers' (float_bounds.h).
  const Outcome scalar_run = run("spinning_cube", {{"simulation.simd", "false"}});
  INFO("drift apic, scalar path " << scalar_run.error);
  CHECK(scalar_run.error < test::apic_bound(scalar_run.substeps));
  const Outcome apic_run = run("spinning_cube");
  const double apic = apic_run.error;
  const double flip = run("spinning_cube", {{"simulation.transfer", "flip"},
                                            {"simulation.flip_blend", "0.99"}}).error;
  const double pic = run("spinning_cube", {{"simulation.transfer", "pic"}}).error;
  INFO("drift apic " << apic << ", flip 0.99 " << flip << ", pic " << pic);
  CHECK(apic < test::simd_apic_bound(apic_run.substeps, test::apic_bound(apic_run.substeps)));
  CHECK(pic > 0.5);      // PIC loses most of it in one second
  CHECK(flip > apic);
  CHECK(flip < pic);
}

TEST_CASE("validation: Neo-Hookean block under uniaxial compression to 60 %", "[validation]") {
  const Outcome o = run("uniaxial_compression");
  INFO("stretch " << o.measure("stretch").value << ", sigma_yy " << o.measure("sigma_yy").value
                  << " Pa against " << o.measure("sigma_yy").exact);
  // The walls end 60 % apart and, with contact at the particles, the bulk follows them: no
  // layer at a wall takes more than its share (the node rule let the particles sink into the
  // walls and left the bulk at 0.74). Far beyond small strain: there the linear answer
  // E (lambda - 1) is 8 % off the exact one.
  CHECK(o.measure("stretch").value < 0.65);
  // The bound is twice the quadrature error the study's ppc sweep measures for 8 jittered
  // particles per cell on the bar (1.5 %). The scene samples a lattice: jittered particles'
  // F drifts from their positions as the strain grows (4.6 % at this stretch, 3.5 % at h / 2;
  // docs/validation.md, case 6).
  CHECK(o.error < 0.03);
}

namespace {

/// Runs an incline case for one floor and transfer scheme.
Outcome run_incline(const std::string& name, const std::string& boundary,
                    const std::string& transfer) {
  return run(name, {{"walls[0].boundary", boundary}, {"simulation.transfer", transfer}});
}

}  // namespace

TEST_CASE("validation: a block slides down a 30 degree incline the exact distance",
          "[validation][incline]") {
  // Coulomb with mu = 0.2 < tan 30: a = g (sin 30 - 0.2 cos 30). A block at rest on a wall
  // moves rigidly, which every transfer carries exactly; what remains is the wall's friction
  // impulse, which must equal mu times the normal impulse. 5 % is the bound.
  for (const char* boundary : {"slip", "separate"})
    for (const char* transfer : {"pic", "flip", "apic", "mls"}) {
      const Outcome o = run_incline("sliding_block", boundary, transfer);
      INFO(boundary << ' ' << transfer << ": slid " << o.measure("distance").value
                    << " m against " << o.measure("distance").exact << " m");
      CHECK(o.error < 0.05);
    }
}

TEST_CASE("validation: a block on a 30 degree incline with friction 0.8 stays",
          "[validation][incline]") {
  // mu = 0.8 > tan 30 = 0.577: the friction can hold the block, which must not creep. 2 mm
  // in 0.5 s is the bound (0.5 % of the 0.40 m the block slides at mu = 0.2).
  for (const char* boundary : {"slip", "separate"})
    for (const char* transfer : {"pic", "flip", "apic", "mls"}) {
      const Outcome o = run_incline("sticking_block", boundary, transfer);
      INFO(boundary << ' ' << transfer << ": moved " << o.measure("distance").value << " m");
      CHECK(o.error < 2e-3);
    }
}

TEST_CASE("validation: a ball rolls down a 30 degree incline with APIC and MLS",
          "[validation][incline]") {
  // mu = 0.5 > (2/7) tan 30: rolling without slipping, a = (5/7) g sin 30. Rolling needs the
  // transfers to keep the ball's spin: APIC and MLS do (Jiang et al. 2015; the spinning cube
  // above). Within 10 % (the bound). The contact point is not at rest: it slides at
  // about 20 % of the centre's speed (docs/validation.md, case 9, an open defect), which is
  // why the ball runs ahead of the rolling answer; the slip ratio is reported, not bounded.
  for (const char* boundary : {"slip", "separate"})
    for (const char* transfer : {"apic", "mls"}) {
      const Outcome o = run_incline("rolling_ball", boundary, transfer);
      INFO(boundary << ' ' << transfer << ": rolled " << o.measure("distance").value
                    << " m against " << o.measure("distance").exact << " m, slip ratio "
                    << o.measure("slip_ratio").value << ", I / m R^2 "
                    << o.measure("inertia_ratio").value);
      CHECK(o.error < 0.1);
    }
  // PIC and FLIP lose angular momentum in every transfer (PIC all of it within a second on the
  // spinning cube), so the ball's spin lags: it drags instead of rolling. Recorded, not hidden.
  for (const char* transfer : {"pic", "flip"}) {
    const Outcome o = run_incline("rolling_ball", "slip", transfer);
    INFO(transfer << ": rolled " << o.measure("distance").value << " m against "
                  << o.measure("distance").exact << " m");
    CHECK(o.measure("distance").value < 0.9 * o.measure("distance").exact);
  }
}

TEST_CASE("validation: water at rest has p = rho g (H - Y) from J", "[validation][water]") {
  const Outcome o = run("hydrostatic_water");
  const Measure& b = o.measure("bottom_pressure");
  INFO("layer pressure rms error / rho g H " << o.error << ", bottom layer " << b.value
                                             << " Pa against " << b.exact << ", scatter "
                                             << o.measure("particle_scatter").value);
  // The grid resolves the pressure gradient to O(h): h / H = 0.0625 of rho g H bounds the
  // RMS error of the cell-thick layers' mean pressure (the bottom layer, which reads the
  // floor's zeroed nodes, carries most of it: docs/validation.md).
  CHECK(o.error < 0.0625);
}

TEST_CASE("validation: the dam break's surge front follows Martin & Moyce 1952",
          "[validation][water]") {
  // Frames up to t = 0.23 s (T = 2.6): the first four of their points.
  const Outcome o = run("dam_break", {{"simulation.frames", "23"}});
  std::ostringstream z;
  for (const Measure& m : o.measures)
    z << m.name << ": Z = " << m.value << ", measured " << m.exact << "\n";
  INFO(z.str() << "RMS relative error " << o.error);
  REQUIRE(o.measures.size() == 4);
  // Their two series (a = 1.125 and 2.25 in) differ by up to 15 % at the same T, and the
  // release of their column is not instantaneous: 20 % bounds the comparison.
  CHECK(o.error < 0.2);
}

TEST_CASE("validation: a slumped sand column's flanks stand no steeper than its repose angle",
          "[validation][sand]") {
  // The slot makes the flow plane strain, where Klar's cone flows at tau / sigma_n =
  // 2 sqrt 3 sin(phi) / (3 - sin(phi)) (the next test): friction_angle 25.377 and 16.573 give
  // repose angles of 30 and 20 degrees. No slope of a cohesionless deposit can stand steeper
  // than that; the fitted flank is about 4 h long, and each bin's surface (its highest
  // particle) is known to a particle spacing, h / 2, so the fit may tilt by atan(1 / 8) = 7
  // degrees. The column falls and spreads (it does not creep), so its deposit is flatter than
  // the repose angle, as Lube et al. 2005's are (docs/validation.md, case 14); the friction
  // must still order the slopes.
  double previous = -1;
  for (auto [phi, repose] : {std::pair{16.573, 20.0}, {25.377, 30.0}}) {
    const Outcome o = run("sand_slope", {{"objects[0].friction_angle", std::to_string(phi)}});
    const Measure& m = o.measure("slope_a2");
    INFO("friction angle " << phi << ": flank slope " << m.value << " degrees, repose angle "
                           << m.exact);
    CHECK(std::abs(m.exact - repose) < 1e-3);
    CHECK(m.value < repose + 7);
    CHECK(m.value > previous);
    previous = m.value;
  }
}

TEST_CASE(
    "validation: in plane-strain shear flow, Klar's cone gives tau / sigma_n = 3 alpha / sqrt 2",
    "[validation][sand]") {
  // Column collapse (case 12) and the slope of a deposit are plane-strain shear flows. In steady
  // simple shear with no dilatancy (Klar's case III keeps tr eps), the stress deviator is pure
  // shear, so |dev tau| = sqrt 2 tau and the cone |dev tau| = alpha tr(-tau) = 3 alpha sigma_n
  // gives the flow friction mu = tau / sigma_n = 3 alpha / sqrt 2 = 2 sqrt 3 sin(phi) /
  // (3 - sin(phi)): tan 34.7 degrees for phi = 30 (docs/validation.md, case 12). Sheared here
  // at one material point: 0.1 % isotropic compression, then 3000 increments of 1e-5.
  using materials::DruckerPragerSand;
  const double E = 3.5e5, nu = 0.3;
  // Inputs phi whose flow friction is tan 20, tan 30 and tan 40 degrees: sin phi = 3 tan theta
  // / (2 sqrt 3 + tan theta), the inverse of the relation above.
  for (auto [phi_deg, theta_deg] : {std::pair{16.573, 20.0}, {25.377, 30.0}, {35.802, 40.0}}) {
    DruckerPragerSand sand;
    sand.mu = E / (2 * (1 + nu));
    sand.lambda = E * nu / ((1 + nu) * (1 - 2 * nu));
    sand.alpha = DruckerPragerSand::cone_alpha(phi_deg * std::numbers::pi / 180);
    Mat3 Fe = Mat3::Identity() * std::exp(-0.001);
    Mat3 shear = Mat3::Identity();
    shear(0, 1) = 1e-5;
    double vc = 0;
    for (int step = 0; step < 3000; ++step) {
      Fe = shear * Fe;
      Mat3 U, V;
      Vec3 sigma;
      svd_rv(Fe, U, sigma, V);
      Vec3 eps = DruckerPragerSand::hencky(sigma);
      sand.project(eps, vc);
      Fe = U * eps.array().exp().matrix().asDiagonal() * V.transpose();
    }
    const Mat3 tau = sand.kirchhoff(Fe);
    const double mu_flow = tau(0, 1) / -tau(1, 1);
    const double expected = 3 * sand.alpha / std::sqrt(2.0);
    INFO("phi " << phi_deg << ": tau / sigma_n " << mu_flow << " against 3 alpha / sqrt 2 "
                << expected << " (" << std::atan(expected) * 180 / std::numbers::pi
                << " degrees); tau_xx " << tau(0, 0) << ", tau_yy " << tau(1, 1) << ", tau_zz "
                << tau(2, 2));
    // The elastic strain (about 0.1 %) and the material spin tilt the deviator off pure shear:
    // 4.5 % at phi = 35.8 with ten times this strain, 0.45 % here: O(strain), inside 1 %.
    CHECK(std::abs(mu_flow / expected - 1) < 0.01);
    CHECK(std::abs(expected / std::tan(theta_deg * std::numbers::pi / 180) - 1) < 1e-4);
  }
}
