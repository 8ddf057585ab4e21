#include "engine/io/output.h"

#include <hdf5.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <type_traits>

#include "engine/core/atomic_file.h"
#include "engine/core/hdf5_handle.h"
#include "engine/io/bgeo.h"
#include "engine/io/ply.h"
#include "engine/io/preview.h"
#include "engine/io/surface.h"
#include "engine/io/xdmf.h"
#include "engine/parallel/comm.h"
#include "engine/parallel/domain.h"
#include "engine/parallel/frame_hdf5.h"

namespace mpm {

namespace {

using hdf5::check;
using hdf5::write_attribute;

/// Errors are reported through exceptions; keep HDF5 from printing its own error stack.
void quiet_hdf5() {
  static const bool done = [] { return H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr) >= 0; }();
  (void)done;
}

void write_dataset(hid_t file, const char* name, hid_t file_type, hid_t mem_type, int rank,
                   const hsize_t* dims, const void* data) {
  hdf5::Handle space{H5Screate_simple(rank, dims, nullptr), H5Sclose};
  hdf5::Handle set{hdf5::create_dataset(file, name, file_type, space.id), H5Dclose};
  if (dims[0] > 0) check(H5Dwrite(set.id, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), name);
}

}  // namespace

FrameView frame_in_id_order(const Particles& p, Real time, int frame, FrameArrays& arrays) {
  const std::size_t n = p.size();
  const std::ptrdiff_t sn = static_cast<std::ptrdiff_t>(n);
  const bool par = sn >= kParallelMinItems;  // each particle writes its own row: any order
  arrays.J.resize(n);
  arrays.id.resize(n);
  bool in_order = true;
#pragma omp parallel for schedule(static) reduction(&& : in_order) if (par)
  for (std::ptrdiff_t q = 0; q < sn; ++q) in_order = in_order && p.id[q] == std::size_t(q);
  if (in_order) {
#pragma omp parallel for schedule(static) if (par)
    for (std::ptrdiff_t q = 0; q < sn; ++q) arrays.J[q] = to_real(p.F[q]).determinant();
    std::copy(p.id.begin(), p.id.end(), arrays.id.begin());
    return FrameView{p.x, p.v, p.object, arrays.J, static_cast<double>(time), frame, arrays.id};
  }
  arrays.x.resize(n);
  arrays.v.resize(n);
  arrays.object.resize(n);
#pragma omp parallel for schedule(static) if (par)
  for (std::ptrdiff_t q = 0; q < sn; ++q) {
    const std::uint32_t i = p.id[q];
    arrays.x[i] = p.x[q];
    arrays.v[i] = p.v[q];
    arrays.object[i] = p.object[q];
    arrays.J[i] = to_real(p.F[q]).determinant();
    arrays.id[i] = i;
  }
  return FrameView{arrays.x, arrays.v, arrays.object, arrays.J, static_cast<double>(time),
                   frame,    arrays.id};
}

std::filesystem::path frame_path(const std::filesystem::path& dir, int frame) {
  char name[32];
  std::snprintf(name, sizeof name, "frame_%05d.h5", frame);
  return dir / name;
}

FrameData frame_data(const FrameView& view) {
  check_frame_view(view);
  const std::size_t n = view.size();
  FrameData d;
  d.position.resize(3 * n);
  d.velocity.resize(3 * n);
  d.object_id.resize(n);
  d.J.resize(n);
  d.id.assign(view.particle_id.begin(), view.particle_id.end());
  const std::ptrdiff_t sn = static_cast<std::ptrdiff_t>(n);
#pragma omp parallel for schedule(static) if (sn >= kParallelMinItems)
  for (std::ptrdiff_t i = 0; i < sn; ++i) {
    for (int a = 0; a < 3; ++a) {
      d.position[3 * i + a] = static_cast<float>(view.position[i][a]);
      d.velocity[3 * i + a] = static_cast<float>(view.velocity[i][a]);
    }
    d.object_id[i] = static_cast<int>(view.object_id[i]);
    d.J[i] = static_cast<float>(view.J[i]);
  }
  d.time = view.time;
  d.frame = view.frame;
  return d;
}

