#pragma once
/// \file The parsed, validated scene as plain data. Only load_scene.cpp knows it came from YAML.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "engine/core/error.h"
#include "engine/core/math.h"
#include "materials/material.h"

namespace mpm {

/// How particle velocities are carried to and from the grid (mls: APIC's transfer with the
/// stress folded into the affine momentum, Hu et al. 2018).
enum class Transfer { apic, pic, flip, mls };

/// Which B-spline carries particle data to the grid and back (engine/step/kernels.h).
enum class Kernel { linear, quadratic, cubic };

/// What a wall does to grid velocities that point into it.
enum class Boundary {
  sticky,    ///< Velocity set to zero.
  slip,      ///< Normal component removed; tangential slides with Coulomb friction.
  separate,  ///< Only an inward normal component is removed; bodies may lift off.
};

/// Where walls and colliders act (engine/step/walls.h, engine/step/contact.h).
enum class Contact {
  nodes,      ///< On the grid nodes inside a wall: depends on where the wall lies between rows.
  particles,  ///< At the particles touching a wall, solved on the grid velocities there.
};

/// Time stepping and global physics.
/// How the stress force is integrated (engine/step/domain_quadrature.h).
enum class Quadrature {
  point,   ///< At each particle, f_i = sum_p V_p sigma_p grad w_i(x_p).
  domain,  ///< Over each particle's domain, with a linear pressure from nodal fits.
};

struct SimulationDesc {
  int frames = 120;                   ///< Frames written after the initial state.
  double frame_dt = 1.0 / 24.0;       ///< Seconds between frames.
  std::optional<double> dt;           ///< Fixed substep (s), or the cap when cfl is set.
  std::optional<double> cfl;          ///< CFL number for the adaptive substep.
  Vec3 gravity{0, -9.81, 0};          ///< m/s^2.
  Transfer transfer = Transfer::apic; ///< Transfer scheme.
  double flip_blend = 0.95;           ///< FLIP fraction when transfer is flip.
  Kernel kernel = Kernel::quadratic;  ///< Interpolation kernel.
  double damping = 0;                 ///< Grid velocity damping rate, 1/s (0: none).
  std::uint64_t seed = 1;             ///< Seed for particle sampling.
  int reorder_every = 8;              ///< Substeps between particle reorders by cell (0: never).
  bool simd = true;                   ///< Float SIMD transfers (true, the default); false: the scalar double path.
  Contact contact = Contact::particles;  ///< Where walls and colliders act.
  int contact_iterations = 12;        ///< Most contact solve iterations per substep (particles).
  /// The spectral radius the contact solve's Chebyshev acceleration assumes (0: none).
  double contact_spectral_radius = 0.95;
  Quadrature quadrature = Quadrature::point;  ///< How the stress force is integrated.
  FileLoc quadrature_loc;                     ///< Where `quadrature` is written.
};

/// Where particles go inside each grid cell.
/// The stress an object starts with.
enum class InitialStress {
  none,     ///< Unloaded: F = I.
  gravity,  ///< At rest under its own weight, a layer with a flat top (settle_under_gravity).
};

enum class Sampling {
  jittered,  ///< One random point per sub-cell of an n^3 split (random in the cell otherwise).
  regular,   ///< The sub-cell centres: a lattice (particles_per_cell must be a cube).
};

/// A regular background grid.
struct GridDesc {
  Vec3 origin{0, 0, 0};  ///< Minimum corner, m.
  Vec3 max{1, 1, 1};     ///< Maximum corner, m.
  Vec3i dims{100, 100, 100};  ///< Cells per axis.
  /// A corner of the lattice particles are sampled on (cells of size h from it); the grid's
  /// origin when unset. Fixing it while the grid moves keeps every particle in place.
  std::optional<Vec3> sampling_origin;
  int buffer = 3;        ///< Cells lining the boundary that particles never enter.
  bool float_nodes = false;  ///< Node mass, momentum and velocity stored in float (precision).
  FileLoc loc;           ///< Where `dims` is written (for errors about the grid's size).

