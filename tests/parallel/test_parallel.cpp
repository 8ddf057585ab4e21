// MPI domain decomposition (engine/parallel/): the slab rule, and `mpirun -np 2 mpm run`
// against one rank: frames equal to round-off, repeated runs bit-identical, bad input exits 2
// on every rank without a hang, a checkpoint resumed on another number of ranks (both ways),
// and a rank failing mid-substep stopping every rank with the cause in report.yaml.
#include <hdf5.h>
#include <sys/wait.h>
#include <yaml-cpp/yaml.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <utility>

#include "engine/io/output.h"
#include "engine/io/summary.h"
#include "engine/parallel/domain.h"
#include "engine/parallel/frame_hdf5.h"
#include "support/helpers.h"

namespace fs = std::filesystem;
using namespace mpm;

namespace {

/// The frame-end energies of two ranks against one, relative to the start's: round-off of
/// sums over 1e5 particles and of the states compared below.
constexpr double kRelativeEnergyBound = 1e-6;

/// Runs `mpm ARGS` on `ranks` ranks (1: without mpirun) with one thread each and the
/// environment settings `env` ("NAME=value "); exit code.
int run_mpm(int ranks, const std::string& args, const fs::path& log, const std::string& env = "") {
  std::string cmd = env + "OMP_NUM_THREADS=1 ";
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

/// How far the frames 0..last of two runs are apart, and the speed scale of the first.
struct Agreement {
  ParticleDiff diff;     ///< The largest differences over the frames.
  double max_speed = 0;  ///< The largest particle speed in the first run's frames, m/s.
};

/// The largest particle differences between the frames of two runs, over frames 0..last.
Agreement worst_diff(const fs::path& a, const fs::path& b, int last) {
  Agreement worst;
  for (int f = 0; f <= last; ++f) {
    const FrameData fa = read_frame_hdf5(frame_path(a, f));
    const ParticleDiff d = compare_frames(fa, read_frame_hdf5(frame_path(b, f)));
    REQUIRE(d.error.empty());
    REQUIRE(d.particles > 0);
    worst.diff.particles = d.particles;
    worst.diff.max_position = std::max(worst.diff.max_position, d.max_position);
    worst.diff.max_velocity = std::max(worst.diff.max_velocity, d.max_velocity);
    worst.diff.max_J = std::max(worst.diff.max_J, d.max_J);
    for (std::size_t q = 0; q < fa.size(); ++q) {
      const float* v = &fa.velocity[3 * q];
      worst.max_speed =
          std::max(worst.max_speed,
                   std::sqrt(double(v[0]) * v[0] + double(v[1]) * v[1] + double(v[2]) * v[2]));
    }
  }
  return worst;
}

/// energy_start and energy_max of a run's report.yaml, J (with more than one rank: sums of
/// each rank's part, added in rank order).
std::pair<double, double> report_energies(const fs::path& dir) {
  const YAML::Node r = YAML::LoadFile((dir / "report.yaml").string());
  return {r["energy_start"].as<double>(), r["energy_max"].as<double>()};
}

/// `scene` for `frames` frames on 1 and 2 ranks; the worst frame difference between them.
Agreement one_against_two(const std::string& name, const std::string& scene,
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
  // The frame-end energies are reductions over the ranks' own particles: the same sums added
  // in another order, and states that differ by the round-off bounded below.
  const auto [start1, max1] = report_energies(dir / "one");
  const auto [start2, max2] = report_energies(dir / "two");
  INFO("energy_start " << start1 << " / " << start2 << " J, energy_max " << max1 << " / " << max2);
  CHECK(std::abs(start2 - start1) <= kRelativeEnergyBound * std::abs(start1));
  CHECK(std::abs(max2 - max1) <= kRelativeEnergyBound * std::abs(start1));
  return worst_diff(dir / "one", dir / "two", frames);
}

// The bound: the ranks add a ghost node's two partial sums in another order than one rank
// sums its particles, a difference of double round-off (1e-16 relative) per substep, which
// float particle storage (F, C) and contact amplify over the frames. The frames store float
// positions (ulp 6e-8 m at 1 m). Measured over these cases: at most 2e-7 m, 4e-6 of the
// scene's largest speed (snowball_paper_wall: 4.2e-5 m/s where the snow moves at 10.3 m/s) and
// 1.2e-6 in J (docs/distributed.md); the bounds leave 2.5 times that or more for growth.
constexpr double kPositionBound = 5e-7;          ///< m
constexpr double kRelativeVelocityBound = 1e-5;  ///< Of the largest speed in the frames.
constexpr double kJBound = 1e-5;

/// Checks two runs agree within the stated bound.
void check_round_off(const Agreement& a) {
  INFO("max |dx| " << a.diff.max_position << " m, max |dv| " << a.diff.max_velocity
                   << " m/s at top speed " << a.max_speed << " m/s, max |dJ| " << a.diff.max_J);
  CHECK(a.diff.max_position < kPositionBound);
  CHECK(a.diff.max_velocity <= kRelativeVelocityBound * a.max_speed);
  CHECK(a.diff.max_J < kJBound);
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

TEST_CASE("two ranks give the frames of one rank to round-off: two_cubes", "[parallel]") {
  check_round_off(one_against_two("two_cubes", "scenes/two_cubes.yaml",
                                  "--set grid.dims=48 --set objects[0].particles_per_cell=4 "
                                  "--set objects[1].particles_per_cell=4",
                                  6));
}

TEST_CASE("two ranks give the frames of one rank to round-off: validation cases", "[parallel]") {
  for (const char* name :
       {"sphere_collision", "dam_break", "sand_slope"}) {  // collision, water, sand
    INFO(name);
    check_round_off(
        one_against_two(name, std::string("scenes/validation/") + name + ".yaml", "",
                        std::string(name) == "sand_slope" ? 1 : 2));  // sand: 176 substeps a frame
  }
}

TEST_CASE("two ranks: contact at the particles is solved as one set on rank 0", "[parallel]") {
  // simulation.contact = particles: each rank finds its own contacts, rank 0 solves every
  // rank's together, and each rank takes the new velocities of the nodes it stores. The water
  // pool touches the floor and four walls across both slabs; the dam break's surge front runs
  // across the slab boundary.
  check_round_off(
      one_against_two("water_contact", "scenes/validation/hydrostatic_water.yaml", "", 1));
  check_round_off(one_against_two("dam_break_contact", "scenes/validation/dam_break.yaml",
                                  "--set simulation.contact=particles", 2));
  // An elastic ball: its surface particles' contact radii are their rest depths, kept by id.
  check_round_off(one_against_two("rolling_contact", "scenes/validation/rolling_ball.yaml",
                                  "--set simulation.contact=particles", 2));
}

TEST_CASE("two ranks: every material, objects that one rank does not hold", "[parallel]") {
  // Five objects in a row along x: each rank holds some objects' particles and none of the
  // others' (empty material ranges: the reorder stage once looped forever on them).
  check_round_off(one_against_two("lineup", "scenes/materials_lineup.yaml", "", 1));
}

TEST_CASE("two ranks: the velocity bound scales with the scene's speed (fast snow)", "[parallel]") {
  // Snow at 10 m/s into a wall, hardened where it compacts: the largest velocity difference
  // of the tested scenes (4.2e-5 m/s), 4e-6 of its speed.
  check_round_off(one_against_two("snowball_paper_wall", "scenes/snowball_paper_wall.yaml", "", 1));
}

TEST_CASE("two ranks: the clumped snowball at a post (mesh wall, hardness from positions)",
          "[parallel]") {
  // scenes/snowball_paper.yaml at 8 cells across the ball (2,149 particles): each rank samples
  // its own particles, whose starting Jp comes from their positions and the seed, and the post
  // is a mesh wall both ranks' nodes meet. 0.02 s: the impact and the first failure.
  check_round_off(one_against_two("snowball_paper", "scenes/snowball_paper.yaml",
                                  "--set \"grid.dims=[80, 40, 40]\"", 1));
}

TEST_CASE("two ranks write the one-rank HDF5 frame file, ids 0..N-1 in order", "[parallel]") {
  // HDF5 the only output and no checkpoint: with MPM_PARALLEL_HDF5 each rank writes its own
  // particles at their id rows (no gather); otherwise rank 0 writes the gathered frame.
  const fs::path dir = test::temp_dir("parallel_collective_hdf5");
  const std::string common = "run " + (test::source_dir() / "scenes/two_cubes.yaml").string() +
                             " --frames 2 --set grid.dims=48 --set objects[0].particles_per_cell=4"
                             " --set objects[1].particles_per_cell=4 --set output.checkpoint=false"
                             " --force --out ";
  REQUIRE(run_mpm(1, common + (dir / "one").string(), dir / "one.log") == 0);
  INFO(read_text(dir / "two.log"));
  REQUIRE(run_mpm(2, common + (dir / "two").string(), dir / "two.log") == 0);
  const YAML::Node report = YAML::LoadFile((dir / "two" / "report.yaml").string());
  CHECK(report["collective_hdf5"].as<bool>() == parallel::collective_hdf5());
  CHECK(report["particles"].as<std::size_t>() ==
        YAML::LoadFile((dir / "one" / "report.yaml").string())["particles"].as<std::size_t>());
  for (int f = 0; f <= 2; ++f) {
    INFO("frame " << f);
    const FrameData one = read_frame_hdf5(frame_path(dir / "one", f));
    const FrameData two = read_frame_hdf5(frame_path(dir / "two", f));
    REQUIRE(two.size() == one.size());
    bool in_order = true;
    for (std::size_t q = 0; q < two.size(); ++q) in_order = in_order && two.id[q] == q;
    CHECK(in_order);
    CHECK(two.object_id == one.object_id);
    CHECK(two.time == one.time);
    CHECK(two.frame == f);
    // Frame 0 is the sampled state, written before any substep: the same values exactly.
    if (f == 0) {
      CHECK(two.position == one.position);
      CHECK(two.velocity == one.velocity);
      CHECK(two.J == one.J);
    }
    // The same datasets with the same file types and shapes as the one-rank writer's.
    const hid_t a = H5Fopen(frame_path(dir / "one", f).c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    const hid_t b = H5Fopen(frame_path(dir / "two", f).c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    REQUIRE(a >= 0);
    REQUIRE(b >= 0);
    H5G_info_t links_a, links_b;
    REQUIRE(H5Gget_info(a, &links_a) >= 0);
    REQUIRE(H5Gget_info(b, &links_b) >= 0);
    CHECK(links_b.nlinks == links_a.nlinks);
    H5O_info_t object_a, object_b;
    REQUIRE(H5Oget_info2(a, &object_a, H5O_INFO_NUM_ATTRS) >= 0);
    REQUIRE(H5Oget_info2(b, &object_b, H5O_INFO_NUM_ATTRS) >= 0);
    CHECK(object_b.num_attrs == object_a.num_attrs);
    for (const char* name : {"position", "velocity", "object_id", "J", "id"}) {
      INFO(name);
      const hid_t da = H5Dopen2(a, name, H5P_DEFAULT), db = H5Dopen2(b, name, H5P_DEFAULT);
      const hid_t ta = H5Dget_type(da), tb = H5Dget_type(db);
      CHECK(H5Tequal(ta, tb) > 0);
      const hid_t sa = H5Dget_space(da), sb = H5Dget_space(db);
      hsize_t dims_a[2] = {0, 0}, dims_b[2] = {0, 0};
      CHECK(H5Sget_simple_extent_dims(sb, dims_b, nullptr) ==
            H5Sget_simple_extent_dims(sa, dims_a, nullptr));
      CHECK((dims_a[0] == dims_b[0] && dims_a[1] == dims_b[1]));
      H5Sclose(sa), H5Sclose(sb), H5Tclose(ta), H5Tclose(tb), H5Dclose(da), H5Dclose(db);
    }
    H5Fclose(a);
    H5Fclose(b);
  }
  // Later frames: the stated round-off bound of two ranks against one.
  check_round_off(worst_diff(dir / "one", dir / "two", 2));
}

TEST_CASE("two runs on two ranks are bit-identical", "[parallel]") {
  const fs::path dir = test::temp_dir("parallel_repeat");
  const std::string common = "run " + (test::source_dir() / "scenes/two_cubes.yaml").string() +
                             " --frames 3 --set grid.dims=48 --set objects[0].particles_per_cell=4"
                             " --set objects[1].particles_per_cell=4 --force --out ";
  REQUIRE(run_mpm(2, common + (dir / "a").string(), dir / "a.log") == 0);
  REQUIRE(run_mpm(2, common + (dir / "b").string(), dir / "b.log") == 0);
  const ParticleDiff d = worst_diff(dir / "a", dir / "b", 3).diff;
  CHECK(d.max_position == 0);
  CHECK(d.max_velocity == 0);
  CHECK(d.max_J == 0);
  // The frame-end energy check's reductions add the ranks' parts in rank order.
  CHECK(report_energies(dir / "a") == report_energies(dir / "b"));
  // So do the summary's per-object statistics, each rank summing its own particles.
  CHECK(read_text(dir / "a" / "summary.yaml") == read_text(dir / "b" / "summary.yaml"));
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

TEST_CASE("quadrature domain on two ranks: an error naming the key and exit 2", "[parallel]") {
  const fs::path dir = test::temp_dir("parallel_domain_quadrature");
  const std::string args =
      "run " + (test::source_dir() / "scenes/validation/hydrostatic_water.yaml").string() +
      " --set simulation.quadrature=domain --force --out " + (dir / "out").string();
  const int code = run_mpm(2, args, dir / "log");
  const std::string log = read_text(dir / "log");
  INFO(log);
  CHECK(code == 2);
  CHECK(log.find("simulation.quadrature") != std::string::npos);
  CHECK(log.find("runs on one rank") != std::string::npos);
}

/// Runs two_cubes (small) for 4 frames in one go on `whole_ranks`, and for 2 frames on
/// `first_ranks` then resumed from its checkpoint to 4 on `second_ranks`; the frames agree.
void check_resume(const std::string& name, int whole_ranks, int first_ranks, int second_ranks) {
  const fs::path dir = test::temp_dir("parallel_resume_" + name);
  const std::string scene = (test::source_dir() / "scenes/two_cubes.yaml").string();
  const std::string sets =
      " --set grid.dims=48 --set objects[0].particles_per_cell=4"
      " --set objects[1].particles_per_cell=4";
  REQUIRE(
      run_mpm(whole_ranks,
              "run " + scene + " --frames 4" + sets + " --force --out " + (dir / "whole").string(),
              dir / "whole.log") == 0);
  REQUIRE(
      run_mpm(first_ranks,
              "run " + scene + " --frames 2" + sets + " --force --out " + (dir / "split").string(),
              dir / "first.log") == 0);
  INFO(read_text(dir / "second.log"));
  REQUIRE(run_mpm(second_ranks,
                  "run " + scene + " --frames 4" + sets + " --resume " + (dir / "split").string(),
                  dir / "second.log") == 0);
  check_round_off(worst_diff(dir / "whole", dir / "split", 4));
}

TEST_CASE("a checkpoint of one rank resumes on two", "[parallel]") {
  check_resume("1to2", 1, 1, 2);
}

TEST_CASE("a checkpoint of two ranks resumes on one", "[parallel]") {
  check_resume("2to1", 2, 2, 1);
}

TEST_CASE("a rank that fails mid-substep stops every rank with the cause in the report",
          "[parallel]") {
  const fs::path dir = test::temp_dir("parallel_rank_failure");
  const fs::path out = dir / "out";
  // two_cubes at grid 48 takes 42 substeps a frame: rank 1 throws in substep 60, in frame 2.
  const std::string args = "run " + (test::source_dir() / "scenes/two_cubes.yaml").string() +
                           " --frames 3 --set grid.dims=48 --set objects[0].particles_per_cell=4"
                           " --set objects[1].particles_per_cell=4 --force --out " +
                           out.string();
  // Each rank's exit code, through a shell per rank (mpirun itself ends the other ranks as
  // soon as one exits with a non-zero code, so its own code tells of one rank only).
  const std::string cmd = "MPM_TEST_FAIL_RANK=1 MPM_TEST_FAIL_SUBSTEP=60 OMP_NUM_THREADS=1 " +
                          std::string(MPIEXEC) +
                          " --allow-run-as-root --oversubscribe -np 2 sh -c '" + MPM_BINARY + " " +
                          args + " --quiet >> " + (dir / "log").string() + " 2>&1; echo $? > " +
                          (dir / "code_").string() + "$OMPI_COMM_WORLD_RANK'";
  CHECK(std::system(cmd.c_str()) == 0);
  const std::string log = read_text(dir / "log");
  INFO(log);
  CHECK(read_text(dir / "code_0") == "1\n");  // a failed run on both ranks
  CHECK(read_text(dir / "code_1") == "1\n");
  CHECK(log.find("MPI_ABORT") == std::string::npos);
  const std::string report = read_text(out / "report.yaml");
  INFO(report);
  CHECK(report.find("status: error") != std::string::npos);
  CHECK(report.find("rank 1, stage test_failure: test failure at substep 60") != std::string::npos);
  CHECK(report.find("the last complete frame is 1") != std::string::npos);
  // The frames before the failure are whole, with every particle; the failed one is absent.
  const FrameData first = read_frame_hdf5(frame_path(out, 1));
  CHECK(first.size() == read_frame_hdf5(frame_path(out, 0)).size());
  CHECK(first.frame == 1);
  CHECK_FALSE(fs::exists(frame_path(out, 2)));
  CHECK_FALSE(fs::exists(out / "frame_00002.h5.tmp"));
}

TEST_CASE("two ranks: the inversion warning counts every rank's particles", "[parallel]") {
  // A 0.3 m cube of E = 10 Pa dropped on a floor flattens through itself (the one-rank case
  // is in tests/regression/test_summary.cpp); its particles lie on both ranks' slabs.
  const fs::path dir = test::temp_dir("parallel_inversion");
  const fs::path scene = dir / "soft.yaml";
  std::ofstream(scene) << "simulation:\n  frames: 20\n  frame_dt: 0.04\n  dt: 1.0e-3\n"
                          "grid:\n  max: [1, 1, 1]\n  dims: 20\n"
                          "objects:\n  - name: soft\n    mesh: "
                       << test::cube_mesh()
                       << "\n    scale: 0.3\n    offset: [0.5, 0.7, 0.5]\n    density: 1000\n"
                          "    material: corotated\n    E: 10\n    nu: 0.3\n"
                          "walls:\n  - plane: {point: [0, 0.15, 0], normal: [0, 1, 0]}\n"
                          "    boundary: separate\n";
  const std::string common = "run " + scene.string() + " --force --out ";
  REQUIRE(run_mpm(1, common + (dir / "one").string(), dir / "one.log") == 0);
  INFO(read_text(dir / "two.log"));
  REQUIRE(run_mpm(2, common + (dir / "two").string(), dir / "two.log") == 0);
  const YAML::Node one = YAML::LoadFile((dir / "one" / "report.yaml").string());
  const YAML::Node two = YAML::LoadFile((dir / "two" / "report.yaml").string());
  REQUIRE(two["particles_per_rank"].size() == 2);
  CHECK(two["particles_per_rank"][0].as<std::uint64_t>() > 0);
  CHECK(two["particles_per_rank"][1].as<std::uint64_t>() > 0);
  REQUIRE(one["warnings"].size() == 1);
  REQUIRE(two["warnings"].size() == 1);
  const std::string w1 = one["warnings"][0].as<std::string>();
  const std::string w2 = two["warnings"][0].as<std::string>();
  INFO(w1 << "\n" << w2);
  // The same object, total particle count and frame: the counts and the smallest J are reduced
  // over the ranks, not taken from one rank's slab.
  const std::regex form("object 'soft': \\d+ of (\\d+) particles inverted .* by frame (\\d+):");
  std::smatch m1, m2;
  REQUIRE(std::regex_search(w1, m1, form));
  REQUIRE(std::regex_search(w2, m2, form));
  CHECK(m2[1].str() == m1[1].str());
  CHECK(m2[2].str() == m1[2].str());
}