void write_frame_hdf5(const std::filesystem::path& file, const FrameView& view) {
  write_frame_hdf5(file, frame_data(view));
}

void write_frame_hdf5(const std::filesystem::path& file, const FrameData& rows) {
  const std::size_t n = rows.size();
  if (rows.position.size() != 3 * n || rows.velocity.size() != 3 * n ||
      rows.object_id.size() != n || rows.id.size() != n)
    throw std::invalid_argument("frame rows of unequal length");
  quiet_hdf5();
  const std::filesystem::path tmp = temporary_path(file);
  {
    hdf5::Handle f{H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose};
    if (f.id < 0) throw std::runtime_error("cannot create frame file '" + tmp.string() + "'");
    const hsize_t d2[2] = {n, 3}, d1[1] = {n};
    write_dataset(f.id, "position", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, 2, d2, rows.position.data());
    write_dataset(f.id, "velocity", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, 2, d2, rows.velocity.data());
    write_dataset(f.id, "object_id", H5T_STD_I32LE, H5T_NATIVE_INT, 1, d1, rows.object_id.data());
    write_dataset(f.id, "J", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, 1, d1, rows.J.data());
    write_dataset(f.id, "id", H5T_STD_U32LE, H5T_NATIVE_UINT32, 1, d1, rows.id.data());
    write_attribute(f.id, "time", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, rows.time);
    write_attribute(f.id, "frame", H5T_STD_I32LE, H5T_NATIVE_INT, rows.frame);
    check(H5Fflush(f.id, H5F_SCOPE_GLOBAL), "frame file");
  }
  replace_file(tmp, file);
}

namespace {

template <class T>
std::vector<T> read_dataset(hid_t file, const char* name, hid_t mem_type, std::size_t width) {
  hdf5::Handle set{H5Dopen2(file, name, H5P_DEFAULT), H5Dclose};
  if (set.id < 0) throw std::runtime_error(std::string("HDF5: no dataset ") + name);
  hdf5::Handle space{H5Dget_space(set.id), H5Sclose};
  const hssize_t count = H5Sget_simple_extent_npoints(space.id);
  if (count < 0) throw std::runtime_error(std::string("HDF5: bad dataset ") + name);
  std::vector<T> out(static_cast<std::size_t>(count));
  if (count > 0 && H5Dread(set.id, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0)
    throw std::runtime_error(std::string("HDF5: cannot read ") + name);
  if (out.size() % width != 0) throw std::runtime_error(std::string("HDF5: bad shape of ") + name);
  return out;
}

template <class T>
T read_attribute(hid_t file, const char* name, hid_t mem_type) {
  hdf5::Handle attr{H5Aopen(file, name, H5P_DEFAULT), H5Aclose};
  T value{};
  if (attr.id < 0 || H5Aread(attr.id, mem_type, &value) < 0)
    throw std::runtime_error(std::string("HDF5: cannot read attribute ") + name);
  return value;
}

}  // namespace

FrameData read_frame_hdf5(const std::filesystem::path& file) {
  quiet_hdf5();
  hdf5::Handle f{H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
  if (f.id < 0) throw std::runtime_error("cannot open frame file '" + file.string() + "'");
  FrameData d;
  d.position = read_dataset<float>(f.id, "position", H5T_NATIVE_FLOAT, 3);
  d.velocity = read_dataset<float>(f.id, "velocity", H5T_NATIVE_FLOAT, 3);
  d.object_id = read_dataset<int>(f.id, "object_id", H5T_NATIVE_INT, 1);
  d.J = read_dataset<float>(f.id, "J", H5T_NATIVE_FLOAT, 1);
  d.id = read_dataset<std::uint32_t>(f.id, "id", H5T_NATIVE_UINT32, 1);
  d.time = read_attribute<double>(f.id, "time", H5T_NATIVE_DOUBLE);
  d.frame = read_attribute<int>(f.id, "frame", H5T_NATIVE_INT);
  if (d.position.size() != 3 * d.size() || d.velocity.size() != 3 * d.size() ||
      d.J.size() != d.size())
    throw std::runtime_error("frame file '" + file.string() + "' has datasets of unequal length");
  return d;
}

namespace {

/// The frames and report of an earlier run in `dir` (none if it does not exist); throws
/// (std::runtime_error naming the folder) if there are any and not `force`.
std::vector<std::filesystem::path> earlier_results(const std::filesystem::path& dir, bool force) {
  std::error_code ec;
  std::vector<std::filesystem::path> old;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    const bool frame =
        name.starts_with("frame_") && (name.ends_with(".h5") || name.ends_with(".h5.tmp"));
    if (frame || name == "report.yaml") old.push_back(e.path());
  }
  if (!old.empty() && !force)
    throw std::runtime_error("output folder '" + dir.string() +
                             "' already holds results of an "
                             "earlier run (" +
                             std::to_string(old.size()) + " files, e.g. " +
                             old.front().filename().string() +
                             "); use --force to replace them, or --out to write elsewhere");
  return old;
}

}  // namespace

void check_output_directory(const std::filesystem::path& dir, bool force) {
  earlier_results(dir, force);
}

void prepare_output_directory(const std::filesystem::path& dir, bool force) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    throw std::runtime_error("cannot create output folder '" + dir.string() + "'" +
                             (ec ? ": " + ec.message() : ""));
  for (const fs::path& f : earlier_results(dir, force)) fs::remove(f, ec);
  const fs::path probe = dir / ".mpm_write_test";
  {
    std::ofstream out(probe);
    out << "ok";
    if (!out) throw std::runtime_error("cannot write to output folder '" + dir.string() + "'");
  }
  fs::remove(probe, ec);
}

