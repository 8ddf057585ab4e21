#include "engine/io/preview.h"

#include <png.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>
#include <system_error>

#include "engine/core/atomic_file.h"
#include "engine/scene/mesh.h"
#include "engine/step/walls.h"

namespace mpm {

namespace {

/// Largest picture side render_preview_image accepts.
constexpr int kMaxSide = 16384;
/// Smallest splat radius, pixels, so that every particle in view covers its own pixel.
constexpr double kMinRadiusPx = 0.75;
/// Light reaching a surface facing away from the light.
constexpr double kAmbient = 0.35;

/// Camera-space basis and pinhole intrinsics for one picture size.
struct CameraFrame {
  Vec3 eye, right, up, forward;  ///< Orthonormal: right x up = -forward (y up, looking +forward).
  double focal_px = 0;           ///< Focal length in pixels.
  double cx = 0, cy = 0;         ///< Principal point: the picture centre.
};

CameraFrame camera_frame(const PreviewCamera& c, int width, int height) {
  if (width < 1 || height < 1 || width > kMaxSide || height > kMaxSide)
    throw std::invalid_argument("preview size " + std::to_string(width) + " x " +
                                std::to_string(height) + " is outside 1.." +
                                std::to_string(kMaxSide));
  if (!(c.fov_deg > 0 && c.fov_deg < 180))
    throw std::invalid_argument("preview field of view must be in (0, 180) degrees");
  if (!(c.particle_radius > 0) || !std::isfinite(c.particle_radius))
    throw std::invalid_argument("preview particle radius must be positive");
  CameraFrame f;
  f.eye = c.position;
  const Vec3 view = c.look_at - c.position;
  if (!view.allFinite() || view.norm() == 0)
    throw std::invalid_argument("preview camera position and look_at must differ");
  f.forward = view.normalized();
  const Vec3 side = f.forward.cross(c.up);
  if (!side.allFinite() || side.norm() < 1e-9 * c.up.norm() || c.up.norm() == 0)
    throw std::invalid_argument("preview camera up is parallel to the view direction");
  f.right = side.normalized();
  f.up = f.right.cross(f.forward);
  const double half_fov = 0.5 * c.fov_deg * std::numbers::pi / 180.0;
  f.focal_px = 0.5 * height / std::tan(half_fov);
  f.cx = 0.5 * width;
  f.cy = 0.5 * height;
  return f;
}

Projection project_with(const CameraFrame& f, const Vec3& x) {
  const Vec3 d = x - f.eye;
  Projection p;
  p.depth = d.dot(f.forward);
  p.x = f.cx + f.focal_px * d.dot(f.right) / p.depth;
  p.y = f.cy - f.focal_px * d.dot(f.up) / p.depth;
  return p;
}

/// 8-bit value of `base` scaled by `intensity` in [0, 1].
std::uint8_t shade(std::uint8_t base, double intensity) {
  return static_cast<std::uint8_t>(std::lround(std::clamp(base * intensity, 0.0, 255.0)));
}

/// Relative depth by which a wall may lie behind a particle and still count as in front: more
/// than float rounding of the depth buffer.
constexpr double kDepthSlack = 1e-5;
/// Relative depth within which a line counts as lying in a plane: not tinted by it (a line is
/// wider than a pixel, so its depth and the plane's at one pixel differ at grazing angles).
constexpr double kInPlane = 1e-2;
/// Opacity of a plane wall's light and dark checkerboard squares.
constexpr double kFillAlpha[2] = {0.25, 0.4};

/// A unit vector perpendicular to unit vector `n`.
Vec3 perpendicular(const Vec3& n) {
  int least = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(n[a]) < std::abs(n[least])) least = a;
  return n.cross(Vec3::Unit(least)).normalized();
}

/// Corners of the polygon in which the plane through `point` with unit normal `n` cuts the box
/// [lo, hi], in order around it; empty if the plane misses the box or only touches an edge.
std::vector<Vec3> plane_cut(const Vec3& point, const Vec3& n, const Vec3& lo, const Vec3& hi) {
  const double tol = 1e-12 * (hi - lo).norm();
  const auto corner = [&](int c) {
    return Vec3((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(), (c & 4) ? hi.z() : lo.z());
  };
  std::vector<Vec3> cut;
  for (int c = 0; c < 8; ++c)
    for (int axis = 0; axis < 3; ++axis) {
      if (c & (1 << axis)) continue;  // each edge once: from corner c along +axis
      const Vec3 a = corner(c), b = corner(c | (1 << axis));
      const double da = (a - point).dot(n), db = (b - point).dot(n);
      if ((da > tol && db > tol) || (da < -tol && db < -tol)) continue;
      if (std::abs(da - db) <= tol) continue;  // the edge lies in the plane: others give its ends
      const Vec3 x = a + (da / (da - db)) * (b - a);
      const bool seen = std::any_of(cut.begin(), cut.end(),
                                    [&](const Vec3& y) { return (x - y).norm() <= 1e3 * tol; });
      if (!seen) cut.push_back(x);
    }
  if (cut.size() < 3) return {};
  Vec3 centre = Vec3::Zero();
  for (const Vec3& x : cut) centre += x;
  centre /= static_cast<double>(cut.size());
  const Vec3 u = perpendicular(n), v = n.cross(u);
  std::sort(cut.begin(), cut.end(), [&](const Vec3& a, const Vec3& b) {
    return std::atan2((a - centre).dot(v), (a - centre).dot(u)) <
           std::atan2((b - centre).dot(v), (b - centre).dot(u));
  });
  return cut;
}

/// A picture being drawn: colours, the depth (along the view axis, m) of the particle each
/// pixel shows, and of the wall line it shows (infinite where none).
struct Canvas {
  RgbImage& img;
  std::vector<float>& depth;
  const CameraFrame& cam;
  std::vector<float> line_depth;
};

/// Draws the segment a-b as a line `radius` pixels about its centre, hidden behind nearer
/// particles, and records its depth in line_depth.
void draw_segment(Canvas& c, const Vec3& a, const Vec3& b, double radius, const Rgb& colour) {
  const CameraFrame& f = c.cam;
  const int width = c.img.width, height = c.img.height;
  // Clip to the view frustum (widened by the line's radius and a pixel): in camera space each
  // side is a linear function g of the segment's parameter s that must stay >= 0.
  const auto to_camera = [&](const Vec3& p) {
    const Vec3 d = p - f.eye;
    return Vec3(d.dot(f.right), d.dot(f.up), d.dot(f.forward));
  };
  const Vec3 ca = to_camera(a), cb = to_camera(b);
  const double m = radius + 1;
  const double left = (-m - f.cx) / f.focal_px, right = (width + m - f.cx) / f.focal_px;
  const double top = (f.cy + m) / f.focal_px, bottom = (f.cy - height - m) / f.focal_px;
  const double near = 1e-9 * std::max(ca.norm(), cb.norm());
  const auto sides = [&](const Vec3& q) {
    return std::array<double, 5>{q.z() - near, q.x() - left * q.z(), right * q.z() - q.x(),
                                 top * q.z() - q.y(), q.y() - bottom * q.z()};
  };
  const std::array<double, 5> ga = sides(ca), gb = sides(cb);
  double s0 = 0, s1 = 1;
  for (int k = 0; k < 5; ++k) {
    if (ga[k] < 0 && gb[k] < 0) return;
    if (ga[k] < 0) s0 = std::max(s0, ga[k] / (ga[k] - gb[k]));
    if (gb[k] < 0) s1 = std::min(s1, ga[k] / (ga[k] - gb[k]));
  }
  if (!(s0 <= s1)) return;
  const Vec3 p0 = a + s0 * (b - a), p1 = a + s1 * (b - a);
  const Projection q0 = project_with(f, p0), q1 = project_with(f, p1);
  const double length = std::hypot(q1.x - q0.x, q1.y - q0.y);
  // Samples at most half a pixel apart on the picture; sigma runs evenly along the projected
  // line, and s (along p0-p1) follows it perspective-correctly (1/depth is linear in sigma).
  const int n = static_cast<int>(std::ceil(2 * length)) + 1;
  for (int k = 0; k <= n; ++k) {
    const double sigma = static_cast<double>(k) / n;
    const double s = sigma * q0.depth / ((1 - sigma) * q1.depth + sigma * q0.depth);
    const Projection q = project_with(f, p0 + s * (p1 - p0));
    const int i0 = std::max(0, static_cast<int>(std::floor(q.x - radius)));
    const int i1 = std::min(width - 1, static_cast<int>(std::ceil(q.x + radius)));
    const int j0 = std::max(0, static_cast<int>(std::floor(q.y - radius)));
    const int j1 = std::min(height - 1, static_cast<int>(std::ceil(q.y + radius)));
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const double dx = i + 0.5 - q.x, dy = j + 0.5 - q.y;
        if (dx * dx + dy * dy > radius * radius) continue;
        const std::size_t pix = static_cast<std::size_t>(j) * width + i;
        if (q.depth > c.depth[pix] * (1 + kDepthSlack)) continue;
        c.line_depth[pix] = std::min(c.line_depth[pix], static_cast<float>(q.depth));
        for (int ch = 0; ch < 3; ++ch) c.img.pixels[3 * pix + ch] = colour[ch];
      }
  }
}

/// Blends a translucent checkerboard over every pixel whose view ray meets the plane through
/// `point` with unit normal `n`, inside the box [lo, hi], nearer than the particle the pixel
/// shows, and nearer than its wall line unless that line lies in the plane.
void fill_plane(Canvas& c, const Vec3& point, const Vec3& n, const Vec3& lo, const Vec3& hi) {
  const CameraFrame& f = c.cam;
  const Vec3 u = perpendicular(n), v = n.cross(u);
  const double square = (hi - lo).maxCoeff() / 10;
  const double tol = 1e-9 * (hi - lo).norm();
  for (int j = 0; j < c.img.height; ++j)
    for (int i = 0; i < c.img.width; ++i) {
      // The ray through the pixel's centre, scaled so that its depth grows 1 m per unit t.
      const Vec3 d = f.forward + f.right * ((i + 0.5 - f.cx) / f.focal_px) +
                     f.up * ((f.cy - (j + 0.5)) / f.focal_px);
      const double denom = d.dot(n);
      if (std::abs(denom) < 1e-12) continue;  // seen edge-on
      const double t = (point - f.eye).dot(n) / denom;
      if (!(t > 0)) continue;
      const Vec3 hit = f.eye + t * d;
      if (((hit - lo).array() < -tol).any() || ((hit - hi).array() > tol).any()) continue;
      const std::size_t pix = static_cast<std::size_t>(j) * c.img.width + i;
      if (t >= c.depth[pix] * (1 - kDepthSlack)) continue;
      if (c.line_depth[pix] <= t * (1 + kInPlane)) continue;
      const auto cell = [&](const Vec3& axis) {
        return static_cast<long long>(std::floor((hit - point).dot(axis) / square));
      };
      const double alpha = kFillAlpha[(cell(u) + cell(v)) & 1];
      for (int ch = 0; ch < 3; ++ch) {
        std::uint8_t& p = c.img.pixels[3 * pix + ch];
        p = static_cast<std::uint8_t>(std::lround((1 - alpha) * p + alpha * kPreviewWallFill[ch]));
      }
    }
}

/// Draws `walls` onto a picture whose particles are already drawn: lines first (hidden by
/// particles in front), then the planes' checkerboards over whatever lies behind them.
void draw_walls(Canvas& c, const PreviewWalls& walls) {
  if (walls.walls.empty() && walls.collider_edges.empty()) return;
  c.line_depth.assign(c.depth.size(), std::numeric_limits<float>::infinity());
  const double radius = 0.75 * std::max(1.0, c.img.height / 480.0);
  const Vec3 lo = walls.clip_min, hi = walls.clip_max;
  for (const WallDesc& w : walls.walls) {
    if (w.shape == WallDesc::Shape::box) {
      const auto corner = [&](int k) {
        return Vec3((k & 1) ? w.max.x() : w.min.x(), (k & 2) ? w.max.y() : w.min.y(),
                    (k & 4) ? w.max.z() : w.min.z());
      };
      for (int k = 0; k < 8; ++k)
        for (int axis = 0; axis < 3; ++axis)
          if (!(k & (1 << axis)))
            draw_segment(c, corner(k), corner(k | (1 << axis)), radius, kPreviewWallLine);
    } else if (w.shape == WallDesc::Shape::plane) {  // colliders are not drawn yet
      const std::vector<Vec3> cut = plane_cut(w.point, w.normal.normalized(), lo, hi);
      for (std::size_t k = 0; k < cut.size(); ++k)
        draw_segment(c, cut[k], cut[(k + 1) % cut.size()], radius, kPreviewWallLine);
    }
  }
  for (const auto& [a, b] : walls.collider_edges) draw_segment(c, a, b, radius, kPreviewWallLine);
  for (const WallDesc& w : walls.walls)
    if (w.shape == WallDesc::Shape::plane) fill_plane(c, w.point, w.normal.normalized(), lo, hi);
}

/// The segments that outline collider `w` in its frame at t = 0: a mesh's feature edges
/// (faces meeting at more than 20 degrees, or open), a sphere's great circles about x, y, z.
std::vector<std::pair<Vec3, Vec3>> collider_outline(const WallDesc& w) {
  std::vector<std::pair<Vec3, Vec3>> out;
  if (w.shape == WallDesc::Shape::sphere) {
    constexpr int kSegments = 48;
    for (int a = 0; a < 3; ++a) {
      const Vec3 u = Vec3::Unit((a + 1) % 3), v = Vec3::Unit((a + 2) % 3);
      auto at = [&](int k) {
        const double t = 2 * std::numbers::pi * k / kSegments;
        return Vec3(w.center + w.radius * (std::cos(t) * u + std::sin(t) * v));
      };
      for (int k = 0; k < kSegments; ++k) out.emplace_back(at(k), at(k + 1));
    }
    return out;
  }
  if (w.shape != WallDesc::Shape::mesh) return out;
  TriangleMesh mesh;
  try {
    mesh = load_mesh(w.file);
  } catch (const MeshError&) {
    return out;  // the simulation has read it already; a file gone since is not drawn
  }
  transform_mesh(mesh, w.scale, w.rotation_deg, w.offset);
  std::map<std::pair<int, int>, std::vector<Vec3>> normals;  // per edge, its faces' normals
  for (const auto& t : mesh.triangles) {
    const Vec3 n = (mesh.vertices[t[1]] - mesh.vertices[t[0]])
                       .cross(mesh.vertices[t[2]] - mesh.vertices[t[0]])
                       .normalized();
    for (int e = 0; e < 3; ++e) normals[std::minmax(t[e], t[(e + 1) % 3])].push_back(n);
  }
  const double cos_feature = std::cos(20 * std::numbers::pi / 180);
  for (const auto& [edge, n] : normals)
    if (n.size() != 2 || std::abs(n[0].dot(n[1])) < cos_feature)
      out.emplace_back(mesh.vertices[edge.first], mesh.vertices[edge.second]);
  return out;
}

}  // namespace

