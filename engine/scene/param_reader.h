#pragma once
/// \file Typed, position-aware reading of one YAML mapping. Only the scene loader includes this.

#include <optional>
#include <set>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "engine/core/error.h"
#include "engine/core/math.h"

namespace mpm {

/// Reads the keys of one YAML mapping with type and range checks.
///
/// Every lookup records the key, so finish() can reject any key that was never asked for,
/// with its file:line:col and the closest known key ("did you mean"). The node is held const:
/// yaml-cpp's non-const operator[] may insert keys while looking them up.
class ParamReader {
 public:
  /// Wraps `node`, found at key path `path` (e.g. "objects[1]") in `file`.
  ParamReader(const YAML::Node& node, std::string file, std::string path);

  /// True if `key` is present (and records it as known).
  bool has(const std::string& key);
  /// Reads `key` or throws SceneError if it is missing or of the wrong type.
  template <class T>
  T require(const std::string& key);
  /// Reads `key`, or returns std::nullopt if it is absent.
  template <class T>
  std::optional<T> get(const std::string& key);
  /// Reads `key`, or returns `fallback` if it is absent.
  template <class T>
  T get_or(const std::string& key, const T& fallback) {
    auto v = get<T>(key);
    return v ? *v : fallback;
  }
  /// Reads a 3-vector that may also be written as one number for all three components.
  Vec3 get_vec3_or_scalar(const std::string& key, const Vec3& fallback);
  /// A reader for the mapping under `key`; throws if `key` is absent or not a mapping.
  ParamReader child(const std::string& key);
  /// The raw sequence under `key` (empty if absent); throws if it is not a sequence.
  YAML::Node sequence(const std::string& key);

  /// Throws SceneError unless `value` lies in [lo, hi] (or the open ends, as asked).
  void check_range(const std::string& key, double value, double lo, double hi,
                   bool lo_open = false, bool hi_open = false) const;
  /// Throws a SceneError about `key` (at its position, or the mapping's if absent).
  [[noreturn]] void fail(const std::string& key, const std::string& what) const;

  /// Throws a SceneError about the required `key`, which is absent. Call it once every other
  /// key of the mapping has been looked up: a key left over is then most likely `key` written
  /// another way, so the error names that key at its own position and suggests its closest
  /// known key, or `key` ("unknown key 'youngs_modulus' (did you mean 'E'?)"); `what` follows.
  [[noreturn]] void fail_missing(const std::string& key, const std::string& what) const;

  /// Throws SceneError naming the first key that was never looked up.
  void finish() const;

  /// Position of `key` in the file, or of this mapping if the key is absent.
  FileLoc loc(const std::string& key = "") const;
  /// "path.key" for messages.
  std::string key_path(const std::string& key) const;
  /// The file this reader reads from.
  const std::string& file() const { return file_; }

 private:
  YAML::Node value(const std::string& key) const;
  /// The keys of the mapping not looked up so far, in file order.
  std::vector<YAML::Node> unread_keys() const;
  /// Throws "unknown key" at `key`'s position, with `guess` as the suggestion (if not empty)
  /// and `also` appended (if empty: the list of known keys).
  [[noreturn]] void fail_unknown(const YAML::Node& key, const std::string& guess,
                                 const std::string& also) const;
  /// A required key is absent: blames an unread key one edit from it, else the mapping.
  [[noreturn]] void fail_absent(const std::string& key, const std::string& what) const;

  YAML::Node node_;
  std::string file_;
  std::string path_;
  std::set<std::string> known_;
};

/// The position of a YAML node as a FileLoc (1-based).
FileLoc node_loc(const YAML::Node& node, const std::string& file);

/// Throws a SceneError if a plain value in `root` runs on into a later line that reads like a key
/// written without its colon: YAML joins "  cfl 0.5" below "  dt: 1.0e-3" into the value of dt,
/// "1.0e-3 cfl 0.5". `text` is the source `root` was parsed from (nodes without a position, such
/// as --set values, are skipped).
void check_missing_colons(const YAML::Node& root, const std::string& text, const std::string& file);

/// For a YAML syntax error at 1-based `line` of `text`: "; line N ('cfl 0.5') seems to be
/// missing a colon: write 'cfl: 0.5'" if one of the few lines before it reads like a key and a
/// value without the colon (yaml-cpp reports such a line at the next key), else "".
std::string missing_colon_hint(const std::string& text, int line);

/// The closest of `candidates` to `word`, or "" if none is close: a candidate that `word` begins
/// (the shortest), else the smallest Damerau-Levenshtein distance, ties to the nearest length.
std::string closest_match(const std::string& word, const std::vector<std::string>& candidates);

}  // namespace mpm
