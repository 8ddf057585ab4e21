// Frame writers: PLY and bgeo read back, the XDMF index against real HDF5 frames, PNG previews.
#include <bit>
#include <catch2/catch.hpp>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <numbers>
#include <random>
#include <regex>
#include <set>
#include <utility>

#include "engine/io/bgeo.h"
#include "engine/io/ply.h"
#include "engine/io/preview.h"
#include "engine/io/xdmf.h"
#include "engine/io/output.h"
#include "output/output_checks.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// Random particles of two objects, owning the arrays a FrameView points into.
struct RandomFrame {
  std::vector<Vec3> x, v;
  std::vector<std::uint32_t> id;
  std::vector<Real> J;
  std::vector<std::uint32_t> particle_id;  // a permutation, not 0..n-1: ids travel as given
  double time = 0.1 + 1.0 / 3.0;  // not a short decimal: the time must survive as text
  int frame = 7;

  explicit RandomFrame(std::size_t n, unsigned seed = 1) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> pos(-1.0, 2.0), vel(-5.0, 5.0), vol(0.5, 1.5);
    for (std::size_t i = 0; i < n; ++i) {
      x.emplace_back(pos(rng), pos(rng), pos(rng));
      v.emplace_back(vel(rng), vel(rng), vel(rng));
      id.push_back(i < n / 2 ? 0u : 1u);
      J.push_back(vol(rng));
      particle_id.push_back(static_cast<std::uint32_t>((7 * i + 3) % n));
    }
  }
  FrameView view() const { return FrameView{x, v, id, J, time, frame, particle_id}; }
};

std::string slurp(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void spit(const std::filesystem::path& file, const std::string& data) {
  std::ofstream(file, std::ios::binary | std::ios::trunc) << data;
}

/// Checks that `got` holds exactly the float-rounded values of `f`.
template <class Points>
void check_same_as(const Points& got, const RandomFrame& f) {
  REQUIRE(got.size() == f.x.size());
  REQUIRE(got.position.size() == 3 * f.x.size());
  REQUIRE(got.velocity.size() == 3 * f.x.size());
  REQUIRE(got.J.size() == f.x.size());
  std::size_t wrong = 0;
  for (std::size_t i = 0; i < f.x.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      wrong += got.position[3 * i + a] != static_cast<float>(f.x[i][a]);
      wrong += got.velocity[3 * i + a] != static_cast<float>(f.v[i][a]);
    }
    wrong += got.object_id[i] != static_cast<int>(f.id[i]);
    wrong += got.J[i] != static_cast<float>(f.J[i]);
    wrong += static_cast<std::uint32_t>(got.id[i]) != f.particle_id[i];
  }
  CHECK(wrong == 0);
  // And the float values are the doubles to float precision.
  CHECK(got.position[3] == Approx(f.x[1][0]).epsilon(1e-7));
  CHECK(got.J.back() == Approx(f.J.back()).epsilon(1e-7));
}

/// 4 bytes at `p` as a big-endian float.
float be_float(const std::string& s, std::size_t p) {
  std::uint32_t bits = 0;
  for (int b = 0; b < 4; ++b) bits = (bits << 8) | static_cast<unsigned char>(s[p + b]);
  return std::bit_cast<float>(bits);
}

/// 4 bytes at `p` as a little-endian float.
float le_float(const std::string& s, std::size_t p) {
  std::uint32_t bits = 0;
  for (int b = 3; b >= 0; --b) bits = (bits << 8) | static_cast<unsigned char>(s[p + b]);
  return std::bit_cast<float>(bits);
}

}  // namespace

