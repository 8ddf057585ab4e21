#pragma once
/// \file Houdini's classic binary geometry (.bgeo, "Bgeo" version 5) for point clouds.
///
/// The layout Partio reads and writes, all numbers big-endian: the magic "Bgeo", 'V', ten
/// int32 (version 5, points, primitives, point groups, primitive groups, point, vertex,
/// primitive and detail attribute counts), one definition per point attribute (int16 name
/// length, name, int16 size, int32 type: 0 float, 1 int, 5 vector; then `size` int32
/// defaults), then per point P as 4 floats (x y z w) followed by the attribute values, and
/// the trailer bytes 0x00 0xff. No primitives, groups or detail attributes are written.

#include <cstddef>
#include <filesystem>
#include <vector>

#include "engine/io/frame_view.h"

namespace mpm {

/// Writes `frame` as an uncompressed classic .bgeo: point attributes P (x y z, w = 1),
/// v (vector, 3 floats), object_id (int) and J (float). Writes `<file>.tmp` and renames it,
/// so the file is whole or absent. Throws std::invalid_argument if the spans differ in
/// length, there are more than INT32_MAX points or an object id exceeds INT32_MAX, and
/// std::runtime_error if the file cannot be written.
void write_bgeo(const std::filesystem::path& file, const FrameView& frame);

/// A .bgeo file read back: the point attributes write_bgeo writes.
struct BgeoPoints {
  std::vector<float> position;  ///< N x 3, row-major (P without w).
  std::vector<float> velocity;  ///< N x 3, row-major (attribute v).
  std::vector<int> object_id;   ///< N.
  std::vector<float> J;         ///< N.
  std::vector<int> id;          ///< N: the stable particle id (Houdini's `id` attribute).

  /// Number of points.
  std::size_t size() const { return object_id.size(); }
};

/// Reads a file written by write_bgeo. Throws std::runtime_error if the magic, version,
/// attribute table, point weights, trailer or length differ from what write_bgeo writes.
BgeoPoints read_bgeo(const std::filesystem::path& file);

}  // namespace mpm
