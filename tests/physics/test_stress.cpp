// The hard cases of scenes/stress/: each must stay finite, inside the grid, within its energy
// budget, and end in the state the physics says.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <optional>

#include "engine/run/run.h"
#include "support/float_bounds.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// Checks every frame: finite particles and grid, no clamping, energy within budget.
struct Watchdog : Observer {
  Real energy_start = 0, worst_excess = 0;
  bool finite = true;
  std::vector<std::vector<Vec3>> positions;  // per frame
  std::vector<Vec3> momentum;                // per frame
  std::vector<Real> energy;                  // per frame, less wall work
  Real momentum_scale = 0;  // largest, over frames, sum m |v| + dt sum |-V0 tau| sum |grad w|

  void record(const Simulation& sim) {
    const Particles& p = sim.particles();
    for (std::size_t q = 0; q < p.size(); ++q)
      finite = finite && p.x[q].allFinite() && p.v[q].allFinite() && p.F[q].allFinite();
    const Grid& g = sim.grid();
    for (const Vec3& v : g.velocity) finite = finite && v.allFinite();
    positions.push_back(p.x);
    Vec3 m = Vec3::Zero();
    for (std::size_t q = 0; q < p.size(); ++q) m += p.mass(q) * p.v[q];
    momentum.push_back(m);
    // The magnitudes the scatter sums for momentum: m |v| and the stress impulses
    // dt |-V0 tau| |grad w_i| (sum over the nodes of |grad w_i| <= 2 sqrt(3) / h, quadratic).
    // -V0 tau from each group at the current F (the SIMD step folds it into the scatter and
    // does not store it).
    std::vector<StoredMat3> stress(p.size());
    for (const MaterialRange& r : sim.materials())
      r.material->compute_stress(std::span<const StoredMat3>(p.F).subspan(r.first, r.count),
                                 p.volume0(r.first),
                                 std::span<StoredMat3>(stress).subspan(r.first, r.count));
    Real scale = 0;
    for (std::size_t q = 0; q < p.size(); ++q)
      scale += p.mass(q) * p.v[q].norm() + sim.stable_dt() * to_real(stress[q]).norm() * 2 *
                                                std::sqrt(3.0) / sim.grid().h.minCoeff();
    momentum_scale = std::max(momentum_scale, scale);
    energy.push_back(sim.total_energy() - sim.wall_work());
    worst_excess = std::max(worst_excess, energy.back() - energy_start);
  }
  void on_start(const Simulation& sim, int) override {
    energy_start = sim.total_energy();
    record(sim);
  }
  void on_frame(const Simulation& sim, int) override { record(sim); }
};

struct Outcome {
  std::unique_ptr<Simulation> sim;
  RunResult result;
  Watchdog watch;
};

/// Runs scenes/stress/<name>.yaml; `simd` and `contact` (if given) replace the scene's
/// simulation.simd and simulation.contact.
Outcome run_stress(const std::string& name, std::optional<bool> simd = std::nullopt,
                   std::optional<Contact> contact = std::nullopt) {
  MaterialRegistry registry = builtin_registry();
  SceneDesc scene =
      load_scene(test::source_dir() / "scenes" / "stress" / (name + ".yaml"), registry);
  if (simd) scene.simulation.simd = *simd;
  if (contact) scene.simulation.contact = *contact;
  Outcome o;
  o.sim = Simulation::create(scene, registry);
  o.result = run_frames(*o.sim, scene.simulation.frames, scene.simulation.frame_dt, {&o.watch});
  return o;
}

/// The assertions every hard case shares.
void check_common(const Outcome& o) {
  INFO("status " << status_name(o.result.status) << ": " << o.result.message);
  CHECK(o.result.status == RunStatus::ok);
  CHECK(o.watch.finite);
  // The walls (and the grid's own boundary) kept every particle in the interior: no particle
  // ever had to be clamped back.
  CHECK(o.sim->clamped_particles() == 0);
  // Explicit MPM with these transfers only dissipates: energy (less the work of moving walls)
  // may not exceed its start by more than 1 % of the largest energy scale seen.
  Real scale = std::abs(o.watch.energy_start);
  for (Real e : o.watch.energy) scale = std::max(scale, std::abs(e));
  CHECK(o.watch.worst_excess <= 0.01 * scale + 1e-9);
}

double height(const std::vector<Vec3>& x) {
  double lo = 1e9, hi = -1e9;
  for (const Vec3& p : x) lo = std::min(lo, p.y()), hi = std::max(hi, p.y());
  return hi - lo;
}

}  // namespace

