#include "engine/scene/param_reader.h"

#include "materials/material.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <sstream>
#include <tuple>

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

namespace {

/// Optimal-string-alignment distance (Damerau-Levenshtein without repeated edits of a
/// substring): insertions, deletions, substitutions and swaps of two neighbours cost 1.
/// Letters compare case-insensitively.
std::size_t edit_distance(const std::string& a, const std::string& b) {
  const auto same = [](char x, char y) {
    return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
  };
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1,
                          d[i - 1][j - 1] + (same(a[i - 1], b[j - 1]) ? 0 : 1)});
      if (i > 1 && j > 1 && same(a[i - 1], b[j - 2]) && same(a[i - 2], b[j - 1]))
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

bool starts_with_nocase(const std::string& text, const std::string& prefix) {
  return prefix.size() <= text.size() && edit_distance(text.substr(0, prefix.size()), prefix) ==
                                             0;  // same letters, any case
}

}  // namespace

std::string closest_match(const std::string& word, const std::vector<std::string>& candidates) {
  if (word.empty()) return "";
  // Rank: a candidate the word begins (a truncated key: "frame" -> "frames"), the shortest
  // first; then the smallest edit distance, a word containing the candidate or contained in
  // it counting as one edit ("output_dir" -> "output"); ties go to the candidate closest in
  // length, then to the first in the list.
  std::string best;
  std::size_t best_class = 2, best_d = std::numeric_limits<std::size_t>::max(), best_len = best_d;
  for (const auto& c : candidates) {
    const std::size_t len = c.size() > word.size() ? c.size() - word.size()
                                                    : word.size() - c.size();
    std::size_t cls = 1, d = 0;
    if (!starts_with_nocase(c, word)) {
      cls = 2;
      d = edit_distance(word, c);
      const bool contains = c.size() >= 2 && word.size() >= 2 &&
                            (word.find(c) != std::string::npos || c.find(word) != std::string::npos);
      if (contains) d = std::min(d, std::size_t(1));
      const std::size_t limit = std::max<std::size_t>(1, std::max(word.size(), c.size()) / 3);
      if (d > limit) continue;
    }
    if (std::tie(cls, d, len) < std::tie(best_class, best_d, best_len))
      best_class = cls, best_d = d, best_len = len, best = c;
  }
  return best;
}

namespace {

std::string trim(const std::string& s) {
  const std::size_t a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t\r") - a + 1);
}

bool is_identifier(const std::string& w) {
  if (w.empty() || !(std::isalpha(static_cast<unsigned char>(w[0])) || w[0] == '_')) return false;
  return std::all_of(w.begin(), w.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
  });
}

/// Checks the plain scalars under `n`. Aliases can make a document cyclic (`&a [*a]`) or
/// exponentially large, so the walk stops at 64 levels or after `budget` nodes: a scene is
/// far smaller, and the loader's own checks see the rest.
void check_scalars(const YAML::Node& n, const std::vector<std::string>& lines,
                   const std::string& file, const std::string& path, int& budget, int depth = 0) {
  if (--budget < 0 || depth > 64) return;
  if (n.IsMap()) {
    for (auto it = n.begin(); it != n.end(); ++it)
      check_scalars(it->second, lines, file,
                    (path.empty() ? "" : path + ".") + it->first.Scalar(), budget, depth + 1);
    return;
  }
  if (n.IsSequence()) {
    for (std::size_t i = 0; i < n.size(); ++i)
      check_scalars(n[i], lines, file, path + "[" + std::to_string(i) + "]", budget, depth + 1);
    return;
  }
  // Only plain (unquoted) scalars with a position are joined from several lines.
  if (!n.IsScalar() || n.Tag() != "?") return;
  const YAML::Mark m = n.Mark();
  if (m.line < 0 || static_cast<std::size_t>(m.line) >= lines.size()) return;
  const std::string& line = lines[m.line];
  if (static_cast<std::size_t>(m.column) > line.size()) return;
  std::string first = line.substr(m.column);
  for (std::size_t c = first.find('#'); c != std::string::npos; c = first.find('#', c + 1))
    if (c > 0 && (first[c - 1] == ' ' || first[c - 1] == '\t')) {
      first.resize(c);
      break;
    }
  first = trim(first);
  const std::string& value = n.Scalar();
  if (first.empty() || first.size() >= value.size() || value.compare(0, first.size(), first) != 0)
    return;
  // The value goes on past its first line: "word value" there is a key that lost its colon.
  const std::string rest = trim(value.substr(first.size()));
  std::istringstream words(rest);
  std::string word, next;
  if (!(words >> word >> next) || !is_identifier(word)) return;
  FileLoc where = node_loc(n, file);
  for (std::size_t l = m.line + 1; l < lines.size(); ++l) {
    const std::string t = trim(lines[l]);
    if (t.rfind(word, 0) == 0) {
      where.line = static_cast<int>(l) + 1;
      where.col = static_cast<int>(lines[l].find(word)) + 1;
      break;
    }
  }
  throw SceneError(where, path,
                   "a colon seems to be missing after '" + word + "': YAML read '" + rest +
                       "' on a later line as part of this value, which became '" + value +
                       "'; write '" + word + ": " + trim(rest.substr(word.size())) +
                       "' on a line of its own");
}