namespace {

std::filesystem::path numbered(const std::filesystem::path& dir, const char* pattern, int frame) {
  char name[64];
  std::snprintf(name, sizeof name, pattern, frame);
  return dir / name;
}

/// An N x width dataset from N fixed-size Eigen objects, in their own scalar type.
template <class T>
void write_rows(hid_t file, const char* name, const std::vector<T>& v, hsize_t width) {
  const hsize_t dims[2] = {v.size(), width};
  // Stored in the particles' own precision, so a resumed run continues bit for bit.
  constexpr bool f32 = std::is_same_v<typename T::Scalar, float>;
  write_dataset(file, name, f32 ? H5T_IEEE_F32LE : H5T_IEEE_F64LE,
                f32 ? H5T_NATIVE_FLOAT : H5T_NATIVE_DOUBLE, 2, dims,
                v.empty() ? nullptr : static_cast<const void*>(v.data()->data()));
}

/// Reads an N x width dataset into N fixed-size Eigen objects (HDF5 converts the type).
template <class T>
void read_rows(hid_t file, const char* name, std::vector<T>& v, std::size_t width) {
  const std::vector<double> d = read_dataset<double>(file, name, H5T_NATIVE_DOUBLE, width);
  if (d.size() != v.size() * width)
    throw std::runtime_error(std::string("checkpoint: dataset ") + name + " has " +
                             std::to_string(d.size() / width) + " entries, the scene has " +
                             std::to_string(v.size()));
  std::copy(d.begin(), d.end(), v.data()->data());
}

}  // namespace

/// The contact impulses of `m` as three datasets (the ids with an entry, their patches and
/// impulses) and the substep they were found in.
static void write_contact_memory(hid_t file, const ContactMemory& m) {
  const std::vector<double> impulse(m.impulses.begin(), m.impulses.end());
  const hsize_t d[1] = {m.ids.size()};
  write_dataset(file, "contact_id", H5T_STD_U32LE, H5T_NATIVE_UINT32, 1, d, m.ids.data());
  write_dataset(file, "contact_patch", H5T_STD_U32LE, H5T_NATIVE_UINT32, 1, d, m.patches.data());
  write_dataset(file, "contact_impulse", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 1, d, impulse.data());
  write_attribute(file, "contact_dt", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, static_cast<double>(m.dt));
}

