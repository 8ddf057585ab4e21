#include "engine/io/summary.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <span>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "engine/core/atomic_file.h"
#include "engine/core/reduce.h"
#include "engine/parallel/comm.h"

namespace mpm {

namespace {

/// One per-object quantity of a summary after its name and particle count: its key, the
/// member that holds it (a number or a vector) and the tolerance `mpm compare` applies. The
/// writer, the reader and the comparison all walk this one list, in its order.
struct Quantity {
  const char* name;
  double ObjectSummary::*number = nullptr;
  Vec3 ObjectSummary::*vector = nullptr;
  double Tolerances::*tolerance;
  /// Components: 1 for a number, 3 for a vector.
  int components() const { return vector ? 3 : 1; }
  /// Component c of the quantity in `o`.
  double get(const ObjectSummary& o, int c) const { return vector ? (o.*vector)[c] : o.*number; }
};

const Quantity kQuantities[] = {
    {"centroid", nullptr, &ObjectSummary::centroid, &Tolerances::centroid},
    {"bbox_min", nullptr, &ObjectSummary::bbox_min, &Tolerances::bbox},
    {"bbox_max", nullptr, &ObjectSummary::bbox_max, &Tolerances::bbox},
    {"mean_speed", &ObjectSummary::mean_speed, nullptr, &Tolerances::speed},
    {"max_speed", &ObjectSummary::max_speed, nullptr, &Tolerances::speed},
    {"kinetic_energy", &ObjectSummary::kinetic_energy, nullptr, &Tolerances::energy},
    {"elastic_energy", &ObjectSummary::elastic_energy, nullptr, &Tolerances::energy},
    {"gravitational_energy", &ObjectSummary::gravitational_energy, nullptr, &Tolerances::energy},
    {"linear_momentum", nullptr, &ObjectSummary::linear_momentum, &Tolerances::momentum},
    {"angular_momentum", nullptr, &ObjectSummary::angular_momentum, &Tolerances::angular_momentum},
};

}  // namespace

// ---------------------------------------------------------------------------------------------
// Summarize

namespace {

/// An object's sums over its particles, for its summary.
struct Sums {
  double mass = 0, speed_sum = 0, max_speed = 0, kinetic = 0, gravitational = 0;
  Vec3 mx = Vec3::Zero(), x_sum = Vec3::Zero(), momentum = Vec3::Zero();
  Vec3 angular = Vec3::Zero();
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = Vec3::Constant(-std::numeric_limits<double>::infinity());
};

/// The sums of `a` and `b` (b's particles after a's).
Sums combine(Sums a, const Sums& b) {
  a.mass += b.mass;
  a.mx += b.mx;
  a.x_sum += b.x_sum;
  a.lo = a.lo.cwiseMin(b.lo);
  a.hi = a.hi.cwiseMax(b.hi);
  a.speed_sum += b.speed_sum;
  a.max_speed = std::max(a.max_speed, b.max_speed);
  a.kinetic += b.kinetic;
  a.gravitational += b.gravitational;
  a.momentum += b.momentum;
  a.angular += b.angular;
  return a;
}

/// The sums of particles [first, end) of `p` (gravity `g`, potential energy and angular
/// momentum about `origin`), over fixed chunks combined in chunk order: the same numbers on
/// any thread count.
Sums particle_sums(const Particles& p, std::size_t first, std::size_t end, const Vec3& origin,
                   const Vec3& g) {
  return reduce_chunks(
      end - first, Sums{},
      [&](std::size_t a, std::size_t b) {
        Sums c;
        for (std::size_t q = first + a; q < first + b; ++q) {
          const double m = p.mass(q);
          const Vec3& x = p.x[q];
          const Vec3& v = p.v[q];
          const Vec3 r = x - origin;
          const double speed = v.norm();
          c.mass += m;
          c.mx += m * x;
          c.x_sum += x;
          c.lo = c.lo.cwiseMin(x);
          c.hi = c.hi.cwiseMax(x);
          c.speed_sum += speed;
          c.max_speed = std::max(c.max_speed, speed);
          c.kinetic += 0.5 * m * v.squaredNorm();
          c.gravitational -= m * g.dot(r);
          c.momentum += m * v;
          c.angular += m * r.cross(v);
        }
        return c;
      },
      combine);
}

/// The elastic energy of object `o` (particles up to `end`): one material range per object
/// in practice; any range lying inside the object counts.
double object_elastic_energy(const Simulation& sim, const ObjectInfo& o, std::size_t end) {
  double elastic = 0;
  const std::vector<Real>& range_energy = sim.range_elastic_energies();
  for (std::size_t k = 0; k < sim.materials().size(); ++k) {
    const MaterialRange& r = sim.materials()[k];
    if (r.count == 0 || !r.material || r.first < o.first || r.first + r.count > end) continue;
    elastic += range_energy[k];
  }
  return elastic;
}

/// With more than one rank: each rank's sums `t`, elastic energy and particle count `n` of
/// its own particles, replaced by their combination in rank order on every rank (the same
/// bits every run); no particle leaves its rank.
void combine_over_ranks(Sums& t, double& elastic, std::size_t& n) {
  std::vector<double> mine = {t.mass,          t.speed_sum, t.max_speed,           t.kinetic,
                              t.gravitational, elastic,     static_cast<double>(n)};
  for (const Vec3* v : {&t.mx, &t.x_sum, &t.momentum, &t.angular, &t.lo, &t.hi})
    mine.insert(mine.end(), v->data(), v->data() + 3);
  const std::vector<double> all = parallel::all_gather(mine);
  elastic = 0;
  n = 0;
  for (std::size_t at = 0; at < all.size(); at += mine.size()) {
    const double* d = &all[at];
    Sums part;
    part.mass = d[0], part.speed_sum = d[1], part.max_speed = d[2], part.kinetic = d[3];
    part.gravitational = d[4];
    Vec3* fields[] = {&part.mx, &part.x_sum, &part.momentum, &part.angular, &part.lo, &part.hi};
    for (int f = 0; f < 6; ++f) *fields[f] = Vec3(d[7 + 3 * f], d[8 + 3 * f], d[9 + 3 * f]);
    t = at == 0 ? part : combine(t, part);
    elastic += d[5];
    n += static_cast<std::size_t>(d[6]);
  }
}

}  // namespace

FrameSummary summarize(const Simulation& sim, int frame) {
  const Particles& p = sim.particles();
  const Vec3 g = sim.scene().simulation.gravity;
  const Vec3 origin = sim.scene().grid.origin;

  FrameSummary out;
  out.frame = frame;
  out.time = sim.time();
  out.objects.reserve(sim.objects().size());
  for (const ObjectInfo& o : sim.objects()) {
    const std::size_t end = std::min(o.first + o.count, p.size());
    ObjectSummary s;
    s.name = o.name;
    s.particles = o.count;
    const std::size_t first = std::min(o.first, end);
    Sums t = particle_sums(p, first, end, origin, g);
    std::size_t n = end - first;
    double elastic = object_elastic_energy(sim, o, end);
    if (sim.domain()) {
      combine_over_ranks(t, elastic, n);
      s.particles = n;
    }
    if (t.mass > 0) {
      s.centroid = t.mx / t.mass;
    } else if (n > 0) {
      s.centroid = t.x_sum / static_cast<double>(n);
    }
    if (n > 0) {
      s.bbox_min = t.lo;
      s.bbox_max = t.hi;
      s.mean_speed = t.speed_sum / static_cast<double>(n);
    }
    s.max_speed = t.max_speed;
    s.kinetic_energy = t.kinetic;
    s.gravitational_energy = t.gravitational;
    s.linear_momentum = t.momentum;
    s.angular_momentum = t.angular;
    s.elastic_energy = elastic;
    out.objects.push_back(std::move(s));
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Write

namespace {

/// Shortest text that reads back as the same double. YAML 1.1 readers (PyYAML) take "1e-05"
/// for a string, so an exponent form always gets a '.' in its mantissa.
std::string number(double v) {
  if (std::isnan(v)) return ".nan";
  if (std::isinf(v)) return v > 0 ? ".inf" : "-.inf";
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  std::string s(buf, r.ptr);
  const std::size_t e = s.find('e');
  if (e != std::string::npos && s.find('.') == std::string::npos) s.insert(e, ".0");
  return s;
}

std::string vec(const Vec3& v) {
  return "[" + number(v.x()) + ", " + number(v.y()) + ", " + number(v.z()) + "]";
}

/// A double-quoted YAML string.
std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char esc[8];
      std::snprintf(esc, sizeof esc, "\\x%02x", static_cast<unsigned>(c));
      out += esc;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

}  // namespace

std::string summary_to_yaml(const RunSummary& summary) {
  std::string y;
  y.reserve(256 + summary.frames.size() * 900 *
                      (summary.frames.empty() ? 1 : summary.frames[0].objects.size()));
  y += "# mpm run summary, SI units (docs/regression-testing.md)\n";
  y += "summary_version: 1\n";
  y += "scene: " + quoted(summary.scene) + "\n";
  y += summary.frames.empty() ? "frames: []\n" : "frames:\n";
  for (const FrameSummary& f : summary.frames) {
    y += "- frame: " + std::to_string(f.frame) + "\n";
    y += "  time: " + number(f.time) + "\n";
    y += f.objects.empty() ? "  objects: []\n" : "  objects:\n";
    for (const ObjectSummary& o : f.objects) {
      y += "  - name: " + quoted(o.name) + "\n";
      y += "    particles: " + std::to_string(o.particles) + "\n";
      for (const Quantity& q : kQuantities)
        y += std::string("    ") + q.name + ": " +
             (q.vector ? vec(o.*q.vector) : number(o.*q.number)) + "\n";
    }
  }
  return y;
}

void write_summary(const std::filesystem::path& file, const RunSummary& summary) {
  const std::string text = summary_to_yaml(summary);
  std::error_code ec;
  if (file.has_parent_path()) std::filesystem::create_directories(file.parent_path(), ec);
  write_file_whole(file, text);
}

// ---------------------------------------------------------------------------------------------
// Read

namespace {

/// Reads typed values out of a parsed summary, naming the file, line and key on any problem.
class SummaryReader {
 public:
  explicit SummaryReader(std::string name) : name_(std::move(name)) {}

  [[noreturn]] void fail(const YAML::Node& at, const std::string& what) const {
    const YAML::Mark m = at.Mark();
    std::string where = name_;
    if (!m.is_null()) where += ":" + std::to_string(m.line + 1);
    throw std::runtime_error(where + ": " + what);
  }

  YAML::Node key(const YAML::Node& map, const char* k, const std::string& where) const {
    if (!map.IsMap()) fail(map, where + " is not a mapping");
    const YAML::Node n = map[k];
    if (!n.IsDefined() || n.IsNull()) fail(map, where + ": missing '" + k + "'");
    return n;
  }

  std::string scalar(const YAML::Node& n, const std::string& what) const {
    if (!n.IsScalar()) fail(n, what + " is not a single value");
    return n.Scalar();
  }

  double real(const YAML::Node& n, const std::string& what) const {
    const std::string s = scalar(n, what);
    if (s == ".nan" || s == ".NaN" || s == ".NAN") return std::numeric_limits<double>::quiet_NaN();
    if (s == ".inf" || s == ".Inf" || s == ".INF" || s == "+.inf")
      return std::numeric_limits<double>::infinity();
    if (s == "-.inf" || s == "-.Inf" || s == "-.INF")
      return -std::numeric_limits<double>::infinity();
    const char* begin = s.data();
    if (!s.empty() && s[0] == '+') ++begin;
    double v = 0;
    const auto r = std::from_chars(begin, s.data() + s.size(), v);
    if (r.ec != std::errc() || r.ptr != s.data() + s.size())
      fail(n, what + " is not a number: '" + s + "'");
    return v;
  }

  long long integer(const YAML::Node& n, const std::string& what, long long min) const {
    const std::string s = scalar(n, what);
    long long v = 0;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    if (r.ec != std::errc() || r.ptr != s.data() + s.size())
      fail(n, what + " is not a whole number: '" + s + "'");
    if (v < min) fail(n, what + " must be >= " + std::to_string(min) + ", got " + s);
    return v;
  }

  Vec3 vec3(const YAML::Node& n, const std::string& what) const {
    if (!n.IsSequence() || n.size() != 3) fail(n, what + " must be a list of 3 numbers");
    return Vec3(real(n[0], what + "[0]"), real(n[1], what + "[1]"), real(n[2], what + "[2]"));
  }

  RunSummary run(const YAML::Node& root) const {
    if (!root.IsMap()) fail(root, "not a run summary (expected a mapping with 'frames')");
    if (const YAML::Node v = root["summary_version"]; v.IsDefined()) {
      const long long version = integer(v, "summary_version", 0);
      if (version != 1)
        fail(v, "summary_version " + std::to_string(version) +
                    " is not supported (this mpm reads version 1)");
    }
    RunSummary s;
    if (const YAML::Node scene = root["scene"]; scene.IsDefined() && !scene.IsNull())
      s.scene = scalar(scene, "scene");
    const YAML::Node frames = key(root, "frames", "summary");
    if (!frames.IsSequence()) fail(frames, "'frames' must be a list");
    for (std::size_t i = 0; i < frames.size(); ++i) s.frames.push_back(frame(frames[i], i));
    return s;
  }

 private:
  FrameSummary frame(const YAML::Node& n, std::size_t index) const {
    const std::string where = "frames[" + std::to_string(index) + "]";
    FrameSummary f;
    f.frame = static_cast<int>(integer(key(n, "frame", where), where + ".frame", 0));
    f.time = real(key(n, "time", where), where + ".time");
    const YAML::Node objects = n["objects"];
    if (objects.IsDefined() && !objects.IsNull()) {
      if (!objects.IsSequence()) fail(objects, where + ".objects must be a list");
      for (std::size_t k = 0; k < objects.size(); ++k)
        f.objects.push_back(object(objects[k], where + ".objects[" + std::to_string(k) + "]"));
    }
    return f;
  }

  ObjectSummary object(const YAML::Node& n, const std::string& where) const {
    ObjectSummary o;
    o.name = scalar(key(n, "name", where), where + ".name");
    const std::string w = where + " (" + o.name + ")";
    o.particles = static_cast<std::size_t>(integer(key(n, "particles", w), w + ".particles", 0));
    for (const Quantity& q : kQuantities) {
      const YAML::Node value = key(n, q.name, w);
      if (q.vector)
        o.*q.vector = vec3(value, w + "." + q.name);
      else
        o.*q.number = real(value, w + "." + q.name);
    }
    return o;
  }

  std::string name_;
};

}  // namespace

RunSummary parse_summary(const std::string& text, const std::string& name) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(name + ": not valid YAML: " + e.what());
  }
  try {
    return SummaryReader(name).run(root);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(name + ": " + e.what());
  }
}

RunSummary read_summary(const std::filesystem::path& path) {
  const std::filesystem::path file = summary_path(path);
  std::error_code ec;
  if (!std::filesystem::exists(file, ec))
    throw std::runtime_error("cannot read summary '" + file.string() + "': no such file");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read summary '" + file.string() + "'");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw std::runtime_error("cannot read summary '" + file.string() + "'");
  return parse_summary(text.str(), file.string());
}

std::filesystem::path summary_path(const std::filesystem::path& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) return path / "summary.yaml";
  return path;
}

