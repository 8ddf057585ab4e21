#include "engine/io/bgeo.h"

#include <bit>
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

/// Houdini attribute type codes of the classic format.
enum HoudiniType : std::int32_t { kFloat = 0, kInt = 1, kVector = 5 };

/// A point attribute definition as write_bgeo writes it.
struct AttributeDef {
  const char* name;    ///< Attribute name as Houdini shows it.
  std::uint16_t size;  ///< Number of 32-bit values per point.
  std::int32_t type;   ///< HoudiniType code.
};

/// The point attributes after P, in file order.
constexpr AttributeDef kAttributes[] = {
    {"v", 3, kVector}, {"object_id", 1, kInt}, {"J", 1, kFloat}, {"id", 1, kInt}};

/// 32-bit values per point: P (4) then every attribute.
constexpr std::size_t kValuesPerPoint = 4 + 3 + 1 + 1 + 1;

/// Appends the low `bytes` bytes of `value` to `out`, most significant first.
void put_be(std::string& out, std::uint32_t value, int bytes = 4) {
  for (int b = bytes - 1; b >= 0; --b) out.push_back(static_cast<char>((value >> (8 * b)) & 0xffu));
}

/// Appends `value` rounded to float, big-endian.
void put_float(std::string& out, double value) {
  put_be(out, std::bit_cast<std::uint32_t>(static_cast<float>(value)));
}

/// Reads big-endian numbers from a byte string, throwing on a read past the end.
class BeReader {
 public:
  /// Reads `data`, the contents of `file` (named in errors).
  BeReader(const std::string& data, const std::filesystem::path& file) : d_(data), file_(file) {}
  /// The next `bytes` (1 to 4) bytes as an unsigned number.
  std::uint32_t u(int bytes) {
    if (d_.size() - pos_ < static_cast<std::size_t>(bytes)) fail("file ends early");
    std::uint32_t v = 0;
    for (int b = 0; b < bytes; ++b) v = (v << 8) | static_cast<unsigned char>(d_[pos_++]);
    return v;
  }
  /// The next int32.
  std::int32_t i32() { return std::bit_cast<std::int32_t>(u(4)); }
  /// The next float.
  float f32() { return std::bit_cast<float>(u(4)); }
  /// The next `n` bytes.
  std::string str(std::size_t n) {
    if (d_.size() - pos_ < n) fail("file ends early");
    std::string s = d_.substr(pos_, n);
    pos_ += n;
    return s;
  }
  /// Bytes not yet read.
  std::size_t left() const { return d_.size() - pos_; }
  /// Throws std::runtime_error naming the file, `why` and the position.
  [[noreturn]] void fail(const std::string& why) const {
    throw std::runtime_error("bgeo file '" + file_.string() + "': " + why + " (at byte " +
                             std::to_string(pos_) + ")");
  }

 private:
  const std::string& d_;
  const std::filesystem::path& file_;
  std::size_t pos_ = 0;
};

}  // namespace

void write_bgeo(const std::filesystem::path& file, const FrameView& frame) {
  check_frame_view(frame);
  constexpr auto kMax = static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max());
  const std::size_t n = frame.size();
  if (n > kMax) throw std::invalid_argument("too many points for bgeo: " + std::to_string(n));
  for (std::uint32_t id : frame.object_id)
    if (id > kMax)
      throw std::invalid_argument("object id " + std::to_string(id) + " does not fit a bgeo int");
  for (std::uint32_t id : frame.particle_id)
    if (id > kMax)
      throw std::invalid_argument("particle id " + std::to_string(id) + " does not fit a bgeo int");

  std::string buf = "Bgeo";
  buf.push_back('V');
  const std::uint32_t header[] = {5,  // version
                                  static_cast<std::uint32_t>(n),
                                  0,  // primitives
                                  0,  // point groups
                                  0,  // primitive groups
                                  static_cast<std::uint32_t>(std::size(kAttributes)),
                                  0,   // vertex attributes
                                  0,   // primitive attributes
                                  0};  // detail attributes
  for (std::uint32_t h : header) put_be(buf, h);
  for (const AttributeDef& a : kAttributes) {
    const std::string name = a.name;
    put_be(buf, static_cast<std::uint32_t>(name.size()), 2);
    buf += name;
    put_be(buf, a.size, 2);
    put_be(buf, static_cast<std::uint32_t>(a.type));
    for (int k = 0; k < a.size; ++k) put_be(buf, 0);  // default value
  }

  buf.reserve(buf.size() + n * kValuesPerPoint * 4 + 2);
  for (std::size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) put_float(buf, frame.position[i][a]);
    put_float(buf, 1.0);  // homogeneous w
    for (int a = 0; a < 3; ++a) put_float(buf, frame.velocity[i][a]);
    put_be(buf, frame.object_id[i]);
    put_float(buf, frame.J[i]);
    put_be(buf, frame.particle_id[i]);
  }
  // No primitives and no detail attributes follow; then the "extra" section markers.
  buf.push_back('\x00');
  buf.push_back('\xff');
  write_file_whole(file, buf);
}

BgeoPoints read_bgeo(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open bgeo file '" + file.string() + "'");
  const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw std::runtime_error("cannot read bgeo file '" + file.string() + "'");

  BeReader r(data, file);
  if (r.str(4) != "Bgeo") r.fail("magic is not 'Bgeo'");
  if (r.str(1) != "V") r.fail("no 'V' after the magic");
  const std::int32_t version = r.i32();
  if (version != 5) r.fail("version " + std::to_string(version) + ", expected 5");
  const std::int32_t points = r.i32();
  if (points < 0) r.fail("negative point count");
  const char* counts[] = {"primitives",       "point groups",      "primitive groups",
                          "point attributes", "vertex attributes", "primitive attributes",
                          "detail attributes"};
  for (int c = 0; c < 7; ++c) {
    const std::int32_t want = c == 3 ? static_cast<std::int32_t>(std::size(kAttributes)) : 0;
    const std::int32_t got = r.i32();
    if (got != want)
      r.fail(std::string(counts[c]) + ": " + std::to_string(got) + ", expected " +
             std::to_string(want));
  }
  for (const AttributeDef& a : kAttributes) {
    const std::string name = r.str(r.u(2));
    if (name != a.name) r.fail("attribute '" + name + "', expected '" + a.name + "'");
    if (r.u(2) != a.size || r.i32() != a.type) r.fail("attribute '" + name + "' has another type");
    for (int k = 0; k < a.size; ++k)
      if (r.i32() != 0) r.fail("attribute '" + name + "' has a non-zero default");
  }

  const auto n = static_cast<std::size_t>(points);
  if (r.left() != n * kValuesPerPoint * 4 + 2)
    r.fail(std::to_string(n) + " points need " + std::to_string(n * kValuesPerPoint * 4 + 2) +
           " more bytes, found " + std::to_string(r.left()));
  BgeoPoints p;
  p.position.resize(3 * n);
  p.velocity.resize(3 * n);
  p.object_id.resize(n);
  p.J.resize(n);
  p.id.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) p.position[3 * i + a] = r.f32();
    if (r.f32() != 1.0f) r.fail("point " + std::to_string(i) + " has w != 1");
    for (int a = 0; a < 3; ++a) p.velocity[3 * i + a] = r.f32();
    p.object_id[i] = r.i32();
    p.J[i] = r.f32();
    p.id[i] = r.i32();
  }
  if (r.u(1) != 0x00 || r.u(1) != 0xff) r.fail("trailer is not 0x00 0xff");
  return p;
}

}  // namespace mpm
