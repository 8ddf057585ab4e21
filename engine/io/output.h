#pragma once
/// \file Frame files (HDF5) and the run report (YAML), written by an observer.

#include <chrono>
#include <filesystem>
#include <vector>

#include "engine/io/frame_view.h"
#include "engine/run/run.h"
#include "engine/scene/scene_desc.h"

namespace mpm {

/// One frame's HDF5 datasets in the file's types, row k the particle with id k: what
/// write_frame_hdf5 writes and read_frame_hdf5 reads back.
struct FrameData {
  std::vector<float> position;    ///< N x 3, row-major, m.
  std::vector<float> velocity;    ///< N x 3, row-major, m/s.
  std::vector<int> object_id;     ///< N.
  std::vector<float> J;           ///< N, det F.
  std::vector<std::uint32_t> id;  ///< N: the stable particle id.
  double time = 0;                ///< Attribute "time", s.
  int frame = 0;                  ///< Attribute "frame".
  /// Number of particles.
  std::size_t size() const { return object_id.size(); }
};

/// Writes `rows` as HDF5 datasets position (N x 3), velocity (N x 3), object_id (N), J (N),
/// id (N), with attributes time and frame. Writes to a temporary name and renames, so a frame
/// file is whole or absent. Throws std::runtime_error on failure.
void write_frame_hdf5(const std::filesystem::path& file, const FrameData& rows);

/// The frame's datasets in the view's order, as write_frame_hdf5 stores them (float), so
/// surfaces built during a run match those built later from its frame files.
FrameData frame_data(const FrameView& view);

/// write_frame_hdf5 of frame_data(frame).
void write_frame_hdf5(const std::filesystem::path& file, const FrameView& frame);

/// Arrays a FrameView can point into when the particles are not in id order.
struct FrameArrays {
  std::vector<Vec3> x;                 ///< Position, by id.
  std::vector<Vec3> v;                 ///< Velocity, by id.
  std::vector<std::uint32_t> object;   ///< Object index, by id.
  std::vector<Real> J;                 ///< det F, by id.
  std::vector<std::uint32_t> id;       ///< 0 .. N-1.
};

/// The particles as a frame in the order of their stable ids (Particles::id), whatever order
/// the reorder stage left them in, so every frame lists the same particle at the same row.
/// Points into `p` where it is already in id order, otherwise into `arrays`.
FrameView frame_in_id_order(const Particles& p, Real time, int frame, FrameArrays& arrays);

/// Reads a file written by write_frame_hdf5. Throws std::runtime_error on failure.
FrameData read_frame_hdf5(const std::filesystem::path& file);

/// Name of frame `frame`'s file in `dir`: frame_00000.h5.
std::filesystem::path frame_path(const std::filesystem::path& dir, int frame);

/// Makes `dir` ready for a new run: creates it, checks it can be written, and refuses
/// (std::runtime_error naming the folder) if it already holds frames or a report, unless
/// `force`, which deletes them first.
void prepare_output_directory(const std::filesystem::path& dir, bool force);

/// prepare_output_directory's refusal alone, changing nothing: throws if `dir` holds frames or
/// a report and not `force`. `mpm run` asks it before building the scene, so that a build of
/// minutes is not spent on a folder it may not write, and prepares the folder after it, so
/// that a scene that fails to build leaves an earlier run's results in place.
void check_output_directory(const std::filesystem::path& dir, bool force);

/// Writes the state a run needs to continue bit for bit (x, v, F, C, material state, time,
/// substeps, frame) in double precision to `file` (temporary name, then rename).
void write_checkpoint(const std::filesystem::path& file, const Simulation& sim, int frame);

/// Restores a checkpoint into `sim`, built from the same scene; returns its frame. Throws
/// std::runtime_error if the file is unreadable or does not match the simulation.
int restore_checkpoint(const std::filesystem::path& file, Simulation& sim);

/// Writes each frame in the scene's formats (HDF5 with an XDMF index, bgeo, PLY, PNG
/// previews, surfaces as PLY meshes and VDB level sets), a checkpoint after the first frame
/// that ends `output.checkpoint_interval` wall seconds after the last one and once more at
/// the end (see on_finish), and report.yaml at the end (with each object's particle spacing
/// and the surface settings, which `mpm surface` reads).
class FrameOutput : public Observer {
 public:
  /// Output into `dir` as `desc` asks; `resumed_frame` > 0 continues a run from that frame
  /// (its files are kept and frame 0 is not rewritten).
  FrameOutput(std::filesystem::path dir, const OutputDesc& desc, int resumed_frame = 0);
  void on_start(const Simulation& sim, int frames) override;
  void on_frame(const Simulation& sim, int frame) override;
  /// Writes the checkpoint of the last frame if it is not written yet and the state is still
  /// that frame's (a run that ended, was stopped at a frame end, or whose observer failed;
  /// not one stopped mid-frame as unstable).
  void on_stop(const Simulation& sim, const RunResult& result) override;
  /// Writes report.yaml.
  void on_finish(const Simulation& sim, const RunResult& result) override;
  /// Seconds spent writing frames so far.
  double seconds() const { return seconds_; }
  /// True when each rank writes its own particles into the HDF5 frames (more than one rank,
  /// MPM_PARALLEL_HDF5, HDF5 among the formats): on_frame runs on every rank before the
  /// frame's gather (docs/distributed.md "Output").
  bool collective() const override { return collective_; }
  /// The other formats and the checkpoint need every particle on rank 0 (the gather).
  bool reads_all_particles() const override { return !collective_ || others_; }
  /// After the gather, when collective: the other formats and the checkpoint on rank 0.
  void on_frame_gathered(const Simulation& sim, int frame) override;

 private:
  void write(const Simulation& sim, int frame);
  void write_collective(const Simulation& sim, int frame);
  void write_index(const Simulation& sim, int frame, std::size_t particles) const;
  void checkpoint(const Simulation& sim, int frame);
  std::filesystem::path dir_;
  OutputDesc desc_;
  int resumed_frame_ = 0;
  bool collective_ = false;
  bool others_ = false;  // formats besides HDF5, or the checkpoint
  int last_frame_ = -1;
  double seconds_ = 0;
  double surface_seconds_ = 0;  // of seconds_, building and writing mesh and vdb surfaces
  double checkpoint_seconds_ = 0;  // of seconds_, writing checkpoint.h5
  int checkpoint_frame_ = -1;      // the frame checkpoint.h5 holds, -1 before the first
  int checkpoints_ = 0;            // checkpoints written by this run
  Real last_frame_time_ = -1;      // sim.time() of the last frame written
  std::chrono::steady_clock::time_point last_checkpoint_ = std::chrono::steady_clock::now();
  FrameArrays scratch_;  // the frame in id order, while it is written
};

}  // namespace mpm
