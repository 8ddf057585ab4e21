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

  YAML::Node node_;
  std::string file_;
  std::string path_;
  std::set<std::string> known_;
};

/// The position of a YAML node as a FileLoc (1-based).
FileLoc node_loc(const YAML::Node& node, const std::string& file);

/// The closest of `candidates` to `word` by edit distance, or "" if none is close.
std::string closest_match(const std::string& word, const std::vector<std::string>& candidates);

}  // namespace mpm
