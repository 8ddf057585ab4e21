// PNG previews draw the scene's walls: plane floors as a translucent checkerboard with their
// outline, boxes as their twelve edges, moved walls where they are, hidden behind particles.
#include <catch2/catch.hpp>
#include <cmath>
#include <vector>

#include "engine/io/output.h"
#include "engine/io/preview.h"
#include "output/output_checks.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

constexpr int kWidth = 320, kHeight = 240;

/// A floor plane at height y with an upward normal.
WallDesc floor_at(double y) {
  WallDesc w;
  w.shape = WallDesc::Shape::plane;
  w.point = Vec3(0, y, 0);
  w.normal = Vec3(0, 1, 0);
  return w;
}

/// A box wall from lo to hi.
WallDesc box(const Vec3& lo, const Vec3& hi) {
  WallDesc w;
  w.shape = WallDesc::Shape::box;
  w.min = lo;
  w.max = hi;
  return w;
}

/// The pixel a world point lands on.
Rgb pixel_at(const RgbImage& img, const PreviewCamera& cam, const Vec3& x) {
  const Projection p = project(cam, img.width, img.height, x);
  REQUIRE(p.visible(img.width, img.height));
  return img.at(static_cast<int>(p.x), static_cast<int>(p.y));
}

/// Whether `p` is a grey (equal channels) darker than the background: the floor's tint.
bool is_floor_tint(const Rgb& p) {
  return p[0] == p[1] && p[1] == p[2] && p[0] < kPreviewBackground[0] &&
         p[0] > kPreviewWallLine[0];
}

/// A frame of particles at `x` of objects `id` (views into the caller's vectors).
FrameView particles(const std::vector<Vec3>& x, const std::vector<std::uint32_t>& id) {
  FrameView v;
  v.position = x;
  v.object_id = id;
  return v;
}


}  // namespace

TEST_CASE("preview: a floor plane is a grey checkerboard with its outline, behind particles",
          "[output][walls]") {
  const Vec3 lo(0, 0, 0), hi(1, 1, 1);
  PreviewCamera cam = default_camera(lo, hi);
  cam.particle_radius = 0.03;
  PreviewWalls walls;
  walls.walls = {floor_at(0.05)};
  walls.clip_min = lo;
  walls.clip_max = hi;
  const FrameView none{};

  // Without walls (as before walls were drawn) the picture is all background.
  const RgbImage bare = render_preview_image(none, cam, kWidth, kHeight);
  for (std::size_t i = 0; i < bare.pixels.size(); i += 3)
    REQUIRE(Rgb{bare.pixels[i], bare.pixels[i + 1], bare.pixels[i + 2]} == kPreviewBackground);

  const RgbImage img = render_preview_image(none, cam, kWidth, kHeight, walls);
  // Inside the floor: tinted grey, both shades of the checkerboard (squares of 0.1 m).
  std::vector<int> shades;
  for (double x = 0.15; x < 0.9; x += 0.1)
    for (double z = 0.15; z < 0.9; z += 0.1) {
      INFO("floor point " << x << ", " << z);
      const Rgb p = pixel_at(img, cam, Vec3(x, 0.05, z));
      CHECK(is_floor_tint(p));
      shades.push_back(p[0]);
    }
  CHECK(*std::min_element(shades.begin(), shades.end()) + 10 <
        *std::max_element(shades.begin(), shades.end()));
  // Its outline, where the plane cuts the grid box: wall lines, midpoints of all four sides.
  for (const Vec3& x : {Vec3(0.5, 0.05, 0), Vec3(0.5, 0.05, 1), Vec3(0, 0.05, 0.5),
                        Vec3(1, 0.05, 0.5)}) {
    INFO("outline point " << x.transpose());
    CHECK(pixel_at(img, cam, x) == kPreviewWallLine);
  }
  // Above the floor's far edge there is nothing: the top rows stay background.
  for (int i = 0; i < kWidth; i += 8) CHECK(img.at(i, 1) == kPreviewBackground);

  SECTION("a particle in front of the floor and its outline hides them") {
    const Vec3 on_edge(0.5, 0.05, 1.0), above(0.3, 0.3, 0.5);
    const std::vector<Vec3> x = {on_edge, above};
    const std::vector<std::uint32_t> id = {0, 1};
    const FrameView two = particles(x, id);
    const RgbImage with = render_preview_image(two, cam, kWidth, kHeight, walls);
    CHECK(test::is_shade_of(pixel_at(with, cam, on_edge), object_colour(0)));
    CHECK(test::is_shade_of(pixel_at(with, cam, above), object_colour(1)));
    // The same particle pixels as without walls: nothing drawn over them.
    const RgbImage without = render_preview_image(two, cam, kWidth, kHeight);
    CHECK(pixel_at(with, cam, above) == pixel_at(without, cam, above));
  }
  SECTION("a particle below the floor, seen through it from above, is tinted") {
    PreviewWalls high = walls;
    high.walls = {floor_at(0.5)};
    const std::vector<Vec3> x = {Vec3(0.5, 0.3, 0.5)};
    const std::vector<std::uint32_t> id = {0};
    const FrameView under = particles(x, id);
    const Rgb plain = pixel_at(render_preview_image(under, cam, kWidth, kHeight), cam, x[0]);
    const Rgb tinted = pixel_at(render_preview_image(under, cam, kWidth, kHeight, high), cam, x[0]);
    CHECK(cam.position.y() > 0.5);
    CHECK(tinted != plain);
  }
}

