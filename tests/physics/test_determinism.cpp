// The same scene, seed and build give bit-identical particle state for 1 and 2 threads, and
// with or without the reorder stage; set_threads caps every parallel part.
#include <catch2/catch.hpp>

#include <omp.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstring>
#include <mutex>
#include <set>
#include <thread>

#include "engine/run/run.h"
#include "support/float_bounds.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// FNV-1a over the bytes of x, v, F, C and every material's state (snow's Jp), particle by
/// particle in the order of their ids, so it does not depend on where the reorder stage put
/// each particle.
std::uint64_t state_hash(const Simulation& sim) {
  const Particles& p = sim.particles();
  std::uint64_t h = 1469598103934665603ull;
  auto eat = [&](const void* data, std::size_t bytes) {
    const auto* b = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) h = (h ^ b[i]) * 1099511628211ull;
  };
  std::vector<std::size_t> at(p.size());  // at[id] = memory index
  for (std::size_t q = 0; q < p.size(); ++q) at[p.id[q]] = q;
  for (std::size_t q : at) {
    eat(&p.x[q], sizeof(Vec3));
    eat(&p.v[q], sizeof(Vec3));
    eat(&p.F[q], sizeof(StoredMat3));
    if (!p.C.empty()) eat(&p.C[q], sizeof(StoredMat3));
    for (const MaterialRange& m : sim.materials()) {
      const std::span<Real> state = m.material->state();
      if (state.empty() || q < m.first || q >= m.first + m.count) continue;
      const std::size_t s = state.size() / m.count;
      eat(&state[(q - m.first) * s], s * sizeof(Real));
    }
  }
  return h;
}

/// Particles whose memory index is not their id.
std::size_t moved_particles(const Simulation& sim) {
  std::size_t moved = 0;
  for (std::size_t q = 0; q < sim.particles().size(); ++q) moved += sim.particles().id[q] != q;
  return moved;
}

/// Runs a collision of an elastic and a plastic object through 4 frames (a few hundred
/// substeps) with `threads` threads and the reorder stage every `reorder_every` substeps.
/// `split_from`: the fewest contacts after which the contact stage splits the gather
/// (SplitGather::min_contacts; this scene's solves have fewer than the default).
std::unique_ptr<Simulation> run_collision(int threads, int reorder_every, bool simd = false,
                                          std::size_t split_from = kSplitMinContacts) {
  omp_set_num_threads(threads);
  // An elastic object of more than kParallelMinItems particles and a plastic one, so every
  // parallel loop really runs in parallel.
  const SceneDesc scene = test::scene_from(
      "simulation: {frame_dt: 0.01, cfl: 0.5, dt: 2.0e-4, reorder_every: " +
      std::to_string(reorder_every) + ", simd: " + (simd ? "true" : "false") + "}\n"
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
  sim->split_gather().min_contacts = split_from;
  const RunResult r = run_frames(*sim, 4, scene.simulation.frame_dt, {});
  REQUIRE(r.status == RunStatus::ok);
  REQUIRE(sim->substeps() >= 200);
  return sim;
}

}  // namespace

TEST_CASE("determinism: bit-identical state for 1 and 2 threads", "[physics]") {
  const int threads = omp_get_max_threads();
  for (const bool simd : {false, true}) {
    INFO((simd ? "SIMD transfers" : "scalar transfers"));
    const auto one = run_collision(1, 8, simd), two = run_collision(2, 8, simd, 1);
    omp_set_num_threads(threads);
    CHECK(state_hash(*one) == state_hash(*two));
    // On two threads the SIMD path gathers the particles far from the wall beside the contact
    // stage (engine/step/split_gather.h), on one it runs the plain order: the hashes above
    // compare the two, provided the split really ran.
    CHECK(one->split_gather().runs == 0);
    if (simd) CHECK(two->split_gather().runs > two->substeps() / 2);
  }
}

