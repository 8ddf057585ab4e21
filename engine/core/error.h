#pragma once
/// \file Errors the engine reports to users, with the place in the scene file they come from.

#include <stdexcept>
#include <string>

namespace mpm {

/// A position in a scene file (1-based line and column; 0 if unknown).
struct FileLoc {
  std::string file;  ///< Path as the user gave it.
  int line = 0;      ///< 1-based line, 0 if unknown.
  int col = 0;       ///< 1-based column, 0 if unknown.

  /// "file:line:col", or as much of it as is known.
  std::string str() const {
    if (line <= 0) return file;
    return file + ':' + std::to_string(line) + ':' + std::to_string(col);
  }
};

/// A scene that cannot be read, validated or built. The message names file, line and key.
class SceneError : public std::runtime_error {
 public:
  /// An error at `loc` about `key_path` (e.g. "objects[1].nu").
  SceneError(const FileLoc& loc, const std::string& key_path, const std::string& what)
      : std::runtime_error(loc.str() + ": " + (key_path.empty() ? "" : key_path + ": ") + what) {}
};

/// Process exit codes, documented in README.md.
enum ExitCode : int {
  kExitOk = 0,        ///< The run finished, or the command succeeded.
  kExitRunFailed = 1, ///< The run started but failed (unstable, I/O error).
  kExitBadInput = 2,  ///< Bad scene file or command line; nothing was simulated.
};

}  // namespace mpm
