#include "engine/scene/plugin_search.h"

#include <algorithm>
#include <cstdlib>

#include "materials/plugin.h"

namespace mpm {

namespace fs = std::filesystem;

namespace {

/// The folders of $MPM_PLUGIN_PATH, in order.
std::vector<fs::path> env_plugin_folders() {
  std::vector<fs::path> places;
  if (const char* env = std::getenv("MPM_PLUGIN_PATH")) {
    const std::string list = env;
    for (std::size_t start = 0; start <= list.size();) {
      const std::size_t end = std::min(list.find(':', start), list.size());
      if (end > start) places.emplace_back(list.substr(start, end - start));
      start = end + 1;
    }
  }
  return places;
}

/// The lib/ folder beside the running program's bin/, or an empty path.
fs::path engine_lib_folder() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path() : exe.parent_path().parent_path() / "lib";
}

}  // namespace

std::vector<fs::path> plugin_folders() {
  std::vector<fs::path> places = env_plugin_folders();
  if (const fs::path lib = engine_lib_folder(); !lib.empty()) places.push_back(lib);
  return places;
}

namespace {

/// `p` made canonical, or `p` made absolute if it does not exist.
fs::path canonical_or_absolute(const fs::path& p) {
  std::error_code ec;
  fs::path c = fs::canonical(p, ec);
  return ec ? fs::absolute(p, ec) : c;
}

/// True if `file` is a `--plugin` file or lies in one of `folders`.
bool user_chose(const fs::path& file, const std::vector<fs::path>& folders,
                const PluginPolicy& policy) {
  const fs::path c = canonical_or_absolute(file);
  for (const fs::path& f : policy.files)
    if (canonical_or_absolute(f) == c) return true;
  for (const fs::path& d : folders)
    if (canonical_or_absolute(d) == c.parent_path()) return true;
  return false;
}

/// How to load a plugin the scene brought along, for the refusal message.
std::string how_to_allow(const fs::path& file) {
  return "a scene's own plugins are not loaded, since they would run code that came with the "
         "scene; if you trust it, run with --allow-scene-plugins, or --plugin " +
         file.string() + ", or add its folder to $MPM_PLUGIN_PATH";
}

}  // namespace

fs::path find_scene_plugin(const std::string& written, const fs::path& scene_dir,
                           const PluginPolicy& policy) {
  const fs::path p = written;
  const std::vector<fs::path> folders = plugin_folders();
  std::error_code ec;
  if (p.has_parent_path()) {
    const fs::path file = p.is_absolute() ? p : scene_dir / p;
    if (!fs::exists(file, ec) || policy.allow_scene_plugins || user_chose(file, folders, policy))
      return file;  // a missing file is reported by the loader with this path
    throw PluginError("plugin '" + written + "' (" + file.string() +
                      ") is named by the scene and is not in a plugin folder (" +
                      "$MPM_PLUGIN_PATH or the engine's lib/) nor given with --plugin; " +
                      how_to_allow(file));
  }
  for (const fs::path& f : policy.files)
    if (f.filename() == p) return f;
  for (const fs::path& d : folders)
    if (fs::is_regular_file(d / p, ec)) return d / p;
  const fs::path beside = scene_dir / p;
  if (fs::is_regular_file(beside, ec)) {
    if (policy.allow_scene_plugins) return beside;
    throw PluginError("plugin '" + written + "' was found only beside the scene (" +
                      beside.string() + "); " + how_to_allow(beside));
  }
  std::string searched;
  for (const fs::path& f : policy.files) searched += "\n  --plugin " + f.string();
  const std::vector<fs::path> env = env_plugin_folders();
  for (const fs::path& d : env) searched += "\n  " + d.string() + " ($MPM_PLUGIN_PATH)";
  if (env.empty()) searched += "\n  ($MPM_PLUGIN_PATH is not set)";
  if (const fs::path lib = engine_lib_folder(); !lib.empty())
    searched += "\n  " + lib.string() + " (the lib/ beside the engine's bin/)";
  if (policy.allow_scene_plugins) searched += "\n  " + scene_dir.string() + " (the scene's folder)";
  throw PluginError("plugin '" + written + "' not found; searched:" + searched +
                    "\nbuild it first (see docs/materials.md), give it with --plugin PATH, or "
                    "add its folder to $MPM_PLUGIN_PATH");
}

}  // namespace mpm