// ---------------------------------------------------------------------------------------------
// SummaryWriter

SummaryWriter::SummaryWriter(std::filesystem::path dir, std::string file_name)
    : file_(std::move(dir) / file_name) {}

void SummaryWriter::on_start(const Simulation& sim, int) {
  // The state on entry is frame 0 for a new run, or the checkpoint's frame when resuming.
  const double frame_dt = sim.scene().simulation.frame_dt;
  const int start =
      frame_dt > 0 ? static_cast<int>(std::max(0L, std::lround(sim.time() / frame_dt))) : 0;
  summary_ = RunSummary{};
  summary_.scene = sim.scene().file.filename().string();
  FrameSummary first = summarize(sim, start);
  if (parallel::rank() != 0) return;  // rank 0 writes the summary
  if (start > 0) {
    // Resuming: keep the earlier frames of this run's summary if they describe the same objects.
    try {
      const RunSummary old = read_summary(file_);
      for (const FrameSummary& f : old.frames) {
        if (f.frame >= start) break;
        bool same = f.objects.size() == first.objects.size();
        for (std::size_t k = 0; same && k < f.objects.size(); ++k)
          same = f.objects[k].name == first.objects[k].name &&
                 f.objects[k].particles == first.objects[k].particles;
        if (!same) {
          summary_.frames.clear();
          break;
        }
        summary_.frames.push_back(f);
      }
    } catch (const std::runtime_error&) {
      summary_.frames.clear();  // no usable earlier summary: start at the resumed frame
    }
  }
  summary_.frames.push_back(std::move(first));
  write();
}

