#include "engine/io/preview.h"

#include "engine/io/atomic_file.h"

#include <png.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <system_error>

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

}  // namespace

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
                              int height) {
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
                    const PreviewCamera& camera, int width, int height) {
  write_png(png, render_preview_image(frame, camera, width, height));
}

}  // namespace mpm
