#include "engine/scene/load_scene.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <initializer_list>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "engine/scene/param_reader.h"
#include "materials/plugin.h"

namespace mpm {

namespace {

/// Reads `key` as one of the named `choices`, or fails with the list; without the key,
/// `fallback` (the described struct's default, so that the struct is the one place defaults live).
template <class E>
E read_choice(ParamReader& r, const std::string& key, E fallback,
              std::initializer_list<std::pair<const char*, E>> choices) {
  if (!r.has(key)) return fallback;
  const std::string value = r.require<std::string>(key);
  std::string names;
  std::size_t i = 0;
  for (const auto& [name, e] : choices) {
    if (value == name) return e;
    if (i > 0) names += i + 1 == choices.size() ? " or " : ", ";
    names += name;
    ++i;
  }
  r.fail(key, "unknown " + key + " '" + value + "'; expected " + names);
}

SimulationDesc read_simulation(ParamReader r) {
  SimulationDesc s;
  s.frames = r.get_or("frames", s.frames);
  r.check_range("frames", s.frames, 0, 1e9);
  s.frame_dt = r.get_or("frame_dt", s.frame_dt);
  r.check_range("frame_dt", s.frame_dt, 0, 1e300, true);
  s.dt = r.get<double>("dt");
  if (s.dt) r.check_range("dt", *s.dt, 0, 1e300, true);
  s.cfl = r.get<double>("cfl");
  if (s.cfl) r.check_range("cfl", *s.cfl, 0, 1, true);
  if (!s.dt && !s.cfl) r.fail("", "give 'dt' (fixed substep), 'cfl' (adaptive substep), or both");
  s.gravity = r.get_or("gravity", s.gravity);
  s.transfer = read_choice<Transfer>(r, "transfer", s.transfer,
                                     {{"apic", Transfer::apic},
                                      {"pic", Transfer::pic},
                                      {"flip", Transfer::flip},
                                      {"mls", Transfer::mls}});
  s.flip_blend = r.get_or("flip_blend", s.flip_blend);
  r.check_range("flip_blend", s.flip_blend, 0, 1);
  s.kernel = read_choice<Kernel>(
      r, "kernel", s.kernel,
      {{"quadratic", Kernel::quadratic}, {"linear", Kernel::linear}, {"cubic", Kernel::cubic}});
  s.damping = r.get_or("damping", s.damping);
  r.check_range("damping", s.damping, 0, 1e300);
  s.seed = r.get_or<std::uint64_t>("seed", s.seed);
  s.reorder_every = r.get_or("reorder_every", s.reorder_every);
  r.check_range("reorder_every", s.reorder_every, 0, 1 << 30);
  s.simd = r.get_or("simd", s.simd);
  s.contact = read_choice<Contact>(r, "contact", s.contact,
                                   {{"nodes", Contact::nodes}, {"particles", Contact::particles}});
  s.contact_iterations = r.get_or("contact_iterations", s.contact_iterations);
  r.check_range("contact_iterations", s.contact_iterations, 1, 1e6);
  s.contact_spectral_radius = r.get_or("contact_spectral_radius", s.contact_spectral_radius);
  r.check_range("contact_spectral_radius", s.contact_spectral_radius, 0, 0.999);
  s.quadrature =
      read_choice<Quadrature>(r, "quadrature", s.quadrature,
                              {{"point", Quadrature::point}, {"domain", Quadrature::domain}});
  s.quadrature_loc = r.loc("quadrature");
  if (s.quadrature == Quadrature::domain && s.kernel != Kernel::quadratic)
    r.fail("quadrature",
           "quadrature 'domain' integrates the quadratic B-spline: it needs "
           "kernel quadratic");
  if (s.transfer == Transfer::mls && s.kernel == Kernel::linear)
    r.fail("transfer", "transfer 'mls' needs kernel quadratic or cubic (its D is not constant "
                       "for the linear kernel)");
  r.finish();
  return s;
}

GridDesc read_grid(ParamReader r) {
  GridDesc g;
  g.origin = r.get_or("origin", g.origin);
  g.max = r.require<Vec3>("max");
  for (int a = 0; a < 3; ++a)
    if (g.max[a] <= g.origin[a]) r.fail("max", "each component must exceed origin's");
  g.dims = r.require<Vec3i>("dims");
  g.loc = r.loc("dims");
  for (int a = 0; a < 3; ++a) r.check_range("dims", g.dims[a], 1, 1e5);
  for (int a = 0; a < 3; ++a)
    if (!std::isnormal(g.spacing()[a]))
      r.fail("max", "the cell size (max - origin) / dims overflows or underflows");
  if (r.has("sampling_origin")) g.sampling_origin = r.require<Vec3>("sampling_origin");
  g.float_nodes =
      read_choice<bool>(r, "precision", g.float_nodes, {{"double", false}, {"float", true}});
  g.buffer = r.get_or("buffer", g.buffer);
  r.check_range("buffer", g.buffer, 2, 1e5);
  if (2 * g.buffer + 1 > g.dims.minCoeff())
    r.fail("buffer", "a buffer of " + std::to_string(g.buffer) + " cells leaves no interior in a " +
                         std::to_string(g.dims.minCoeff()) + "-cell axis");
  r.finish();
  return g;
}

Boundary read_boundary(ParamReader& r) {
  return read_choice<Boundary>(
      r, "boundary", WallDesc{}.boundary,
      {{"sticky", Boundary::sticky}, {"slip", Boundary::slip}, {"separate", Boundary::separate}});
}

/// Reads a collider's file path, relative to the scene's folder unless absolute.
std::filesystem::path read_collider_file(ParamReader& r, const std::filesystem::path& scene_dir) {
  std::filesystem::path file = r.require<std::string>("file");
  if (file.empty()) r.fail("file", "the file name must not be empty");
  return file.is_relative() ? scene_dir / file : file;
}

WallDesc read_wall(ParamReader r, const std::filesystem::path& scene_dir) {
  WallDesc w;
  w.loc = r.loc();
  const std::pair<const char*, WallDesc::Shape> shapes[] = {{"plane", WallDesc::Shape::plane},
                                                            {"box", WallDesc::Shape::box},
                                                            {"mesh", WallDesc::Shape::mesh},
                                                            {"sphere", WallDesc::Shape::sphere},
                                                            {"vdb", WallDesc::Shape::vdb}};
  int given = 0;
  for (const auto& [name, shape] : shapes)
    if (r.has(name)) w.shape = shape, ++given;
  if (given != 1)
    r.fail("", "a wall needs exactly one of 'plane', 'box', 'mesh', 'sphere' or 'vdb'");
  if (w.shape == WallDesc::Shape::plane) {
    ParamReader p = r.child("plane");
    w.point = p.require<Vec3>("point");
    w.normal = p.require<Vec3>("normal");
    if (w.normal.stableNorm() < 1e-12) p.fail("normal", "the normal must not be zero");
    w.normal.stableNormalize();  // stable: norm() of [1e300, 0, 0] overflows to inf
    p.finish();
  } else if (w.shape == WallDesc::Shape::box) {
    ParamReader b = r.child("box");
    w.min = b.require<Vec3>("min");
    w.max = b.require<Vec3>("max");
    for (int a = 0; a < 3; ++a)
      if (w.max[a] <= w.min[a]) b.fail("max", "each component must exceed min's");
    b.finish();
  } else if (w.shape == WallDesc::Shape::mesh) {
    ParamReader m = r.child("mesh");
    w.file = read_collider_file(m, scene_dir);
    w.file_loc = m.loc("file");
    w.scale = m.get_vec3_or_scalar("scale", w.scale);
    for (int a = 0; a < 3; ++a)
      if (w.scale[a] == 0) m.fail("scale", "scale must not be zero");
    w.rotation_deg = m.get_or("rotation", w.rotation_deg);
    w.offset = m.get_or("offset", w.offset);
    m.finish();
  } else if (w.shape == WallDesc::Shape::sphere) {
    ParamReader s = r.child("sphere");
    w.center = s.require<Vec3>("center");
    w.radius = s.require<double>("radius");
    s.check_range("radius", w.radius, 0, 1e300, true);
    s.finish();
  } else {
    ParamReader v = r.child("vdb");
    w.file = read_collider_file(v, scene_dir);
    w.file_loc = v.loc("file");
    w.grid_name = v.require<std::string>("grid");
    w.grid_loc = v.loc("grid");
    v.finish();
  }
  const bool collider = w.shape != WallDesc::Shape::plane && w.shape != WallDesc::Shape::box;
  if (r.has("angular_velocity") && !collider)
    r.fail("angular_velocity",
           "only colliders (mesh, sphere, vdb) spin; a plane or box moves "
           "with 'velocity' or 'path'");
  w.angular_velocity = r.get_or("angular_velocity", w.angular_velocity);
  w.boundary = read_boundary(r);
  w.friction = r.get_or("friction", 0.0);
  w.velocity = r.get_or("velocity", w.velocity);
  const YAML::Node path = r.sequence("path");
  if (path.size() > 0 && w.velocity.norm() > 0)
    r.fail("path", "give a wall 'velocity' or a 'path', not both");
  for (std::size_t k = 0; k < path.size(); ++k) {
    const YAML::Node row = path[k];
    auto bad = [&] {
      throw SceneError(node_loc(row, r.file()), r.key_path("path") + "[" + std::to_string(k) + "]",
                       "expected [t, dx, dy, dz]: a time (s) and an offset (m), times increasing");
    };
    if (!row.IsSequence() || row.size() != 4) bad();
    double v[4];
    for (int i = 0; i < 4; ++i) {
      if (!row[i].IsScalar()) bad();
      try {
        std::size_t used = 0;
        v[i] = std::stod(row[i].Scalar(), &used);
        if (used != row[i].Scalar().size() || !std::isfinite(v[i])) bad();
      } catch (const std::invalid_argument&) {
        bad();
      } catch (const std::out_of_range&) {
        bad();
      }
    }
    if (!w.path.empty() && v[0] <= w.path.back().t) bad();
    w.path.push_back({v[0], Vec3(v[1], v[2], v[3])});
  }
  r.check_range("friction", w.friction, 0, 1e300);
  r.finish();
  return w;
}

ObjectDesc read_object(ParamReader r, const std::filesystem::path& scene_dir,
                       const MaterialRegistry& registry) {
  ObjectDesc o;
  o.loc = r.loc();
  o.name = r.require<std::string>("name");
  o.mesh = r.require<std::string>("mesh");
  o.mesh_loc = r.loc("mesh");
  if (o.mesh.is_relative()) o.mesh = scene_dir / o.mesh;
  o.scale = r.get_vec3_or_scalar("scale", o.scale);
  for (int a = 0; a < 3; ++a)
    if (o.scale[a] == 0) r.fail("scale", "scale must not be zero");
  o.rotation_deg = r.get_or("rotation", o.rotation_deg);
  o.offset = r.get_or("offset", o.offset);
  // Errors about where the object lies blame a --set that moved it, else the object.
  o.placement_loc = o.loc;
  for (const char* k : {"offset", "scale", "rotation"})
    if (r.has(k) && r.loc(k).line == 0) o.placement_loc = r.loc(k);
  o.velocity = r.get_or("velocity", o.velocity);
  o.angular_velocity = r.get_or("angular_velocity", o.angular_velocity);
  o.velocity_gradient = r.get_or("velocity_gradient", o.velocity_gradient);
  o.mass = r.get<double>("mass");
  o.density = r.get<double>("density");
  if (o.mass && o.density) r.fail("density", "give 'mass' or 'density', not both");
  if (!o.mass && !o.density) r.fail("", "give the object's 'mass' (kg) or 'density' (kg/m^3)");
  if (o.mass) r.check_range("mass", *o.mass, 0, 1e300, true);
  if (o.density) r.check_range("density", *o.density, 0, 1e300, true);
  o.particles_per_cell = r.get_or("particles_per_cell", o.particles_per_cell);
  r.check_range("particles_per_cell", o.particles_per_cell, 1, 1000);
  o.sampling =
      read_choice<Sampling>(r, "sampling", o.sampling,
                            {{"jittered", Sampling::jittered}, {"regular", Sampling::regular}});
  const int strata = static_cast<int>(std::lround(std::cbrt(o.particles_per_cell)));
  if (o.sampling == Sampling::regular && strata * strata * strata != o.particles_per_cell)
    r.fail("sampling", "regular sampling needs particles_per_cell to be a cube (1, 8, 27, ...), not " +
                           std::to_string(o.particles_per_cell));
  o.initial_stress = read_choice<InitialStress>(
      r, "initial_stress", o.initial_stress,
      {{"none", InitialStress::none}, {"gravity", InitialStress::gravity}});
  o.material = r.require<std::string>("material");
  const MaterialInfo* info = registry.find(o.material);
  if (!info)
    r.fail("material", "unknown material '" + o.material + "'; registered materials: " +
                           registry.names() + " (a plugin's materials need the plugin loaded: " +
                           "list it under 'plugins:' or give --plugin PATH; docs/materials.md)");
  for (const ParamSpec& spec : info->params) r.has(spec.name);  // every key known first
  for (const ParamSpec& spec : info->params) {
    std::optional<double> v = r.get<double>(spec.name);
    if (!v && spec.required)
      r.fail_missing(spec.name, "missing required key '" + spec.name + "' (" + spec.description +
                                    ") for material '" + o.material + "'");
    const double value = v ? *v : spec.default_value;
    if (v) r.check_range(spec.name, value, spec.min, spec.max, spec.min_exclusive,
                         spec.max_exclusive);
    o.params[spec.name] = value;
  }
  r.finish();
  return o;
}

/// output.surface: how the mesh and vdb formats build surfaces (lengths in particle spacings).
SurfaceDesc read_surface(ParamReader r) {
  SurfaceDesc s;
  s.radius = r.get_or("radius", s.radius);
  r.check_range("radius", s.radius, 0.5, 4);
  s.voxel = r.get_or("voxel", s.voxel);
  r.check_range("voxel", s.voxel, 0.1, 1);
  // ParticlesToLevelSet skips spheres narrower than 1.5 voxels: refuse rather than lose them.
  if (s.radius < 1.5 * s.voxel)
    r.fail("voxel", "voxel (" + std::to_string(s.voxel) + " particle spacings) must be at most "
                    "radius / 1.5 (" + std::to_string(s.radius / 1.5) +
                    "): a sphere narrower than 1.5 voxels would be dropped");
  s.smoothing = r.get_or("smoothing", s.smoothing);
  r.check_range("smoothing", s.smoothing, 0, 100);
  s.normals = r.get_or("normals", s.normals);
  s.density = r.get_or("density", s.density);
  s.velocity = r.get_or("velocity", s.velocity);
  r.finish();
  return s;
}

OutputDesc read_output(ParamReader r) {
  OutputDesc o;
  o.directory = r.get_or<std::string>("directory", "output");
  o.loc = r.loc("directory");
  if (r.has("formats")) {
    o.formats.clear();
    const YAML::Node list = r.sequence("formats");
    if (list.size() == 0)
      r.fail("formats", std::string("give at least one format: ") + format_names());
    for (const auto& item : list) {
      const auto f = item.IsScalar() ? format_from_name(item.Scalar()) : std::nullopt;
      if (!f)
        throw SceneError(node_loc(item, r.file()), r.key_path("formats"),
                         "unknown format " + (item.IsScalar() ? "'" + item.Scalar() + "'" : "") +
                             "; expected " + format_names());
      if (std::find(o.formats.begin(), o.formats.end(), *f) == o.formats.end())
        o.formats.push_back(*f);
    }
  }
  if (r.has("camera")) {
    ParamReader c = r.child("camera");
    CameraDesc cam;
    cam.position = c.require<Vec3>("position");
    cam.look_at = c.require<Vec3>("look_at");
    cam.fov_deg = c.get_or("fov", cam.fov_deg);
    c.check_range("fov", cam.fov_deg, 1, 170);
    if (!((cam.position - cam.look_at).stableNorm() >= 1e-9))
      c.fail("look_at", "the camera must not look at its own position");
    c.finish();
    o.camera = cam;
  }
  o.preview_size = r.get_or("preview_size", o.preview_size);
  for (int i = 0; i < 2; ++i) r.check_range("preview_size", o.preview_size[i], 16, 8192);
  o.checkpoint = r.get_or("checkpoint", o.checkpoint);
  o.checkpoint_interval = r.get_or("checkpoint_interval", o.checkpoint_interval);
  r.check_range("checkpoint_interval", o.checkpoint_interval, 0, 1e9);
  if (r.has("surface")) o.surface = read_surface(r.child("surface"));
  r.finish();
  return o;
}

SceneDesc read_scene(const YAML::Node& root, const std::filesystem::path& file,
                     MaterialRegistry& registry, const LoadOptions& options) {
  const std::string fname = file.string();
  if (!root.IsMap())
    throw SceneError(node_loc(root, fname), "", "a scene file must be a mapping of sections");
  ParamReader r(root, fname, "");
  SceneDesc scene;
  scene.file = file;
  const std::filesystem::path dir = file.parent_path();
  // Plugins first: objects may name the materials they add. The command line's come first.
  for (const std::filesystem::path& f : options.plugins.files) {
    try {
      load_plugin(f, registry);
    } catch (const PluginError& e) {
      throw SceneError({"--plugin " + f.string()}, "", e.what());
    }
  }
  const YAML::Node plugins = r.sequence("plugins");
  for (std::size_t i = 0; i < plugins.size(); ++i) {
    const std::string key = "plugins[" + std::to_string(i) + "]";
    if (!plugins[i].IsScalar())
      throw SceneError(node_loc(plugins[i], fname), key, "expected a path to a shared library");
    if (!options.load_plugins)
      throw SceneError(node_loc(plugins[i], fname), key, "plugins are disabled here");
    std::filesystem::path lib;
    try {
      lib = find_scene_plugin(plugins[i].Scalar(), dir, options.plugins);
      load_plugin(lib, registry);
    } catch (const PluginError& e) {
      throw SceneError(node_loc(plugins[i], fname), key, e.what());
    }
    scene.plugins.push_back(lib);
  }
  scene.simulation = read_simulation(r.child("simulation"));
  scene.grid = read_grid(r.child("grid"));
  if (scene.simulation.quadrature == Quadrature::domain && scene.grid.float_nodes)
    throw SceneError(scene.simulation.quadrature_loc, "simulation.quadrature",
                     "quadrature 'domain' keeps its node sums in double: it needs grid.precision "
                     "double");

  const YAML::Node objects = r.sequence("objects");
  if (objects.size() == 0) r.fail("objects", "a scene needs at least one object");
  std::set<std::string> names;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    ParamReader o(objects[i], fname, "objects[" + std::to_string(i) + "]");
    scene.objects.push_back(read_object(o, dir, registry));
    if (!names.insert(scene.objects.back().name).second)
      o.fail("name", "object name '" + scene.objects.back().name + "' is used twice");
  }
  const YAML::Node walls = r.sequence("walls");
  for (std::size_t i = 0; i < walls.size(); ++i)
    scene.walls.push_back(
        read_wall(ParamReader(walls[i], fname, "walls[" + std::to_string(i) + "]"), dir));

