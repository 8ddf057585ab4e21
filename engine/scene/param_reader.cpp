#include "engine/scene/param_reader.h"

#include "materials/material.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace mpm {

namespace {

std::string describe(const YAML::Node& n) {
  if (n.IsScalar()) return "'" + n.Scalar() + "'";
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a mapping";
  return "nothing";
}

std::string format_number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

FileLoc node_loc(const YAML::Node& node, const std::string& file) {
  const YAML::Mark m = node.Mark();
  // Only values set with --set have no position in the file (they were built, not parsed).
  if (m.line < 0) return {file + " (--set)", 0, 0};
  return {file, m.line + 1, m.column + 1};
}

std::string closest_match(const std::string& word, const std::vector<std::string>& candidates) {
  auto distance = [](const std::string& a, const std::string& b) {
    std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
    for (std::size_t i = 1; i <= a.size(); ++i) {
      cur[0] = i;
      for (std::size_t j = 1; j <= b.size(); ++j) {
        const bool same = std::tolower(a[i - 1]) == std::tolower(b[j - 1]);
        cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (same ? 0 : 1)});
      }
      std::swap(prev, cur);
    }
    return prev[b.size()];
  };
  std::string best;
  std::size_t best_d = std::numeric_limits<std::size_t>::max();
  for (const auto& c : candidates) {
    std::size_t d = distance(word, c);
    // A prefix or a word containing the candidate ("youngs_modulus" -> "E" is too far).
    if (word.find(c) != std::string::npos || c.find(word) != std::string::npos)
      d = std::min(d, std::size_t(1));
    if (d < best_d) best_d = d, best = c;
  }
  const std::size_t limit = std::max<std::size_t>(2, word.size() / 3);
  return best_d <= limit ? best : "";
}

ParamReader::ParamReader(const YAML::Node& node, std::string file, std::string path)
    : node_(node), file_(std::move(file)), path_(std::move(path)) {
  if (!node_.IsMap() && !node_.IsNull())
    throw SceneError(node_loc(node_, file_), path_, "expected a mapping of keys, found " +
                                                       describe(node_));
}