/// The contact impulses written by write_contact_memory into `m`; none in a checkpoint
/// without them (written before they were kept).
static void read_contact_memory(hid_t file, ContactMemory& m) {
  if (H5Lexists(file, "contact_id", H5P_DEFAULT) <= 0) return;
  const auto id = read_dataset<std::uint32_t>(file, "contact_id", H5T_NATIVE_UINT32, 1);
  const auto patch = read_dataset<std::uint32_t>(file, "contact_patch", H5T_NATIVE_UINT32, 1);
  const auto impulse = read_dataset<double>(file, "contact_impulse", H5T_NATIVE_DOUBLE, 1);
  if (patch.size() != id.size() || impulse.size() != id.size())
    throw std::runtime_error("checkpoint: the contact datasets differ in length");
  m.keep(id, patch, std::vector<Real>(impulse.begin(), impulse.end()),
         read_attribute<double>(file, "contact_dt", H5T_NATIVE_DOUBLE));
}

void write_checkpoint(const std::filesystem::path& file, const Simulation& sim, int frame) {
  quiet_hdf5();
  const std::filesystem::path tmp = temporary_path(file);
  const Particles& p = sim.particles();
  {
    hdf5::Handle f{H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose};
    if (f.id < 0) throw std::runtime_error("cannot create checkpoint '" + tmp.string() + "'");
    write_rows(f.id, "x", p.x, 3);
    write_rows(f.id, "v", p.v, 3);
    write_rows(f.id, "F", p.F, 9);
    if (!p.C.empty()) write_rows(f.id, "C", p.C, 9);
    // The particles in their memory order with their ids: the reorder stage's order decides
    // the order of the sums in the grid, so a resumed run needs it to continue bit for bit.
    const hsize_t d1[1] = {p.id.size()};
    write_dataset(f.id, "id", H5T_STD_U32LE, H5T_NATIVE_UINT32, 1, d1, p.id.data());
    for (std::size_t g = 0; g < sim.materials().size(); ++g) {
      const std::span<Real> st = sim.materials()[g].material->state();
      const hsize_t dims[1] = {st.size()};
      const std::string name = "material_state_" + std::to_string(g);
      write_dataset(f.id, name.c_str(), H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 1, dims, st.data());
    }
    write_contact_memory(f.id, sim.contact_memory());
    write_attribute(f.id, "time", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE,
                    static_cast<double>(sim.time()));
    write_attribute(f.id, "frame", H5T_STD_I32LE, H5T_NATIVE_INT, frame);
    write_attribute(f.id, "stored_real_bytes", H5T_STD_I32LE, H5T_NATIVE_INT,
                    static_cast<int>(sizeof(StoredReal)));
    write_attribute(f.id, "substeps", H5T_STD_U64LE, H5T_NATIVE_ULLONG,
                    static_cast<unsigned long long>(sim.substeps()));
    check(H5Fflush(f.id, H5F_SCOPE_GLOBAL), "checkpoint");
  }
  replace_file(tmp, file);
}