  if (r.has("output")) scene.output = read_output(r.child("output"));
  r.finish();
  return scene;
}

/// A copy of `n` whose nodes carry no file position, so errors about them say "--set".
/// Throws std::length_error past 64 levels or `budget` nodes: aliases can make a value endless
/// (`&a [*a]`) or huge (a list of lists of one list ...).
YAML::Node unplaced_copy(const YAML::Node& n, int& budget, int depth = 0) {
  if (--budget < 0 || depth > 64) throw std::length_error("value too large");
  if (n.IsScalar()) return YAML::Node(n.Scalar());
  if (n.IsSequence()) {
    YAML::Node out(YAML::NodeType::Sequence);
    for (const auto& e : n) out.push_back(unplaced_copy(e, budget, depth + 1));
    return out;
  }
  if (n.IsMap()) {
    YAML::Node out(YAML::NodeType::Map);
    for (const auto& kv : n) out[kv.first.Scalar()] = unplaced_copy(kv.second, budget, depth + 1);
    return out;
  }
  return YAML::Node(YAML::NodeType::Null);
}

/// Sets root[key path] = value, creating missing mapping keys but not list entries.
void apply_override(YAML::Node root, const SceneOverride& o, const std::string& fname) {
  const FileLoc where{fname + " (--set " + o.key + "=" + o.value + ")"};
  YAML::Node value;
  int budget = 10000;
  try {
    value = unplaced_copy(YAML::Load(o.value), budget);
  } catch (const YAML::Exception& e) {
    throw SceneError(where, o.key, "the value is not valid YAML: " + e.msg);
  } catch (const std::length_error&) {
    throw SceneError(where, o.key, "the value is too deep or too large (an alias inside itself?)");
  }
  // Split "objects[1].E" into steps: "objects", 1, "E".
  YAML::Node node = root;
  std::string done;
  std::size_t i = 0;
  const std::string& k = o.key;
  while (i < k.size()) {
    if (k[i] == '.') {
      ++i;
      continue;
    }
    if (k[i] == '[') {
      const std::size_t close = k.find(']', i);
      if (close == std::string::npos) throw SceneError(where, o.key, "unclosed '['");
      std::size_t index = 0;
      try {
        index = std::stoul(k.substr(i + 1, close - i - 1));
      } catch (const std::exception&) {
        throw SceneError(where, o.key, "bad list index");
      }
      if (!node.IsSequence() || index >= node.size())
        throw SceneError(where, o.key, "'" + done + "' has no entry [" + std::to_string(index) + "]");
      done += k.substr(i, close - i + 1);
      i = close + 1;
      if (i >= k.size()) {
        node[index] = value;
        return;
      }
      node.reset(node[index]);
      continue;
    }
    std::size_t end = k.find_first_of(".[", i);
    if (end == std::string::npos) end = k.size();
    const std::string name = k.substr(i, end - i);
    done += (done.empty() ? "" : ".") + name;
    if (!node.IsMap() && !node.IsNull())
      throw SceneError(where, o.key, "'" + done + "' is inside a value that is not a mapping");
    if (end >= k.size()) {
      node[name] = value;
      return;
    }
    YAML::Node next = node[name];
    if (!next.IsDefined() || next.IsNull()) {
      if (k[end] == '[') {
        std::vector<std::string> lists;
        if (node.IsMap())
          for (const auto& kv : node)
            if (kv.second.IsSequence()) lists.push_back(kv.first.Scalar());
        const std::string guess = closest_match(name, lists);
        throw SceneError(where, o.key, "there is no list '" + done + "'" +
                                           (guess.empty() ? "" : " (did you mean '" + guess + "'?)"));
      }
      node[name] = YAML::Node(YAML::NodeType::Map);
    }
    node.reset(node[name]);
    i = end;
  }
  throw SceneError(where, o.key, "empty key");
}

YAML::Node parse_yaml(const std::string& text, const std::string& fname) {
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    FileLoc loc{fname, e.mark.line + 1, e.mark.column + 1};
    if (e.mark.line < 0) loc = {fname, 0, 0};
    throw SceneError(loc, "", "YAML syntax error: " + e.msg +
                                  (e.mark.line < 0 ? "" : missing_colon_hint(text, loc.line)));
  }
}

}  // namespace

