#include "engine/cli/cli.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "engine/core/version.h"
#include "engine/io/output.h"
#include "engine/io/summary.h"
#include "engine/io/surface.h"
#include "engine/parallel/comm.h"
#include "engine/parallel/domain.h"
#include "engine/run/progress.h"
#include "engine/run/run.h"
#include "engine/scene/load_scene.h"
#include "engine/step/simd/transfer_simd.h"
#include "engine/step/simulation.h"
#include "engine/step/validate.h"
#include "engine/tools/bench.h"
#include "engine/tools/roofline.h"
#include "engine/tools/validation/study.h"
#include "materials/plugin.h"

namespace {

/// The usage text's first lines, before the commands.
constexpr const char* kUsageHead = R"(mpm - a Material Point Method engine for the CPU

Usage:
)";

/// The usage text after the commands: the options of run, the exit codes, signals.
constexpr const char* kUsageTail = R"(  mpm --help | --version

Options of run:
  --out DIR          write frames and report.yaml to DIR (default: the scene's output.directory)
  --force            replace the results of an earlier run in the output folder
  --resume DIR       continue the run in DIR from its last complete frame (checkpoint.h5)
  --format LIST      formats to write, e.g. hdf5,png (hdf5, bgeo, ply, png, mesh, vdb;
                     default: the scene's output.formats, else hdf5)
  --frames N         simulate N frames instead of the scene's simulation.frames
  --set KEY=VALUE    override a scene value, e.g. --set grid.dims=64 --set objects[0].E=2e4
                     (repeatable; checked like the file)
  --plugin PATH      load the material plugin PATH first (repeatable; also for validate,
                     golden and materials); a scene's `plugins:` entry of its file name uses it
  --allow-scene-plugins
                     also load plugins the scene brings: found beside it, or named by a path
                     outside $MPM_PLUGIN_PATH and the engine's lib/ (they run that code)
  --threads N        use N threads (default: all cores)
  --quiet            print only warnings and the final summary line
  --log-level LEVEL  trace, debug, info, warn, error or off (default info)

Exit codes: 0 success; 1 the run failed (unstable, interrupted, or output could not be
written; the report says why and frames already written stay whole); 2 bad scene or usage.
Ctrl-C or SIGTERM stops a run at the end of the current frame, after writing the frame
and the checkpoint; a second one stops it at once (the last checkpoint written stays).
)";

/// The commands of `mpm`, in the order of kCommands (and of the usage text).
enum class Command { run, validate, materials, preview, surface, bench, study, golden, compare };

/// The command line.
struct Args {
  std::string name;                ///< The command's word as given ("" if none).
  Command command = Command::run;  ///< The command, when `name` is one of kCommands.
  std::string scene, second, out, resume, formats, output_file, log_level = "info";
  std::vector<std::string> tols;
  std::vector<std::string> given;  ///< The options given, in order (to refuse ignored ones).
  std::string cases, csv;
  std::optional<long> particles;
  std::optional<bool> simd;  ///< mpm bench --simd on|off (or an instruction set: on)
  std::string simd_target;   ///< mpm bench --simd SSE4|AVX2|AVX3: the one to force.
  std::optional<int> frames, threads, fps;
  std::vector<std::string> sets, plugins;
  bool quiet = false, force = false, quick = false, allow_scene_plugins = false;
};

int cmd_run(const Args& args);
int cmd_materials(const Args& args);
int cmd_preview(const Args& args);
int cmd_surface(const Args& args);
int cmd_bench(const Args& args);
int cmd_study(const Args& args);
int cmd_compare(const Args& args);

/// One command of `mpm`: its word, its handler, how it runs and its lines of the usage text.
struct CommandInfo {
  Command command;              ///< The command.
  const char* name;             ///< Its word on the command line.
  int (*handler)(const Args&);  ///< Runs it; returns the exit code.
  bool mpi;                     ///< Under mpirun it splits the scene over the ranks.
  int operands;                 ///< Words after it: the scene or folder (compare: A and B).
  const char* help;             ///< Its lines of the usage text (without the last newline).
};

/// Every command, in the usage text's order: the one list run_cli dispatches on (the help
/// as it prints, so not formatted).
// clang-format off
constexpr CommandInfo kCommands[] = {
    {Command::run, "run", cmd_run, true, 1,
     R"(  mpm run SCENE.yaml [options]   simulate and write frames and report.yaml)"},
    {Command::validate, "validate", cmd_run, true, 1,
     R"(  mpm validate SCENE.yaml [--set KEY=VALUE ...] [--plugin PATH ...] [--allow-scene-plugins]
                                 check a scene and print what it would simulate)"},
    {Command::materials, "materials", cmd_materials, false, 1,
     R"(  mpm materials [SCENE.yaml | PLUGIN.so] [--plugin PATH ...]
                                 list every registered material (and a scene's or a file's
                                 plugins) with its keys, units, defaults and ranges)"},
    {Command::preview, "preview", cmd_preview, false, 1,
     R"(  mpm preview DIR [--fps N]      join DIR/preview/frame_*.png into DIR/preview.mp4 (ffmpeg))"},
    {Command::surface, "surface", cmd_surface, false, 1,
     R"(  mpm surface DIR [--format mesh,vdb]
                                 build the surfaces of a finished run from its frame_*.h5
                                 (mesh: frame_NNNNN_<object>.ply; vdb: frame_NNNNN.vdb;
                                 default mesh), as the mesh and vdb formats write them)"},
    {Command::bench, "bench", cmd_bench, false, 1,
     R"(  mpm bench [--cases jello,snow,sparse,two_cubes,machine] [--particles N] [--threads N]
            [--csv FILE] [--simd on|off|SSE4|AVX2|AVX3]
                                 time standard cases (median of 3 after a warm-up;
                                 jello, snow, neo_hookean, sand, water: a falling cube of
                                 that material; sparse: jello in a larger grid;
                                 two_cubes: the whole scene, once; machine: peak FLOP
                                 rate and memory bandwidth; --simd off: the scalar path;
                                 --simd AVX2: that instruction set's code, where the CPU
                                 has a wider one)
  mpm bench SCENE.yaml [--frames N] [--set KEY=VALUE ...] [--threads N] [--csv FILE]
                                 time your own scene as mpm run runs it (frames to a
                                 scratch folder): particle-steps/s and time per stage)"},
    {Command::study, "study", cmd_study, false, 1,
     R"(  mpm study [--quick] [--cases SWEEP,...] -o DIR
                                 run the validation cases over sweeps of h, particles per
                                 cell, CFL, dt, transfer, kernel, grid precision and SIMD;
                                 write DIR/study.csv and DIR/series.csv (docs/accuracy.md))"},
    {Command::golden, "golden", cmd_run, true, 1,
     R"(  mpm golden SCENE.yaml --frames N -o FILE [--force]
                                 run N frames and write the run summary to FILE (a golden;
                                 --force replaces an existing FILE))"},
    {Command::compare, "compare", cmd_compare, false, 2,
     R"(  mpm compare A B [--tol QUANTITY=VALUE ...] [--frames N]
                                 compare two runs (output folders or summary files), B being
                                 the reference, over B's frames (or frames 0..N); exit 0
                                 within tolerance, 1 not, 2 bad input)"},
};
// clang-format on

/// The command named `name`, or nullptr.
const CommandInfo* find_command(const std::string& name) {
  for (const CommandInfo& c : kCommands)
    if (name == c.name) return &c;
  return nullptr;
}

/// The usage text of `mpm --help`: the commands' lines from kCommands between head and tail.
std::string usage_text() {
  std::string text = kUsageHead;
  for (const CommandInfo& c : kCommands) text += std::string(c.help) + "\n";
  return text + kUsageTail;
}

[[noreturn]] void usage_error(const std::string& what) {
  std::fprintf(stderr, "mpm: %s\n(run 'mpm --help' for usage)\n", what.c_str());
  std::exit(mpm::kExitBadInput);
}

std::vector<std::string> split_list(const std::string& text) {
  std::vector<std::string> items;
  std::stringstream list(text);
  for (std::string c; std::getline(list, c, ',');) items.push_back(c);
  return items;
}

int parse_count(const std::string& flag, const std::string& value, int min) {
  try {
    std::size_t used = 0;
    const int v = std::stoi(value, &used);
    if (used == value.size() && v >= min) return v;
  } catch (const std::exception&) {
  }
  usage_error(flag + " expects a whole number >= " + std::to_string(min) + ", got '" + value + "'");
}

Args parse_args(int argc, char** argv) {
  Args a;
  std::vector<std::string> words(argv + 1, argv + argc);
  for (std::size_t i = 0; i < words.size(); ++i) {
    const std::string& w = words[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= words.size()) usage_error(w + " needs a value");
      return words[++i];
    };
    if (w.size() > 1 && w[0] == '-') a.given.push_back(w);
    if (w == "--help" || w == "-h") {
      std::fputs(usage_text().c_str(), stdout);
      std::exit(mpm::kExitOk);
    } else if (w == "--version") {
      std::printf("mpm %s (commit %s)\n", MPM_VERSION, mpm::git_commit());
      std::exit(mpm::kExitOk);
    } else if (w == "--out") {
      a.out = value();
    } else if (w == "--frames") {
      a.frames = parse_count(w, value(), 0);
    } else if (w == "--threads") {
      a.threads = parse_count(w, value(), 1);
    } else if (w == "--set") {
      a.sets.push_back(value());
    } else if (w == "--plugin") {
      a.plugins.push_back(value());
    } else if (w == "--allow-scene-plugins") {
      a.allow_scene_plugins = true;
    } else if (w == "--cases") {
      a.cases = value();
    } else if (w == "--csv") {
      a.csv = value();
    } else if (w == "--particles") {
      a.particles = parse_count(w, value(), 1000);
    } else if (w == "--simd") {
      const std::string v = value();
      a.simd = v != "off";
      if (v != "on" && v != "off") a.simd_target = v;
    } else if (w == "--tol") {
      a.tols.push_back(value());
    } else if (w == "-o") {
      a.output_file = value();
    } else if (w == "--resume") {
      a.resume = value();
    } else if (w == "--format") {
      a.formats = value();
    } else if (w == "--fps") {
      a.fps = parse_count(w, value(), 1);
    } else if (w == "--force") {
      a.force = true;
    } else if (w == "--quick") {
      a.quick = true;
    } else if (w == "--quiet") {
      a.quiet = true;
    } else if (w == "--log-level") {
      a.log_level = value();
    } else if (!w.empty() && w[0] == '-') {
      usage_error("unknown option '" + w + "'");
    } else if (a.name.empty()) {
      a.name = w;
      if (const CommandInfo* c = find_command(w)) a.command = c->command;
    } else if (a.scene.empty()) {
      a.scene = w;
    } else if (const CommandInfo* c = find_command(a.name);
               c && c->operands == 2 && a.second.empty()) {
      a.second = w;
    } else {
      usage_error("unexpected argument '" + w + "'");
    }
  }
  if (a.name.empty()) usage_error("no command given");
  return a;
}

