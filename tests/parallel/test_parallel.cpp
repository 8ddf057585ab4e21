// MPI domain decomposition (engine/parallel/): the slab rule, and `mpirun -np 2 mpm run`
// against one rank: frames equal to round-off, repeated runs bit-identical, bad input exits 2
// on every rank without a hang, and a checkpoint resumed on another number of ranks.
#include <sys/wait.h>

#include <catch2/catch.hpp>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "engine/io/output.h"
#include "engine/io/summary.h"
#include "engine/parallel/domain.h"
#include "support/helpers.h"

namespace fs = std::filesystem;
using namespace mpm;

namespace {

/// Runs `mpm ARGS` on `ranks` ranks (1: without mpirun) with one thread each; exit code.
int run_mpm(int ranks, const std::string& args, const fs::path& log) {
  std::string cmd = "OMP_NUM_THREADS=1 ";
  if (ranks > 1)
    cmd += std::string(MPIEXEC) + " --allow-run-as-root --oversubscribe -np " +
           std::to_string(ranks) + " ";
  cmd += std::string(MPM_BINARY) + " " + args + " --quiet > " + log.string() + " 2>&1";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string read_text(const fs::path& file) {
  std::ifstream in(file);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

/// The largest particle differences between the frames of two runs, over frames 0..last.
ParticleDiff worst_diff(const fs::path& a, const fs::path& b, int last) {
  ParticleDiff worst;
  for (int f = 0; f <= last; ++f) {
    const ParticleDiff d =
        compare_frames(read_frame_hdf5(frame_path(a, f)), read_frame_hdf5(frame_path(b, f)));
    REQUIRE(d.error.empty());
    REQUIRE(d.particles > 0);
    worst.particles = d.particles;
    worst.max_position = std::max(worst.max_position, d.max_position);
    worst.max_velocity = std::max(worst.max_velocity, d.max_velocity);
    worst.max_J = std::max(worst.max_J, d.max_J);
  }
  return worst;
}

/// `scene` for `frames` frames on 1 and 2 ranks; the worst frame difference between them.
ParticleDiff one_against_two(const std::string& name, const std::string& scene,
                             const std::string& sets, int frames) {
  const fs::path dir = test::temp_dir("parallel_" + name);
  const std::string common = "run " + (test::source_dir() / scene).string() + " --frames " +
                             std::to_string(frames) + " " + sets + " --force --out ";
  REQUIRE(run_mpm(1, common + (dir / "one").string(), dir / "one.log") == 0);
  INFO(read_text(dir / "two.log"));
  REQUIRE(run_mpm(2, common + (dir / "two").string(), dir / "two.log") == 0);
  const std::string report = read_text(dir / "two" / "report.yaml");
  CHECK(report.find("ranks: 2") != std::string::npos);
  // `mpm compare` reads the two-rank run like any other, against the one-rank run.
  const std::string compare = std::string(MPM_BINARY) + " compare " + (dir / "two").string() + " " +
                              (dir / "one").string() + " > " + (dir / "compare.log").string() +
                              " 2>&1";
  CHECK(std::system(compare.c_str()) == 0);
  return worst_diff(dir / "one", dir / "two", frames);
}

}  // namespace

TEST_CASE("slabs balance particle counts and give every rank a layer", "[parallel]") {
  // 100 particles in layers 2..5 of 10: two ranks split them 50/50 at layer 4.
  std::vector<std::uint64_t> layers(10, 0);
  layers[2] = layers[3] = layers[4] = layers[5] = 25;
  const parallel::Slabs two = parallel::balanced_slabs(layers, 2, 0);
  CHECK(two.first_layer == std::vector<int>{0, 4, 10});
  CHECK(two.owner_of_layer(3) == 0);
  CHECK(two.owner_of_layer(4) == 1);
  CHECK(two.owner_of_layer(-1) == 0);
  CHECK(two.owner_of_layer(12) == 1);
  // 10, 30, 60 particles: two ranks split nearest 50 at layer 2 (40 | 60), not 3 (100 | 0).
  const parallel::Slabs nearest = parallel::balanced_slabs({10, 30, 60, 0}, 2, 0);
  CHECK(nearest.first_layer == std::vector<int>{0, 2, 4});
  // All particles in one layer: the bounds still increase, one layer per rank at least.
  std::vector<std::uint64_t> one(4, 0);
  one[0] = 1000;
  const parallel::Slabs four = parallel::balanced_slabs(one, 4, 1);
  CHECK(four.first_layer == std::vector<int>{0, 1, 2, 3, 4});
}

// The bound: the ranks add a ghost node's two partial sums in another order than one rank
// sums its particles, a difference of double round-off (1e-16 relative) per substep, which
// float particle storage (F, C) and the contact of the two cubes amplify over the frames.
// The frames store float positions (ulp 6e-8 m at 1 m). Measured over these cases: at most
// 6e-8 m, 1.2e-6 m/s and 1.1e-6 in J (one float ulp; docs/distributed.md); the bounds
// below leave about ten times that for growth over the frames.
constexpr double kPositionBound = 5e-7;  ///< m
constexpr double kVelocityBound = 1e-5;  ///< m/s
constexpr double kJBound = 1e-5;
TEST_CASE("two ranks give the frames of one rank to round-off: two_cubes", "[parallel]") {
  const ParticleDiff d = one_against_two("two_cubes", "scenes/two_cubes.yaml",
                                         "--set grid.dims=48 --set objects[0].particles_per_cell=4 "
                                         "--set objects[1].particles_per_cell=4",
                                         6);
  CHECK(d.max_position < kPositionBound);
  CHECK(d.max_velocity < kVelocityBound);
  CHECK(d.max_J < kJBound);
}

TEST_CASE("two ranks give the frames of one rank to round-off: validation cases", "[parallel]") {
  for (const char* name :
       {"sphere_collision", "dam_break", "sand_slope"}) {  // collision, water, sand
    INFO(name);
    const ParticleDiff d =
        one_against_two(name, std::string("scenes/validation/") + name + ".yaml", "",
                        std::string(name) == "sand_slope" ? 1 : 2);  // sand: 176 substeps a frame
    CHECK(d.max_position < kPositionBound);
    CHECK(d.max_velocity < kVelocityBound);
    CHECK(d.max_J < kJBound);
  }
}

TEST_CASE("two ranks: every material, objects that one rank does not hold", "[parallel]") {
  // Five objects in a row along x: each rank holds some objects' particles and none of the
  // others' (empty material ranges: the reorder stage once looped forever on them).
  const ParticleDiff d = one_against_two("lineup", "scenes/materials_lineup.yaml", "", 1);
  CHECK(d.max_position < kPositionBound);
  CHECK(d.max_velocity < kVelocityBound);
  CHECK(d.max_J < kJBound);
}

TEST_CASE("two runs on two ranks are bit-identical", "[parallel]") {
  const fs::path dir = test::temp_dir("parallel_repeat");
  const std::string common = "run " + (test::source_dir() / "scenes/two_cubes.yaml").string() +
                             " --frames 3 --set grid.dims=48 --set objects[0].particles_per_cell=4"
                             " --set objects[1].particles_per_cell=4 --force --out ";
  REQUIRE(run_mpm(2, common + (dir / "a").string(), dir / "a.log") == 0);
  REQUIRE(run_mpm(2, common + (dir / "b").string(), dir / "b.log") == 0);
  const ParticleDiff d = worst_diff(dir / "a", dir / "b", 3);
  CHECK(d.max_position == 0);
  CHECK(d.max_velocity == 0);
  CHECK(d.max_J == 0);
}

TEST_CASE("more ranks than slabs: an error on rank 0 and exit 2 on every rank", "[parallel]") {
  const fs::path dir = test::temp_dir("parallel_too_many");
  // 7 cells per axis: 8 nodes, two 4-node slabs, for three ranks.
  const std::string args = "run " + (test::source_dir() / "scenes/jello_cube.yaml").string() +
                           " --set grid.dims=7 --set grid.buffer=2 --set objects[0].scale=0.1"
                           " --force --out " +
                           (dir / "out").string();
  const int code = run_mpm(3, args, dir / "log");
  const std::string log = read_text(dir / "log");
  INFO(log);
  CHECK(code == 2);
  CHECK(log.find("3 ranks need at least 3 slabs") != std::string::npos);
  CHECK(log.find("grid.dims") != std::string::npos);
}

TEST_CASE("a checkpoint of one rank resumes on two", "[parallel]") {
  const fs::path dir = test::temp_dir("parallel_resume");
  const std::string scene = (test::source_dir() / "scenes/two_cubes.yaml").string();
  const std::string sets =
      " --set grid.dims=48 --set objects[0].particles_per_cell=4"
      " --set objects[1].particles_per_cell=4";
  REQUIRE(
      run_mpm(1,
              "run " + scene + " --frames 4" + sets + " --force --out " + (dir / "whole").string(),
              dir / "whole.log") == 0);
  REQUIRE(
      run_mpm(1,
              "run " + scene + " --frames 2" + sets + " --force --out " + (dir / "split").string(),
              dir / "first.log") == 0);
  INFO(read_text(dir / "second.log"));
  REQUIRE(run_mpm(2,
                  "run " + scene + " --frames 4" + sets + " --resume " + (dir / "split").string(),
                  dir / "second.log") == 0);
  const ParticleDiff d = worst_diff(dir / "whole", dir / "split", 4);
  CHECK(d.max_position < kPositionBound);
  CHECK(d.max_velocity < kVelocityBound);
}