TEST_CASE("stress: stiff cubes (E = 1e7, 1e8) with the CFL step rest intact", "[physics][stress]") {
  // Their floor lies 0.2 cells above the grid's buffer: with contact at the particles the
  // buffer yields to it (buffer_layers_behind_walls), else the cube bounced off the buffer,
  // without the floor's friction, and left it spinning (0.217 m tall six frames on).
  for (const Contact contact : {Contact::nodes, Contact::particles})
    for (const char* name : {"stiff_E1e7", "stiff_E1e8"}) {
      INFO(name << (contact == Contact::nodes ? ", contact at the nodes"
                                              : ", contact at the particles"));
      const Outcome o = run_stress(name, std::nullopt, contact);
      check_common(o);
      // Stiff: it lands and keeps its 0.2 m size to within 2 %.
      CHECK(height(o.watch.positions.back()) == Approx(0.2).epsilon(0.02));
      double min_y = 1e9;
      for (const Vec3& x : o.watch.positions.back()) min_y = std::min(min_y, x.y());
      CHECK(min_y > 0.1 - 0.5 / 32);
    }
}

TEST_CASE("stress: nearly incompressible (nu = 0.49, 0.499) keeps its volume", "[physics][stress]") {
  for (const char* name : {"incompressible_nu0.49", "incompressible_nu0.499"}) {
    INFO(name);
    const Outcome o = run_stress(name);
    check_common(o);
    for (const StoredMat3& F : o.sim->particles().F) {
      const double J = F.determinant();
      REQUIRE(J > 0.95);
      REQUIRE(J < 1.05);
    }
  }
}

TEST_CASE("stress: fast impact at 20 m/s into sticky, slip and separate walls", "[physics][stress]") {
  for (const char* name : {"impact_sticky", "impact_slip", "impact_separate"}) {
    INFO(name);
    const Outcome o = run_stress(name);
    check_common(o);
    // Never through the wall at x = 0.8 (grid walls act within half a cell).
    for (const auto& frame : o.watch.positions)
      for (const Vec3& x : frame) REQUIRE(x.x() < 0.8 + 0.5 / 32);
    // The stiff cube bounces back intact (no crushing).
    CHECK(o.watch.momentum.back().x() < 0);
    for (const StoredMat3& F : o.sim->particles().F) REQUIRE(std::abs(F.determinant() - 1) < 0.1);
  }
}

TEST_CASE("stress: crushed to a tenth of its height, the block recovers", "[physics][stress]") {
  for (const char* name : {"crush_corotated", "crush_neo_hookean"}) {
    INFO(name);
    const Outcome o = run_stress(name);
    check_common(o);
    // While held (t = 0.2 to 0.25 s, frames 8 to 10) the block is a few cells thick at most.
    CHECK(height(o.watch.positions[9]) < 0.032 + 2 * (1.0 / 64) + 0.01);
    // After the wall goes back up the elastic block springs back to its 0.32 m height.
    double recovered = 0;
    for (std::size_t f = 14; f < o.watch.positions.size(); ++f)
      recovered = std::max(recovered, height(o.watch.positions[f]));
    CHECK(recovered > 0.9 * 0.32);
  }
}

TEST_CASE("stress: two bodies meet head-on without gravity or walls: momentum is kept",
          "[physics][stress]") {
  for (const bool simd : {false, true}) {
    INFO((simd ? "SIMD transfers" : "scalar transfers"));
    const Outcome o = run_stress("head_on", simd);
    check_common(o);
    const Vec3 p0 = o.watch.momentum.front();
    double scale = 0;
    for (std::size_t q = 0; q < o.sim->particles().size(); ++q)
      scale += o.sim->particles().mass(q) * o.sim->particles().v[q].norm();
    double worst = 0;
    for (const Vec3& p : o.watch.momentum) worst = std::max(worst, (p - p0).norm());
    INFO("largest momentum change " << worst << " kg m/s, sum m |v| " << scale);
    // SIMD: kSubstepRel u of the scatter's momentum scale per substep (support/float_bounds.h);
    // 91 substeps: 6.6e-4 of it, measured 3.1e-8.
    const double bound = simd ? test::simd_momentum_bound(o.sim->substeps(), o.watch.momentum_scale)
                              : 1e-12 * scale;
    CHECK(worst < bound);
  }
}

