#pragma once
/// \file Render-ready surfaces from particles: per object a narrow-band level set (OpenVDB),
/// smoothed, meshed into a closed triangle surface; written as PLY meshes and VDB files.
///
/// The pipeline for one object with particle spacing s (SurfaceDesc holds the factors):
///  1. every particle becomes a sphere of radius `radius` s, rasterised into a narrow-band
///     level set of voxel size `voxel` s (openvdb::tools::ParticlesToLevelSet; Museth 2013,
///     "VDB", ACM TOG, doi:10.1145/2487228.2487235);
///  2. `smoothing` passes of mean-value flow (a 3^3 box filter, openvdb::tools::LevelSetFilter,
///     which renormalises the band after each) flatten the bumps of single particles;
///  3. the level set is offset inwards by the distance from the outer particles' spheres to
///     the body's true boundary (kSurfaceInset, below), so the surface encloses the object's
///     volume rather than the volume of the spheres;
///  4. openvdb::tools::volumeToMesh (no adaptivity) gives quads, each split into two
///     triangles: a closed surface, every edge shared by two triangles.
/// Positions are taken in float, as frame files store them, so surfaces built during a run
/// and afterwards from its HDF5 frames (`mpm surface`) are the same bytes.

#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "engine/io/output.h"
#include "engine/io/ply.h"
#include "engine/scene/scene_desc.h"

namespace mpm {

/// How far inside the smoothed spheres' surface the body's boundary lies, in particle spacings
/// beyond the sphere radius: the surface is moved in by (radius - kSurfaceInset) s. The outer
/// particles lie about half a spacing inside the boundary (sampled in the cells the mesh
/// fills); measured on the cube, sphere and bunny at the defaults (docs/output.md).
constexpr double kSurfaceInset = 0.5;

/// What a surface is built for: an object's name and its particle spacing.
struct SurfaceObject {
  std::string name;    ///< The object's name (file and grid names).
  double spacing = 0;  ///< Particle spacing s = (cell volume / particles per cell)^(1/3), m.
};

/// Each object's name and particle spacing, (cell volume / particles_per_cell)^(1/3).
std::vector<SurfaceObject> surface_objects(const SceneDesc& scene);

/// The triangle surface of the particles of object `object` in `frame` (empty if the object
/// has no particles). Throws std::runtime_error if OpenVDB fails.
PlyMesh build_surface(const FrameData& frame, int object, double spacing, const SurfaceDesc& desc);

/// Writes frame `frame`'s surfaces into `dir`: with `mesh`, `frame_NNNNN_<object>.ply` per
/// object (write_ply_mesh); with `vdb`, one `frame_NNNNN.vdb` holding per object a level set
/// grid named after it (class level set) and, as `desc` asks, `<object>_density` (fog volume,
/// 0 outside to 1 inside) and `<object>_velocity` (the nearest particle's velocity, m/s).
/// Every file is written to a temporary name and renamed. Throws std::runtime_error.
void write_surfaces(const std::filesystem::path& dir, const FrameData& frame,
                    const std::vector<SurfaceObject>& objects, const SurfaceDesc& desc, bool mesh,
                    bool vdb);

/// Name of object `name`'s mesh of frame `frame` in `dir`: frame_00000_<name>.ply.
std::filesystem::path surface_mesh_path(const std::filesystem::path& dir, int frame,
                                        const std::string& name);

/// Name of frame `frame`'s VDB file in `dir`: frame_00000.vdb.
std::filesystem::path surface_vdb_path(const std::filesystem::path& dir, int frame);

/// `mpm surface DIR`: builds the `mesh` and/or `vdb` files of every frame_NNNNN.h5 in `dir`
/// from the objects and surface settings in DIR/report.yaml; returns the frames done.
/// Throws SceneError (exit code 2) if `dir` has no frames or no usable report.yaml.
int surfaces_from_run(const std::filesystem::path& dir, bool mesh, bool vdb);

}  // namespace mpm
