// `mpm bench` on tiny cases: what it reports, not how fast (timings are never asserted).
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>

#include "engine/tools/bench.h"
#include "engine/tools/roofline.h"

using namespace mpm;

namespace {

/// Runs `cases` at 3000 particles for `substeps` substeps, once: seconds, not minutes.
std::vector<BenchResult> tiny_bench(std::vector<std::string> cases, int substeps) {
  BenchOptions opt;
  opt.cases = std::move(cases);
  opt.particles = 3000;
  opt.substeps = substeps;
  opt.repeats = 1;
  return run_benchmarks(opt);
}

}  // namespace

TEST_CASE("bench reports particles, rates and the stages each case runs", "[regression]") {
  const std::vector<BenchResult> results =
      tiny_bench({"jello", "snow", "neo_hookean", "sand", "water"}, 3);
  REQUIRE(results.size() == 5);
  for (const BenchResult& r : results) {
    INFO(r.name);
    CHECK(r.particles > 1500);
    CHECK(r.particles < 6000);
    CHECK(r.particle_steps_per_second > 0);
    CHECK(r.peak_rss_bytes_per_particle > 0);
    const auto has = [&](const std::string& stage) {
      return std::any_of(r.stage_ns.begin(), r.stage_ns.end(),
                         [&](const auto& s) { return s.first == stage; });
    };
    // Every built-in model's stress is folded into the SIMD scatter: no pass, no array.
    CHECK(!has("compute_stress"));
    CHECK(has("particles_to_grid"));
    CHECK(has("grid_to_particles"));
    const bool plastic = r.name == "snow" || r.name == "sand" || r.name == "water";
    CHECK(has("plasticity") == plastic);  // only what the scene calls for
  }
  const std::string table = format_bench_table(results);
  CHECK(table.find("jello") != std::string::npos);
  CHECK(format_bench_csv(results).find("snow") != std::string::npos);
}

TEST_CASE("bench: the sparse case stores the same grid nodes in an 8 times larger domain",
          "[regression]") {
  // The grid keeps storage only for the blocks the particles touch (engine/step/grid.h).
  const std::vector<BenchResult> r = tiny_bench({"jello", "sparse"}, 2);
  REQUIRE(r.size() == 2);
  CHECK(r[1].grid_nodes > 6 * r[0].grid_nodes);
  CHECK(r[1].stored_nodes > 0);
  // The same cube in both: a x a x a blocks in the tight grid, and at most one block more per
  // axis where the larger grid's block boundaries cut it differently.
  const double a = std::cbrt(static_cast<double>(r[0].stored_nodes) / 64);
  CHECK(r[1].stored_nodes <= 64 * std::pow(a + 1, 3) + 0.5);
  CHECK(r[1].stored_nodes < r[1].grid_nodes / 4);
}

TEST_CASE("bench SCENE.yaml: any scene, run as mpm run runs it, with its overrides",
          "[regression]") {
  // A shipped scene shortened to one frame, its grid coarsened by --set: the figures are the
  // scene's own (its particle count, its stages: contact at the particles by --set).
  BenchOptions opt;
  opt.scene = (std::filesystem::path(MPM_SOURCE_DIR) / "scenes/dam_break.yaml").string();
  opt.frames = 1;
  opt.load.overrides = {{"simulation.contact", "particles"}};
  const std::vector<BenchResult> r = run_benchmarks(opt);
  REQUIRE(r.size() == 1);
  CHECK(r[0].name == "dam_break");
  CHECK(r[0].particles > 1000);
  CHECK(r[0].substeps > 0);
  CHECK(r[0].particle_steps_per_second > 0);
  const auto has = [&](const std::string& stage) {
    return std::any_of(r[0].stage_ns.begin(), r[0].stage_ns.end(),
                       [&](const auto& s) { return s.first == stage; });
  };
  CHECK(has("contact"));
  CHECK_FALSE(has("walls"));
  // A bad override is the scene's error, with the key, before anything runs.
  opt.load.overrides = {{"simulation.bogus", "1"}};
  CHECK_THROWS_WITH(run_benchmarks(opt), Catch::Contains("simulation.bogus"));
}

TEST_CASE("bench refuses an unknown case with the list of cases", "[regression]") {
  BenchOptions opt;
  opt.cases = {"jelly"};
  CHECK_THROWS_WITH(run_benchmarks(opt), Catch::Contains("two_cubes"));
}

TEST_CASE("bench machine peaks: SIMD FMA beats scalar, and a bandwidth is measured",
          "[regression]") {
  // What must hold on any x86-64: the dispatched vector target has more than one float lane,
  // and lanes x FMA make the vector float rate larger than the scalar double rate. Rates are
  // compared only within this one measurement, never against a fixed time.
  const MachinePeaks p = measure_machine_peaks(1, 3);  // best of 3: one descheduled run does not decide
  CHECK(p.threads == 1);
  CHECK_FALSE(p.simd_target.empty());
  CHECK(p.float_lanes >= 4);
  CHECK(p.float_gflops > p.scalar_double_gflops);
  CHECK(p.float_gflops > p.double_gflops);
  CHECK(p.triad_gbytes > 0);
}
