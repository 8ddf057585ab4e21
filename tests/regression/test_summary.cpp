// Run summaries: values against the particles, exact YAML round trip, comparison and
// tolerances, bad input, file size, and free-fall physics seen through the summary.
#include <omp.h>

#include <catch2/catch.hpp>

#include <regex>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <sys/wait.h>
#include <tuple>

#include <yaml-cpp/yaml.h>

#include "engine/run/run.h"
#include "engine/io/summary.h"
#include "support/float_bounds.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// Two small elastic cubes far apart, falling freely (no walls), with different velocities.
// clang-format off
std::string two_cubes(int frames, std::optional<bool> simd = std::nullopt) {
  return "simulation:\n"
         "  frames: " + std::to_string(frames) + "\n"
         "  frame_dt: 0.02\n"
         "  dt: 0.002\n" +
         (simd ? std::string("  simd: ") + (*simd ? "true" : "false") + "\n" : "") +
         "grid:\n"
         "  max: [1, 1, 1]\n"
         "  dims: 20\n"
         "objects:\n"
         "  - name: left\n"
         "    mesh: " + test::cube_mesh() + "\n"
         "    scale: 0.15\n"
         "    offset: [0.3, 0.7, 0.5]\n"
         "    velocity: [0.3, 0.0, 0.1]\n"
         "    density: 1000\n"
         "    material: corotated\n"
         "    E: 1.0e5\n"
         "    nu: 0.3\n"
         "  - name: right\n"
         "    mesh: " + test::cube_mesh() + "\n"
         "    scale: 0.15\n"
         "    rotation: [10, 20, 30]\n"
         "    offset: [0.7, 0.6, 0.5]\n"
         "    velocity: [-0.2, 0.5, -0.1]\n"
         "    density: 500\n"
         "    material: corotated\n"
         "    E: 2.0e5\n"
         "    nu: 0.25\n";
}
// clang-format on

/// Per-object numbers computed straight from the particles, grouped by each particle's object
/// id (not by the ObjectInfo ranges summarize() uses).
struct Independent {
  std::vector<double> mass, kinetic, gravitational, max_speed, mean_speed;
  std::vector<Vec3> centroid, momentum, angular, lo, hi;
  double elastic_total = 0;
  double time = 0;
};

Independent compute_independently(const Simulation& sim) {
  const Particles& p = sim.particles();
  const std::size_t n_obj = sim.objects().size();
  const Vec3 g = sim.scene().simulation.gravity, o = sim.scene().grid.origin;
  Independent r;
  r.mass.assign(n_obj, 0);
  r.kinetic.assign(n_obj, 0);
  r.gravitational.assign(n_obj, 0);
  r.max_speed.assign(n_obj, 0);
  r.mean_speed.assign(n_obj, 0);
  r.centroid.assign(n_obj, Vec3::Zero());
  r.momentum.assign(n_obj, Vec3::Zero());
  r.angular.assign(n_obj, Vec3::Zero());
  r.lo.assign(n_obj, Vec3::Constant(1e300));
  r.hi.assign(n_obj, Vec3::Constant(-1e300));
  std::vector<double> count(n_obj, 0);
  for (std::size_t q = 0; q < p.size(); ++q) {
    const std::size_t k = p.object[q];
    const double m = p.mass(q);
    const Vec3 &x = p.x[q], &v = p.v[q];
    r.mass[k] += m;
    r.centroid[k] += m * x;
    r.kinetic[k] += 0.5 * m * v.squaredNorm();
    r.gravitational[k] += -m * g.dot(x - o);
    r.max_speed[k] = std::max(r.max_speed[k], v.norm());
    r.mean_speed[k] += v.norm();
    count[k] += 1;
    r.momentum[k] += m * v;
    r.angular[k] += m * (x - o).cross(v);
    r.lo[k] = r.lo[k].cwiseMin(x);
    r.hi[k] = r.hi[k].cwiseMax(x);
  }
  for (std::size_t k = 0; k < n_obj; ++k) {
    r.centroid[k] /= r.mass[k];
    r.mean_speed[k] /= count[k];
  }
  r.elastic_total = sim.elastic_energy();
  r.time = sim.time();
  return r;
}

/// Records the independent numbers at frame 0 and after every frame.
struct Recorder : Observer {
  std::vector<Independent> frames;
  void on_start(const Simulation& sim, int) override {
    frames.push_back(compute_independently(sim));
  }
  void on_frame(const Simulation& sim, int) override {
    frames.push_back(compute_independently(sim));
  }
};

/// Checks after each frame that summary.yaml on disk already holds every frame so far.
struct FileWatcher : Observer {
  std::filesystem::path file;
  std::vector<std::size_t> frames_on_disk;
  void on_frame(const Simulation&, int) override {
    frames_on_disk.push_back(read_summary(file).frames.size());
  }
};

struct Run {
  RunSummary summary;
  std::filesystem::path dir;
  std::unique_ptr<Simulation> sim;
};

Run run_two_cubes(const std::string& name, int frames, std::vector<Observer*> extra = {},
                  std::optional<bool> simd = std::nullopt) {
  Run r;
  r.dir = test::temp_dir(name);
  const SceneDesc scene = test::scene_from(two_cubes(frames, simd));
  r.sim = Simulation::create(scene, builtin_registry());
  SummaryWriter writer(r.dir);
  std::vector<Observer*> observers{&writer};
  observers.insert(observers.end(), extra.begin(), extra.end());
  const RunResult result = run_frames(*r.sim, frames, scene.simulation.frame_dt, observers);
  REQUIRE(result.status == RunStatus::ok);
  r.summary = writer.summary();
  return r;
}

/// Bit-for-bit equality of two doubles (NaN equals NaN, 0 differs from -0).
bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