TEST_CASE("PLY: a random frame reads back exactly, header and byte order as specified",
          "[output]") {
  const auto dir = test::temp_dir("ply");
  const RandomFrame f(1000);
  const auto file = dir / "frame.ply";
  write_ply(file, f.view());
  CHECK_FALSE(std::filesystem::exists(dir / "frame.ply.tmp"));

  const PlyPoints p = read_ply(file);
  check_same_as(p, f);
  CHECK(p.time == f.time);
  CHECK(p.frame == 7);

  // The raw bytes, without the reader: header text, then 36 bytes per vertex, little-endian.
  const std::string raw = slurp(file);
  CHECK(raw.rfind("ply\nformat binary_little_endian 1.0\n", 0) == 0);
  CHECK(raw.find("\nelement vertex 1000\n") != std::string::npos);
  CHECK(raw.find("\nproperty float x\nproperty float y\nproperty float z\n"
                 "property float vx\nproperty float vy\nproperty float vz\n"
                 "property int object_id\nproperty float J\nproperty uint id\nend_header\n") !=
        std::string::npos);
  const std::size_t body = raw.find("end_header\n") + std::strlen("end_header\n");
  CHECK(raw.size() - body == 1000 * 36);
  CHECK(le_float(raw, body) == static_cast<float>(f.x[0][0]));
  CHECK(le_float(raw, body + 4 * 7) == static_cast<float>(f.J[0]));
  CHECK(le_float(raw, body + 36 + 4 * 8) == std::bit_cast<float>(f.particle_id[1]));

  SECTION("writing again replaces the file") {
    const RandomFrame g(10, 2);
    write_ply(file, g.view());
    check_same_as(read_ply(file), g);
  }
  SECTION("an empty frame") {
    const RandomFrame g(0);
    write_ply(file, g.view());
    CHECK(read_ply(file).size() == 0);
  }
  SECTION("the reader rejects anything else") {
    spit(dir / "short.ply", raw.substr(0, raw.size() - 1));
    CHECK_THROWS_AS(read_ply(dir / "short.ply"), std::runtime_error);
    spit(dir / "long.ply", raw + "x");
    CHECK_THROWS_AS(read_ply(dir / "long.ply"), std::runtime_error);
    std::string other = raw;
    other.replace(other.find("property float J"), 16, "property int   J");
    spit(dir / "other.ply", other);
    CHECK_THROWS_AS(read_ply(dir / "other.ply"), std::runtime_error);
    std::string ascii = raw;
    ascii.replace(ascii.find("binary_little_endian"), 20, "ascii               ");
    spit(dir / "ascii.ply", ascii);
    CHECK_THROWS_AS(read_ply(dir / "ascii.ply"), std::runtime_error);
    CHECK_THROWS_AS(read_ply(dir / "missing.ply"), std::runtime_error);
  }
  SECTION("spans of unequal length are refused and nothing is written") {
    FrameView bad = f.view();
    bad.J = bad.J.first(999);
    CHECK_THROWS_AS(write_ply(dir / "bad.ply", bad), std::invalid_argument);
    CHECK_FALSE(std::filesystem::exists(dir / "bad.ply"));
    CHECK_FALSE(std::filesystem::exists(dir / "bad.ply.tmp"));
  }
}

TEST_CASE("bgeo: a random frame reads back exactly, classic Bgeo v5 big-endian layout",
          "[output]") {
  const auto dir = test::temp_dir("bgeo");
  const RandomFrame f(1000);
  const auto file = dir / "frame.bgeo";
  write_bgeo(file, f.view());
  CHECK_FALSE(std::filesystem::exists(dir / "frame.bgeo.tmp"));
  check_same_as(read_bgeo(file), f);

  // The raw bytes, without the reader.
  const std::string raw = slurp(file);
  REQUIRE(raw.size() > 100);
  CHECK(raw.substr(0, 5) == "BgeoV");
  CHECK(raw.substr(5, 4) == std::string("\0\0\0\5", 4));      // version 5
  CHECK(raw.substr(9, 4) == std::string("\0\0\x03\xe8", 4));  // 1000 points
  CHECK(raw.substr(13, 8) == std::string(8, '\0'));           // no primitives, point groups
  CHECK(raw.substr(25, 4) == std::string("\0\0\0\4", 4));     // 4 point attributes
  // Definitions: "v" vector of 3, "object_id" int, "J" float, "id" int, zero defaults.
  CHECK(raw.substr(41, 9) == std::string("\0\1v\0\3\0\0\0\5", 9));
  const std::size_t header = 41 + (2 + 1 + 2 + 4 + 12) + (2 + 9 + 2 + 4 + 4) +
                             (2 + 1 + 2 + 4 + 4) + (2 + 2 + 2 + 4 + 4);
  CHECK(raw.substr(header - 14, 14) == std::string("\0\2id\0\1\0\0\0\1\0\0\0\0", 14));
  CHECK(raw.size() == header + 1000 * 40 + 2);
  CHECK(be_float(raw, header) == static_cast<float>(f.x[0][0]));
  CHECK(be_float(raw, header + 12) == 1.0f);  // w of P
  CHECK(be_float(raw, header + 16) == static_cast<float>(f.v[0][0]));
  CHECK(be_float(raw, header + 32) == static_cast<float>(f.J[0]));
  CHECK(raw.substr(raw.size() - 2) == std::string("\0\xff", 2));

  SECTION("the reader checks magic, version and length") {
    std::string bad = raw;
    bad[0] = 'b';
    spit(dir / "magic.bgeo", bad);
    CHECK_THROWS_AS(read_bgeo(dir / "magic.bgeo"), std::runtime_error);
    bad = raw;
    bad[8] = 4;
    spit(dir / "version.bgeo", bad);
    CHECK_THROWS_AS(read_bgeo(dir / "version.bgeo"), std::runtime_error);
    spit(dir / "short.bgeo", raw.substr(0, raw.size() - 3));
    CHECK_THROWS_AS(read_bgeo(dir / "short.bgeo"), std::runtime_error);
    bad = raw;
    bad[header + 12] = 0x40;  // w = 4
    spit(dir / "w.bgeo", bad);
    CHECK_THROWS_AS(read_bgeo(dir / "w.bgeo"), std::runtime_error);
  }
  SECTION("an empty frame") {
    const RandomFrame g(0);
    write_bgeo(file, g.view());
    CHECK(read_bgeo(file).size() == 0);
  }
}