int restore_checkpoint(const std::filesystem::path& file, Simulation& sim) {
  quiet_hdf5();
  hdf5::Handle f{H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
  if (f.id < 0) throw std::runtime_error("cannot open checkpoint '" + file.string() + "'");
  // A float build's F and C would be widened or rounded by a double build and the other way
  // round: not the run that was stopped, so refuse.
  const int bytes = read_attribute<int>(f.id, "stored_real_bytes", H5T_NATIVE_INT);
  if (bytes != static_cast<int>(sizeof(StoredReal)))
    throw std::runtime_error("checkpoint '" + file.string() + "' was written by a build storing " +
                             "particle matrices in " + (bytes == 4 ? "float" : "double") +
                             "; this build stores them in " + kStoredPrecision +
                             " (CMake option MPM_DOUBLE_PARTICLES)");
  Particles& p = sim.particles();
  read_rows(f.id, "x", p.x, 3);
  read_rows(f.id, "v", p.v, 3);
  read_rows(f.id, "F", p.F, 9);
  if (!p.C.empty()) read_rows(f.id, "C", p.C, 9);
  const std::vector<std::uint32_t> id =
      read_dataset<std::uint32_t>(f.id, "id", H5T_NATIVE_UINT32, 1);
  if (id.size() != p.id.size())
    throw std::runtime_error("checkpoint: dataset id has " + std::to_string(id.size()) +
                             " entries, the scene has " + std::to_string(p.id.size()));
  p.id = id;
  for (std::size_t g = 0; g < sim.materials().size(); ++g) {
    const std::span<Real> st = sim.materials()[g].material->state();
    const std::string name = "material_state_" + std::to_string(g);
    const std::vector<double> d = read_dataset<double>(f.id, name.c_str(), H5T_NATIVE_DOUBLE, 1);
    if (d.size() != st.size())
      throw std::runtime_error("checkpoint: " + name + " does not match the scene's materials");
    std::copy(d.begin(), d.end(), st.begin());
  }
  read_contact_memory(f.id, sim.contact_memory());
  sim.set_time(read_attribute<double>(f.id, "time", H5T_NATIVE_DOUBLE));
  sim.set_substeps(read_attribute<unsigned long long>(f.id, "substeps", H5T_NATIVE_ULLONG));
  return read_attribute<int>(f.id, "frame", H5T_NATIVE_INT);
}

FrameOutput::FrameOutput(std::filesystem::path dir, const OutputDesc& desc, int resumed_frame)
    : dir_(std::move(dir)), desc_(desc), resumed_frame_(resumed_frame) {
  if (resumed_frame_ > 0) checkpoint_frame_ = resumed_frame_;  // the file it resumed from
  const bool hdf5 =
      std::find(desc_.formats.begin(), desc_.formats.end(), Format::hdf5) != desc_.formats.end();
  collective_ = parallel::ranks() > 1 && parallel::collective_hdf5() && hdf5;
  others_ = desc_.checkpoint || desc_.formats != std::vector<Format>{Format::hdf5};
}

void FrameOutput::write_index(const Simulation& sim, int frame, std::size_t particles) const {
  std::vector<XdmfFrame> index;
  for (int k = 0; k <= frame; ++k)
    if (std::filesystem::exists(frame_path(dir_, k)))
      index.push_back(
          {frame_path(dir_, k).filename().string(),
           k == frame ? static_cast<double>(sim.time()) : k * sim.scene().simulation.frame_dt,
           particles});
  write_xdmf(dir_ / "frames.xmf", index);
}

void FrameOutput::write_collective(const Simulation& sim, int frame) {
  // Every rank writes its own particles at their id rows; rank 0 writes the index.
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t n = parallel::write_frame_hdf5_collective(
      frame_path(dir_, frame), sim.particles(), static_cast<double>(sim.time()), frame);
  if (parallel::rank() == 0) write_index(sim, frame, n);
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  last_frame_ = frame;
}

void FrameOutput::write(const Simulation& sim, int frame) {
  const auto t0 = std::chrono::steady_clock::now();
  const FrameView view = frame_in_id_order(sim.particles(), sim.time(), frame, scratch_);
  for (Format f : desc_.formats) {
    switch (f) {
      case Format::hdf5: {
        if (collective_) break;  // written by every rank before the gather
        write_frame_hdf5(frame_path(dir_, frame), view);
        write_index(sim, frame, view.size());
        break;
      }
      case Format::bgeo:
        write_bgeo(numbered(dir_, "frame_%05d.bgeo", frame), view);
        break;
      case Format::ply:
        write_ply(numbered(dir_, "frame_%05d.ply", frame), view);
        break;
      case Format::png: {
        const GridDesc& g = sim.scene().grid;
        PreviewCamera cam = default_camera(g.origin, g.max);
        if (desc_.camera) {
          cam.position = desc_.camera->position;
          cam.look_at = desc_.camera->look_at;
          cam.fov_deg = desc_.camera->fov_deg;
        }
        // Splats about half the particle spacing across, so bodies look solid.
        int ppc = 1000;
        for (const ObjectDesc& o : sim.scene().objects) ppc = std::min(ppc, o.particles_per_cell);
        cam.particle_radius = 0.6 * g.spacing().minCoeff() / std::cbrt(ppc);
        std::filesystem::create_directories(dir_ / "preview");
        render_preview(numbered(dir_ / "preview", "frame_%05d.png", frame), view, cam,
                       desc_.preview_size.x(), desc_.preview_size.y(),
                       preview_walls(sim.scene(), static_cast<double>(sim.time())));
        break;
      }
      case Format::mesh:
      case Format::vdb:
        break;  // below, both from one level set per object
    }
  }
  const auto has = [&](Format f) {
    return std::find(desc_.formats.begin(), desc_.formats.end(), f) != desc_.formats.end();
  };
  if (has(Format::mesh) || has(Format::vdb)) {
    const auto s0 = std::chrono::steady_clock::now();
    write_surfaces(dir_, frame_data(view), surface_objects(sim.scene()), desc_.surface,
                   has(Format::mesh), has(Format::vdb));
    surface_seconds_ +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - s0).count();
  }
  scratch_ = FrameArrays{};  // frames are rare: give the memory back between them
  // A checkpoint costs three times a frame file (27 MB against 8 MB for two_cubes): written
  // on a wall-clock interval, and by on_finish at the end, so a run pays for a handful.
  const double since = std::chrono::duration<double>(t0 - last_checkpoint_).count();
  if (desc_.checkpoint && since >= desc_.checkpoint_interval) checkpoint(sim, frame);
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  last_frame_ = frame;
  last_frame_time_ = sim.time();
}