bool same_bits(const Vec3& a, const Vec3& b) {
  return same_bits(a.x(), b.x()) && same_bits(a.y(), b.y()) && same_bits(a.z(), b.z());
}

/// Every field of two summaries, bit for bit; the first difference goes to INFO via `why`.
bool identical(const RunSummary& a, const RunSummary& b, std::string& why) {
  if (a.scene != b.scene) return why = "scene", false;
  if (a.frames.size() != b.frames.size()) return why = "frame count", false;
  for (std::size_t i = 0; i < a.frames.size(); ++i) {
    const FrameSummary &fa = a.frames[i], &fb = b.frames[i];
    const std::string at = "frame " + std::to_string(i) + ": ";
    if (fa.frame != fb.frame || !same_bits(fa.time, fb.time)) return why = at + "time", false;
    if (fa.objects.size() != fb.objects.size()) return why = at + "objects", false;
    for (std::size_t k = 0; k < fa.objects.size(); ++k) {
      const ObjectSummary &x = fa.objects[k], &y = fb.objects[k];
      const std::map<std::string, bool> fields{
          {"name", x.name == y.name},
          {"particles", x.particles == y.particles},
          {"centroid", same_bits(x.centroid, y.centroid)},
          {"bbox_min", same_bits(x.bbox_min, y.bbox_min)},
          {"bbox_max", same_bits(x.bbox_max, y.bbox_max)},
          {"mean_speed", same_bits(x.mean_speed, y.mean_speed)},
          {"max_speed", same_bits(x.max_speed, y.max_speed)},
          {"kinetic_energy", same_bits(x.kinetic_energy, y.kinetic_energy)},
          {"elastic_energy", same_bits(x.elastic_energy, y.elastic_energy)},
          {"gravitational_energy", same_bits(x.gravitational_energy, y.gravitational_energy)},
          {"linear_momentum", same_bits(x.linear_momentum, y.linear_momentum)},
          {"angular_momentum", same_bits(x.angular_momentum, y.angular_momentum)}};
      for (const auto& [field, equal] : fields)
        if (!equal) return why = at + "object " + std::to_string(k) + " " + field, false;
    }
  }
  return true;
}

const Difference& row(const CompareResult& r, const std::string& quantity) {
  for (const Difference& d : r.largest)
    if (d.quantity == quantity || d.quantity.rfind(quantity + ".", 0) == 0) return d;
  FAIL("no row for " << quantity);
  return r.largest.front();
}

/// Approx relative to `scale`, so that values near zero are compared on the right scale.
bool near(double a, double b, double scale, double eps = 1e-12) {
  return std::abs(a - b) <= eps * std::max(scale, 1e-300);
}

}  // namespace

TEST_CASE("summary.yaml holds the values computed from the particles", "[summary]") {
  for (const bool simd : {false, true}) {
  INFO((simd ? "SIMD transfers" : "scalar transfers"));
  Recorder recorder;
  const int frames = 5;
  Run run = run_two_cubes("summary_values", frames, {&recorder}, simd);
  const RunSummary s = read_summary(run.dir / "summary.yaml");
  REQUIRE(s.scene == "test.yaml");
  REQUIRE(s.frames.size() == frames + 1);
  REQUIRE(recorder.frames.size() == frames + 1);
  const std::size_t n_total = run.sim->particles().size();
  for (int f = 0; f <= frames; ++f) {
    INFO("frame " << f);
    const FrameSummary& fs = s.frames[f];
    const Independent& ind = recorder.frames[f];
    CHECK(fs.frame == f);
    CHECK(fs.time == ind.time);
    CHECK(fs.time == Approx(f * 0.02).epsilon(1e-12));
    REQUIRE(fs.objects.size() == 2);
    CHECK(fs.objects[0].name == "left");
    CHECK(fs.objects[1].name == "right");
    CHECK(fs.objects[0].particles + fs.objects[1].particles == n_total);
    CHECK(fs.objects[0].particles > 100);
    double elastic = 0;
    for (std::size_t k = 0; k < 2; ++k) {
      INFO("object " << fs.objects[k].name);
      const ObjectSummary& o = fs.objects[k];
      const double L = 1.0;  // the grid's size: the scale of positions
      for (int a = 0; a < 3; ++a) {
        CHECK(near(o.centroid[a], ind.centroid[k][a], L));
        CHECK(o.bbox_min[a] == ind.lo[k][a]);
        CHECK(o.bbox_max[a] == ind.hi[k][a]);
        CHECK(near(o.linear_momentum[a], ind.momentum[k][a], ind.momentum[k].norm() + 1e-3));
        CHECK(near(o.angular_momentum[a], ind.angular[k][a], ind.angular[k].norm() + 1e-3));
      }
      CHECK(o.kinetic_energy == Approx(ind.kinetic[k]).epsilon(1e-12));
      CHECK(o.gravitational_energy == Approx(ind.gravitational[k]).epsilon(1e-12));
      CHECK(o.max_speed == ind.max_speed[k]);
      CHECK(o.mean_speed == Approx(ind.mean_speed[k]).epsilon(1e-12));
      // A uniform, shape-keeping motion: the centroid velocity is the mean velocity.
      // SIMD: every particle's velocity within test::simd_velocity_bound of the body's
      // (support/float_bounds.h), so max and mean speed within twice that: 2 kSubstepRel u
      // relative, 1.4e-5; measured 1.6e-6.
      CHECK(o.max_speed ==
            Approx(o.mean_speed).epsilon(simd ? 2 * test::kSubstepRel * test::kFloatU : 1e-9));
      elastic += o.elastic_energy;
    }
    CHECK(near(elastic, ind.elastic_total, std::abs(s.frames[f].objects[0].kinetic_energy)));
    // Frame f's state: the centroid moved by v0 t + g t^2 / 2 (+ g t dt / 2) from frame 0.
    const double t = fs.time;
    const Vec3 expected = s.frames[0].objects[0].centroid + Vec3(0.3, 0, 0.1) * t +
                          Vec3(0, -9.81, 0) * (0.5 * t * t + 0.5 * t * 0.002);
    // SIMD: test::simd_position_bound at the speed |v0 + g t| (7e-7 m at t = 0.1 s; measured
    // 1.9e-9 m).
    const double speed = (Vec3(0.3, 0, 0.1) + Vec3(0, -9.81, 0) * t).norm();
    CHECK((fs.objects[0].centroid - expected).norm() <=  // <=: frame 0 is exact, bound 0
          (simd ? test::simd_position_bound(t, speed) : 1e-10));
  }
  }
}