namespace {

/// Value of attribute `name` in the first tag of `text` (empty if absent).
std::string attr(const std::string& text, const std::string& name) {
  const std::regex re("\\b" + name + "=\"([^\"]*)\"");
  std::smatch m;
  return std::regex_search(text, m, re) ? m[1].str() : std::string();
}

}  // namespace

TEST_CASE("XDMF: a temporal collection over the HDF5 frames, every path, time and size right",
          "[output]") {
  const auto dir = test::temp_dir("xdmf");
  const std::vector<std::size_t> sizes = {1000, 1000, 600};
  const std::vector<double> times = {0.0, 1.0 / 24, 2.0 / 24};
  std::vector<XdmfFrame> frames;
  for (int k = 0; k < 3; ++k) {
    RandomFrame f(sizes[k], k + 1);
    f.time = times[k];
    f.frame = k;
    write_frame_hdf5(frame_path(dir, k), f.view());
    frames.push_back({frame_path(dir, k).filename().string(), times[k], sizes[k]});
  }
  const auto xmf = dir / "particles.xmf";
  write_xdmf(xmf, frames);
  CHECK_FALSE(std::filesystem::exists(dir / "particles.xmf.tmp"));

  const std::string text = slurp(xmf);
  CHECK(text.rfind("<?xml version=\"1.0\" ?>", 0) == 0);
  CHECK(text.find("<Xdmf Version=\"3.0\">") != std::string::npos);
  const std::regex collection("<Grid [^>]*GridType=\"Collection\" CollectionType=\"Temporal\">");
  CHECK(std::regex_search(text, collection));
  for (const char* tag : {"Xdmf", "Domain", "Grid", "Geometry", "Attribute", "DataItem"}) {
    INFO(tag);
    const std::regex open(std::string("<") + tag + "[ >]"), close(std::string("</") + tag + ">");
    const auto count = [&](const std::regex& re) {
      return std::distance(std::sregex_iterator(text.begin(), text.end(), re),
                           std::sregex_iterator());
    };
    CHECK(count(open) == count(close));
  }

  // One uniform grid per frame, in order.
  const std::vector<std::string> grids = test::uniform_grids(text);
  REQUIRE(grids.size() == 3);

  const std::regex item_re("<DataItem ([^>]*)>([^<:]+):/(\\w+)</DataItem>");
  for (int k = 0; k < 3; ++k) {
    INFO("frame " << k);
    const std::string& g = grids[k];
    const std::string n = std::to_string(sizes[k]);
    std::smatch m;
    REQUIRE(std::regex_search(g, m, std::regex("<Time Value=\"([^\"]+)\"/>")));
    const std::string time_text = m[1].str();
    double t = -1;
    std::from_chars(time_text.data(), time_text.data() + time_text.size(), t);
    CHECK(t == times[k]);
    REQUIRE(std::regex_search(g, m, std::regex("<Topology [^>]*>")));
    CHECK(attr(m[0].str(), "TopologyType") == "Polyvertex");
    CHECK(attr(m[0].str(), "NumberOfElements") == n);

    // Each DataItem inside its owner: geometry, then the three attributes.
    struct Want {
      std::string owner, dataset, dims, type;
    };
    const std::vector<Want> wants = {
        {"<Geometry GeometryType=\"XYZ\">", "position", n + " 3", "Float"},
        {"<Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">", "velocity",
         n + " 3", "Float"},
        {"<Attribute Name=\"object_id\" AttributeType=\"Scalar\" Center=\"Node\">", "object_id", n,
         "Int"},
        {"<Attribute Name=\"J\" AttributeType=\"Scalar\" Center=\"Node\">", "J", n, "Float"}};
    std::set<std::string> seen;
    for (auto it = std::sregex_iterator(g.begin(), g.end(), item_re); it != std::sregex_iterator();
         ++it)
      seen.insert((*it)[3].str());
    // The run's datasets and the connectivity shared by all frames (tests/output/test_xdmf.cpp).
    for (const char* dataset : {"position", "velocity", "object_id", "J", "connectivity"}) {
      INFO(dataset);
      CHECK(seen.count(dataset) == 1);
    }
    for (const Want& w : wants) {
      INFO(w.dataset);
      const std::size_t at = g.find(w.owner);
      REQUIRE(at != std::string::npos);
      const std::string rest = g.substr(at + w.owner.size());
      REQUIRE(std::regex_search(rest, m, item_re));
      CHECK(m[3].str() == w.dataset);
      CHECK(m[2].str() == frames[k].h5_file_name);
      CHECK(attr(m[1].str(), "Dimensions") == w.dims);
      CHECK(attr(m[1].str(), "NumberType") == w.type);
      CHECK(attr(m[1].str(), "Precision") == "4");
      CHECK(attr(m[1].str(), "Format") == "HDF");
    }
    // The files it names are the frames, with that many particles at that time.
    const FrameData d = read_frame_hdf5(dir / frames[k].h5_file_name);
    CHECK(d.size() == sizes[k]);
    CHECK(d.time == times[k]);
  }

  SECTION("file names are escaped; a ':' or a non-finite time is refused") {
    write_xdmf(xmf, {{"a&b<c>.h5", 0.5, 3}});
    const std::string escaped = slurp(xmf);
    CHECK(escaped.find("a&amp;b&lt;c&gt;.h5:/position") != std::string::npos);
    CHECK(escaped.find("a&b") == std::string::npos);
    CHECK_THROWS_AS(write_xdmf(xmf, {{"c:frame.h5", 0, 1}}), std::invalid_argument);
    CHECK_THROWS_AS(write_xdmf(xmf, {{"frame.h5", std::nan(""), 1}}), std::invalid_argument);
    CHECK(slurp(xmf) == escaped);  // a refused call leaves the old file alone
  }
}

