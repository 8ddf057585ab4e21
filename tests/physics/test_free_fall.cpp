// Free fall: every particle follows symplectic Euler's exact discrete trajectory.
#include <catch2/catch.hpp>

#include "engine/run/run.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

std::string falling_cube(double dt, const std::string& transfer) {
  return "simulation:\n"
         "  frame_dt: 0.05\n"
         "  dt: " + std::to_string(dt) + "\n"
         "  transfer: " + transfer + "\n"
         "grid:\n"
         "  max: [1, 1, 1]\n"
         "  dims: 32\n"
         "objects:\n"
         "  - name: cube\n"
         "    mesh: " + test::cube_mesh() + "\n"
         "    scale: 0.2\n"
         "    rotation: [10, 20, 30]\n"
         "    offset: [0.4, 0.7, 0.5]\n"
         "    velocity: [0.3, 0.5, -0.2]\n"
         "    density: 1000\n"
         "    material: corotated\n"
         "    E: 1.0e5\n"
         "    nu: 0.3\n";
}

}  // namespace

TEST_CASE("free fall matches x0 + v0 t + g t^2/2 + g t dt/2 at three dt", "[physics]") {
  // Symplectic Euler (grid v += dt g, then x += dt v) gives x_n = x(t_n) + g t_n dt / 2
  // exactly (references.md, "Validation cases"); what remains must be round-off.
  for (const std::string transfer : {"apic", "pic", "flip"})
    for (double dt : {2e-3, 1e-3, 5e-4}) {
      const SceneDesc scene = test::scene_from(falling_cube(dt, transfer));
      auto sim = Simulation::create(scene, builtin_registry());
      const std::vector<Vec3> x0 = sim->particles().x;
      const int frames = 4;
      const RunResult r = run_frames(*sim, frames, scene.simulation.frame_dt, {});
      REQUIRE(r.status == "ok");
      const double t = frames * scene.simulation.frame_dt;
      const double dt_taken = t / sim->substeps();
      CHECK(dt_taken == Approx(dt));
      const Vec3 g = scene.simulation.gravity, v0 = scene.objects[0].velocity;
      const Vec3 shift = v0 * t + g * (0.5 * t * t + 0.5 * t * dt_taken);
      double worst = 0;  // particle by particle: the reorder stage moves them in memory
      const Particles& p = sim->particles();
      for (std::size_t q = 0; q < x0.size(); ++q)
        worst = std::max(worst, (p.x[q] - (x0[p.id[q]] + shift)).norm());
      INFO(transfer << " dt = " << dt << ": largest deviation " << worst << " m");
      CHECK(worst < 1e-10);
      for (const StoredMat3& F : sim->particles().F) REQUIRE((to_real(F) - Mat3::Identity()).norm() < 1e-10);
    }
}