TEST_CASE("the summary file is rewritten after every frame", "[summary]") {
  FileWatcher watcher;
  const auto dir = test::temp_dir("summary_progress");
  watcher.file = dir / "summary.yaml";
  const SceneDesc scene = test::scene_from(two_cubes(4));
  auto sim = Simulation::create(scene, builtin_registry());
  SummaryWriter writer(dir);
  REQUIRE(writer.file() == dir / "summary.yaml");
  // The watcher runs after the writer, so the file must already hold frames 0..f.
  const RunResult r = run_frames(*sim, 4, scene.simulation.frame_dt, {&writer, &watcher});
  REQUIRE(r.status == RunStatus::ok);
  CHECK(watcher.frames_on_disk == std::vector<std::size_t>{2, 3, 4, 5});
  CHECK_FALSE(std::filesystem::exists(dir / "summary.yaml.tmp"));
}

TEST_CASE("a resumed run keeps the earlier frames of its summary", "[summary]") {
  Run full = run_two_cubes("summary_resume", 5);
  // The same scene run to frame 3 without observers, as a checkpoint would restore it.
  const SceneDesc scene = test::scene_from(two_cubes(5));
  auto sim = Simulation::create(scene, builtin_registry());
  REQUIRE(run_frames(*sim, 3, scene.simulation.frame_dt, {}).status == RunStatus::ok);
  SummaryWriter resumed(full.dir);
  resumed.on_start(*sim, 5);
  RunSummary expected = full.summary;
  expected.frames.resize(4);  // frames 0, 1, 2 from the file, 3 from the state
  std::string why;
  const bool same = identical(read_summary(full.dir), expected, why);
  INFO(why);
  CHECK(same);
  CHECK(resumed.summary().frames.back().frame == 3);
  // A new run (time 0) starts afresh, whatever the folder holds.
  auto fresh = Simulation::create(scene, builtin_registry());
  SummaryWriter restart(full.dir);
  restart.on_start(*fresh, 5);
  CHECK(read_summary(full.dir).frames.size() == 1);
}

TEST_CASE("summary write -> read round trip is exact", "[summary]") {
  Run run = run_two_cubes("summary_roundtrip", 3);
  std::string why;
  const RunSummary back = read_summary(run.dir / "summary.yaml");
  const bool same = identical(back, run.summary, why);
  INFO(why);
  CHECK(same);

  // Awkward doubles: not short decimals, tiny, huge, subnormal, signed zero, non-finite.
  RunSummary odd = run.summary;
  ObjectSummary& o = odd.frames[1].objects[1];
  o.centroid = Vec3(0.1 + 1.0 / 3.0, -1e-300, 5e-324);
  o.bbox_min = Vec3(-0.0, 1e300, std::nextafter(1.0, 2.0));
  o.bbox_max = Vec3(1e20, 1e-5, 123456789012345680.0);
  o.kinetic_energy = std::numeric_limits<double>::quiet_NaN();
  o.elastic_energy = std::numeric_limits<double>::infinity();
  o.gravitational_energy = -std::numeric_limits<double>::infinity();
  o.name = "a \"quoted\" name: with\\colon";
  odd.frames[1].objects[0].name = "yes";   // a YAML 1.1 boolean, must stay a string
  odd.frames[2].objects[1].name = o.name;  // names must agree across frames for compare
  odd.scene = "scenes/my scene.yaml";
  const std::string text = summary_to_yaml(odd);
  // Exponent forms carry a '.', so YAML 1.1 readers such as PyYAML see numbers.
  CHECK(text.find("1.0e+20") != std::string::npos);
  CHECK(text.find("1.0e-05") != std::string::npos);
  const RunSummary odd_back = parse_summary(text, "odd.yaml");
  const bool odd_same = identical(odd_back, odd, why);
  INFO(why);
  CHECK(odd_same);
}

TEST_CASE("a run compared with itself passes with zero differences", "[summary]") {
  Run run = run_two_cubes("summary_self", 4);
  const Tolerances tol = default_tolerances(run.summary);
  const CompareResult r = compare_summaries(run.summary, read_summary(run.dir), tol);
  INFO(format_comparison(r));
  CHECK(r.ok);
  CHECK(r.error.empty());
  CHECK(r.frames == 5);
  CHECK(r.objects == 2);
  REQUIRE(r.largest.size() == 10);
  for (const Difference& d : r.largest) {
    INFO(d.quantity);
    CHECK(d.difference == 0);
    CHECK(d.ok());
    CHECK(d.first_frame_over == -1);
  }
  const std::string table = format_comparison(r);
  CHECK(table.find("FAIL") == std::string::npos);
  CHECK(table.find("PASS: every quantity within tolerance (5 frames, 2 objects)") !=
        std::string::npos);
  // Even exact comparison passes: the same build gives the same bits.
  CHECK(compare_summaries(run.summary, run.summary, parse_tolerance_overrides(tol, {"all=0"})).ok);
}