void SummaryWriter::on_frame(const Simulation& sim, int frame) {
  FrameSummary f = summarize(sim, frame);
  if (parallel::rank() != 0) return;
  summary_.frames.push_back(std::move(f));
  write();
}

void SummaryWriter::on_finish(const Simulation&, const RunResult&) {
  if (!summary_.frames.empty()) write();
}

void SummaryWriter::write() const {
  write_summary(file_, summary_);
}

// ---------------------------------------------------------------------------------------------
// Tolerances

Tolerances default_tolerances(const RunSummary& reference, const RelativeTolerances& rel) {
  double extent = 0, lever = 0, speed = 0, moving = 0, momentum = 0;
  double u_min = std::numeric_limits<double>::infinity(), u_max = -u_min;
  for (const FrameSummary& f : reference.frames) {
    double frame_moving = 0, frame_u = 0;
    for (const ObjectSummary& o : f.objects) {
      extent = std::max(extent, (o.bbox_max - o.bbox_min).maxCoeff());
      for (int corner = 0; corner < 8; ++corner) {
        const Vec3 c((corner & 1 ? o.bbox_max : o.bbox_min).x(),
                     (corner & 2 ? o.bbox_max : o.bbox_min).y(),
                     (corner & 4 ? o.bbox_max : o.bbox_min).z());
        lever = std::max(lever, c.norm());
      }
      speed = std::max(speed, o.max_speed);
      frame_moving += std::abs(o.kinetic_energy) + std::abs(o.elastic_energy);
      frame_u += o.gravitational_energy;
      momentum = std::max(momentum, o.linear_momentum.norm());
    }
    moving = std::max(moving, frame_moving);
    u_min = std::min(u_min, frame_u);
    u_max = std::max(u_max, frame_u);
  }
  // Gravitational energy is measured from the grid origin: its size says where the origin is,
  // not how much energy the run moves around. Its range over the run does.
  const double energy = moving + (u_max > u_min ? u_max - u_min : 0.0);
  // NaN in a reference (a broken golden) must not turn every tolerance into NaN.
  auto clean = [](double x) { return std::isfinite(x) ? x : 0.0; };
  Tolerances t;
  t.centroid = rel.centroid * clean(extent);
  t.bbox = rel.bbox * clean(extent);
  t.speed = rel.speed * clean(speed);
  t.energy = rel.energy * clean(energy);
  t.momentum = rel.momentum * clean(momentum);
  t.angular_momentum = rel.momentum * clean(momentum) * clean(lever);
  return t;
}

