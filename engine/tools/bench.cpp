#include "engine/tools/bench.h"

#include <omp.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <stdexcept>

#include "engine/core/version.h"
#include "engine/io/output.h"
#include "engine/io/summary.h"
#include "engine/run/run.h"
#include "engine/scene/load_scene.h"
#include "engine/step/simd/transfer_simd.h"
#include "engine/step/simulation.h"
#include "engine/tools/child_process.h"

namespace mpm {

namespace {

/// A standard case: the falling cube of one material (bench_scene).
struct BenchCase {
  const char* name;                                    ///< The case's name on the command line.
  const char* material;                                ///< The built-in material it drops.
  double density;                                      ///< kg/m^3.
  std::vector<std::pair<std::string, double>> params;  ///< Besides the material's defaults.
};

/// The material cases: one per built-in material, each stiff enough that the cube keeps its
/// shape over the timed substeps (jello: fixed corotated, the reference of issue 32's targets).
const std::vector<BenchCase>& bench_cases() {
  static const std::vector<BenchCase> cases{
      {"jello", "corotated", 1000, {{"E", 1e5}, {"nu", 0.3}}},
      {"snow", "snow", 400, {{"E", 1.4e5}, {"nu", 0.3}}},
      {"neo_hookean", "neo_hookean", 1000, {{"E", 1e5}, {"nu", 0.3}}},
      {"sand", "sand", 1600, {{"E", 1e6}, {"nu", 0.3}}},
      {"water", "water", 1000, {{"bulk_modulus", 1e5}}},
  };
  return cases;
}

/// The case called `name`, or nullptr.
const BenchCase* find_case(const std::string& name) {
  for (const BenchCase& c : bench_cases())
    if (name == c.name) return &c;
  return nullptr;
}

/// A falling cube of case `c`'s material (its other parameters at their defaults) on a slip
/// floor, sized for about `particles` particles at 8 per cell, in a grid whose side is
/// `domain_scale` times the tight one.
SceneDesc bench_scene(const BenchCase& c, long particles, double domain_scale, bool simd) {
  SceneDesc s;
  s.simulation.simd = simd;
  s.file = "bench";
  const double cells_per_side = std::cbrt(particles / 8.0);
  const int dims = static_cast<int>(std::ceil((cells_per_side + 12) * domain_scale));
  const double h = 1.0 / dims;
  s.grid.dims = Vec3i::Constant(dims);
  s.grid.max = Vec3::Ones();
  s.simulation.dt = 1e-4;
  ObjectDesc o;
  o.name = "cube";
  o.mesh = std::filesystem::path(MPM_SOURCE_DIR) / "scenes/meshes/cube.obj";
  o.scale = Vec3::Constant(cells_per_side * h);
  o.offset = Vec3(0.5, (5 + cells_per_side / 2) * h, 0.5);
  o.velocity = Vec3(0, -1, 0);
  o.density = c.density;
  o.material = c.material;
  o.params.insert(c.params.begin(), c.params.end());
  const MaterialRegistry registry = builtin_registry();
  for (const ParamSpec& spec : registry.find(c.material)->params)
    o.params.insert({spec.name, spec.default_value});
  s.objects.push_back(o);
  WallDesc floor;
  floor.point = Vec3(0, 4 * h, 0);
  floor.boundary = Boundary::slip;
  s.walls.push_back(floor);
  return s;
}

/// The names of the standard cases, for messages: "jello, snow, ..., sparse or two_cubes".
std::string case_names() {
  std::string out;
  for (const BenchCase& c : bench_cases()) out += std::string(c.name) + ", ";
  return out + "sparse or two_cubes";
}

/// Puts the mean contact solve of `stats` into `r` (none: zeros).
void add_contact_stats(const ContactSolveStats& stats, BenchResult& r) {
  if (stats.solves == 0) return;
  r.contact_iterations = static_cast<double>(stats.iterations) / stats.solves;
  r.contact_residual = stats.residual / stats.solves;
}

/// The scene `file` as `mpm run` runs it (`frames` frames, default all; its frames and
/// summary written to a scratch folder, removed after), timed once over the whole run and
/// reported as `name`; `simd`, when given, overrides its simulation.simd.
BenchResult run_whole_scene(const std::string& name, const std::filesystem::path& file,
                            const LoadOptions& load, std::optional<int> frames,
                            std::optional<bool> simd) {
  MaterialRegistry registry = builtin_registry();
  SceneDesc scene = load_scene(file, registry, load);
  if (simd) scene.simulation.simd = *simd;
  if (frames) scene.simulation.frames = *frames;
  const auto sim = Simulation::create(scene, registry);
  const std::filesystem::path out = std::filesystem::temp_directory_path() /
                                    ("mpm-bench-" + name + "-" + std::to_string(getpid()));
  prepare_output_directory(out, true);
  RunResult run;
  try {
    FrameOutput output(out, scene.output, 0);
    SummaryWriter summary(out);
    run = run_frames(*sim, scene.simulation.frames, scene.simulation.frame_dt,
                     {&output, &summary});
  } catch (...) {
    std::filesystem::remove_all(out);  // no gigabyte of frames left behind in the temp folder
    throw;
  }
  std::filesystem::remove_all(out);
  if (run.status != RunStatus::ok)
    throw std::runtime_error(name + " ended " + status_name(run.status));
  BenchResult r;
  r.name = name;
  r.particles = static_cast<long>(sim->particles().size());
  r.grid_nodes = static_cast<long>(sim->grid().nodes.cast<double>().prod());
  r.substeps = static_cast<int>(sim->substeps());
  r.simd = scene.simulation.simd;
  r.threads = omp_get_max_threads();
  const double steps = static_cast<double>(r.particles) * r.substeps;
  r.particle_steps_per_second = steps / run.wall_seconds;  // as `mpm run` reports it
  for (const auto& [name, seconds] : sim->stage_seconds())
    r.stage_ns.emplace_back(name, seconds * 1e9 / steps);
  r.stored_nodes = static_cast<long>(sim->grid().mass.size());
  r.peak_rss_bytes_per_particle = peak_rss_bytes() / r.particles;
  add_contact_stats(sim->contact_memory().stats, r);
  return r;
}

BenchResult run_case(const std::string& name, const BenchOptions& opt) {
  if (name == "two_cubes")
    return run_whole_scene(name, std::filesystem::path(MPM_SOURCE_DIR) / "scenes/two_cubes.yaml",
                           LoadOptions{{}, false, {}}, {}, opt.simd);
  SceneDesc scene;
  if (name == "sparse")
    scene = bench_scene(*find_case("jello"), opt.particles, 2, opt.simd);
  else if (const BenchCase* c = find_case(name))
    scene = bench_scene(*c, opt.particles, 1, opt.simd);
  else
    throw std::invalid_argument("unknown bench case '" + name + "'; expected " + case_names());
  const auto sim = Simulation::create(scene, builtin_registry());
  BenchResult r;
  r.name = name;
  r.particles = static_cast<long>(sim->particles().size());
  r.grid_nodes = static_cast<long>(sim->grid().nodes.cast<double>().prod());
  r.substeps = opt.substeps;
  r.threads = omp_get_max_threads();
  const Real dt = *scene.simulation.dt;
  for (int s = 0; s < 2; ++s) sim->substep(dt);  // warm-up
  std::vector<double> rates;
  std::vector<std::vector<double>> stage_runs;
  for (int rep = 0; rep < opt.repeats; ++rep) {
    std::vector<double> before;
    for (const Stage& st : sim->stages()) before.push_back(st.seconds);
    const auto t0 = std::chrono::steady_clock::now();
    for (int s = 0; s < opt.substeps; ++s) sim->substep(dt);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    rates.push_back(static_cast<double>(r.particles) * opt.substeps / secs);
    std::vector<double> stage;
    for (std::size_t i = 0; i < sim->stages().size(); ++i)
      stage.push_back((sim->stages()[i].seconds - before[i]) * 1e9 /
                      (static_cast<double>(r.particles) * opt.substeps));
    stage_runs.push_back(stage);
  }
  // The median repetition by rate, and its stage breakdown.
  std::vector<int> order(rates.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return rates[a] < rates[b]; });
  const int mid = order[order.size() / 2];
  r.particle_steps_per_second = rates[mid];
  for (std::size_t i = 0; i < sim->stages().size(); ++i)
    r.stage_ns.emplace_back(sim->stages()[i].name, stage_runs[mid][i]);
  r.stored_nodes = static_cast<long>(sim->grid().mass.size());
  r.peak_rss_bytes_per_particle = peak_rss_bytes() / r.particles;
  add_contact_stats(sim->contact_memory().stats, r);
  return r;
}

std::string serialize(const BenchResult& r) {
  std::ostringstream s;
  s.precision(17);
  s << r.name << ' ' << r.particles << ' ' << r.grid_nodes << ' ' << r.stored_nodes << ' '
    << r.substeps << ' ' << r.threads << ' ' << r.particle_steps_per_second << ' '
    << r.peak_rss_bytes_per_particle << ' ' << r.contact_iterations << ' ' << r.contact_residual;
  for (const auto& [n, v] : r.stage_ns) s << ' ' << n << ' ' << v;
  return s.str();
}

BenchResult deserialize(const std::string& text) {
  std::istringstream s(text);
  BenchResult r;
  s >> r.name >> r.particles >> r.grid_nodes >> r.stored_nodes >> r.substeps >> r.threads >>
      r.particle_steps_per_second >> r.peak_rss_bytes_per_particle >> r.contact_iterations >>
      r.contact_residual;
  std::string n;
  double v;
  while (s >> n >> v) r.stage_ns.emplace_back(n, v);
  return r;
}

}  // namespace

