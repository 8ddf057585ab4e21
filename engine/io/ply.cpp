#include "engine/io/ply.h"

#include <bit>
#include <charconv>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <system_error>

#include "engine/core/atomic_file.h"

namespace mpm {

namespace {

/// Bytes per vertex: 7 floats and two ints.
constexpr std::size_t kRecordBytes = 9 * 4;

/// The property lines write_ply writes, in order.
constexpr const char* kProperties[] = {
    "property float x",  "property float y",  "property float z",       "property float vx",
    "property float vy", "property float vz", "property int object_id", "property float J",
    "property uint id"};

/// Appends the 4 bytes of `bits` to `out`, least significant first.
void put_le(std::string& out, std::uint32_t bits) {
  for (int b = 0; b < 4; ++b) out.push_back(static_cast<char>((bits >> (8 * b)) & 0xffu));
}

/// The 4 bytes at `p` read least significant first.
std::uint32_t get_le(const char* p) {
  std::uint32_t bits = 0;
  for (int b = 0; b < 4; ++b) bits |= std::uint32_t(static_cast<unsigned char>(p[b])) << (8 * b);
  return bits;
}

/// Shortest text that reads back as exactly `value`.
std::string exact_text(double value) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, value);
  return std::string(buf, r.ptr);
}

/// Throws std::runtime_error naming `file` and `why`.
[[noreturn]] void bad(const std::filesystem::path& file, const std::string& why) {
  throw std::runtime_error("PLY file '" + file.string() + "': " + why);
}

/// Parses all of `text` as a T, or throws.
template <class T>
T parse_all(const std::filesystem::path& file, const std::string& text, const char* what) {
  T value{};
  const auto r = std::from_chars(text.data(), text.data() + text.size(), value);
  if (r.ec != std::errc() || r.ptr != text.data() + text.size())
    bad(file, std::string("bad ") + what + " '" + text + "'");
  return value;
}

/// A PLY file read whole, and a cursor over its header's lines.
struct PlyText {
  std::filesystem::path file;
  std::string data;
  std::size_t pos = 0;  ///< Start of the next header line; after end_header, of the body.

  explicit PlyText(const std::filesystem::path& f) : file(f) {
    std::ifstream in(file, std::ios::binary);
    if (!in) throw std::runtime_error("cannot open PLY file '" + file.string() + "'");
    data.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    if (in.bad()) bad(file, "read error");
  }
  /// The next header line, without its newline.
  std::string next_line() {
    const std::size_t end = data.find('\n', pos);
    if (end == std::string::npos) bad(file, "header ends early");
    std::string line = data.substr(pos, end - pos);
    pos = end + 1;
    return line;
  }
  /// Reads the next line and throws unless it is `want`.
  void expect(const std::string& want) {
    const std::string line = next_line();
    if (line != want) bad(file, "expected '" + want + "' in the header, found '" + line + "'");
  }
  /// Bytes after the header.
  std::size_t body() const { return data.size() - pos; }
};

}  // namespace

void write_ply(const std::filesystem::path& file, const FrameView& frame) {
  check_frame_view(frame);
  const std::size_t n = frame.size();
  for (std::uint32_t id : frame.object_id)
    if (id > static_cast<std::uint32_t>(std::numeric_limits<std::int32_t>::max()))
      throw std::invalid_argument("object id " + std::to_string(id) + " does not fit a PLY int");

  std::string header = "ply\nformat binary_little_endian 1.0\n";
  header += "comment time " + exact_text(frame.time) + "\n";
  header += "comment frame " + std::to_string(frame.frame) + "\n";
  header += "element vertex " + std::to_string(n) + "\n";
  for (const char* p : kProperties) header += std::string(p) + "\n";
  header += "end_header\n";

  std::string bytes = std::move(header);
  bytes.reserve(bytes.size() + n * kRecordBytes);
  for (std::size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a)
      put_le(bytes, std::bit_cast<std::uint32_t>(float(frame.position[i][a])));
    for (int a = 0; a < 3; ++a)
      put_le(bytes, std::bit_cast<std::uint32_t>(float(frame.velocity[i][a])));
    put_le(bytes, frame.object_id[i]);
    put_le(bytes, std::bit_cast<std::uint32_t>(float(frame.J[i])));
    put_le(bytes, frame.particle_id[i]);
  }
  write_file_whole(file, bytes);
}