/// The commands each option applies to; an option given to another command is refused rather
/// than ignored. Options not listed (--quiet, --log-level) apply to every command.
void check_options(const Args& a) {
  using C = Command;
  static const std::vector<std::pair<std::string, std::vector<Command>>> kApplies = {
      {"--out", {C::run}},
      {"--force", {C::run, C::golden}},
      {"--resume", {C::run}},
      {"--format", {C::run, C::surface}},
      {"--frames", {C::run, C::golden, C::compare, C::bench}},
      {"--set", {C::run, C::validate, C::golden, C::bench}},
      {"--plugin", {C::run, C::validate, C::golden, C::materials, C::bench}},
      {"--allow-scene-plugins", {C::run, C::validate, C::golden, C::materials, C::bench}},
      {"--threads", {C::run, C::validate, C::golden, C::bench, C::study}},
      {"--cases", {C::bench, C::study}},
      {"--csv", {C::bench}},
      {"--particles", {C::bench}},
      {"--simd", {C::bench}},
      {"--tol", {C::compare}},
      {"-o", {C::golden, C::study}},
      {"--fps", {C::preview}},
      {"--quick", {C::study}},
  };
  if (!find_command(a.name)) return;
  for (const std::string& flag : a.given)
    for (const auto& [option, commands] : kApplies) {
      if (flag != option ||
          std::find(commands.begin(), commands.end(), a.command) != commands.end())
        continue;
      std::string list;
      for (const Command c : commands)
        for (const CommandInfo& info : kCommands)
          if (info.command == c) list += (list.empty() ? "" : ", ") + std::string(info.name);
      usage_error("'mpm " + a.name + "' does not take " + option + " (it would be ignored; " +
                  option + " is for: " + list + ")");
    }
}