TEST_CASE("a nudged centroid fails at the right frame, object and quantity", "[summary]") {
  Run run = run_two_cubes("summary_nudge", 6);
  const Tolerances tol = default_tolerances(run.summary);
  REQUIRE(tol.centroid > 0);

  RunSummary nudged = run.summary;
  nudged.frames[4].objects[1].centroid.y() += 3 * tol.centroid;
  nudged.frames[5].objects[1].centroid.y() += 10 * tol.centroid;  // the largest, later
  const CompareResult r = compare_summaries(nudged, run.summary, tol);
  const std::string table = format_comparison(r);
  INFO(table);
  CHECK_FALSE(r.ok);
  CHECK(r.error.empty());
  const Difference& d = row(r, "centroid");
  CHECK(d.quantity == "centroid.y");
  CHECK(d.frame == 5);
  CHECK(d.object == "right");
  CHECK(d.first_frame_over == 4);
  CHECK(d.difference == Approx(10 * tol.centroid).epsilon(1e-6));
  CHECK(d.value_a == nudged.frames[5].objects[1].centroid.y());
  CHECK(d.value_b == run.summary.frames[5].objects[1].centroid.y());
  CHECK(d.tolerance == tol.centroid);
  CHECK_FALSE(d.ok());
  for (const Difference& other : r.largest)
    if (&other != &d) CHECK(other.ok());
  // The table names the failing row and says where.
  std::istringstream lines(table);
  std::string line, centroid_line;
  while (std::getline(lines, line))
    if (line.rfind("centroid.y", 0) == 0) centroid_line = line;
  CHECK(centroid_line.find("right") != std::string::npos);
  CHECK(centroid_line.find("FAIL (first over at frame 4)") != std::string::npos);
  CHECK(table.find("FAIL: 1 of 10 quantities beyond tolerance") != std::string::npos);

  // Below the tolerance it passes; a looser override lets the big nudge pass too.
  RunSummary small = run.summary;
  small.frames[3].objects[0].centroid.x() -= 0.5 * tol.centroid;
  CHECK(compare_summaries(small, run.summary, tol).ok);
  const Tolerances loose =
      parse_tolerance_overrides(tol, {"centroid=" + std::to_string(20 * tol.centroid)});
  CHECK(compare_summaries(nudged, run.summary, loose).ok);

  // A NaN in the run is never within tolerance.
  RunSummary broken = run.summary;
  broken.frames[2].objects[0].kinetic_energy = std::numeric_limits<double>::quiet_NaN();
  const CompareResult rb = compare_summaries(broken, run.summary, tol);
  CHECK_FALSE(rb.ok);
  CHECK(row(rb, "kinetic_energy").frame == 2);
  CHECK(row(rb, "kinetic_energy").object == "left");
}

TEST_CASE("summaries of different runs give an error, not a verdict", "[summary]") {
  Run run = run_two_cubes("summary_mismatch", 3);
  const Tolerances tol = default_tolerances(run.summary);
  auto error_of = [&](const RunSummary& a) {
    const CompareResult r = compare_summaries(a, run.summary, tol);
    CHECK_FALSE(r.ok);
    CHECK(format_comparison(r).rfind("cannot compare: ", 0) == 0);
    return r.error;
  };
  RunSummary fewer = run.summary;
  fewer.frames.pop_back();
  CHECK_THAT(error_of(fewer), Catch::Contains("different frame counts: 3 frames (0..2) vs 4"));

  RunSummary renamed = run.summary;
  for (FrameSummary& f : renamed.frames) f.objects[1].name = "other";
  CHECK_THAT(error_of(renamed), Catch::Contains("'other' vs 'right'"));

  RunSummary one_object = run.summary;
  for (FrameSummary& f : one_object.frames) f.objects.pop_back();
  CHECK_THAT(error_of(one_object), Catch::Contains("objects 'left' vs 'left', 'right'"));

  RunSummary more_particles = run.summary;
  for (FrameSummary& f : more_particles.frames) f.objects[0].particles += 1;
  CHECK_THAT(error_of(more_particles), Catch::Contains("particles vs"));

  RunSummary other_dt = run.summary;
  for (FrameSummary& f : other_dt.frames) f.time *= 2;
  CHECK_THAT(error_of(other_dt), Catch::Contains("different frame_dt?"));

  CHECK_THAT(error_of(RunSummary{}), Catch::Contains("no frames"));
}

TEST_CASE("a 2-object 10-frame summary is small", "[summary]") {
  Run run = run_two_cubes("summary_size", 10);
  const auto bytes = std::filesystem::file_size(run.dir / "summary.yaml");
  INFO(bytes << " bytes");
  CHECK(bytes < 20 * 1024);
  CHECK(run.summary.frames.size() == 11);
}