namespace {


/// A camera 2.5 m in front of (0.5, 0.5, 0.5), looking along -z.
PreviewCamera front_camera(double radius) {
  PreviewCamera c;
  c.look_at = Vec3(0.5, 0.5, 0.5);
  c.position = Vec3(0.5, 0.5, 3.0);
  c.particle_radius = radius;
  return c;
}

}  // namespace

TEST_CASE("preview: projection puts look_at in the centre, right is right and up is up",
          "[output]") {
  const PreviewCamera c = front_camera(0.05);
  const Projection centre = project(c, 64, 48, c.look_at);
  CHECK(centre.x == Approx(32));
  CHECK(centre.y == Approx(24));
  CHECK(centre.depth == Approx(2.5));
  CHECK(centre.visible(64, 48));
  // 40 degree vertical field of view: a point tan(20 deg) * 2.5 above look_at is at the top.
  const double up = 2.5 * std::tan(std::numbers::pi / 9);
  const Projection top = project(c, 64, 48, c.look_at + Vec3(0, up, 0));
  CHECK(top.y == Approx(0).margin(1e-3));
  CHECK(project(c, 64, 48, c.look_at + Vec3(0.1, 0, 0)).x > 33);
  CHECK(project(c, 64, 48, c.look_at + Vec3(0, 0.1, 0)).y < 23);
  CHECK_FALSE(project(c, 64, 48, Vec3(0.5, 0.5, 4.0)).visible(64, 48));  // behind
  PreviewCamera bad = c;
  bad.up = Vec3(0, 0, 1);  // parallel to the view direction
  CHECK_THROWS_AS(project(bad, 64, 48, c.look_at), std::invalid_argument);
}

