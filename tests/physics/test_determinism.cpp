// The same scene, seed and build give bit-identical particle state for 1 and 2 threads.
#include <catch2/catch.hpp>

#include <omp.h>

#include <cstring>

#include "engine/run/run.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// FNV-1a over the bytes of x, v, F, C and every material's state (snow's Jp).
std::uint64_t state_hash(const Simulation& sim) {
  const Particles& p = sim.particles();
  std::uint64_t h = 1469598103934665603ull;
  auto eat = [&](const void* data, std::size_t bytes) {
    const auto* b = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) h = (h ^ b[i]) * 1099511628211ull;
  };
  eat(p.x.data(), p.x.size() * sizeof(Vec3));
  eat(p.v.data(), p.v.size() * sizeof(Vec3));
  eat(p.F.data(), p.F.size() * sizeof(StoredMat3));
  eat(p.C.data(), p.C.size() * sizeof(StoredMat3));
  for (const MaterialRange& m : sim.materials()) {
    const std::span<Real> state = m.material->state();
    eat(state.data(), state.size() * sizeof(Real));
  }
  return h;
}

std::uint64_t run_with_threads(int threads) {
  omp_set_num_threads(threads);
  // An elastic object of more than kParallelMinItems particles and a plastic one, so every
  // parallel loop really runs in parallel; a few hundred substeps through a collision.
  const SceneDesc scene = test::scene_from(
      "simulation: {frame_dt: 0.01, cfl: 0.5, dt: 2.0e-4}\n"
      "grid: {max: [1, 1, 1], dims: 40}\n"
      "objects:\n"
      "  - {name: jelly, mesh: " + test::cube_mesh() + ", scale: 0.3, offset: [0.32, 0.3, 0.5],\n"
      "     velocity: [1, -1, 0], density: 1000, material: corotated, E: 5.0e4, nu: 0.3}\n"
      "  - {name: snow, mesh: " + test::cube_mesh() + ", scale: 0.2, rotation: [0, 30, 0],\n"
      "     offset: [0.68, 0.3, 0.5], velocity: [-1, -1, 0], density: 400, material: snow,\n"
      "     E: 5.0e4, nu: 0.2}\n"
      "walls:\n"
      "  - {plane: {point: [0, 0.15, 0], normal: [0, 1, 0]}, boundary: slip, friction: 0.3}\n");
  auto sim = Simulation::create(scene, builtin_registry());
  REQUIRE(sim->objects()[0].count > static_cast<std::size_t>(kParallelMinItems));
  const RunResult r = run_frames(*sim, 4, scene.simulation.frame_dt, {});
  REQUIRE(r.status == "ok");
  REQUIRE(sim->substeps() >= 200);
  return state_hash(*sim);
}

}  // namespace

TEST_CASE("determinism: bit-identical state for 1 and 2 threads", "[physics]") {
  const int threads = omp_get_max_threads();
  const std::uint64_t one = run_with_threads(1), two = run_with_threads(2);
  omp_set_num_threads(threads);
  CHECK(one == two);
}