TEST_CASE("free fall seen through the summary: p grows by M g t, energy as symplectic Euler",
          "[summary][physics]") {
  for (const bool simd : {false, true}) {
  INFO((simd ? "SIMD transfers" : "scalar transfers"));
  Run run = run_two_cubes("summary_free_fall", 8, {}, simd);
  const Vec3 g(0, -9.81, 0);
  const double dt = 0.002;
  double mass[2] = {0, 0};
  const Particles& p = run.sim->particles();
  for (std::size_t q = 0; q < p.size(); ++q) mass[p.object[q]] += p.mass(q);
  const FrameSummary& first = run.summary.frames.front();
  for (const FrameSummary& f : run.summary.frames) {
    INFO("frame " << f.frame);
    const double t = f.time;
    for (std::size_t k = 0; k < 2; ++k) {
      INFO("object " << f.objects[k].name);
      const ObjectSummary &o = f.objects[k], &o0 = first.objects[k];
      const Vec3 expected_p = o0.linear_momentum + mass[k] * g * t;
      // SIMD bounds (support/float_bounds.h): the momentum drifts by at most kSubstepRel u of
      // sum m |v| <= M |v| per substep (10 per frame), |v| <= |v0| + |g| t; measured 8.8e-8
      // of 1 + |p|, bound 4e-4 of M |v| after 8 frames.
      const double speed = o0.linear_momentum.norm() / mass[k] + g.norm() * t;
      const std::size_t substeps = static_cast<std::size_t>(std::lround(t / dt));
      CHECK((o.linear_momentum - expected_p).norm() <=  // <=: frame 0 is exact, bound 0
            (simd ? test::simd_momentum_bound(substeps, mass[k] * speed)
                  : 1e-12 * (1 + expected_p.norm())));
      // F stays I in free fall: no elastic energy. SIMD: F within test::simd_F_bound of I
      // (h = 1/20), and corotated's energy density mu |F - R|^2 + lambda / 2 (J - 1)^2 is at
      // most (mu + 3 lambda / 2) |F - I|^2 <= 1.25 E |F - I|^2 (nu <= 0.3) over the volume
      // M / rho (left: E = 1e5, rho = 1000; right: 2e5, 500). Measured 1.7e-12 of K0.
      const double E = k == 0 ? 1e5 : 2e5, rho = k == 0 ? 1000 : 500;
      const double dF = test::simd_F_bound(substeps, t, speed, 1.0 / 20);
      CHECK(std::abs(o.elastic_energy) <
            (simd ? 1.25 * E * mass[k] / rho * dF * dF + 1e-12 * o0.kinetic_energy
                  : 1e-12 * o0.kinetic_energy));
      // Symplectic Euler (grid v += dt g, then x += dt v) gives v_n = v0 + g t and
      // x_n = x0 + v0 t + g t^2/2 + g t dt/2, so K + U drifts by exactly -M |g|^2 t dt / 2;
      // that, and nothing but round-off, is what the summary must show.
      const double e0 = o0.kinetic_energy + o0.gravitational_energy;
      const double e = o.kinetic_energy + o.gravitational_energy;
      const double drift = -0.5 * mass[k] * g.squaredNorm() * t * dt;
      // SIMD: U moves by M |g| times the position error (test::simd_position_bound), K by
      // M |v| times the velocity error (test::simd_velocity_bound); measured 2.6e-8 of |U0|.
      const double simd_e = mass[k] * (g.norm() * test::simd_position_bound(t, speed) +
                                       speed * test::simd_velocity_bound(speed));
      CHECK(std::abs(e - (e0 + drift)) <
            (simd ? simd_e + 1e-12 * std::abs(o0.gravitational_energy)
                  : 1e-12 * std::abs(o0.gravitational_energy)));
    }
  }
  // The drift is real and resolved: after 8 frames it is far above round-off.
  const double t_end = run.summary.frames.back().time;
  CHECK(0.5 * mass[0] * g.squaredNorm() * t_end * dt >
        1e-6 * std::abs(first.objects[0].gravitational_energy));
  }
}

TEST_CASE("default tolerances scale with the reference run", "[summary]") {
  RunSummary s;
  s.frames.resize(2);
  for (int f = 0; f < 2; ++f) {
    s.frames[f].frame = f;
    ObjectSummary o;
    o.name = "a";
    o.particles = 10;
    o.bbox_min = Vec3(1, 2, 3);
    o.bbox_max = Vec3(1.5, 2.2 + f, 3.1);  // largest extent 1.2 (frame 1, y)
    o.max_speed = 2 + f;                   // largest 3
    o.kinetic_energy = 4 + f;              // |K| + |E_el|: 5, then 6
    o.elastic_energy = -1;
    o.gravitational_energy = 100 - 5 * f;       // range 5, whatever the offset 100
    o.linear_momentum = Vec3(0, 3 * f, 4 * f);  // largest |p| 5
    s.frames[f].objects.push_back(o);
  }
  const Tolerances t = default_tolerances(s);
  CHECK(t.centroid == Approx(1e-3 * 1.2));
  CHECK(t.bbox == Approx(5e-3 * 1.2));
  CHECK(t.speed == Approx(5e-3 * 3));
  CHECK(t.energy == Approx(1e-3 * (6 + 5)));
  CHECK(t.momentum == Approx(5e-3 * 5));
  CHECK(t.angular_momentum == Approx(5e-3 * 5 * Vec3(1.5, 3.2, 3.1).norm()));
  // Twice the size: twice the length tolerances, same speed tolerance.
  RunSummary big = s;
  for (FrameSummary& f : big.frames)
    for (ObjectSummary& o : f.objects) o.bbox_min *= 2, o.bbox_max *= 2;
  CHECK(default_tolerances(big).centroid == Approx(2 * t.centroid));
  CHECK(default_tolerances(big).speed == t.speed);
  // Moving the grid origin shifts gravitational energy but not the energy tolerance.
  RunSummary shifted = s;
  for (FrameSummary& f : shifted.frames) f.objects[0].gravitational_energy += 1e4;
  CHECK(default_tolerances(shifted).energy == Approx(t.energy));
}

TEST_CASE("tolerance overrides: QUANTITY=VALUE, unknown names are listed", "[summary]") {
  const Tolerances base{1, 2, 3, 4, 5, 6};
  const Tolerances t =
      parse_tolerance_overrides(base, {"centroid=1e-4", "energy=0.5", "angular_momentum=7"});
  CHECK(t.centroid == 1e-4);
  CHECK(t.bbox == 2);
  CHECK(t.speed == 3);
  CHECK(t.energy == 0.5);
  CHECK(t.momentum == 5);
  CHECK(t.angular_momentum == 7);
  const Tolerances all = parse_tolerance_overrides(base, {"all=0", "speed=1"});
  CHECK(all.centroid == 0);
  CHECK(all.angular_momentum == 0);
  CHECK(all.speed == 1);
  CHECK_THROWS_WITH(parse_tolerance_overrides(base, {"centriod=1"}),
                    Catch::Contains("unknown tolerance quantity 'centriod'") &&
                        Catch::Contains("centroid, bbox, speed, energy, momentum"));
  CHECK_THROWS_AS(parse_tolerance_overrides(base, {"centriod=1"}), std::invalid_argument);
  CHECK_THROWS_AS(parse_tolerance_overrides(base, {"centroid"}), std::invalid_argument);
  CHECK_THROWS_AS(parse_tolerance_overrides(base, {"centroid=-1"}), std::invalid_argument);
  CHECK_THROWS_AS(parse_tolerance_overrides(base, {"centroid=abc"}), std::invalid_argument);
  CHECK_THROWS_AS(parse_tolerance_overrides(base, {"centroid=1e-3x"}), std::invalid_argument);
  CHECK_THROWS_AS(parse_tolerance_overrides(base, {"centroid=nan"}), std::invalid_argument);
}