namespace {

constexpr const char* kToleranceNames =
    "centroid, bbox, speed, energy, momentum, angular_momentum, all";

}  // namespace

Tolerances parse_tolerance_overrides(Tolerances base, const std::vector<std::string>& items) {
  for (const std::string& item : items) {
    const std::size_t eq = item.find('=');
    if (eq == std::string::npos)
      throw std::invalid_argument(
          "tolerance '" + item +
          "' must be QUANTITY=VALUE, e.g. centroid=1e-4; quantities: " + kToleranceNames);
    const std::string q = item.substr(0, eq), text = item.substr(eq + 1);
    double value = 0;
    const char* begin = text.data();
    const char* end = text.data() + text.size();
    const auto r = std::from_chars(begin, end, value);
    if (text.empty() || r.ec != std::errc() || r.ptr != end || !std::isfinite(value) || value < 0)
      throw std::invalid_argument("tolerance '" + item + "': '" + text +
                                  "' is not a finite number >= 0");
    if (q == "centroid") {
      base.centroid = value;
    } else if (q == "bbox") {
      base.bbox = value;
    } else if (q == "speed") {
      base.speed = value;
    } else if (q == "energy") {
      base.energy = value;
    } else if (q == "momentum") {
      base.momentum = value;
    } else if (q == "angular_momentum") {
      base.angular_momentum = value;
    } else if (q == "all") {
      base = Tolerances{value, value, value, value, value, value};
    } else {
      throw std::invalid_argument("unknown tolerance quantity '" + q + "' in '" + item +
                                  "'; valid quantities: " + kToleranceNames);
    }
  }
  return base;
}