PreviewWalls preview_walls(const SceneDesc& scene, double time) {
  PreviewWalls out;
  out.clip_min = scene.grid.origin;
  out.clip_max = scene.grid.max;
  for (const WallDesc& w : scene.walls) {
    if (w.shape != WallDesc::Shape::plane && w.shape != WallDesc::Shape::box) {
      // As Collider::pose: turned by |w| t about the spin centre, which moves along the path.
      const Vec3 centre = w.shape == WallDesc::Shape::sphere ? w.center : w.offset;
      const Vec3 shift = path_offset(w.velocity, w.path, static_cast<Real>(time));
      const double spin = w.angular_velocity.norm();
      const Mat3 r = spin > 0 ? Mat3(Eigen::AngleAxis<Real>(spin * time, w.angular_velocity / spin))
                              : Mat3(Mat3::Identity());
      for (const auto& [a, b] : collider_outline(w))
        out.collider_edges.emplace_back(centre + shift + r * (a - centre),
                                        centre + shift + r * (b - centre));
      continue;
    }
    // The walls stage moves every plane of a wall by the same offset (build_wall_planes).
    const WallPlane motion{w.point, w.normal, w.boundary, static_cast<Real>(w.friction),
                           w.velocity, w.path};
    const Vec3 d = motion.offset(static_cast<Real>(time));
    WallDesc placed = w;
    placed.point += d;
    placed.min += d;
    placed.max += d;
    out.walls.push_back(std::move(placed));
  }
  return out;
}