TEST_CASE("reading a bad summary names the file and the problem", "[summary]") {
  const auto dir = test::temp_dir("summary_bad");
  CHECK_THROWS_WITH(read_summary(dir / "missing.yaml"),
                    Catch::Contains("missing.yaml") && Catch::Contains("no such file"));
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return dir / name;
  };
  CHECK_THROWS_WITH(read_summary(write("syntax.yaml", "frames: [\n")),
                    Catch::Contains("syntax.yaml") && Catch::Contains("not valid YAML"));
  CHECK_THROWS_WITH(read_summary(write("list.yaml", "- 1\n- 2\n")),
                    Catch::Contains("list.yaml") && Catch::Contains("not a run summary"));
  CHECK_THROWS_WITH(read_summary(write("noframes.yaml", "scene: x\n")),
                    Catch::Contains("noframes.yaml") && Catch::Contains("missing 'frames'"));
  const std::string object =
      "frames:\n"
      "- frame: 0\n"
      "  time: 0\n"
      "  objects:\n"
      "  - name: cube\n"
      "    particles: 8\n"
      "    centroid: [0, 0, 0]\n"
      "    bbox_min: [0, 0, 0]\n"
      "    bbox_max: [0, 0, 0]\n"
      "    mean_speed: 0\n"
      "    max_speed: 0\n"
      "    kinetic_energy: 0\n"
      "    elastic_energy: 0\n"
      "    gravitational_energy: 0\n"
      "    linear_momentum: [0, 0, 0]\n"
      "    angular_momentum: [0, 0, 0]\n";
  CHECK(read_summary(write("good.yaml", object)).frames.at(0).objects.at(0).particles == 8);
  std::string no_energy = object;
  no_energy.replace(no_energy.find("    kinetic_energy: 0\n"), 22, "");
  CHECK_THROWS_WITH(read_summary(write("nokinetic.yaml", no_energy)),
                    Catch::Contains("nokinetic.yaml:5") &&
                        Catch::Contains("frames[0].objects[0] (cube): missing 'kinetic_energy'"));
  std::string bad_number = object;
  bad_number.replace(bad_number.find("max_speed: 0"), 12, "max_speed: fast");
  CHECK_THROWS_WITH(
      read_summary(write("badnumber.yaml", bad_number)),
      Catch::Contains("badnumber.yaml:11") && Catch::Contains("max_speed is not a number: 'fast'"));
  std::string short_vec = object;
  short_vec.replace(short_vec.find("centroid: [0, 0, 0]"), 19, "centroid: [0, 0]");
  CHECK_THROWS_WITH(read_summary(write("shortvec.yaml", short_vec)),
                    Catch::Contains("centroid must be a list of 3 numbers"));
  CHECK_THROWS_WITH(read_summary(write("version.yaml", "summary_version: 2\nframes: []\n")),
                    Catch::Contains("summary_version 2 is not supported"));
  // A folder stands for the summary.yaml inside it.
  CHECK(summary_path(dir) == dir / "summary.yaml");
  CHECK(summary_path(dir / "good.yaml") == dir / "good.yaml");
}

TEST_CASE("frames compared particle by particle", "[summary]") {
  FrameData a;
  const std::size_t n = 20;
  for (std::size_t q = 0; q < n; ++q) {
    for (int c = 0; c < 3; ++c) {
      a.position.push_back(0.01f * q + c);
      a.velocity.push_back(0.1f * c - 0.02f * q);
    }
    a.object_id.push_back(q < n / 2 ? 0 : 1);
    a.J.push_back(1.0f);
  }
  const ParticleDiff same = compare_frames(a, a);
  CHECK(same.error.empty());
  CHECK(same.particles == n);
  CHECK(same.max_position == 0);
  CHECK(same.max_velocity == 0);
  CHECK(same.max_J == 0);

  FrameData b = a;
  b.position[3 * 7 + 0] += 0.003f;
  b.position[3 * 7 + 2] += 0.004f;
  b.position[3 * 2 + 1] += 0.001f;
  b.velocity[3 * 13 + 1] -= 0.5f;
  b.J[5] = 0.9f;
  const ParticleDiff d = compare_frames(a, b);
  CHECK(d.error.empty());
  CHECK(d.position_index == 7);
  CHECK(d.max_position == Approx(0.005).epsilon(1e-4));
  CHECK(d.velocity_index == 13);
  CHECK(d.max_velocity == Approx(0.5).epsilon(1e-4));
  CHECK(d.J_index == 5);
  CHECK(d.max_J == Approx(0.1).epsilon(1e-4));

  FrameData shorter = a;
  shorter.position.resize(3 * (n - 1));
  shorter.velocity.resize(3 * (n - 1));
  shorter.object_id.resize(n - 1);
  shorter.J.resize(n - 1);
  CHECK_THAT(compare_frames(a, shorter).error,
             Catch::Contains("different particle counts: 20 vs 19"));
  FrameData other_object = a;
  other_object.object_id[4] = 1;
  CHECK_THAT(compare_frames(a, other_object).error, Catch::Contains("particle 4"));
}