int list_materials(const mpm::MaterialRegistry& registry) {
  for (const mpm::MaterialInfo& m : registry.all()) {
    std::printf("%s: %s\n  reference: %s\n", m.name.c_str(), m.description.c_str(),
                m.reference.c_str());
    std::printf("  %-22s %-8s %-10s %-16s %s\n", "key", "unit", "default", "range", "meaning");
    for (const mpm::ParamSpec& p : m.params) {
      char def[32];
      std::snprintf(def, sizeof def, "%g", p.default_value);
      std::printf("  %-22s %-8s %-10s %-16s %s\n", p.name.c_str(),
                  p.unit.empty() ? "-" : p.unit.c_str(), p.required ? "required" : def,
                  mpm::range_text(p.min, p.max, p.min_exclusive, p.max_exclusive).c_str(),
                  p.description.c_str());
    }
  }
  return mpm::kExitOk;
}

std::atomic<bool> g_stop{false};

/// The first signal asks the run to stop at the frame end; the next one ends the process
/// (signal() is async-signal-safe).
extern "C" void on_signal(int sig) {
  g_stop.store(true);
  std::signal(sig, SIG_DFL);
  static const char kSay[] =
      "\nmpm: stopping at the end of this frame (its frame and checkpoint are written); "
      "signal again to stop now\n";
  [[maybe_unused]] const ssize_t ignored = write(STDERR_FILENO, kSay, sizeof kSay - 1);
}