// ---------------------------------------------------------------------------------------------
// Compare

namespace {

/// |a - b|; infinite when exactly one of them is not finite or they are unequal non-finite
/// values, zero when both are the same infinity or both NaN (an identical broken run).
double difference(double a, double b) {
  if (std::isfinite(a) && std::isfinite(b)) return std::abs(a - b);
  if (std::isnan(a) && std::isnan(b)) return 0;
  if (a == b) return 0;
  return std::numeric_limits<double>::infinity();
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

/// The object names of a frame, quoted and comma-separated.
std::string names(const FrameSummary& f) {
  std::string out;
  for (const ObjectSummary& o : f.objects) out += (out.empty() ? "'" : ", '") + o.name + "'";
  return out.empty() ? "(none)" : out;
}

/// Why two summaries do not describe the same run, or "" if they do.
std::string mismatch(const RunSummary& a, const RunSummary& b) {
  if (a.frames.empty() || b.frames.empty())
    return std::string("a summary has no frames (") + (a.frames.empty() ? "first" : "second") + ")";
  if (a.frames.size() != b.frames.size())
    return "different frame counts: " + std::to_string(a.frames.size()) + " frames (" +
           std::to_string(a.frames.front().frame) + ".." + std::to_string(a.frames.back().frame) +
           ") vs " + std::to_string(b.frames.size()) + " frames (" +
           std::to_string(b.frames.front().frame) + ".." + std::to_string(b.frames.back().frame) +
           "); run with the same --frames as the golden";
  for (std::size_t i = 0; i < a.frames.size(); ++i) {
    const FrameSummary &fa = a.frames[i], &fb = b.frames[i];
    const std::string at = "frames[" + std::to_string(i) + "]";
    if (fa.frame != fb.frame)
      return at + ": frame " + std::to_string(fa.frame) + " vs frame " + std::to_string(fb.frame);
    if (!(difference(fa.time, fb.time) <= 1e-9 * std::max(std::abs(fa.time), std::abs(fb.time))))
      return "frame " + std::to_string(fa.frame) + ": time " + fmt("%.17g", fa.time) + " s vs " +
             fmt("%.17g", fb.time) + " s (different frame_dt?)";
    if (fa.objects.size() != fb.objects.size())
      return "frame " + std::to_string(fa.frame) + ": objects " + names(fa) + " vs " + names(fb);
    for (std::size_t k = 0; k < fa.objects.size(); ++k) {
      const ObjectSummary &oa = fa.objects[k], &ob = fb.objects[k];
      if (oa.name != ob.name)
        return "frame " + std::to_string(fa.frame) + ": object " + std::to_string(k) + " is '" +
               oa.name + "' vs '" + ob.name + "'";
      if (oa.particles != ob.particles)
        return "frame " + std::to_string(fa.frame) + ": object '" + oa.name + "' has " +
               std::to_string(oa.particles) + " particles vs " + std::to_string(ob.particles) +
               " (different grid, particles_per_cell, mesh or seed?)";
    }
  }
  return "";
}

}  // namespace

FrameSelection select_frames(const RunSummary& a, const RunSummary& b,
                             std::optional<int> last_frame) {
  FrameSelection sel{a, b, "", ""};
  const auto span = [](const RunSummary& s) {
    return s.frames.empty() ? std::string("no frames")
                            : std::to_string(s.frames.front().frame) + ".." +
                                  std::to_string(s.frames.back().frame);
  };
  const auto keep_to = [](RunSummary& s, int last) {
    while (!s.frames.empty() && s.frames.back().frame > last) s.frames.pop_back();
  };
  if (last_frame) {
    for (const auto& [s, which] : {std::pair{&a, "the first summary"}, {&b, "the reference"}})
      if (s->frames.empty() || s->frames.back().frame < *last_frame) {
        sel.error = "--frames " + std::to_string(*last_frame) + ": " + which + " has frames " +
                    span(*s) + ", not frame " + std::to_string(*last_frame);
        return sel;
      }
    keep_to(sel.a, *last_frame);
    keep_to(sel.b, *last_frame);
    if (sel.a.frames.size() < a.frames.size() || sel.b.frames.size() < b.frames.size())
      sel.note = "compared frames " + span(sel.b) + " (--frames " + std::to_string(*last_frame) +
                 "); the run has frames " + span(a) + ", the reference " + span(b);
    return sel;
  }
  if (!b.frames.empty() && a.frames.size() > b.frames.size()) {
    sel.a.frames.resize(b.frames.size());
    sel.note = "compared frames " + span(b) +
               ", all of the reference's; the run goes on to frame " +
               std::to_string(a.frames.back().frame) + ": its frames after " +
               std::to_string(b.frames.back().frame) + " are not compared";
  }
  return sel;
}

CompareResult compare_summaries(const RunSummary& a, const RunSummary& b, const Tolerances& tol) {
  CompareResult result;
  result.error = mismatch(a, b);
  if (!result.error.empty()) return result;
  result.frames = static_cast<int>(a.frames.size());
  result.objects = static_cast<int>(a.frames.front().objects.size());
  static const char* const kAxis[] = {"x", "y", "z"};
  result.ok = true;
  for (const Quantity& q : kQuantities) {
    Difference worst;
    worst.quantity = q.name;
    worst.tolerance = tol.*(q.tolerance);
    worst.difference = -1;
    for (std::size_t i = 0; i < a.frames.size(); ++i) {
      const FrameSummary &fa = a.frames[i], &fb = b.frames[i];
      for (std::size_t k = 0; k < fa.objects.size(); ++k) {
        for (int c = 0; c < q.components(); ++c) {
          const double va = q.get(fa.objects[k], c), vb = q.get(fb.objects[k], c);
          const double d = difference(va, vb);
          if (d > worst.tolerance && worst.first_frame_over < 0) worst.first_frame_over = fa.frame;
          if (d > worst.difference) {
            worst.difference = d;
            worst.frame = fa.frame;
            worst.object = fa.objects[k].name;
            worst.value_a = va;
            worst.value_b = vb;
            worst.quantity =
                q.components() == 1 ? std::string(q.name) : std::string(q.name) + "." + kAxis[c];
          }
        }
      }
    }
    if (worst.difference <= 0) {  // identical everywhere (or no objects): name the quantity
      worst.difference = 0;
      worst.quantity = q.name;
    }
    result.ok = result.ok && worst.ok();
    result.largest.push_back(std::move(worst));
  }
  return result;
}

std::string format_comparison(const CompareResult& r) {
  if (!r.error.empty()) return "cannot compare: " + r.error + "\n";
  std::size_t qw = 8, ow = 6;
  for (const Difference& d : r.largest) {
    qw = std::max(qw, d.quantity.size());
    ow = std::max(ow, d.object.size());
  }
  std::string out;
  char line[512];
  std::snprintf(line, sizeof line, "%-*s %5s  %-*s %19s %19s %10s %10s  %s\n", static_cast<int>(qw),
                "quantity", "frame", static_cast<int>(ow), "object", "a", "b (reference)", "|a-b|",
                "tolerance", "result");
  out += line;
  int failed = 0;
  for (const Difference& d : r.largest) {
    std::string verdict = d.ok() ? "PASS" : "FAIL";
    if (!d.ok()) {
      ++failed;
      verdict += " (first over at frame " + std::to_string(d.first_frame_over) + ")";
    }
    // Identical everywhere: no single place to point at.
    const bool none = d.difference == 0;
    std::snprintf(line, sizeof line, "%-*s %5s  %-*s %19.12g %19.12g %10.3e %10.3e  %s\n",
                  static_cast<int>(qw), d.quantity.c_str(),
                  none ? "-" : std::to_string(d.frame).c_str(), static_cast<int>(ow),
                  none ? "-" : d.object.c_str(), d.value_a, d.value_b, d.difference, d.tolerance,
                  verdict.c_str());
    out += line;
  }
  const std::string scope = std::to_string(r.frames) + " frames, " + std::to_string(r.objects) +
                            (r.objects == 1 ? " object" : " objects");
  if (failed == 0) {
    out += "PASS: every quantity within tolerance (" + scope + ")\n";
  } else {
    out += "FAIL: " + std::to_string(failed) + " of " + std::to_string(r.largest.size()) +
           " quantities beyond tolerance (" + scope + ")\n";
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Frames

ParticleDiff compare_frames(const FrameData& a, const FrameData& b) {
  ParticleDiff d;
  if (a.size() != b.size()) {
    d.error = "different particle counts: " + std::to_string(a.size()) + " vs " +
              std::to_string(b.size());
    return d;
  }
  if (a.position.size() != 3 * a.size() || b.position.size() != 3 * b.size() ||
      a.velocity.size() != 3 * a.size() || b.velocity.size() != 3 * b.size() ||
      a.J.size() != a.size() || b.J.size() != b.size()) {
    d.error = "a frame has datasets of unequal length";
    return d;
  }
  d.particles = a.size();
  auto distance = [](const std::vector<float>& u, const std::vector<float>& w, std::size_t q) {
    double s = 0;
    for (int c = 0; c < 3; ++c) {
      const double e = difference(u[3 * q + c], w[3 * q + c]);
      s += e * e;
    }
    return std::sqrt(s);
  };
  for (std::size_t q = 0; q < a.size(); ++q) {
    if (a.object_id[q] != b.object_id[q]) {
      d.error = "particle " + std::to_string(q) + " belongs to object " +
                std::to_string(a.object_id[q]) + " vs " + std::to_string(b.object_id[q]);
      return d;
    }
    const double dx = distance(a.position, b.position, q);
    const double dv = distance(a.velocity, b.velocity, q);
    const double dJ = difference(a.J[q], b.J[q]);
    if (dx > d.max_position) d.max_position = dx, d.position_index = q;
    if (dv > d.max_velocity) d.max_velocity = dv, d.velocity_index = q;
    if (dJ > d.max_J) d.max_J = dJ, d.J_index = q;
  }
  return d;
}

}  // namespace mpm