TEST_CASE("a longer run is compared over the golden's frames, and says so", "[summary]") {
  Run run = run_two_cubes("summary_longer", 6);
  RunSummary golden = run.summary;
  golden.frames.resize(4);  // frames 0..3: a golden made with --frames 3

  // The run goes on past the golden: its first four frames are compared, and a line says so.
  const FrameSelection sel = select_frames(run.summary, golden);
  CHECK(sel.error.empty());
  REQUIRE(sel.a.frames.size() == 4);
  CHECK(sel.b.frames.size() == 4);
  CHECK_THAT(sel.note, Catch::Contains("compared frames 0..3") &&
                           Catch::Contains("the run goes on to frame 6"));
  const CompareResult r = compare_summaries(sel.a, sel.b, default_tolerances(sel.b));
  INFO(format_comparison(r));
  CHECK(r.ok);
  CHECK(r.frames == 4);

  // A change in the compared frames fails; one after the golden's last frame cannot be seen.
  RunSummary early = run.summary, late = run.summary;
  early.frames[3].objects[0].centroid.x() += 0.1;
  late.frames[5].objects[0].centroid.x() += 0.1;
  const FrameSelection se = select_frames(early, golden), sl = select_frames(late, golden);
  CHECK_FALSE(compare_summaries(se.a, se.b, default_tolerances(se.b)).ok);
  CHECK(compare_summaries(sl.a, sl.b, default_tolerances(sl.b)).ok);

  // A run shorter than its golden still cannot pass.
  RunSummary shorter = run.summary;
  shorter.frames.resize(3);
  const FrameSelection ss = select_frames(shorter, golden);
  CHECK(ss.note.empty());
  CHECK_THAT(compare_summaries(ss.a, ss.b, default_tolerances(ss.b)).error,
             Catch::Contains("different frame counts"));

  // Same length: nothing to say.
  CHECK(select_frames(run.summary, run.summary).note.empty());

  // --frames N: frames 0..N of both, which both must have.
  const FrameSelection two = select_frames(run.summary, golden, 2);
  CHECK(two.error.empty());
  CHECK(two.a.frames.size() == 3);
  CHECK(two.b.frames.size() == 3);
  CHECK_THAT(two.note, Catch::Contains("compared frames 0..2 (--frames 2)"));
  CHECK_THAT(select_frames(run.summary, golden, 5).error,
             Catch::Contains("--frames 5: the reference has frames 0..3, not frame 5"));
  CHECK_THAT(select_frames(shorter, run.summary, 4).error,
             Catch::Contains("--frames 4: the first summary has frames 0..2"));
}

namespace {

/// Runs `mpm ARGS` with stdout and stderr in one file; returns the exit code and the text.
std::pair<int, std::string> mpm_output(const std::string& args, const std::filesystem::path& dir) {
  const auto out = dir / "mpm_output.txt";
  const int status =
      std::system((std::string(MPM_BINARY) + " " + args + " > " + out.string() + " 2>&1").c_str());
  std::ifstream in(out);
  std::stringstream text;
  text << in.rdbuf();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, text.str()};
}

}  // namespace

TEST_CASE("mpm golden keeps an existing golden unless --force, and names the file it writes",
          "[summary]") {
  const auto dir = test::temp_dir("summary_golden_cli");
  std::ofstream(dir / "scene.yaml") << two_cubes(3);
  const std::string scene = (dir / "scene.yaml").string(), golden = (dir / "g.yaml").string();

  auto [code, text] = mpm_output("golden " + scene + " --frames 1 -o " + golden, dir);
  INFO(text);
  CHECK(code == 0);
  CHECK_THAT(text, Catch::Contains("golden summary in " + golden));
  CHECK_THAT(text, !Catch::Contains("output in"));
  // The header gives the frames that will run (--frames), not the scene's 3.
  CHECK_THAT(text, Catch::Contains("frames: 1 of 0.02 s"));
  const RunSummary first = read_summary(golden);
  CHECK(first.frames.size() == 2);

  // Again without --force: refused, the golden unchanged.
  std::tie(code, text) = mpm_output("golden " + scene + " --frames 2 -o " + golden, dir);
  CHECK(code == 2);
  CHECK_THAT(text, Catch::Contains("exists; give --force"));
  CHECK(read_summary(golden).frames.size() == 2);
  std::tie(code, text) = mpm_output("golden " + scene + " --frames 2 -o " + golden + " --force", dir);
  CHECK(code == 0);
  CHECK(read_summary(golden).frames.size() == 3);

  // A 3-frame run against the 2-frame golden: compared over frames 0..2, with a line saying so.
  std::tie(code, text) =
      mpm_output("run " + scene + " --out " + (dir / "run").string() + " --quiet", dir);
  REQUIRE(code == 0);
  std::tie(code, text) = mpm_output("compare " + (dir / "run").string() + " " + golden, dir);
  CHECK(code == 0);
  CHECK_THAT(text, Catch::Contains("compared frames 0..2, all of the reference's; the run goes on "
                                   "to frame 3"));
  CHECK_THAT(text, Catch::Contains("PASS: every quantity within tolerance (3 frames, 2 objects)"));
  // The other way round (a run shorter than its golden) cannot be compared.
  std::tie(code, text) = mpm_output("compare " + golden + " " + (dir / "run").string(), dir);
  CHECK(code == 2);
  std::tie(code, text) =
      mpm_output("compare " + (dir / "run").string() + " " + golden + " --frames 1", dir);
  CHECK(code == 0);
  CHECK_THAT(text, Catch::Contains("compared frames 0..1 (--frames 1)"));
  CHECK_THAT(text, Catch::Contains("(2 frames, 2 objects)"));
}