/// The plugins the command line allows (--plugin, --allow-scene-plugins).
mpm::PluginPolicy plugin_policy(const Args& args) {
  return {{args.plugins.begin(), args.plugins.end()}, args.allow_scene_plugins};
}

int cmd_materials(const Args& args) {
  mpm::MaterialRegistry registry = mpm::builtin_registry();
  try {
    for (const std::string& p : args.plugins) mpm::load_plugin(p, registry);
    if (args.scene.ends_with(".so"))
      mpm::load_plugin(args.scene, registry);
    else if (!args.scene.empty())
      mpm::load_scene(args.scene, registry, {{}, true, plugin_policy(args)});
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return mpm::kExitBadInput;
  }
  return list_materials(registry);
}

int cmd_preview(const Args& args) {
  if (args.scene.empty()) usage_error("'mpm preview' needs an output folder");
  const std::filesystem::path dir = args.scene;
  if (!std::filesystem::is_directory(dir / "preview")) {
    std::fprintf(stderr, "error: %s has no preview/ folder: run with --format png first\n",
                 dir.c_str());
    return mpm::kExitBadInput;
  }
  if (std::system("command -v ffmpeg > /dev/null 2>&1") != 0) {
    std::fprintf(stderr,
                 "error: ffmpeg is not installed (apt-get install ffmpeg); the PNG "
                 "frames are in %s/preview/\n",
                 dir.c_str());
    return mpm::kExitRunFailed;
  }
  const std::string cmd = "ffmpeg -loglevel error -y -framerate " +
                          std::to_string(args.fps.value_or(24)) + " -i '" +
                          (dir / "preview" / "frame_%05d.png").string() +
                          "' -pix_fmt yuv420p -vf 'scale=trunc(iw/2)*2:trunc(ih/2)*2' '" +
                          (dir / "preview.mp4").string() + "'";
  if (std::system(cmd.c_str()) != 0) return mpm::kExitRunFailed;
  std::printf("%s\n", (dir / "preview.mp4").c_str());
  return mpm::kExitOk;
}

/// mpm surface DIR [--format mesh,vdb]: surfaces from a finished run's frames.
int cmd_surface(const Args& args) {
  if (args.scene.empty()) usage_error("'mpm surface' needs a run's output folder");
  bool mesh = args.formats.empty(), vdb = false;
  for (const std::string& name : split_list(args.formats)) {
    if (name == "mesh")
      mesh = true;
    else if (name == "vdb")
      vdb = true;
    else
      usage_error("'mpm surface' writes the formats mesh and vdb, not '" + name + "'");
  }
  if (!mesh && !vdb) usage_error("--format needs mesh, vdb or both");
  try {
    const int frames = mpm::surfaces_from_run(args.scene, mesh, vdb);
    std::printf("%s: surfaces of %d frames (%s%s%s)\n", args.scene.c_str(), frames,
                mesh ? "mesh" : "", mesh && vdb ? ", " : "", vdb ? "vdb" : "");
  } catch (const mpm::SceneError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return mpm::kExitBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return mpm::kExitRunFailed;
  }
  return mpm::kExitOk;
}