namespace {

/// Every output format by its name in scenes and on the command line.
constexpr std::pair<std::string_view, Format> kFormats[] = {
    {"hdf5", Format::hdf5}, {"bgeo", Format::bgeo}, {"ply", Format::ply},
    {"png", Format::png},   {"mesh", Format::mesh}, {"vdb", Format::vdb}};

}  // namespace

std::optional<Format> format_from_name(const std::string& name) {
  for (const auto& [n, f] : kFormats)
    if (n == name) return f;
  return std::nullopt;
}

const char* format_names() {
  static const std::string names = [] {
    std::string s;
    const std::size_t n = std::size(kFormats);
    for (std::size_t i = 0; i < n; ++i) {
      s += i == 0 ? "" : i + 1 == n ? " or " : ", ";
      s += kFormats[i].first;
    }
    return s;
  }();
  return names.c_str();
}

SceneOverride parse_override(const std::string& text) {
  const std::size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw SceneError({"--set " + text}, "", "expected KEY=VALUE, e.g. --set grid.dims=64");
  return {text.substr(0, eq), text.substr(eq + 1)};
}

SceneDesc load_scene_from_string(const std::string& yaml, const std::filesystem::path& file_name,
                                 MaterialRegistry& registry, const LoadOptions& options) {
  YAML::Node root = parse_yaml(yaml, file_name.string());
  if (!options.overrides.empty() && !root.IsMap())
    throw SceneError({file_name.string()}, "", "a scene file must be a mapping of sections");
  for (const SceneOverride& o : options.overrides) apply_override(root, o, file_name.string());
  check_missing_colons(root, yaml, file_name.string());
  try {
    return read_scene(root, file_name, registry, options);
  } catch (const YAML::Exception& e) {
    // Any yaml-cpp error the reader did not anticipate still names the file and position.
    throw SceneError({file_name.string(), e.mark.line + 1, e.mark.column + 1}, "", e.msg);
  }
}

SceneDesc load_scene(const std::filesystem::path& path, MaterialRegistry& registry,
                     const LoadOptions& options) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw SceneError({path.string()}, "", "cannot open scene file: no such file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError({path.string()}, "", "cannot open scene file: not readable");
  std::ostringstream text;
  text << in.rdbuf();
  return load_scene_from_string(text.str(), path, registry, options);
}

}  // namespace mpm