TEST_CASE("a run whose particles invert ends ok but warns, naming the object", "[summary]") {
  // A 0.3 m cube of E = 10 Pa (meant as kPa?) dropped on a floor flattens through itself.
  const auto scene_with = [](const std::string& E) {
    return "simulation:\n  frames: 20\n  frame_dt: 0.04\n  dt: 1.0e-3\n"
           "grid:\n  max: [1, 1, 1]\n  dims: 20\n"
           "objects:\n  - name: soft\n    mesh: " + test::cube_mesh() + "\n    scale: 0.3\n"
           "    offset: [0.5, 0.7, 0.5]\n    density: 1000\n    material: corotated\n"
           "    E: " + E + "\n    nu: 0.3\n"
           "walls:\n  - plane: {point: [0, 0.15, 0], normal: [0, 1, 0]}\n"
           "    boundary: separate\n";
  };
  for (const std::string E : {"10", "1.0e5"}) {
    INFO("E = " << E);
    const auto dir = test::temp_dir("summary_inverted");
    const SceneDesc scene = test::scene_from(scene_with(E));
    std::unique_ptr<Simulation> sim = Simulation::create(scene, builtin_registry());
    FrameOutput output(dir, scene.output);
    const RunResult r = run_frames(*sim, scene.simulation.frames, scene.simulation.frame_dt,
                                   {&output});
    CHECK(r.status == RunStatus::ok);
    // Whether any particle ends inverted, seen from the particles themselves.
    bool inverted = false;
    const Particles& p = sim->particles();
    for (std::size_t q = 0; q < p.size(); ++q) inverted |= to_real(p.F[q]).determinant() <= 0;
    const YAML::Node report = YAML::LoadFile((dir / "report.yaml").string());
    if (E == "10") {
      CHECK(inverted);
      REQUIRE(r.warnings.size() == 1);
      CHECK_THAT(r.warnings[0], Catch::Contains("object 'soft'") &&
                                    Catch::Contains("particles inverted (J = det F <= 0"));
      // The smallest J is a non-positive number and the frame a frame of this run.
      std::smatch m;
      REQUIRE(std::regex_search(r.warnings[0], m, std::regex("smallest (\\S+)\\) by frame (\\d+):")));
      CHECK(std::stod(m[1].str()) <= 0);
      CHECK(std::stoi(m[2].str()) >= 1);
      CHECK(std::stoi(m[2].str()) <= r.frames_done);
      REQUIRE(report["warnings"].IsSequence());
      CHECK(report["warnings"][0].as<std::string>() == r.warnings[0]);
    } else {
      CHECK_FALSE(inverted);
      CHECK(r.warnings.empty());
      CHECK_FALSE(report["warnings"].IsDefined());
    }
  }
}

TEST_CASE("summaries and energies are bit-identical for 1 and 2 threads",
          "[summary]") {
  // The per-frame sums run in parallel over fixed chunks (engine/core/reduce.h), combined in
  // chunk order: the thread count must not change a bit. A cube of more than
  // kParallelMinItems particles, deformed by a few substeps of a fall onto a floor.
  const SceneDesc scene = test::scene_from(
      "simulation: {frame_dt: 0.01, dt: 5.0e-4}\n"
      "grid: {max: [1, 1, 1], dims: 32}\n"
      "objects:\n"
      "  - {name: jelly, mesh: " + test::cube_mesh() + ", scale: 0.4, offset: [0.5, 0.35, 0.5],\n"
      "     velocity: [0.5, -2, 0.3], density: 1000, material: corotated, E: 1.0e5, nu: 0.3}\n"
      "  - {name: snow, mesh: " + test::cube_mesh() + ", scale: 0.2, offset: [0.5, 0.75, 0.5],\n"
      "     velocity: [0, -2, 0], density: 400, material: snow, E: 1.0e5, nu: 0.2}\n"
      "walls:\n"
      "  - {plane: {point: [0, 0.14, 0], normal: [0, 1, 0]}, boundary: sticky}\n");
  auto sim = Simulation::create(scene, builtin_registry());
  REQUIRE(sim->objects()[0].count > 2 * static_cast<std::size_t>(kParallelMinItems));
  const RunResult r = run_frames(*sim, 3, scene.simulation.frame_dt, {});
  REQUIRE(r.status == RunStatus::ok);
  const int threads = omp_get_max_threads();
  auto measure = [&](int n) {
    omp_set_num_threads(n);
    return std::make_tuple(summarize(*sim, 3), sim->total_energy(), sim->elastic_energy(),
                           sim->kinetic_energy());
  };
  const auto [one, e1, el1, k1] = measure(1);
  const auto [two, e2, el2, k2] = measure(2);
  omp_set_num_threads(threads);
  CHECK(std::memcmp(&e1, &e2, sizeof e1) == 0);
  CHECK(std::memcmp(&el1, &el2, sizeof el1) == 0);
  CHECK(std::memcmp(&k1, &k2, sizeof k1) == 0);
  CHECK(el1 > 0);  // deformed: the check sees real numbers
  REQUIRE(one.objects.size() == two.objects.size());
  for (std::size_t k = 0; k < one.objects.size(); ++k) {
    const ObjectSummary &a = one.objects[k], &b = two.objects[k];
    INFO("object " << a.name);
    CHECK(a.centroid == b.centroid);
    CHECK(a.bbox_min == b.bbox_min);
    CHECK(a.bbox_max == b.bbox_max);
    CHECK(a.mean_speed == b.mean_speed);
    CHECK(a.max_speed == b.max_speed);
    CHECK(a.kinetic_energy == b.kinetic_energy);
    CHECK(a.elastic_energy == b.elastic_energy);
    CHECK(a.gravitational_energy == b.gravitational_energy);
    CHECK(a.linear_momentum == b.linear_momentum);
    CHECK(a.angular_momentum == b.angular_momentum);
  }
}