int cmd_study(const Args& args) {
  if (args.output_file.empty()) usage_error("'mpm study' needs -o DIR");
  mpm::validation::StudyOptions opt;
  opt.quick = args.quick;
  opt.threads = args.threads.value_or(0);
  opt.experiments = split_list(args.cases);
  return mpm::validation::study_main(opt, args.output_file);
}

int cmd_bench(const Args& args) {
  mpm::BenchOptions opt;
  if (args.threads) opt.threads = *args.threads;
  if (args.particles) opt.particles = *args.particles;
  if (args.simd) opt.simd = *args.simd;
  opt.simd_given = args.simd.has_value();
  if (!args.simd_target.empty() && !mpm::simd::force_target(args.simd_target)) {
    std::string names;  // "" where the CPU has none the SIMD path can use
    mpm::simd::for_each_target(
        [&](const char* n) { names += (names.empty() ? "" : " ") + std::string(n); });
    usage_error("--simd expects on, off or an instruction set this build and CPU run (" +
                (names.empty() ? std::string("none") : names) + "), got '" + args.simd_target +
                "'");
  }
  if (!args.cases.empty()) opt.cases = split_list(args.cases);
  if (!args.scene.empty()) {
    if (!args.cases.empty() || args.particles)
      usage_error(
          "'mpm bench SCENE.yaml' times the scene; --cases and --particles are for the "
          "standard cases");
    opt.scene = args.scene;
    opt.frames = args.frames;
    opt.load.plugins = plugin_policy(args);
  } else if (!args.sets.empty() || args.frames) {
    usage_error("'mpm bench' takes --set and --frames with a scene: mpm bench SCENE.yaml");
  }
  try {
    for (const std::string& s : args.sets) opt.load.overrides.push_back(mpm::parse_override(s));
    // `machine`: the peak FLOP rate and memory bandwidth, for the roofline.
    if (const auto m = std::find(opt.cases.begin(), opt.cases.end(), "machine");
        m != opt.cases.end()) {
      opt.cases.erase(m);
      std::printf("%s", mpm::format_machine_peaks(mpm::measure_machine_peaks(opt.threads)).c_str());
      if (opt.cases.empty()) return mpm::kExitOk;
    }
    const auto results = mpm::run_benchmarks(opt);
    std::printf("%s", mpm::format_bench_table(results).c_str());
    if (!args.csv.empty()) {
      std::ofstream csv(args.csv);
      csv << mpm::format_bench_csv(results);
      if (!csv) throw std::runtime_error("cannot write '" + args.csv + "'");
    }
  } catch (const std::invalid_argument& e) {
    usage_error(e.what());
  } catch (const mpm::SceneError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return mpm::kExitBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return mpm::kExitRunFailed;
  }
  return mpm::kExitOk;
}

int cmd_compare(const Args& args) {
  if (args.scene.empty() || args.second.empty()) usage_error("'mpm compare' needs A and B");
  try {
    const mpm::FrameSelection sel = mpm::select_frames(mpm::read_summary(args.scene),
                                                       mpm::read_summary(args.second), args.frames);
    if (!sel.error.empty()) {
      std::fprintf(stderr, "error: %s\n", sel.error.c_str());
      return mpm::kExitBadInput;
    }
    // Tolerances from the reference frames compared, as if the golden were made that long.
    const mpm::Tolerances tol =
        mpm::parse_tolerance_overrides(mpm::default_tolerances(sel.b), args.tols);
    const mpm::CompareResult r = mpm::compare_summaries(sel.a, sel.b, tol);
    if (!r.error.empty()) {
      std::fprintf(stderr, "error: %s\n", r.error.c_str());
      return mpm::kExitBadInput;
    }
    if (!sel.note.empty()) std::printf("%s\n", sel.note.c_str());
    std::printf("%s", mpm::format_comparison(r).c_str());
    return r.ok ? mpm::kExitOk : mpm::kExitRunFailed;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return mpm::kExitBadInput;
  }
}

/// A scene described, validated and built for run, validate or golden, with where it writes.
struct BuiltRun {
  mpm::SceneDesc scene;                  ///< As loaded, with the command line's overrides.
  std::unique_ptr<mpm::Simulation> sim;  ///< Built (and restored, with --resume).
  std::filesystem::path out;             ///< The output folder (a golden's: its file's).
  int resumed_frame = 0;                 ///< The frame restored from, 0 for a fresh run.
};