Rgb object_colour(std::uint32_t object_id) {
  // Colour-blind-friendly hues (Okabe-Ito without black and grey), all far from the background.
  static constexpr Rgb kPalette[] = {{0, 114, 178},  {230, 159, 0},   {0, 158, 115},
                                     {213, 94, 0},   {204, 121, 167}, {86, 180, 233},
                                     {240, 228, 66}, {120, 60, 160}};
  return kPalette[object_id % std::size(kPalette)];
}

Projection project(const PreviewCamera& camera, int width, int height, const Vec3& x) {
  return project_with(camera_frame(camera, width, height), x);
}

PreviewCamera default_camera(const Vec3& grid_min, const Vec3& grid_max) {
  if (!grid_min.allFinite() || !grid_max.allFinite() ||
      !(grid_max.array() > grid_min.array()).all())
    throw std::invalid_argument("default_camera: grid_max must exceed grid_min in every axis");
  PreviewCamera c;
  const Vec3 centre = 0.5 * (grid_min + grid_max);
  const Vec3 back = Vec3(0, 0.3, 1).normalized();  // from the centre towards the camera
  c.look_at = centre;
  c.position = centre + back;  // only the direction matters for the basis
  c.up = Vec3(0, 1, 0);
  const CameraFrame basis = camera_frame(c, 1, 1);
  // A corner at offset o from the centre, seen from distance D along `back`, is at depth
  // D - o.back and must satisfy |o.up| <= tan(fov / 2) (D - o.back), and the same for o.right
  // (pictures at least as wide as tall). The smallest D for all eight corners, 5 % margin.
  const double tan_half = std::tan(0.5 * c.fov_deg * std::numbers::pi / 180.0);
  double distance = 0;
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3 o =
        Vec3((corner & 1) ? grid_max.x() : grid_min.x(), (corner & 2) ? grid_max.y() : grid_min.y(),
             (corner & 4) ? grid_max.z() : grid_min.z()) -
        centre;
    const double off_axis = std::max(std::abs(o.dot(basis.up)), std::abs(o.dot(basis.right)));
    distance = std::max(distance, o.dot(back) + off_axis / tan_half);
  }
  c.position = centre + 1.05 * distance * back;
  c.particle_radius = (grid_max - grid_min).norm() / 400;
  return c;
}