/// "cfl: 0.5" if `line` reads like a key and a value without the colon between them ("cfl
/// 0.5", "- cfl 0.5"), else "".
std::string colon_fix(std::string line) {
  line = trim(line);
  if (line.rfind("- ", 0) == 0) line = trim(line.substr(2));
  if (line.empty() || line[0] == '#' || line.find(':') != std::string::npos) return "";
  std::istringstream words(line);
  std::string word, next;
  if (!(words >> word >> next) || !is_identifier(word)) return "";
  return word + ": " + trim(line.substr(word.size()));
}

}  // namespace

std::string missing_colon_hint(const std::string& text, int line) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  // yaml-cpp reports the error at the next key after the line that lost its colon.
  for (int l = std::min<int>(line, static_cast<int>(lines.size())) - 1; l >= 0 && l >= line - 4;
       --l) {
    const std::string fix = colon_fix(lines[l]);
    if (!fix.empty())
      return "; line " + std::to_string(l + 1) + " ('" + trim(lines[l]) +
             "') seems to be missing a colon: write '" + fix + "'";
  }
  return "";
}

void check_missing_colons(const YAML::Node& root, const std::string& text,
                          const std::string& file) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  int budget = 100000;
  check_scalars(root, lines, file, "", budget);
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
  if (!has(key)) fail_absent(key, "missing required key '" + key + "'");
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
  if (!has(key)) fail_absent(key, "missing required key '" + key + "'");
  return ParamReader(value(key), file_, key_path(key));
}

YAML::Node ParamReader::sequence(const std::string& key) {
  if (!has(key)) return YAML::Node(YAML::NodeType::Sequence);
  const YAML::Node n = value(key);
  if (!n.IsSequence()) fail(key, "expected a list, found " + describe(n));
  return n;
}

std::vector<YAML::Node> ParamReader::unread_keys() const {
  std::vector<YAML::Node> out;
  if (!node_.IsMap()) return out;
  for (auto it = node_.begin(); it != node_.end(); ++it)
    if (!known_.count(it->first.Scalar())) out.push_back(it->first);
  return out;
}

void ParamReader::fail_unknown(const YAML::Node& key, const std::string& guess,
                               const std::string& also) const {
  const std::string k = key.Scalar();
  std::string msg = "unknown key '" + k + "'";
  // "dt 0.5" as a key: a key and its value without the colon between them.
  if (const std::string fix = colon_fix(k); !fix.empty()) {
    msg += ": a colon seems to be missing; write '" + fix + "'";
    const std::string word = fix.substr(0, fix.find(':'));
    if (!known_.count(word)) {
      const std::vector<std::string> known(known_.begin(), known_.end());
      const std::string g = closest_match(word, known);
      if (!g.empty()) msg += " (did you mean '" + g + "'?)";
    }
    throw SceneError(node_loc(key, file_), key_path(k), msg);
  }
  if (!guess.empty()) msg += " (did you mean '" + guess + "'?)";
  if (also.empty()) {
    std::string expected;
    for (const auto& c : known_) expected += (expected.empty() ? "" : ", ") + c;
    msg += "; expected one of: " + expected;
  } else {
    msg += "; " + also;
  }
  throw SceneError(node_loc(key, file_), key_path(k), msg);
}

void ParamReader::fail_absent(const std::string& key, const std::string& what) const {
  // Keys after this one are not looked up yet, so only a key one edit away (or a prefix
  // either way: "dim" for "dims") is taken for this one misspelt.
  for (const YAML::Node& k : unread_keys()) {
    const std::string& w = k.Scalar();
    if (w.empty()) continue;
    const bool prefix = starts_with_nocase(key, w) || starts_with_nocase(w, key);
    if (prefix || edit_distance(w, key) <= 1) fail_unknown(k, key, what);
  }
  fail(key, what);
}

void ParamReader::fail_missing(const std::string& key, const std::string& what) const {
  const std::vector<YAML::Node> unread = unread_keys();
  if (unread.empty()) fail(key, what);
  // Every other key was looked up: a key left over is most likely the missing one, written
  // another way ("youngs_modulus" for "E"). Take the one closest to `key`, else the first.
  const YAML::Node* pick = &unread.front();
  for (const YAML::Node& k : unread)
    if (!closest_match(k.Scalar(), {key}).empty()) {
      pick = &k;
      break;
    }
  std::vector<std::string> known(known_.begin(), known_.end());
  std::string guess = closest_match(pick->Scalar(), known);
  if (guess.empty()) guess = key;
  fail_unknown(*pick, guess, what);
}

void ParamReader::finish() const {
  const std::vector<YAML::Node> unread = unread_keys();
  if (unread.empty()) return;
  const std::vector<std::string> known(known_.begin(), known_.end());
  fail_unknown(unread.front(), closest_match(unread.front().Scalar(), known), "");
}

}  // namespace mpm