/// Describes, validates and builds the run of `args` and prepares where it writes; every
/// problem is a SceneError (exit code 2).
BuiltRun build_run(const Args& args, mpm::MaterialRegistry& registry) {
  BuiltRun b;
  mpm::SceneDesc& scene = b.scene;
  std::filesystem::path& out = b.out;
  mpm::LoadOptions options;
  for (const std::string& s : args.sets) options.overrides.push_back(mpm::parse_override(s));
  options.plugins = plugin_policy(args);
  scene = mpm::load_scene(args.scene, registry, options);
  if (args.frames) scene.simulation.frames = *args.frames;  // the header says what will run
  if (!args.formats.empty()) {
    scene.output.formats.clear();
    std::stringstream list(args.formats);
    for (std::string name; std::getline(list, name, ',');) {
      const auto f = mpm::format_from_name(name);
      if (!f)
        throw mpm::SceneError({"--format"}, "",
                              "unknown format '" + name + "'; expected " + mpm::format_names());
      scene.output.formats.push_back(*f);
    }
  }
  out = !args.resume.empty() ? std::filesystem::path(args.resume)
        : args.out.empty()   ? scene.output.directory
                             : std::filesystem::path(args.out);
  // The output folder's problems as the key or option that named it.
  const auto folder_error = [&](const std::exception& e) {
    if (!args.out.empty()) return mpm::SceneError({"--out"}, "", e.what());
    return mpm::SceneError(scene.output.loc, "output.directory", e.what());
  };
  const bool writes_run =
      args.command == Command::run && args.resume.empty() && mpm::parallel::rank() == 0;
  // Refused before the build (sampling a large scene takes minutes), emptied after it.
  if (writes_run) {
    try {
      mpm::check_output_directory(out, args.force);
    } catch (const std::exception& e) {
      throw folder_error(e);
    }
  }
  b.sim = mpm::Simulation::create(scene, registry);
  if (!args.resume.empty()) {
    try {
      b.resumed_frame = mpm::restore_checkpoint(out / "checkpoint.h5", *b.sim);
    } catch (const std::exception& e) {
      throw mpm::SceneError({"--resume"}, "", e.what());
    }
  } else if (args.command == Command::golden) {
    out = std::filesystem::path(args.output_file).parent_path();
    if (out.empty()) out = ".";
    if (std::filesystem::exists(args.output_file) && !args.force)
      throw mpm::SceneError(
          {"-o"}, "", "'" + args.output_file + "' exists; give --force to replace this golden");
  } else if (writes_run) {
    try {
      mpm::prepare_output_directory(out, args.force);
    } catch (const std::exception& e) {
      throw folder_error(e);
    }
  }
  return b;
}