std::vector<BenchResult> run_benchmarks(const BenchOptions& opt) {
  if (opt.threads > 0) set_threads(opt.threads);
  std::vector<BenchResult> out;
  if (!opt.scene.empty()) {
    {  // a bad scene is a SceneError here, before any child runs
      MaterialRegistry registry = builtin_registry();
      load_scene(opt.scene, registry, opt.load);
    }
    const std::string name = std::filesystem::path(opt.scene).stem().string();
    const std::string text = run_in_child(
        [&] {
          return serialize(run_whole_scene(
                     name, opt.scene, opt.load, opt.frames,
                     opt.simd_given ? std::optional<bool>(opt.simd) : std::nullopt)) +
                 "\n";
        },
        "bench scene '" + opt.scene + "'");
    out.push_back(deserialize(text));
    return out;
  }
  for (const std::string& name : opt.cases) {
    if (!find_case(name) && name != "sparse" && name != "two_cubes")
      throw std::invalid_argument("unknown bench case '" + name + "'; expected " + case_names());
    const std::string text =
        run_in_child([&] { return serialize(run_case(name, opt)) + "\n"; }, "bench case '" + name + "'");
    out.push_back(deserialize(text));
    out.back().simd = opt.simd;
  }
  return out;
}

std::string format_bench_table(const std::vector<BenchResult>& results) {
  std::ostringstream s;
  char line[512];
  std::snprintf(line, sizeof line, "mpm bench  (particle matrices stored in %s, arithmetic in double; commit %s)\n",
                kStoredPrecision, git_commit());
  s << line;
  if (!results.empty())
    s << "transfers: "
      << (results.front().simd
              ? std::string("SIMD where supported (simulation.simd: true), instruction set ") +
                    (simd::target_name() ? simd::target_name() : "none")
              : std::string("scalar double (simulation.simd: false)"))
      << "\n";
  std::snprintf(line, sizeof line, "%-9s %10s %10s %10s %8s %7s %14s %10s\n", "case",
                "particles", "nodes", "stored", "substeps", "threads", "Mparticle-st/s",
                "B/particle");
  s << line;
  for (const BenchResult& r : results) {
    std::snprintf(line, sizeof line, "%-9s %10ld %10ld %10ld %8d %7d %14.3f %10.0f\n",
                  r.name.c_str(), r.particles, r.grid_nodes, r.stored_nodes, r.substeps, r.threads,
                  r.particle_steps_per_second / 1e6, r.peak_rss_bytes_per_particle);
    s << line;
  }
  for (const BenchResult& r : results)
    if (r.contact_iterations > 0) {
      std::snprintf(line, sizeof line,
                    "%s: contact solve, per substep with contacts: %.2f iterations, residual "
                    "%.3g m/s\n",
                    r.name.c_str(), r.contact_iterations, r.contact_residual);
      s << line;
    }
  s << "\nns per particle-step by stage\n";
  for (const BenchResult& r : results) {
    s << r.name << ":";
    for (const auto& [n, v] : r.stage_ns) {
      std::snprintf(line, sizeof line, " %s %.1f", n.c_str(), v);
      s << line;
    }
    s << "\n";
  }
  return s.str();
}

std::string format_bench_csv(const std::vector<BenchResult>& results) {
  std::ostringstream s;
  s << "case,particles,grid_nodes,stored_nodes,substeps,threads,precision,commit,"
       "particle_steps_per_second,"
       "peak_rss_bytes_per_particle,stage,ns_per_particle_step\n";
  for (const BenchResult& r : results)
    for (const auto& [n, v] : r.stage_ns)
      s << r.name << ',' << r.particles << ',' << r.grid_nodes << ',' << r.stored_nodes << ','
        << r.substeps << ',' << r.threads << ',' << kStoredPrecision << ',' << git_commit()
        << ',' << r.particle_steps_per_second << ',' << r.peak_rss_bytes_per_particle << ',' << n
        << ',' << v << '\n';
  return s.str();
}

}  // namespace mpm