RgbImage render_preview_image(const FrameView& frame, const PreviewCamera& camera, int width,
                              int height, const PreviewWalls& walls) {
  if (frame.object_id.size() != frame.position.size())
    throw std::invalid_argument("preview: position and object_id differ in length");
  const CameraFrame cam = camera_frame(camera, width, height);

  RgbImage img;
  img.width = width;
  img.height = height;
  img.pixels.resize(3 * static_cast<std::size_t>(width) * height);
  for (std::size_t i = 0; i < img.pixels.size(); i += 3)
    for (int c = 0; c < 3; ++c) img.pixels[i + c] = kPreviewBackground[c];
  std::vector<float> depth(static_cast<std::size_t>(width) * height,
                           std::numeric_limits<float>::infinity());

  // Light direction in camera space (x right, y up, z towards the viewer): upper left, front.
  const Vec3 light = Vec3(-0.4, 0.6, 0.7).normalized();
  const double R = camera.particle_radius;
  for (std::size_t q = 0; q < frame.size(); ++q) {
    if (!frame.position[q].allFinite()) continue;
    const Projection p = project_with(cam, frame.position[q]);
    if (!(p.depth > R)) continue;  // behind the camera, or the camera is inside the sphere
    const double r = std::max(kMinRadiusPx, cam.focal_px * R / p.depth);
    const double x0 = std::floor(p.x - r), x1 = std::ceil(p.x + r);
    const double y0 = std::floor(p.y - r), y1 = std::ceil(p.y + r);
    if (x1 < 0 || y1 < 0 || x0 >= width || y0 >= height) continue;
    const int i0 = static_cast<int>(std::max(0.0, x0));
    const int i1 = static_cast<int>(std::min(width - 1.0, x1));
    const int j0 = static_cast<int>(std::max(0.0, y0));
    const int j1 = static_cast<int>(std::min(height - 1.0, y1));
    const Rgb base = object_colour(frame.object_id[q]);
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const double dx = (i + 0.5 - p.x) / r, dy = (j + 0.5 - p.y) / r;
        const double d2 = dx * dx + dy * dy;
        if (d2 > 1) continue;
        const double nz = std::sqrt(1 - d2);
        const std::size_t pix = static_cast<std::size_t>(j) * width + i;
        const auto z = static_cast<float>(p.depth - R * nz);
        if (z >= depth[pix]) continue;
        depth[pix] = z;
        const double lambert = std::max(0.0, Vec3(dx, -dy, nz).dot(light));
        const double intensity = kAmbient + (1 - kAmbient) * lambert;
        for (int c = 0; c < 3; ++c) img.pixels[3 * pix + c] = shade(base[c], intensity);
      }
  }
  Canvas canvas{img, depth, cam, {}};
  draw_walls(canvas, walls);
  return img;
}