TEST_CASE("stress: a snowball hits the floor at 10 m/s and breaks without blowing up",
          "[physics][stress]") {
  const Outcome o = run_stress("snowball_floor");
  check_common(o);
  // Plastic: most of the kinetic energy is gone, and the snow has compacted (Jp < 1 somewhere).
  double initial_kinetic = 0;
  for (std::size_t q = 0; q < o.sim->particles().size(); ++q)
    initial_kinetic += 0.5 * o.sim->particles().mass(q) * 100.0;  // all started at 10 m/s
  CHECK(o.sim->kinetic_energy() < 0.2 * initial_kinetic);
  const auto st = o.sim->materials()[0].material->state();
  CHECK(*std::min_element(st.begin(), st.end()) < 0.99);
}

TEST_CASE("stress: edges: near the buffer, 1 particle per cell, a single particle",
          "[physics][stress]") {
  const Outcome o = run_stress("edges");
  check_common(o);
  REQUIRE(o.sim->objects().size() == 3);
  CHECK(o.sim->objects()[2].count == 1);
  // Everything lands on the floor and stays above it.
  for (const Vec3& x : o.watch.positions.back()) CHECK(x.y() > 0.1 - 0.5 / 32 - 1e-3);
}

TEST_CASE("stress: a 1e-3 kg cube lands on a 1e3 kg cube", "[physics][stress]") {
  const Outcome o = run_stress("mass_ratio");
  check_common(o);
  const ObjectInfo& heavy = o.sim->objects()[0];
  const ObjectInfo& light = o.sim->objects()[1];
  // Over the last third of the run the light cube stays on the heavy one: above it, within two
  // cells (single-velocity-field MPM contact acts at that range), never launched off.
  const std::size_t frames = o.watch.positions.size();
  for (std::size_t f = 2 * frames / 3; f < frames; ++f) {
    const auto& x = o.watch.positions[f];
    double heavy_top = -1e9, light_bottom = 1e9;
    for (std::size_t q = heavy.first; q < heavy.first + heavy.count; ++q)
      heavy_top = std::max(heavy_top, x[q].y());
    for (std::size_t q = light.first; q < light.first + light.count; ++q)
      light_bottom = std::min(light_bottom, x[q].y());
    INFO("frame " << f);
    CHECK(light_bottom > heavy_top);
    CHECK(light_bottom < heavy_top + 2.0 / 32);
  }
  // Its centre of mass has come to rest: under a tenth of its landing speed sqrt(2 g 0.1 m)
  // (its particles still vibrate: so light a cube is barely damped). The heavy cube is unmoved.
  auto centre_speed = [&](const ObjectInfo& ob) {
    Vec3 p = Vec3::Zero();
    for (std::size_t q = ob.first; q < ob.first + ob.count; ++q)
      p += o.sim->particles().mass(q) * o.sim->particles().v[q];
    return p.norm() / ob.mass;
  };
  CHECK(centre_speed(light) < 0.1 * std::sqrt(2 * 9.81 * 0.1));
  // The heavy cube only sags under its own weight (strain rho g H / E = 0.025, so its centre
  // drops by about a millimetre, oscillating): far less than a quarter cell.
  auto centre = [&](const ObjectInfo& ob, const std::vector<Vec3>& x) {
    Vec3 c = Vec3::Zero();
    for (std::size_t q = ob.first; q < ob.first + ob.count; ++q) c += x[q];
    return Vec3(c / ob.count);
  };
  CHECK((centre(heavy, o.watch.positions.back()) - centre(heavy, o.watch.positions.front()))
            .norm() < 0.25 / 32);
}

TEST_CASE("stress: 100,000 substeps of a resting block: no drift", "[physics][stress]") {
  const Outcome o = run_stress("long_rest");
  check_common(o);
  CHECK(o.sim->substeps() == 100000);
  // After settling (first half), the centre of mass and the energy stay put.
  auto centre_y = [](const std::vector<Vec3>& x) {
    double s = 0;
    for (const Vec3& p : x) s += p.y();
    return s / x.size();
  };
  const std::size_t half = o.watch.positions.size() / 2;
  CHECK(std::abs(centre_y(o.watch.positions.back()) - centre_y(o.watch.positions[half])) < 1e-4);
  CHECK(o.watch.energy.back() <= o.watch.energy[half] + 1e-6 * std::abs(o.watch.energy[half]));
  CHECK(std::abs(o.watch.energy.back() - o.watch.energy[half]) < 1e-3 * std::abs(o.watch.energy[half]));
}