TEST_CASE("reorder: particles moved in memory by cell, the same motion by id to round-off",
          "[physics]") {
  // Reordering changes which particle of a cell is added first to the grid sums (the sort
  // breaks ties by memory index), so it changes results at round-off, and only there, except
  // where the contact solve amplifies it (below).
  const int threads = omp_get_max_threads();
  for (const bool simd : {false, true}) {
    INFO((simd ? "SIMD transfers" : "scalar transfers"));
    const auto never = run_collision(2, 0, simd), often = run_collision(2, 1, simd);
    const std::uint64_t hash = state_hash(*often);
    CHECK(state_hash(*run_collision(1, 1, simd)) == hash);  // still the same for any thread count
    omp_set_num_threads(threads);
    CHECK(moved_particles(*never) == 0);
    CHECK(moved_particles(*often) > never->particles().size() / 2);
    // Each object keeps its range: the particles at [first, first + count) are its own.
    for (const ObjectInfo& o : often->objects())
      for (std::size_t q = o.first; q < o.first + o.count; ++q)
        REQUIRE(often->particles().id[q] - o.first < o.count);
    std::vector<std::size_t> at(often->particles().size());
    for (std::size_t q = 0; q < at.size(); ++q) at[often->particles().id[q]] = q;
    double dx = 0, dv = 0;
    for (std::size_t q = 0; q < at.size(); ++q) {
      dx = std::max(dx, (often->particles().x[at[q]] - never->particles().x[q]).norm());
      dv = std::max(dv, (often->particles().v[at[q]] - never->particles().v[q]).norm());
    }
    INFO("largest difference by id: position " << dx << " m, velocity " << dv << " m/s");
    // Scalar: the sums differ at double round-off; F and C are stored with epsilon kStoredEps,
    // so what surfaces is a few storage roundings of F. Bound: one storage epsilon of a cell
    // (h = 1/40), 3e-9 m; measured 3.3e-10 m after 4 frames of the float build.
    if (!simd) {
      CHECK(dx < test::kStoredEps / 40);
      continue;
    }
    // SIMD: the sums are float, so each run is within test::simd_position_bound of the exact
    // transfers (support/float_bounds.h) and the two within twice that; speeds at most
    // |v0| + g t = sqrt(2) + 9.81 * 0.04 (or the largest seen at the end, if more). 1.0e-6 m.
    // The floor's contact solve (12 projected Jacobi iterations, not run to convergence) is
    // not a smooth function of its input: a float round-off can change which particles are in
    // reach or push, and its unconverged answer then moves by up to what it leaves unresolved,
    // its residual. So near the floor the velocities may differ by up to the mean residual of
    // the solves, and positions by that times the run's 0.04 s. Measured (AVX2): 4.4e-4 m/s
    // and 3.8e-6 m, against a residual of 2.3e-3 m/s; without the floor the same runs differ
    // by 1.1e-6 m/s and 8.4e-8 m in their frames (on AVX-512 also with it: 9.0e-9 m).
    double speed = std::sqrt(2.0) + 9.81 * 0.04, residual = 0;
    for (const auto* sim : {never.get(), often.get()}) {
      for (const Vec3& v : sim->particles().v) speed = std::max(speed, v.norm());
      const ContactSolveStats& solves = sim->contact_memory().stats;
      REQUIRE(solves.solves > 0);
      residual = std::max(residual, solves.residual / static_cast<double>(solves.solves));
    }
    INFO("the contact solves' mean residual " << residual << " m/s");
    CHECK(dv < residual);
    CHECK(dx < 2 * test::simd_position_bound(0.04, speed) + residual * 0.04);
  }
}

TEST_CASE("set_threads caps OpenMP and TBB (OpenVDB's set-up work) alike") {
  const int threads = omp_get_max_threads();
  const auto tbb_cap = [] {
    return tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  };
  const std::size_t uncapped = tbb_cap();
  // The threads a TBB loop runs on: with its cap at one, only the calling thread.
  const auto tbb_threads = [] {
    std::mutex m;
    std::set<std::thread::id> ids;
    tbb::parallel_for(0, 256, [&](int i) {
      volatile double sink = 0;
      for (int k = 0; k < 20000; ++k) sink = sink + std::sqrt(double(i + k));
      const std::lock_guard<std::mutex> lock(m);
      ids.insert(std::this_thread::get_id());
    });
    return ids.size();
  };
  set_threads(1);
  CHECK(omp_get_max_threads() == 1);
  CHECK(tbb_cap() == 1);
  CHECK(tbb_threads() == 1);
  set_threads(2);
  CHECK(omp_get_max_threads() == 2);
  CHECK(tbb_cap() == 2);
  set_threads(0);  // lifts TBB's cap, leaves OpenMP's setting
  CHECK(tbb_cap() == uncapped);
  CHECK(omp_get_max_threads() == 2);
  omp_set_num_threads(threads);
}
