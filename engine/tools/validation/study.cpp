#include "engine/tools/validation/study.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "engine/core/atomic_file.h"
#include "engine/core/error.h"
#include "engine/run/run.h"
#include "engine/tools/child_process.h"

namespace mpm::validation {

namespace {

/// A sweep: one case over a list of settings.
struct Experiment {
  std::string name;
  std::string case_name;
  std::vector<Setting> full, quick;
};

std::vector<Setting> over_refine(std::vector<int> levels, Setting base = {}) {
  std::vector<Setting> out;
  for (int r : levels) {
    Setting s = base;
    s.refine = r;
    out.push_back(s);
  }
  return out;
}

/// Every kernel over `levels` on the scene's (regular) lattice, then quadratic jittered.
std::vector<Setting> over_kernels_and_refine(std::vector<int> levels) {
  std::vector<Setting> out;
  for (const char* k : {"linear", "quadratic", "cubic"})
    for (Setting s : over_refine(levels)) {
      s.kernel = k;
      out.push_back(s);
    }
  for (Setting s : over_refine(levels)) {
    s.sampling = "jittered";
    out.push_back(s);
  }
  return out;
}

std::vector<Setting> over_transfers(Setting base) {
  std::vector<Setting> out;
  for (auto [t, blend] : {std::pair{"pic", 0.0}, {"flip", 0.95}, {"flip", 0.99}, {"apic", 0.0}}) {
    Setting s = base;
    s.transfer = t;
    if (blend > 0) s.flip_blend = blend;
    out.push_back(s);
  }
  return out;
}

template <class T, class Fn>
std::vector<Setting> over(std::vector<T> values, Setting base, Fn set) {
  std::vector<Setting> out;
  for (const T& v : values) {
    Setting s = base;
    set(s, v);
    out.push_back(s);
  }
  return out;
}

/// Issue 15's speed options at each of `levels`: transfer apic and mls, each with the grid in
/// double and in float and the transfers scalar and SIMD (simulation.simd always set, so the
/// scene default does not matter); at the first level also each of `others` (e.g. pic,
/// flip 0.99) on the double grid, scalar, for reference.
std::vector<Setting> speed_options(std::vector<int> levels, Setting base,
                                   std::vector<std::pair<const char*, double>> others) {
  std::vector<Setting> out;
  for (Setting at_h : over_refine(levels, base)) {
    for (const char* t : {"apic", "mls"})
      for (const char* precision : {"double", "float"})
        for (bool simd : {false, true}) {
          Setting s = at_h;
          s.transfer = t;
          s.grid_precision = precision;
          s.simd = simd;
          out.push_back(s);
        }
    if (at_h.refine != levels.front()) continue;
    for (auto [t, blend] : others) {
      Setting s = at_h;
      s.transfer = t;
      if (blend > 0) s.flip_blend = blend;
      s.grid_precision = "double";
      s.simd = false;
      out.push_back(s);
    }
  }
  return out;
}

/// The incline cases (issue 16): every transfer on a `slip` and a `separate` floor at each of
/// `levels`.
std::vector<Setting> incline_sweep(std::vector<int> levels) {
  std::vector<Setting> out;
  for (Setting at_h : over_refine(levels))
    for (const char* boundary : {"slip", "separate"})
      for (const char* t : {"pic", "apic", "flip", "mls"}) {
        Setting s = at_h;
        s.boundary = boundary;
        s.transfer = t;
        out.push_back(s);
      }
  return out;
}

/// The dam break (issue 17): every transfer (PIC, FLIP 0.95 and 0.99, APIC, MLS) at the scene's
/// h, then APIC at each finer level of `levels`.
/// `levels` with grid.buffer = 3 cells times the level, so the domain boundary stays where the
/// scene puts it (on hydrostatic_column's box wall: see docs/accuracy.md).
std::vector<Setting> over_refine_fixed_buffer(std::vector<int> levels) {
  std::vector<Setting> out = over_refine(levels);
  for (Setting& s : out) s.buffer = 3 * s.refine;
  return out;
}

std::vector<Setting> dam_break_sweep(std::vector<int> levels) {
  std::vector<Setting> out = over_transfers({});
  Setting mls;
  mls.transfer = "mls";
  out.push_back(mls);
  for (Setting s : over_refine(levels))
    if (s.refine > 1) out.push_back(s);
  return out;
}

/// 1, 8 and 27 particles per cell, each on a lattice and jittered.
std::vector<Setting> ppc_sweep(Setting base) {
  std::vector<Setting> out;
  for (int n : {1, 8, 27})
    for (const char* sampling : {"regular", "jittered"}) {
      Setting s = base;
      s.ppc = n;
      s.sampling = sampling;
      out.push_back(s);
    }
  return out;
}

/// Issue 30: the walls at 8 offsets from 0 to 7/8 of a cell against the node rows, with each
/// of `transfers`, for each of `contacts` (simulation.contact), at each of `levels`.
std::vector<Setting> offset_sweep(std::vector<int> levels, std::vector<const char*> contacts,
                                  std::vector<const char*> transfers = {"apic", "mls"}) {
  std::vector<Setting> out;
  for (Setting at_h : over_refine(levels))
    for (const char* contact : contacts)
      for (const char* t : transfers)
        for (int k = 0; k < 8; ++k) {
          Setting s = at_h;
          s.contact = contact;
          s.transfer = t;
          s.wall_offset = k / 8.0;
          out.push_back(s);
        }
  return out;
}

/// `settings`, each with the stress integrated by `rule` (simulation.quadrature).
std::vector<Setting> with_quadrature(std::vector<Setting> settings, const char* rule) {
  for (Setting& s : settings) s.quadrature = rule;
  return settings;
}

/// `settings`, each run for `frames` frames.
std::vector<Setting> with_frames(std::vector<Setting> settings, int frames) {
  for (Setting& s : settings) s.frames = frames;
  return settings;
}

/// `a`, then `b`.
std::vector<Setting> joined(std::vector<Setting> a, const std::vector<Setting>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

/// `settings`, each with one cell of margin around the grid (its node rows unchanged).
std::vector<Setting> with_margin(std::vector<Setting> settings) {
  for (Setting& s : settings) s.margin = 1;
  return settings;
}

const std::vector<Experiment>& experiments() {
  static const std::vector<Experiment> all = [] {
    Setting bar4;
    bar4.refine = 4;
    Setting bar2;
    bar2.refine = 2;
    Setting short_bar = bar2;
    short_bar.frames = 12;  // three periods
    // The scene caps dt at 1e-3 s, which binds above cfl 0.4 at h = L/40: lift the cap.
    const auto set_cfl = [](Setting& s, double c) {
      s.cfl = c;
      s.dt = 1.0;
    };
    const auto set_dt = [](Setting& s, double dt) { s.dt = dt; };
    const auto set_phi = [](Setting& s, double phi) { s.friction_angle = phi; };
    const std::vector<std::pair<const char*, double>> pic_flip = {{"pic", 0.0}, {"flip", 0.99}};
    std::vector<Setting> quick_h = over_refine({1, 2, 4});
    for (Setting& s : quick_h) s.frames = 12;
    return std::vector<Experiment>{
        {"h_convergence", "bar_vibration", over_kernels_and_refine({1, 2, 4, 8}), quick_h},
        {"ppc", "bar_vibration", ppc_sweep(bar4), ppc_sweep(short_bar)},
        {"cfl", "bar_vibration", over<double>({0.1, 0.2, 0.4, 0.8}, bar4, set_cfl),
         over<double>({0.2, 0.8}, short_bar, set_cfl)},
        {"transfer_bar", "bar_vibration", over_transfers(bar4), {}},
        {"transfer_spin", "spinning_cube", over_transfers({}), over_transfers({})},
        {"dt", "free_fall", over<double>({4e-3, 2e-3, 1e-3, 5e-4}, {}, set_dt),
         over<double>({2e-3, 1e-3}, {}, set_dt)},
        {"column_h", "resting_column", over_refine({1, 2, 4}), {}},
        {"collision", "sphere_collision", over_transfers({}), over_refine({1})},
        {"compression", "uniaxial_compression", over_refine({1, 2}), {}},
        // Issue 16: h-convergence of the incline cases, per floor and transfer.
        {"incline_sliding", "sliding_block", incline_sweep({1, 2}), {}},
        {"incline_sticking", "sticking_block", incline_sweep({1, 2}), {}},
        {"incline_rolling", "rolling_ball", incline_sweep({1, 2}), {}},
        // Issue 15: mls against apic, the float grid against double, SIMD against scalar.
        // Kept out of --quick: about 10 minutes together on a loaded 2-core machine.
        {"speed_bar", "bar_vibration", speed_options({1, 2}, {}, pic_flip), {}},
        {"speed_spin", "spinning_cube", speed_options({1, 2}, {}, pic_flip), {}},
        {"speed_collision", "sphere_collision", speed_options({1, 2}, {}, pic_flip), {}},
        {"speed_column", "resting_column", speed_options({1, 2}, {}, {}), {}},
        // Issue 17: water and sand. The hydrostatic column at H / h = 8, 16, 32; the dam break
        // per transfer and at h / 2; the a = 2 sand column's runout at h and h / 2.
        {"water_h", "hydrostatic_column", over_refine_fixed_buffer({1, 2, 4}),
         over_refine_fixed_buffer({1, 2})},
        {"dam_break", "dam_break", dam_break_sweep({1, 2}), {}},
        {"collapse_h", "sand_slope", over_refine({1, 2}), {}},
        // The a = 2 column at the friction angles whose plane-strain flow friction is tan 20,
        // tan 30 and tan 40 degrees (docs/validation.md, case 12): its flank slope.
        {"repose", "sand_slope", over<double>({16.573, 25.377, 35.802}, {}, set_phi), {}},
        // Issue 30: every contact case with its walls at 8 offsets against the node rows.
        {"offset_sliding", "wide_sliding_block", offset_sweep({1, 2}, {"nodes", "particles"}),
         offset_sweep({1}, {"particles"})},
        {"offset_sticking", "wide_sticking_block", offset_sweep({1, 2}, {"nodes", "particles"}),
         offset_sweep({1}, {"particles"})},
        {"offset_rolling", "rolling_ball", offset_sweep({1, 2}, {"nodes", "particles"}),
         offset_sweep({1}, {"particles"})},
        // The blocks at h / 4 with contact at the particles (about 2 minutes a run on two
        // threads): kept apart so that the sweeps above stay short.
        {"offset_sliding_h4", "wide_sliding_block", offset_sweep({4}, {"particles"}), {}},
        {"offset_sticking_h4", "wide_sticking_block", offset_sweep({4}, {"particles"}), {}},
        {"offset_rolling_h4", "rolling_ball", offset_sweep({4}, {"particles"}), {}},
        // The pool with its stress at the particles (point) and over their domains; quick: the
        // latter to 0.2 s, settled from 0.1 s (docs/accuracy.md).
        {"offset_water", "hydrostatic_water",
         joined(offset_sweep({1}, {"nodes", "particles"}),
                with_quadrature(offset_sweep({1}, {"particles"}), "domain")),
         with_frames(with_quadrature(offset_sweep({1}, {"particles"}), "domain"), 4)},
        // sand_slope's side walls lie on its buffer's edge: a cell of margin lets them move.
        {"offset_collapse", "sand_slope", with_margin(offset_sweep({1}, {"nodes", "particles"})),
         with_margin(offset_sweep({1}, {"particles"}))},
    };
  }();
  return all;
}

std::string text(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

/// The --set overrides for `s` on a scene whose grid has `dims` cells.
std::vector<SceneOverride> overrides_for(const Setting& s, const SceneDesc& scene) {
  std::vector<SceneOverride> o;
  const Vec3i d = scene.grid.dims * s.refine + Vec3i::Constant(2 * s.margin.value_or(0));
  o.push_back({"grid.dims", "[" + std::to_string(d.x()) + ", " + std::to_string(d.y()) + ", " +
                                std::to_string(d.z()) + "]"});
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const std::string obj = "objects[" + std::to_string(i) + "].";
    if (s.ppc) o.push_back({obj + "particles_per_cell", std::to_string(*s.ppc)});
    if (s.sampling) o.push_back({obj + "sampling", *s.sampling});
    if (s.friction_angle) o.push_back({obj + "friction_angle", text(*s.friction_angle)});
  }
  if (s.cfl) o.push_back({"simulation.cfl", text(*s.cfl)});
  if (s.dt) o.push_back({"simulation.dt", text(*s.dt)});
  if (s.transfer) o.push_back({"simulation.transfer", *s.transfer});
  if (s.flip_blend) o.push_back({"simulation.flip_blend", text(*s.flip_blend)});
  if (s.kernel) o.push_back({"simulation.kernel", *s.kernel});
  if (s.frames) o.push_back({"simulation.frames", std::to_string(*s.frames)});
  if (s.grid_precision) o.push_back({"grid.precision", *s.grid_precision});
  if (s.simd) o.push_back({"simulation.simd", *s.simd ? "true" : "false"});
  if (s.boundary) o.push_back({"walls[0].boundary", *s.boundary});
  if (s.buffer) o.push_back({"grid.buffer", std::to_string(*s.buffer)});
  if (s.contact) o.push_back({"simulation.contact", *s.contact});
  if (s.quadrature) o.push_back({"simulation.quadrature", *s.quadrature});
  if (s.wall_offset || s.margin) {
    const Vec3 cell = scene.grid.spacing() / s.refine;
    const Vec3 shift = cell * s.wall_offset.value_or(0), grow = cell * s.margin.value_or(0);
    const auto point = [](const Vec3& x) {
      return "[" + text(x.x()) + ", " + text(x.y()) + ", " + text(x.z()) + "]";
    };
    o.push_back({"grid.origin", point(scene.grid.origin - shift - grow)});
    o.push_back({"grid.max", point(scene.grid.max - shift + grow)});
    // The particles stay where they were: only the node rows move against the walls.
    o.push_back(
        {"grid.sampling_origin", point(scene.grid.sampling_origin.value_or(scene.grid.origin))});
  }
  return o;
}

const char* transfer_name(Transfer t) {
  switch (t) {
    case Transfer::apic: return "apic";
    case Transfer::pic: return "pic";
    case Transfer::flip: return "flip";
    case Transfer::mls: return "mls";
  }
  return "?";
}
const char* kernel_name(Kernel k) {
  return k == Kernel::linear ? "linear" : k == Kernel::quadratic ? "quadratic" : "cubic";
}

// The child sends its Outcome back as lines of text.
std::string serialize(const Outcome& o, double rss) {
  std::ostringstream s;
  s.precision(17);
  s << o.status << '\n' << o.error_name << '\n' << o.error << ' ' << o.particles << ' '
    << o.substeps << ' ' << o.seconds << ' ' << rss << '\n';
  for (const Measure& m : o.measures)
    s << "m " << m.name << ' ' << m.value << ' ' << m.exact << ' ' << (m.unit.empty() ? "-" : m.unit)
      << '\n';
  for (const Series& ser : o.series) {
    s << "s " << ser.t.size() << ' ' << ser.name << '\n';
    for (std::size_t i = 0; i < ser.t.size(); ++i) s << ser.t[i] << ' ' << ser.value[i] << '\n';
  }
  return s.str();
}

Outcome deserialize(const std::string& text, double& rss) {
  std::istringstream s(text);
  Outcome o;
  std::getline(s, o.status);
  std::getline(s, o.error_name);
  s >> o.error >> o.particles >> o.substeps >> o.seconds >> rss;
  for (std::string tag; s >> tag;) {
    if (tag == "m") {
      Measure m;
      s >> m.name >> m.value >> m.exact >> m.unit;
      if (m.unit == "-") m.unit.clear();
      o.measures.push_back(m);
    } else {
      std::size_t n = 0;
      Series ser;
      s >> n;
      s.get();
      std::getline(s, ser.name);
      ser.t.resize(n);
      ser.value.resize(n);
      for (std::size_t i = 0; i < n; ++i) s >> ser.t[i] >> ser.value[i];
      o.series.push_back(ser);
    }
  }
  return o;
}

}  // namespace

std::vector<std::string> experiment_names() {
  std::vector<std::string> names;
  for (const Experiment& e : experiments()) names.push_back(e.name);
  return names;
}

std::vector<StudyRow> run_study(const StudyOptions& opt,
                                const std::function<void(const StudyRow&)>& progress) {
  for (const std::string& name : opt.experiments) {
    bool known = false;
    for (const Experiment& e : experiments()) known = known || e.name == name;
    if (!known) {
      std::string list;
      for (const std::string& n : experiment_names()) list += (list.empty() ? "" : ", ") + n;
      throw std::invalid_argument("unknown study sweep '" + name + "'; expected one of " + list);
    }
  }
  if (opt.threads > 0) set_threads(opt.threads);
  std::vector<StudyRow> rows;
  for (const Experiment& e : experiments()) {
    if (!opt.experiments.empty() &&
        std::find(opt.experiments.begin(), opt.experiments.end(), e.name) == opt.experiments.end())
      continue;
    const Case& c = *find_case(e.case_name);
    MaterialRegistry registry = builtin_registry();
    const SceneDesc base = load_scene(scene_path(c), registry, LoadOptions{{}, false, {}});
    for (const Setting& s : opt.quick ? e.quick : e.full) {
      const std::vector<SceneOverride> o = overrides_for(s, base);
      const SceneDesc scene = load_scene(scene_path(c), registry, LoadOptions{o, false, {}});
      StudyRow row;
      row.experiment = e.name;
      row.case_name = c.name;
      row.setting = s;
      row.h = scene.grid.spacing().minCoeff();
      row.ppc = scene.objects.at(0).particles_per_cell;
      row.sampling = scene.objects.at(0).sampling == Sampling::regular ? "regular" : "jittered";
      row.transfer = transfer_name(scene.simulation.transfer);
      if (scene.simulation.transfer == Transfer::flip) {
        std::ostringstream blend;
        blend << scene.simulation.flip_blend;  // 6 significant digits: "0.95"
        row.transfer += blend.str();
      }
      row.kernel = kernel_name(scene.simulation.kernel);
      row.grid_precision = scene.grid.float_nodes ? "float" : "double";
      row.simd = scene.simulation.simd;
      row.cfl = scene.simulation.cfl.value_or(0);
      row.dt = scene.simulation.dt.value_or(0);
      const std::string out = run_in_child(
          [&] {
            const Outcome outcome = run_case(c, o);
            return serialize(outcome, peak_rss_bytes());  // after the run: its peak
          },
          "study run " + e.name + " (" + setting_label(row) + ")");
      row.outcome = deserialize(out, row.peak_rss_bytes);
      if (progress) progress(row);
      rows.push_back(std::move(row));
    }
  }
  return rows;
}

std::string setting_label(const StudyRow& r) {
  std::ostringstream s;
  s << r.kernel << " h=" << r.h << " ppc=" << r.ppc << (r.sampling == "regular" ? "r" : "j");
  if (r.cfl > 0) s << " cfl=" << r.cfl;
  else s << " dt=" << r.dt;
  s << ' ' << r.transfer;
  // Only where the sweep sets them, so the other sweeps' labels end in the transfer.
  if (r.setting.grid_precision) s << " grid=" << r.grid_precision;
  if (r.setting.simd) s << (r.simd ? " simd" : " scalar");
  if (r.setting.boundary) s << " floor=" << *r.setting.boundary;
  if (r.setting.friction_angle) s << " phi=" << *r.setting.friction_angle;
  if (r.setting.contact) s << " contact=" << *r.setting.contact;
  if (r.setting.quadrature) s << " quadrature=" << *r.setting.quadrature;
  if (r.setting.wall_offset) s << " offset=" << *r.setting.wall_offset << "h";
  return s.str();
}

std::string study_csv(const std::vector<StudyRow>& rows) {
  std::ostringstream s;
  s.precision(9);
  s << "experiment,case,kernel,h,ppc,sampling,cfl,dt,transfer,precision,grid_precision,simd,"
       "floor,contact,quadrature,wall_offset,status,error_name,error,"
       "particles,substeps,particle_steps,wall_seconds,particle_steps_per_second,peak_rss_mb,"
       "measures\n";
  for (const StudyRow& r : rows) {
    const Outcome& o = r.outcome;
    const double steps = static_cast<double>(o.particles) * o.substeps;
    s << r.experiment << ',' << r.case_name << ',' << r.kernel << ',' << r.h << ',' << r.ppc << ','
      << r.sampling << ',' << r.cfl << ',' << r.dt << ',' << r.transfer << ',' << kStoredPrecision
      << ',' << r.grid_precision << ',' << (r.simd ? "true" : "false") << ','
      << r.setting.boundary.value_or("") << ',' << r.setting.contact.value_or("") << ','
      << r.setting.quadrature.value_or("") << ',' << r.setting.wall_offset.value_or(0) << ','
      << o.status << ",\"" << o.error_name << "\"," << o.error << ',' << o.particles << ','
      << o.substeps << ',' << steps << ',' << o.seconds << ','
      << (o.seconds > 0 ? steps / o.seconds : 0) << ',' << r.peak_rss_bytes / 1e6 << ",\"";
    for (std::size_t i = 0; i < o.measures.size(); ++i)
      s << (i ? "; " : "") << o.measures[i].name << '=' << o.measures[i].value
        << (o.measures[i].exact != 0 ? " (exact " : "")
        << (o.measures[i].exact != 0 ? text(o.measures[i].exact) + ")" : "");
    s << "\"\n";
  }
  return s.str();
}

std::string series_csv(const std::vector<StudyRow>& rows) {
  std::ostringstream s;
  s.precision(12);
  s << "experiment,case,label,series,t,value\n";
  for (const StudyRow& r : rows)
    for (const Series& ser : r.outcome.series)
      for (std::size_t i = 0; i < ser.t.size(); ++i)
        s << r.experiment << ',' << r.case_name << ",\"" << setting_label(r) << "\",\"" << ser.name
          << "\"," << ser.t[i] << ',' << ser.value[i] << '\n';
  return s.str();
}

int study_main(const StudyOptions& opt, const std::filesystem::path& dir) {
  std::vector<StudyRow> rows;
  try {
    rows = run_study(opt, [](const StudyRow& r) {
      std::printf("%-15s %-20s %-58s %-8s error %.3e  %6.1f s  %.0f MB\n", r.experiment.c_str(),
                  r.case_name.c_str(), setting_label(r).c_str(), r.outcome.status.c_str(),
                  r.outcome.error, r.outcome.seconds, r.peak_rss_bytes / 1e6);
      std::fflush(stdout);
    });
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "mpm study: %s\n", e.what());
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mpm study: %s\n", e.what());
    return kExitRunFailed;
  }
  try {
    std::filesystem::create_directories(dir);
    write_file_whole(dir / "study.csv", study_csv(rows));
    write_file_whole(dir / "series.csv", series_csv(rows));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mpm study: %s\n", e.what());
    return kExitRunFailed;
  }
  std::printf("wrote %s and %s\n", (dir / "study.csv").c_str(), (dir / "series.csv").c_str());
  return kExitOk;
}

double convergence_order(const std::vector<double>& h, const std::vector<double>& error) {
  const std::size_t n = h.size();
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = std::log(h[i]), y = std::log(error[i]);
    sx += x, sy += y, sxx += x * x, sxy += x * y;
  }
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

}  // namespace mpm::validation