/// run, validate and golden: describe and validate the scene, build it, then run it.
int cmd_run(const Args& args) {
  mpm::MaterialRegistry registry = mpm::builtin_registry();
  if (args.command == Command::golden && args.output_file.empty())
    usage_error("'mpm golden' needs -o FILE");
  if (args.scene.empty()) usage_error("'mpm " + args.name + "' needs a scene file");

  BuiltRun built;
  try {
    built = build_run(args, registry);
    if (mpm::parallel::any_all(false)) return mpm::kExitBadInput;  // another rank failed
  } catch (const mpm::SceneError& e) {
    // Every rank stops with code 2; rank 0 says why (the same error on every rank, or its own:
    // only rank 0 prepares the output directory).
    if (mpm::parallel::rank() == 0) std::fprintf(stderr, "error: %s\n", e.what());
    mpm::parallel::any_all(true);
    return mpm::kExitBadInput;
  }
  const mpm::SceneDesc& scene = built.scene;
  const std::unique_ptr<mpm::Simulation>& sim = built.sim;
  const std::filesystem::path& out = built.out;
  const int resumed_frame = built.resumed_frame;
  const bool root = mpm::parallel::rank() == 0;
  if (root)
    for (const std::string& w : mpm::scene_warnings(*sim)) spdlog::warn("{}", w);
  if (args.command == Command::validate) {
    if (!root) return mpm::kExitOk;
    std::printf("%s: valid, %zu particles\n%s", args.scene.c_str(), sim->particles().size(),
                mpm::scene_summary(*sim).c_str());
    return mpm::kExitOk;
  }

  const int frames = args.frames.value_or(scene.simulation.frames);
  // A golden writes only its summary file; a run writes its folder.
  const std::string written = args.command == Command::golden
                                  ? "golden summary in " + args.output_file
                                  : "output in " + out.string();
  if (!args.quiet && root) std::printf("%s", mpm::scene_summary(*sim).c_str());
  // Split over the ranks (each built the same state) after the one-rank checks above: a
  // grid too thin to split is the same error on every rank.
  if (mpm::parallel::ranks() > 1) {
    try {
      sim->set_domain(mpm::parallel::Domain::create(*sim));
    } catch (const mpm::SceneError& e) {
      if (root) std::fprintf(stderr, "error: %s\n", e.what());
      return mpm::kExitBadInput;
    }
  }
  spdlog::info("{} particles, {} frames, {}", sim->particles().size(), frames, written);
  if (resumed_frame > 0) spdlog::info("resuming from frame {}", resumed_frame);

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  mpm::FrameOutput output(out, scene.output, resumed_frame);
  mpm::SummaryWriter summary(out);
  mpm::SummaryWriter golden(out, std::filesystem::path(args.output_file).filename().string());
  mpm::Progress progress(isatty(fileno(stderr)) != 0);
  std::vector<mpm::Observer*> observers;
  if (args.command == Command::golden)
    observers = {&golden};
  else
    observers = {&output, &summary};
  if (!args.quiet) observers.push_back(&progress);
  // Rank 0 holds every particle after each frame's gather; a collective observer (the
  // summary) reduces over every rank's particles before it, so it runs on every rank.
  if (!root) std::erase_if(observers, [](const mpm::Observer* o) { return !o->collective(); });
  const mpm::RunResult r = mpm::run_frames(*sim, frames, scene.simulation.frame_dt, observers,
                                           &g_stop, resumed_frame + 1);

  // Each rank's own particles when no observer needed the frame's gather: count over the ranks.
  const std::size_t particles =
      sim->domain() ? mpm::parallel::sum_all(static_cast<std::uint64_t>(sim->particles().size()))
                    : sim->particles().size();
  const double steps = static_cast<double>(particles) * sim->substeps();
  if (!root) return r.status == mpm::RunStatus::ok ? mpm::kExitOk : mpm::kExitRunFailed;
  std::printf(
      "%s: %s, %zu particles, %d frames, %zu substeps in %.1f s (%.2fM particle-steps/s; "
      "%.2fM in the substep loop); %s%s\n",
      args.scene.c_str(), mpm::status_name(r.status), particles, r.frames_done, sim->substeps(),
      r.wall_seconds, r.wall_seconds > 0 ? steps / r.wall_seconds / 1e6 : 0.0,
      r.loop_seconds > 0 ? steps / r.loop_seconds / 1e6 : 0.0, written.c_str(),
      r.warnings.empty()             ? ""
      : args.command == Command::run ? " (with warnings: see the log and report.yaml)"
                                     : " (with warnings: see the log)");
  if (r.status != mpm::RunStatus::ok) {
    std::fprintf(stderr, "error: %s\n", r.message.c_str());
    return mpm::kExitRunFailed;
  }
  return mpm::kExitOk;
}

}  // namespace

namespace mpm {

int run_cli(int argc, char** argv) {
  const Args args = parse_args(argc, argv);
  const auto level = spdlog::level::from_str(args.log_level);
  if (level == spdlog::level::off && args.log_level != "off")
    usage_error("unknown log level '" + args.log_level + "'");
  spdlog::set_level(args.quiet ? spdlog::level::warn : level);
  if (args.threads) set_threads(*args.threads);
  keep_freed_memory();  // no page faults for the step's per-substep buffers
  check_options(args);

  const CommandInfo* command = find_command(args.name);
  if (!command) usage_error("unknown command '" + args.name + "'");
  if (!command->mpi) return command->handler(args);
  // Under mpirun the run, validate and golden commands split the scene over the ranks
  // (docs/distributed.md); rank 0 alone logs and prints.
  parallel::Session mpi(argc, argv);
  if (parallel::rank() > 0) spdlog::set_level(spdlog::level::err);
  return command->handler(args);
}

}  // namespace mpm