TEST_CASE("preview: a box wall is drawn as its twelve edges and nothing inside",
          "[output][walls]") {
  const Vec3 lo(0, 0, 0), hi(1, 1, 1);
  const PreviewCamera cam = default_camera(lo, hi);
  PreviewWalls walls;
  walls.walls = {box(Vec3(0.2, 0.2, 0.2), Vec3(0.8, 0.7, 0.9))};
  walls.clip_min = lo;
  walls.clip_max = hi;
  const RgbImage img = render_preview_image(FrameView{}, cam, kWidth, kHeight, walls);
  const Vec3 a = walls.walls[0].min, b = walls.walls[0].max;
  int edges = 0;
  for (int k = 0; k < 8; ++k)
    for (int axis = 0; axis < 3; ++axis) {
      if (k & (1 << axis)) continue;
      Vec3 from((k & 1) ? b.x() : a.x(), (k & 2) ? b.y() : a.y(), (k & 4) ? b.z() : a.z());
      Vec3 to = from;
      to[axis] = b[axis];
      INFO("edge " << from.transpose() << " to " << to.transpose());
      CHECK(pixel_at(img, cam, 0.5 * (from + to)) == kPreviewWallLine);
      CHECK(pixel_at(img, cam, 0.3 * from + 0.7 * to) == kPreviewWallLine);
      ++edges;
    }
  CHECK(edges == 12);
  CHECK(pixel_at(img, cam, 0.5 * (a + b)) == kPreviewBackground);
  // Lines are about 1.5 pixels wide: most of the picture stays background.
  int background = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) background += img.at(x, y) == kPreviewBackground;
  CHECK(background > 0.9 * kWidth * kHeight);
}

TEST_CASE("preview_walls: walls where the walls stage puts them at the frame's time",
          "[output][walls]") {
  const std::string yaml = R"(
simulation: {frames: 1, dt: 1.0e-3}
grid: {origin: [-1, 0, 0], max: [1, 2, 1], dims: 20}
objects:
  - {name: c, mesh: meshes/cube.obj, scale: 0.2, offset: [0, 1, 0.5], mass: 1,
     material: corotated, E: 1.0e4, nu: 0.3}
walls:
  - plane: {point: [0, 0.1, 0], normal: [0, 2, 0]}
    velocity: [0, 0.1, 0]
  - box: {min: [-0.9, 0.1, 0.1], max: [0.9, 1.9, 0.9]}
    path: [[0, 0, 0, 0], [1, 0.1, 0, 0]]
)";
  const SceneDesc scene = test::scene_from(yaml);
  const PreviewWalls at = preview_walls(scene, 0.5);
  CHECK(at.clip_min == Vec3(-1, 0, 0));
  CHECK(at.clip_max == Vec3(1, 2, 1));
  REQUIRE(at.walls.size() == 2);
  CHECK(at.walls[0].shape == WallDesc::Shape::plane);
  CHECK((at.walls[0].point - Vec3(0, 0.15, 0)).norm() < 1e-15);
  CHECK(at.walls[0].normal == Vec3(0, 1, 0));
  CHECK(at.walls[1].shape == WallDesc::Shape::box);
  CHECK((at.walls[1].min - Vec3(-0.85, 0.1, 0.1)).norm() < 1e-15);
  CHECK((at.walls[1].max - Vec3(0.95, 1.9, 0.9)).norm() < 1e-15);
  // After the path's last key the box stays there.
  CHECK((preview_walls(scene, 3.0).walls[1].min - Vec3(-0.8, 0.1, 0.1)).norm() < 1e-15);
}

TEST_CASE("preview: a run's PNG frames show the scene's floor and box", "[output][walls]") {
  // A small cube resting high in the box: the floor is free of particles below it.
  const std::string yaml = R"(
simulation: {frames: 1, dt: 1.0e-3}
grid: {max: [1, 1, 1], dims: 20}
objects:
  - {name: c, mesh: meshes/cube.obj, scale: 0.2, offset: [0.5, 0.6, 0.5], mass: 1,
     material: corotated, E: 1.0e4, nu: 0.3}
walls:
  - plane: {point: [0, 0.05, 0], normal: [0, 1, 0]}
  - box: {min: [0.15, 0.05, 0.15], max: [0.85, 0.95, 0.85]}
output: {formats: [png], preview_size: [320, 240]}
)";
  const SceneDesc scene = test::scene_from(yaml);
  auto sim = Simulation::create(scene, builtin_registry());
  const auto dir = test::temp_dir("preview_walls_run");
  FrameOutput out(dir, scene.output);
  out.on_start(*sim, 1);
  const RgbImage img = read_png(dir / "preview" / "frame_00000.png");
  REQUIRE(img.width == 320);
  const PreviewCamera cam = default_camera(scene.grid.origin, scene.grid.max);
  // The floor outside the box, and inside the box in front of the cube: tinted.
  for (const Vec3& x : {Vec3(0.5, 0.05, 0.93), Vec3(0.3, 0.05, 0.75), Vec3(0.92, 0.05, 0.92)}) {
    INFO("floor point " << x.transpose());
    const Rgb p = pixel_at(img, cam, x);
    INFO("pixel " << int(p[0]) << " " << int(p[1]) << " " << int(p[2]));
    CHECK(is_floor_tint(p));
  }
  // The box's upper edges and the floor's outline: wall lines.
  for (const Vec3& x : {Vec3(0.5, 0.95, 0.15), Vec3(0.15, 0.5, 0.85), Vec3(0.5, 0.05, 1.0)}) {
    INFO("line point " << x.transpose());
    CHECK(pixel_at(img, cam, x) == kPreviewWallLine);
  }
  // The cube itself, in front of everything.
  CHECK(test::is_shade_of(pixel_at(img, cam, Vec3(0.5, 0.6, 0.6)), object_colour(0)));
}