void write_png(const std::filesystem::path& file, const RgbImage& image) {
  if (image.width < 1 || image.height < 1 ||
      image.pixels.size() != 3 * static_cast<std::size_t>(image.width) * image.height)
    throw std::runtime_error("cannot write '" + file.string() + "': image has a bad size");
  const std::filesystem::path tmp = temporary_path(file);
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(image.width);
  png.height = static_cast<png_uint_32>(image.height);
  png.format = PNG_FORMAT_RGB;
  if (!png_image_write_to_file(&png, tmp.c_str(), 0, image.pixels.data(), 3 * image.width,
                               nullptr)) {
    const std::string why = png.message;
    png_image_free(&png);
    std::error_code ignore;
    std::filesystem::remove(tmp, ignore);
    throw std::runtime_error("cannot write PNG '" + tmp.string() + "': " + why);
  }
  replace_file(tmp, file);
}

RgbImage read_png(const std::filesystem::path& file) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&png, file.c_str()))
    throw std::runtime_error("cannot read PNG '" + file.string() + "': " + png.message);
  png.format = PNG_FORMAT_RGB;
  RgbImage img;
  img.width = static_cast<int>(png.width);
  img.height = static_cast<int>(png.height);
  try {
    img.pixels.assign(PNG_IMAGE_SIZE(png), 0);
  } catch (...) {
    png_image_free(&png);
    throw;
  }
  if (!png_image_finish_read(&png, nullptr, img.pixels.data(), 0, nullptr))
    throw std::runtime_error("cannot read PNG '" + file.string() + "': " + png.message);
  return img;
}

void render_preview(const std::filesystem::path& png, const FrameView& frame,
                    const PreviewCamera& camera, int width, int height,
                    const PreviewWalls& walls) {
  write_png(png, render_preview_image(frame, camera, width, height, walls));
}

}  // namespace mpm