TEST_CASE("preview: a particle at look_at is a shaded disc of its object's colour in the centre",
          "[output]") {
  const auto dir = test::temp_dir("preview");
  const PreviewCamera c = front_camera(0.2);  // 0.2 m at 2.5 m: about 5.3 pixels at 48 rows
  const std::vector<Vec3> x = {c.look_at};
  const std::vector<std::uint32_t> id = {1};
  const FrameView one{x, {}, id, {}, 0.0, 0};
  const auto png = dir / "one.png";
  render_preview(png, one, c, 64, 48);
  CHECK_FALSE(std::filesystem::exists(dir / "one.png.tmp"));

  const RgbImage img = read_png(png);
  REQUIRE(img.width == 64);
  REQUIRE(img.height == 48);
  REQUIRE(img.pixels.size() == 64 * 48 * 3);
  for (int y = 22; y <= 25; ++y)
    for (int x = 30; x <= 33; ++x) {
      INFO("pixel " << x << ", " << y);
      CHECK(test::is_shade_of(img.at(x, y), object_colour(1)));
      CHECK_FALSE(test::is_shade_of(img.at(x, y), object_colour(0)));
    }
  const std::pair<int, int> outside[] = {{0, 0}, {63, 0}, {0, 47}, {63, 47}, {32, 14}, {42, 24}};
  for (auto [x, y] : outside) {
    INFO("pixel " << x << ", " << y);
    CHECK(img.at(x, y) == kPreviewBackground);
  }
  // Lambert with the light at the upper left: that side of the disc is brighter.
  const auto sum = [](const Rgb& p) { return p[0] + p[1] + p[2]; };
  CHECK(sum(img.at(29, 21)) > sum(img.at(34, 26)) + 30);
  // The same picture as rendered in memory.
  CHECK(img.pixels == render_preview_image(one, c, 64, 48).pixels);

  SECTION("the nearer particle wins, whatever the drawing order") {
    const std::vector<Vec3> two = {c.look_at, c.look_at + Vec3(0, 0, 0.5)};
    for (bool near_first : {true, false}) {
      std::vector<Vec3> xs = two;
      std::vector<std::uint32_t> ids = {1, 0};  // object 0 is the nearer one
      if (near_first) {
        std::swap(xs[0], xs[1]);
        std::swap(ids[0], ids[1]);
      }
      const RgbImage im = render_preview_image(FrameView{xs, {}, ids, {}, 0, 0}, c, 64, 48);
      INFO("near first: " << near_first);
      CHECK(test::is_shade_of(im.at(32, 24), object_colour(0)));
    }
  }
}

TEST_CASE("preview: the default camera frames the whole grid box from the front, above",
          "[output]") {
  const Vec3 lo(0, 0, 0), hi(1, 0.5, 2);
  const PreviewCamera c = default_camera(lo, hi);
  CHECK(c.position.z() > hi.z());
  CHECK(c.position.y() > 0.5 * (lo.y() + hi.y()));
  CHECK((c.look_at - 0.5 * (lo + hi)).norm() < 1e-12);
  double farthest = 0;  // largest distance of a corner from the centre, in half-heights
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3 p((corner & 1) ? hi.x() : lo.x(), (corner & 2) ? hi.y() : lo.y(),
                 (corner & 4) ? hi.z() : lo.z());
    const Projection q = project(c, 320, 240, p);
    INFO("corner " << p.transpose());
    CHECK(q.visible(320, 240));
    farthest = std::max({farthest, std::abs(q.x - 160) / 120, std::abs(q.y - 120) / 120});
  }
  CHECK(farthest < 1);    // inside, for pictures at least as wide as tall
  CHECK(farthest > 0.8);  // and filling the picture, not a speck in the middle
  CHECK_THROWS_AS(default_camera(hi, lo), std::invalid_argument);

  // A random frame inside the box shows both objects and the background.
  RandomFrame f(1000);
  for (Vec3& x : f.x) x = lo + (x.array() + 1.0).matrix().cwiseProduct(hi - lo) / 3.0;
  PreviewCamera big = c;
  big.particle_radius = 0.02;  // about 2 pixels
  const auto png = test::temp_dir("preview_default") / "frame.png";
  render_preview(png, f.view(), big, 320, 240);
  const RgbImage img = read_png(png);
  int object0 = 0, object1 = 0, background = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      object0 += test::is_shade_of(img.at(x, y), object_colour(0));
      object1 += test::is_shade_of(img.at(x, y), object_colour(1));
      background += img.at(x, y) == kPreviewBackground;
    }
  CHECK(object0 > 1000);
  CHECK(object1 > 1000);
  CHECK(background > 320 * 240 / 2);
}