PlyPoints read_ply(const std::filesystem::path& file) {
  // The header: lines up to and including "end_header\n".
  PlyText ply(file);
  auto expect = [&](const std::string& want) { ply.expect(want); };
  auto value_after = [&](const std::string& prefix) {
    const std::string line = ply.next_line();
    if (line.rfind(prefix, 0) != 0)
      bad(file, "expected '" + prefix + "...' in the header, found '" + line + "'");
    return line.substr(prefix.size());
  };

  PlyPoints p;
  expect("ply");
  expect("format binary_little_endian 1.0");
  p.time = parse_all<double>(file, value_after("comment time "), "time");
  p.frame = parse_all<int>(file, value_after("comment frame "), "frame");
  const auto n = parse_all<std::size_t>(file, value_after("element vertex "), "vertex count");
  for (const char* prop : kProperties) expect(prop);
  expect("end_header");

  const std::size_t body = ply.body();
  if (n > body / kRecordBytes || body != n * kRecordBytes)
    bad(file, std::to_string(n) + " vertices need " + std::to_string(n * kRecordBytes) +
                  " bytes after the header, found " + std::to_string(body));

  p.position.resize(3 * n);
  p.velocity.resize(3 * n);
  p.object_id.resize(n);
  p.J.resize(n);
  p.id.resize(n);
  const char* r = ply.data.data() + ply.pos;
  for (std::size_t i = 0; i < n; ++i, r += kRecordBytes) {
    for (int a = 0; a < 3; ++a) p.position[3 * i + a] = std::bit_cast<float>(get_le(r + 4 * a));
    for (int a = 0; a < 3; ++a)
      p.velocity[3 * i + a] = std::bit_cast<float>(get_le(r + 12 + 4 * a));
    p.object_id[i] = std::bit_cast<std::int32_t>(get_le(r + 24));
    p.J[i] = std::bit_cast<float>(get_le(r + 28));
    p.id[i] = get_le(r + 32);
  }
  return p;
}

void write_ply_mesh(const std::filesystem::path& file, const PlyMesh& mesh,
                    const std::vector<std::string>& comments) {
  const std::size_t n = mesh.vertices.size();
  const bool normals = !mesh.normals.empty();
  if (normals && mesh.normals.size() != n)
    throw std::invalid_argument("PLY mesh: " + std::to_string(mesh.normals.size()) +
                                " normals for " + std::to_string(n) + " vertices");
  for (const auto& t : mesh.triangles)
    for (int v : t)
      if (v < 0 || static_cast<std::size_t>(v) >= n)
        throw std::invalid_argument("PLY mesh: vertex index " + std::to_string(v) +
                                    " out of range (" + std::to_string(n) + " vertices)");
  std::string bytes = "ply\nformat binary_little_endian 1.0\n";
  for (const std::string& c : comments) bytes += "comment " + c + "\n";
  bytes += "element vertex " + std::to_string(n) + "\n";
  bytes += "property float x\nproperty float y\nproperty float z\n";
  if (normals) bytes += "property float nx\nproperty float ny\nproperty float nz\n";
  bytes += "element face " + std::to_string(mesh.triangles.size()) + "\n";
  bytes += "property list uchar int vertex_indices\nend_header\n";
  bytes.reserve(bytes.size() + n * (normals ? 24 : 12) + mesh.triangles.size() * 13);
  for (std::size_t i = 0; i < n; ++i) {
    for (float c : mesh.vertices[i]) put_le(bytes, std::bit_cast<std::uint32_t>(c));
    if (normals)
      for (float c : mesh.normals[i]) put_le(bytes, std::bit_cast<std::uint32_t>(c));
  }
  for (const auto& t : mesh.triangles) {
    bytes.push_back(3);
    for (int v : t) put_le(bytes, static_cast<std::uint32_t>(v));
  }
  write_file_whole(file, bytes);
}

PlyMesh read_ply_mesh(const std::filesystem::path& file) {
  PlyText ply(file);
  auto next_line = [&]() { return ply.next_line(); };
  auto expect = [&](const std::string& want) { ply.expect(want); };
  expect("ply");
  expect("format binary_little_endian 1.0");
  std::string line = next_line();
  while (line.rfind("comment ", 0) == 0) line = next_line();
  if (line.rfind("element vertex ", 0) != 0) bad(file, "expected 'element vertex N'");
  const auto n = parse_all<std::size_t>(file, line.substr(15), "vertex count");
  expect("property float x");
  expect("property float y");
  expect("property float z");
  line = next_line();
  const bool normals = line == "property float nx";
  if (normals) {
    expect("property float ny");
    expect("property float nz");
    line = next_line();
  }
  if (line.rfind("element face ", 0) != 0) bad(file, "expected 'element face N'");
  const auto f = parse_all<std::size_t>(file, line.substr(13), "face count");
  expect("property list uchar int vertex_indices");
  expect("end_header");
  const std::size_t vertex_bytes = normals ? 24 : 12;
  const std::size_t body = ply.body();
  if (n > body / vertex_bytes || f > body / 13 || body != n * vertex_bytes + f * 13)
    bad(file, std::to_string(n) + " vertices and " + std::to_string(f) +
                  " triangles do not fill the " + std::to_string(body) + " bytes after the header");
  PlyMesh m;
  m.vertices.resize(n);
  if (normals) m.normals.resize(n);
  const char* r = ply.data.data() + ply.pos;
  for (std::size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) m.vertices[i][a] = std::bit_cast<float>(get_le(r + 4 * a));
    if (normals)
      for (int a = 0; a < 3; ++a) m.normals[i][a] = std::bit_cast<float>(get_le(r + 12 + 4 * a));
    r += vertex_bytes;
  }
  m.triangles.resize(f);
  for (std::size_t i = 0; i < f; ++i, r += 13) {
    if (*r != 3) bad(file, "face " + std::to_string(i) + " is not a triangle");
    for (int a = 0; a < 3; ++a) {
      const std::uint32_t v = get_le(r + 1 + 4 * a);
      if (v >= n) bad(file, "face " + std::to_string(i) + " names vertex " + std::to_string(v));
      m.triangles[i][a] = static_cast<int>(v);
    }
  }
  return m;
}

}  // namespace mpm
