#pragma once
/// \file Binary PLY point clouds, one vertex per particle, and triangle meshes (Blender,
/// MeshLab, CloudCompare, ParaView, Houdini).

#include <array>
#include <cstddef>
#include <string>
#include <filesystem>
#include <vector>

#include "engine/io/frame_view.h"

namespace mpm {

/// Writes `frame` as a binary_little_endian PLY 1.0 point cloud: element vertex N with float x,
/// y, z, float vx, vy, vz, int object_id, float J, and header comments "time T" and "frame F".
/// Writes `<file>.tmp` and renames it, so the file is whole or absent. Throws
/// std::invalid_argument if the spans differ in length or an object id exceeds INT32_MAX,
/// std::runtime_error if the file cannot be written.
void write_ply(const std::filesystem::path& file, const FrameView& frame);

/// A PLY file read back: the vertex properties write_ply writes.
struct PlyPoints {
  std::vector<float> position;  ///< N x 3, row-major.
  std::vector<float> velocity;  ///< N x 3, row-major.
  std::vector<int> object_id;   ///< N.
  std::vector<float> J;         ///< N.
  std::vector<std::uint32_t> id;  ///< N: the stable particle id.
  double time = 0;              ///< Header comment "time", s.
  int frame = 0;                ///< Header comment "frame".

  /// Number of particles.
  std::size_t size() const { return object_id.size(); }
};

/// Reads a file written by write_ply. Throws std::runtime_error if the file cannot be read or
/// its header or size differs in any way from what write_ply writes.
PlyPoints read_ply(const std::filesystem::path& file);

/// A triangle mesh in float, as PLY stores it.
struct PlyMesh {
  std::vector<std::array<float, 3>> vertices;  ///< Positions, m.
  std::vector<std::array<float, 3>> normals;   ///< Unit normals per vertex, or empty.
  std::vector<std::array<int, 3>> triangles;   ///< Vertex indices, counter-clockwise from outside.
};

/// Writes `mesh` as a binary_little_endian PLY 1.0 mesh: element vertex with float x, y, z
/// (and nx, ny, nz if it has normals), element face with `property list uchar int
/// vertex_indices`, and `comments` as header comments. Writes `<file>.tmp` and renames it.
/// Throws std::invalid_argument if normals and vertices differ in number or an index is out
/// of range, std::runtime_error if the file cannot be written.
void write_ply_mesh(const std::filesystem::path& file, const PlyMesh& mesh,
                    const std::vector<std::string>& comments = {});

/// Reads a file written by write_ply_mesh. Throws std::runtime_error if the file cannot be
/// read or differs from that layout.
PlyMesh read_ply_mesh(const std::filesystem::path& file);

}  // namespace mpm
