#pragma once
/// \file A CPU preview renderer: particles as shaded sphere splats, written as PNG.
///
/// No GPU and no display: each particle is projected through a pinhole camera and drawn as a
/// disc shaded like a sphere (Lambert, one fixed light), with a depth buffer, coloured by
/// object from a fixed palette on a light grey background. The scene's walls are drawn with
/// the same camera and depth buffer: box edges and the outline of each plane's cut through the
/// grid box as dark grey lines, and each plane's cut as a translucent grey checkerboard.

#include <array>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "engine/io/frame_view.h"
#include "engine/core/math.h"
#include "engine/scene/scene_desc.h"

namespace mpm {

/// A pinhole camera and the size particles are drawn at.
struct PreviewCamera {
  Vec3 position = Vec3(0, 0, 1);   ///< Eye point, m.
  Vec3 look_at = Vec3::Zero();     ///< Point imaged at the centre of the picture, m.
  Vec3 up = Vec3(0, 1, 0);         ///< Up in the picture; not parallel to the view direction.
  double fov_deg = 40;             ///< Vertical field of view, degrees, in (0, 180).
  double particle_radius = 0.005;  ///< World radius of each particle's sphere, m.
};

/// An 8-bit RGB colour.
using Rgb = std::array<std::uint8_t, 3>;

/// Background colour of previews: light grey.
inline constexpr Rgb kPreviewBackground = {224, 224, 224};

/// Colour of wall lines (box edges, plane outlines): dark grey.
inline constexpr Rgb kPreviewWallLine = {70, 70, 70};

/// Colour a plane wall's translucent checkerboard blends towards: mid grey.
inline constexpr Rgb kPreviewWallFill = {110, 110, 110};

/// Unshaded colour of object `object_id`: a fixed palette of 8 colours, repeated.
Rgb object_colour(std::uint32_t object_id);

/// An RGB image, 3 bytes per pixel, rows from the top.
struct RgbImage {
  int width = 0;                     ///< Pixels per row.
  int height = 0;                    ///< Rows.
  std::vector<std::uint8_t> pixels;  ///< width * height * 3 bytes, row-major from the top-left.

  /// Colour of the pixel in column `x`, row `y` (row 0 at the top); no bounds check.
  Rgb at(int x, int y) const {
    const std::size_t i = 3 * (static_cast<std::size_t>(y) * width + x);
    return {pixels[i], pixels[i + 1], pixels[i + 2]};
  }
};

/// Where a world point lands in a picture.
struct Projection {
  double x = 0;      ///< Pixels from the left edge; pixel column i covers [i, i + 1).
  double y = 0;      ///< Pixels from the top edge; pixel row j covers [j, j + 1).
  double depth = 0;  ///< Distance in front of the camera along its view axis, m; <= 0 behind.

  /// Whether the point is in front of the camera and inside a width x height picture.
  bool visible(int width, int height) const {
    return depth > 0 && x >= 0 && x < width && y >= 0 && y < height;
  }
};

/// Projects world point `x` into a width x height picture taken by `camera`; `look_at` lands
/// at (width / 2, height / 2). Throws std::invalid_argument for a degenerate camera.
Projection project(const PreviewCamera& camera, int width, int height, const Vec3& x);

/// A camera in front of the grid box (+z side) and slightly above, looking at its centre, far
/// enough that the whole box is in view for pictures at least as wide as tall; particles are
/// drawn with radius 1/400 of the box diagonal. Throws std::invalid_argument unless
/// grid_max > grid_min in every axis.
PreviewCamera default_camera(const Vec3& grid_min, const Vec3& grid_max);

/// What a preview draws besides the particles: walls where they are at the frame's time.
struct PreviewWalls {
  std::vector<WallDesc> walls;    ///< Planes and boxes, already moved to their place (m).
  Vec3 clip_min = Vec3::Zero();   ///< Planes are drawn where they cut this box (the grid), m.
  Vec3 clip_max = Vec3::Ones();   ///< Maximum corner of that box, m.
  /// Colliders as line segments where they are: a mesh's feature edges, a sphere's three
  /// great circles (a vdb collider is not drawn), m.
  std::vector<std::pair<Vec3, Vec3>> collider_edges;
};

/// The walls of `scene` at time `time` (a moving wall displaced as the walls stage moves it,
/// engine/step/walls.h; a collider moved and turned as engine/step/colliders.h places it),
/// clipped to the grid box. Reads each mesh collider's file again.
PreviewWalls preview_walls(const SceneDesc& scene, double time);

/// Renders the particles of `frame` (position and object_id; velocity and J are not used, and
/// may be empty) seen by `camera`, and `walls`. Particles behind the camera or not finite are
/// skipped; every particle in view covers at least the pixel it lands on. A wall line is about
/// 1.5 pixels wide at 480 rows (wider in proportion for taller pictures) and hidden behind
/// particles in front of it; a plane's checkerboard (squares a tenth of the clip box's
/// largest side) tints what lies behind it and leaves what is in front. Throws
/// std::invalid_argument for position and object_id spans of unequal length, a degenerate
/// camera, or a size outside 1..16384.
RgbImage render_preview_image(const FrameView& frame, const PreviewCamera& camera, int width,
                              int height, const PreviewWalls& walls = {});

/// Writes `image` as an 8-bit RGB PNG to `<file>.tmp` and renames it, so the file is whole or
/// absent. Throws std::runtime_error on failure.
void write_png(const std::filesystem::path& file, const RgbImage& image);

/// Reads any PNG as 8-bit RGB (alpha composited on black, grey expanded). Throws
/// std::runtime_error on failure.
RgbImage read_png(const std::filesystem::path& file);

/// render_preview_image, then write_png to `png`.
void render_preview(const std::filesystem::path& png, const FrameView& frame,
                    const PreviewCamera& camera, int width, int height,
                    const PreviewWalls& walls = {});

}  // namespace mpm