void FrameOutput::checkpoint(const Simulation& sim, int frame) {
  const auto t0 = std::chrono::steady_clock::now();
  write_checkpoint(dir_ / "checkpoint.h5", sim, frame);
  last_checkpoint_ = std::chrono::steady_clock::now();
  checkpoint_seconds_ += std::chrono::duration<double>(last_checkpoint_ - t0).count();
  checkpoint_frame_ = frame;
  ++checkpoints_;
}

void FrameOutput::on_start(const Simulation& sim, int) {
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  if (ec)
    throw std::runtime_error("cannot create output folder '" + dir_.string() +
                             "': " + ec.message());
  if (resumed_frame_ > 0) {
    last_frame_ = resumed_frame_;
    return;
  }
  // Frame 0: every particle is on rank 0 before the first frame's distribution.
  if (collective_) write_collective(sim, 0);
  if (!collective_ || (others_ && parallel::rank() == 0)) write(sim, 0);
}

void FrameOutput::on_frame(const Simulation& sim, int frame) {
  if (collective_)
    write_collective(sim, frame);
  else
    write(sim, frame);
}

void FrameOutput::on_frame_gathered(const Simulation& sim, int frame) {
  if (others_ && parallel::rank() == 0) write(sim, frame);
}

void FrameOutput::on_stop(const Simulation& sim, const RunResult&) {
  // The last frame's checkpoint, while the state is still that frame's (rank 0 holds every
  // particle after the frame's gather, which the checkpoint asks for): a run stopped
  // mid-frame (unstable, a failed stage) keeps the last one written.
  if (parallel::rank() != 0 || !desc_.checkpoint || last_frame_ <= checkpoint_frame_ ||
      sim.time() != last_frame_time_)
    return;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    checkpoint(sim, last_frame_);
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("cannot write the checkpoint: ") + e.what());
  }
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