  /// Cell size per axis, m.
  Vec3 spacing() const { return (max - origin).cwiseQuotient(dims.cast<Real>()); }
};

/// One body: a closed mesh filled with particles of one material.
struct ObjectDesc {
  std::string name;                ///< Unique name.
  std::filesystem::path mesh;      ///< Absolute or scene-relative path, resolved by the loader.
  Vec3 scale{1, 1, 1};             ///< Scale per axis, applied first.
  Vec3 rotation_deg{0, 0, 0};      ///< Degrees about x, then y, then z.
  Vec3 offset{0, 0, 0};            ///< Where the mesh origin goes, m.
  Vec3 velocity{0, 0, 0};          ///< Initial velocity of the centroid, m/s.
  Vec3 angular_velocity{0, 0, 0};  ///< Initial spin about the centroid, rad/s.
  Mat3 velocity_gradient = Mat3::Zero();  ///< Initial dv/dx about the centroid (adds to spin), 1/s.
  std::optional<double> mass;      ///< Total mass, kg (or density).
  std::optional<double> density;   ///< kg/m^3 (or mass).
  int particles_per_cell = 8;      ///< Particles per grid cell.
  Sampling sampling = Sampling::jittered;  ///< Placement inside each cell.
  InitialStress initial_stress = InitialStress::none;  ///< The stress it starts with.
  std::string material;            ///< Name in the material registry.
  ParamValues params;              ///< The material's parameters, validated.
  FileLoc loc;                     ///< Where the object starts in the scene file.
  FileLoc mesh_loc;                ///< Where its mesh path is written.
  FileLoc placement_loc;           ///< Where its offset, scale or rotation was --set, else loc.
};

/// A keyframe of a moving wall: its offset from the start position at time t.
struct WallKey {
  double t = 0;                ///< Time, s.
  Vec3 offset{0, 0, 0};        ///< Displacement from the scene position, m.
};

/// A wall acting on grid velocities: a plane, a box, or a solid collider (mesh, sphere, vdb).
struct WallDesc {
  /// plane, box: half-spaces; mesh, sphere, vdb: solid colliders given by a signed distance.
  enum class Shape { plane, box, mesh, sphere, vdb };
  Shape shape = Shape::plane;      ///< Which kind of wall.
  Vec3 point{0, 0, 0};             ///< Plane: a point on it, m.
  Vec3 normal{0, 1, 0};            ///< Plane: unit normal pointing into the free side.
  Vec3 min{0, 0, 0};               ///< Box: minimum corner, m.
  Vec3 max{1, 1, 1};               ///< Box: maximum corner, m.
  std::filesystem::path file;      ///< Mesh or vdb: absolute or scene-relative path, resolved.
  FileLoc file_loc;                ///< Where `file` is written.
  std::string grid_name;           ///< Vdb: name of the level set grid in the file.
  FileLoc grid_loc;                ///< Where `grid` is written.
  Vec3 scale{1, 1, 1};             ///< Mesh: scale per axis, applied first.
  Vec3 rotation_deg{0, 0, 0};      ///< Mesh: degrees about x, then y, then z.
  Vec3 offset{0, 0, 0};            ///< Mesh: where the mesh origin goes (its spin centre), m.
  Vec3 center{0, 0, 0};            ///< Sphere: centre, m.
  double radius = 0;               ///< Sphere: radius, m.
  Vec3 angular_velocity{0, 0, 0};  ///< Collider spin about its offset or centre, rad/s.
  Boundary boundary = Boundary::sticky;  ///< Condition.
  double friction = 0;             ///< Coulomb coefficient (slip and separate).
  Vec3 velocity{0, 0, 0};          ///< Constant velocity of the wall (it moves), m/s.
  std::vector<WallKey> path;       ///< Or keyframes, linear in between, held after the last.
  FileLoc loc;                     ///< Where the wall starts in the scene file.
};

/// File formats a run can write per frame (mesh: a triangle surface per object as PLY; vdb:
/// one OpenVDB file of level sets per frame).
enum class Format { hdf5, bgeo, ply, png, mesh, vdb };

/// How the `mesh` and `vdb` formats turn an object's particles into a surface
/// (engine/io/surface.h). Lengths are in the object's particle spacing s = (h^3 / ppc)^(1/3).
struct SurfaceDesc {
  double radius = 1.0;     ///< Sphere radius around each particle, in s.
  double voxel = 0.6;      ///< Level set voxel size, in s.
  int smoothing = 6;       ///< Mean-value flow passes (3^3 box filter) on the level set.
  bool normals = true;     ///< Per-vertex normals in the mesh PLY.
  bool density = false;    ///< vdb: also a `<object>_density` fog volume per object.
  bool velocity = false;   ///< vdb: also a `<object>_velocity` grid per object.
};

/// A camera for PNG previews.
struct CameraDesc {
  Vec3 position{0.5, 0.7, 2.5};  ///< Eye position, m.
  Vec3 look_at{0.5, 0.4, 0.5};   ///< Point at the image centre, m.
  double fov_deg = 40;           ///< Vertical field of view, degrees.
};

/// Where and what to write.
struct OutputDesc {
  std::filesystem::path directory = "output";  ///< Frame folder (absolute or cwd-relative).
  FileLoc loc;                                 ///< Where the directory is written.
  std::vector<Format> formats{Format::hdf5};   ///< Formats written per frame.
  std::optional<CameraDesc> camera;            ///< PNG camera; default frames the grid.
  Vec2i preview_size{640, 480};                ///< PNG width and height, pixels.
  bool checkpoint = true;                      ///< Keep DIR/checkpoint.h5 for --resume.
  /// Wall-clock seconds between checkpoints (0: after every frame); one is also written at
  /// the end of the run, when it is stopped by a signal, and after an observer's error.
  double checkpoint_interval = 15;
  SurfaceDesc surface;                         ///< Surfaces for the mesh and vdb formats.
};

/// A whole scene, validated.
struct SceneDesc {
  std::filesystem::path file;      ///< The scene file it was read from.
  SimulationDesc simulation;       ///< Time stepping and physics.
  GridDesc grid;                   ///< Background grid.
  std::vector<ObjectDesc> objects; ///< Bodies.
  std::vector<WallDesc> walls;     ///< Walls.
  OutputDesc output;               ///< Output.
  std::vector<std::filesystem::path> plugins;  ///< Material plugins loaded for this scene.
};

}  // namespace mpm