YAML::Node ParamReader::value(const std::string& key) const {
  const YAML::Node& n = node_;  // const lookup never inserts
  if (!n.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
  return n[key];
}

bool ParamReader::has(const std::string& key) {
  known_.insert(key);
  const YAML::Node v = value(key);
  return v.IsDefined() && !v.IsNull();
}

FileLoc ParamReader::loc(const std::string& key) const {
  if (!key.empty()) {
    const YAML::Node v = value(key);
    if (v.IsDefined()) return node_loc(v, file_);
  }
  return node_loc(node_, file_);
}

std::string ParamReader::key_path(const std::string& key) const {
  if (path_.empty()) return key;
  if (key.empty()) return path_;
  return path_ + "." + key;
}

void ParamReader::fail(const std::string& key, const std::string& what) const {
  throw SceneError(loc(key), key_path(key), what);
}

void ParamReader::check_range(const std::string& key, double v, double lo, double hi,
                              bool lo_open, bool hi_open) const {
  const bool ok = (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
  if (ok) return;
  fail(key, "value " + format_number(v) + " is out of range: expected " +
                range_text(lo, hi, lo_open, hi_open));
}

namespace {

double parse_double(const YAML::Node& n, const ParamReader& r, const std::string& key) {
  if (!n.IsScalar()) r.fail(key, "expected a number, found " + describe(n));
  const std::string& s = n.Scalar();
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(s, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != s.size()) r.fail(key, "expected a number, found '" + s + "'");
  if (!std::isfinite(v)) r.fail(key, "expected a finite number, found '" + s + "'");
  return v;
}

long long parse_integer(const YAML::Node& n, const ParamReader& r, const std::string& key) {
  const double v = parse_double(n, r, key);
  if (v != std::floor(v) || std::abs(v) > 9.0e15)
    r.fail(key, "expected a whole number, found '" + n.Scalar() + "'");
  return static_cast<long long>(v);
}

template <class T>
T convert(const YAML::Node& n, const ParamReader& r, const std::string& key);

template <>
double convert<double>(const YAML::Node& n, const ParamReader& r, const std::string& key) {
  return parse_double(n, r, key);
}

template <>
int convert<int>(const YAML::Node& n, const ParamReader& r, const std::string& key) {
  const long long v = parse_integer(n, r, key);
  if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max())
    r.fail(key, "value " + n.Scalar() + " does not fit in an integer");
  return static_cast<int>(v);
}

template <>
std::uint64_t convert<std::uint64_t>(const YAML::Node& n, const ParamReader& r,
                                     const std::string& key) {
  const long long v = parse_integer(n, r, key);
  if (v < 0) r.fail(key, "expected a non-negative whole number, found '" + n.Scalar() + "'");
  return static_cast<std::uint64_t>(v);
}

template <>
bool convert<bool>(const YAML::Node& n, const ParamReader& r, const std::string& key) {
  bool b = false;
  if (!n.IsScalar() || !YAML::convert<bool>::decode(n, b))
    r.fail(key, "expected true or false, found " + describe(n));
  return b;
}

template <>
std::string convert<std::string>(const YAML::Node& n, const ParamReader& r,
                                 const std::string& key) {
  if (!n.IsScalar()) r.fail(key, "expected a text value, found " + describe(n));
  return n.Scalar();
}

template <>
Vec3 convert<Vec3>(const YAML::Node& n, const ParamReader& r, const std::string& key) {
  if (!n.IsSequence() || n.size() != 3)
    r.fail(key, "expected a list of three numbers [x, y, z], found " + describe(n));
  Vec3 v;
  for (int i = 0; i < 3; ++i) v[i] = parse_double(n[i], r, key);
  return v;
}

template <>
Vec3i convert<Vec3i>(const YAML::Node& n, const ParamReader& r, const std::string& key) {
  if (n.IsScalar()) {
    const int v = convert<int>(n, r, key);
    return Vec3i(v, v, v);
  }
  if (!n.IsSequence() || n.size() != 3)
    r.fail(key, "expected a whole number or a list of three, found " + describe(n));
  Vec3i v;
  for (int i = 0; i < 3; ++i) v[i] = convert<int>(n[i], r, key);
  return v;
}

template <>
Vec2i convert<Vec2i>(const YAML::Node& n, const ParamReader& r, const std::string& key) {
  if (!n.IsSequence() || n.size() != 2)
    r.fail(key, "expected a list of two whole numbers, found " + describe(n));
  return Vec2i(convert<int>(n[0], r, key), convert<int>(n[1], r, key));
}

template <>
Mat3 convert<Mat3>(const YAML::Node& n, const ParamReader& r, const std::string& key) {
  const auto bad = [&] {
    r.fail(key, "expected three rows of three numbers [[a, b, c], [d, e, f], [g, h, i]], found " +
                    describe(n));
  };
  if (!n.IsSequence() || n.size() != 3) bad();
  Mat3 m;
  for (int i = 0; i < 3; ++i) {
    if (!n[i].IsSequence() || n[i].size() != 3) bad();
    for (int j = 0; j < 3; ++j) m(i, j) = parse_double(n[i][j], r, key);
  }
  return m;
}

}  // namespace

template <class T>
std::optional<T> ParamReader::get(const std::string& key) {
  if (!has(key)) return std::nullopt;
  return convert<T>(value(key), *this, key);
}

template <class T>
T ParamReader::require(const std::string& key) {
  if (!has(key)) fail(key, "missing required key '" + key + "'");
  return convert<T>(value(key), *this, key);
}

template std::optional<double> ParamReader::get<double>(const std::string&);
template std::optional<int> ParamReader::get<int>(const std::string&);
template std::optional<std::uint64_t> ParamReader::get<std::uint64_t>(const std::string&);
template std::optional<bool> ParamReader::get<bool>(const std::string&);
template std::optional<std::string> ParamReader::get<std::string>(const std::string&);
template std::optional<Vec3> ParamReader::get<Vec3>(const std::string&);
template std::optional<Vec3i> ParamReader::get<Vec3i>(const std::string&);
template std::optional<Vec2i> ParamReader::get<Vec2i>(const std::string&);
template std::optional<Mat3> ParamReader::get<Mat3>(const std::string&);
template double ParamReader::require<double>(const std::string&);
template int ParamReader::require<int>(const std::string&);
template std::string ParamReader::require<std::string>(const std::string&);
template Vec3 ParamReader::require<Vec3>(const std::string&);
template Vec3i ParamReader::require<Vec3i>(const std::string&);

Vec3 ParamReader::get_vec3_or_scalar(const std::string& key, const Vec3& fallback) {
  if (!has(key)) return fallback;
  const YAML::Node n = value(key);
  if (n.IsScalar()) return Vec3::Constant(parse_double(n, *this, key));
  return convert<Vec3>(n, *this, key);
}

ParamReader ParamReader::child(const std::string& key) {
  if (!has(key)) fail(key, "missing required key '" + key + "'");
  return ParamReader(value(key), file_, key_path(key));
}

YAML::Node ParamReader::sequence(const std::string& key) {
  if (!has(key)) return YAML::Node(YAML::NodeType::Sequence);
  const YAML::Node n = value(key);
  if (!n.IsSequence()) fail(key, "expected a list, found " + describe(n));
  return n;
}

void ParamReader::finish() const {
  if (!node_.IsMap()) return;
  const std::vector<std::string> known(known_.begin(), known_.end());
  for (auto it = node_.begin(); it != node_.end(); ++it) {
    const std::string k = it->first.Scalar();
    if (known_.count(k)) continue;
    std::string msg = "unknown key '" + k + "'";
    const std::string guess = closest_match(k, known);
    if (!guess.empty()) msg += " (did you mean '" + guess + "'?)";
    std::string expected;
    for (const auto& c : known) expected += (expected.empty() ? "" : ", ") + c;
    msg += "; expected one of: " + expected;
    throw SceneError(node_loc(it->first, file_), key_path(k), msg);
  }
}

}  // namespace mpm