namespace {

/// report.yaml's split over MPI ranks (docs/distributed.md) for a run of `n` particles; one
/// rank: no communication. `collective`: each rank wrote its own particles into the HDF5
/// frames, without the frame's gather.
void emit_rank_stats(YAML::Emitter& y, const Simulation& sim, std::size_t n, bool collective) {
  parallel::DomainStats ds;
  ds.particles = {n};
  ds.comm_seconds = {0.0};
  ds.bytes = {0};
  if (const parallel::Domain* domain = parallel::domain_of(sim)) ds = domain->stats();
  y << YAML::Key << "ranks" << YAML::Value << ds.ranks;
  y << YAML::Key << "particles_per_rank" << YAML::Value << YAML::Flow << ds.particles;
  y << YAML::Key << "collective_hdf5" << YAML::Value << collective;
  y << YAML::Key << "load_imbalance" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key
    << "max" << YAML::Value << ds.imbalance_max << YAML::Key << "mean" << YAML::Value
    << ds.imbalance_mean << YAML::EndMap;
  y << YAML::Key << "comm_seconds" << YAML::Value << YAML::Flow << ds.comm_seconds;
  std::vector<double> per_substep;
  for (std::uint64_t b : ds.bytes)
    per_substep.push_back(ds.substeps ? static_cast<double>(b) / ds.substeps : 0.0);
  y << YAML::Key << "comm_bytes_per_substep" << YAML::Value << YAML::Flow << per_substep;
  y << YAML::Key << "halo_bytes_per_substep" << YAML::Value
    << (ds.substeps ? static_cast<double>(ds.halo_bytes) / ds.substeps : 0.0);
}

/// report.yaml's objects, and how `mpm surface DIR` builds the same surfaces as the mesh and
/// vdb formats (`s`).
void emit_objects(YAML::Emitter& y, const Simulation& sim, const SurfaceDesc& s) {
  y << YAML::Key << "objects" << YAML::Value << YAML::BeginSeq;
  const std::vector<SurfaceObject> surfaces = surface_objects(sim.scene());
  for (std::size_t k = 0; k < sim.objects().size(); ++k) {
    const ObjectInfo& o = sim.objects()[k];
    y << YAML::BeginMap;
    y << YAML::Key << "name" << YAML::Value << o.name;
    y << YAML::Key << "material" << YAML::Value << o.material;
    y << YAML::Key << "particles" << YAML::Value << o.count;
    y << YAML::Key << "mass" << YAML::Value << o.mass;
    y << YAML::Key << "particle_spacing" << YAML::Value << surfaces[k].spacing;
    y << YAML::EndMap;
  }
  y << YAML::EndSeq;
  y << YAML::Key << "surface" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "radius" << YAML::Value << s.radius;
  y << YAML::Key << "voxel" << YAML::Value << s.voxel;
  y << YAML::Key << "smoothing" << YAML::Value << s.smoothing;
  y << YAML::Key << "normals" << YAML::Value << s.normals;
  y << YAML::Key << "density" << YAML::Value << s.density;
  y << YAML::Key << "velocity" << YAML::Value << s.velocity;
  y << YAML::EndMap;
}

}  // namespace

void FrameOutput::on_finish(const Simulation& sim, const RunResult& r) {
  // Without the frame's gather each rank holds its own particles: count them over the ranks.
  std::size_t n = sim.particles().size();
  if (collective_) n = parallel::sum_all(static_cast<std::uint64_t>(n));
  if (parallel::rank() != 0) return;
  YAML::Emitter y;
  y << YAML::BeginMap;
  y << YAML::Key << "status" << YAML::Value << status_name(r.status);
  if (!r.message.empty()) y << YAML::Key << "message" << YAML::Value << r.message;
  if (r.instability) {
    const Instability& u = *r.instability;
    y << YAML::Key << "instability" << YAML::Value << YAML::BeginMap;
    y << YAML::Key << "cause" << YAML::Value << u.cause;
    y << YAML::Key << "frame" << YAML::Value << u.frame;
    y << YAML::Key << "substep" << YAML::Value << u.substep;
    y << YAML::Key << "object" << YAML::Value << u.object;
    y << YAML::Key << "suggested_dt" << YAML::Value << u.suggested_dt;
    y << YAML::EndMap;
  }
  if (!r.warnings.empty()) {
    y << YAML::Key << "warnings" << YAML::Value << YAML::BeginSeq;
    for (const std::string& w : r.warnings) y << w;
    y << YAML::EndSeq;
  }
  y << YAML::Key << "scene" << YAML::Value << sim.scene().file.string();
  y << YAML::Key << "particles" << YAML::Value << n;
  y << YAML::Key << "frames" << YAML::Value << r.frames_done;
  y << YAML::Key << "last_frame_file" << YAML::Value
    << (last_frame_ >= 0 ? frame_path(dir_, last_frame_).filename().string() : "");
  y << YAML::Key << "time" << YAML::Value << sim.time();
  y << YAML::Key << "substeps" << YAML::Value << sim.substeps();
  y << YAML::Key << "dt_min" << YAML::Value << r.dt_min;
  y << YAML::Key << "dt_max" << YAML::Value << r.dt_max;
  y << YAML::Key << "wall_seconds" << YAML::Value << r.wall_seconds;
  y << YAML::Key << "loop_seconds" << YAML::Value << r.loop_seconds;
  y << YAML::Key << "output_seconds" << YAML::Value << seconds_;
  y << YAML::Key << "surface_seconds" << YAML::Value << surface_seconds_;
  y << YAML::Key << "checkpoint_seconds" << YAML::Value << checkpoint_seconds_;
  y << YAML::Key << "checkpoints" << YAML::Value << checkpoints_;
  // The frame --resume continues from (-1: no checkpoint).
  y << YAML::Key << "checkpoint_frame" << YAML::Value
    << (desc_.checkpoint ? checkpoint_frame_ : -1);
  y << YAML::Key << "check_seconds" << YAML::Value << r.check_seconds;
  y << YAML::Key << "observer_seconds" << YAML::Value << r.observer_seconds;
  const double steps = static_cast<double>(n) * sim.substeps();
  y << YAML::Key << "particle_steps_per_second" << YAML::Value
    << (r.loop_seconds > 0 ? steps / r.loop_seconds : 0.0);
  y << YAML::Key << "run_particle_steps_per_second" << YAML::Value
    << (r.wall_seconds > 0 ? steps / r.wall_seconds : 0.0);
  y << YAML::Key << "clamped_particles" << YAML::Value << sim.clamped_particles();
  emit_rank_stats(y, sim, n, collective_);
  y << YAML::Key << "stages" << YAML::Value << YAML::BeginMap;
  for (const auto& [name, seconds] : sim.stage_seconds())
    y << YAML::Key << name << YAML::Value << seconds;
  y << YAML::Key << "output" << YAML::Value << seconds_;
  y << YAML::EndMap;
  y << YAML::Key << "energy_start" << YAML::Value << r.energy_start;
  y << YAML::Key << "energy_max" << YAML::Value << r.energy_max;
  y << YAML::Key << "frame_steps" << YAML::Value << YAML::BeginSeq;
  for (const FrameSteps& f : r.steps)
    y << YAML::Flow << YAML::BeginMap << YAML::Key << "frame" << YAML::Value << f.frame << YAML::Key
      << "substeps" << YAML::Value << f.substeps << YAML::Key << "dt_min" << YAML::Value << f.dt_min
      << YAML::Key << "dt_max" << YAML::Value << f.dt_max << YAML::EndMap;
  y << YAML::EndSeq;
  emit_objects(y, sim, desc_.surface);
  y << YAML::EndMap;

  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  write_file_whole(dir_ / "report.yaml", std::string(y.c_str()) + "\n");
}

}  // namespace mpm
