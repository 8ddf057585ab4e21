#include "engine/parallel/frame_hdf5.h"

#include <hdf5.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/core/atomic_file.h"
#include "engine/core/hdf5_handle.h"
#include "engine/core/particles.h"
#include "engine/parallel/comm.h"

#ifdef H5_HAVE_PARALLEL
#include <mpi.h>
#endif

namespace mpm::parallel {

#ifndef H5_HAVE_PARALLEL

bool collective_hdf5() {
  return false;
}

std::size_t write_frame_hdf5_collective(const std::filesystem::path&, const Particles&, double,
                                        int) {
  throw std::runtime_error(
      "this build's HDF5 is not parallel: configure with MPM_PARALLEL_HDF5=ON");
}

#else

namespace {

/// Rows [first, first + count) of a dataset, for this rank's particles in id order.
struct Run {
  hsize_t first;
  hsize_t count;
};

/// Creates dataset `name` (rows x width) collectively and writes this rank's rows, the
/// consecutive id runs `runs`, from `data` (its rows in the same order), with a collective
/// MPI-IO transfer: every rank calls it, also one with no rows.
void write_rows(hid_t file, const char* name, hid_t file_type, hid_t mem_type, hsize_t rows,
                hsize_t width, const std::vector<Run>& runs, std::size_t local_rows,
                const void* data) {
  const int rank = width > 1 ? 2 : 1;
  const hsize_t dims[2] = {rows, width};
  hdf5::Handle space{H5Screate_simple(rank, dims, nullptr), H5Sclose};
  hdf5::Handle set{hdf5::create_dataset(file, name, file_type, space.id), H5Dclose};
  if (rows == 0) return;
  H5Sselect_none(space.id);
  for (const Run& r : runs) {
    const hsize_t start[2] = {r.first, 0}, count[2] = {r.count, width};
    hdf5::check(H5Sselect_hyperslab(space.id, H5S_SELECT_OR, start, nullptr, count, nullptr), name);
  }
  const hsize_t mem_dims[2] = {std::max<hsize_t>(local_rows, 1), width};
  hdf5::Handle memory{H5Screate_simple(rank, mem_dims, nullptr), H5Sclose};
  if (local_rows == 0) H5Sselect_none(memory.id);
  hdf5::Handle transfer{H5Pcreate(H5P_DATASET_XFER), H5Pclose};
  hdf5::check(H5Pset_dxpl_mpio(transfer.id, H5FD_MPIO_COLLECTIVE), name);
  hdf5::check(H5Dwrite(set.id, mem_type, memory.id, space.id, transfer.id, data), name);
}

}  // namespace

bool collective_hdf5() {
  return true;
}

std::size_t write_frame_hdf5_collective(const std::filesystem::path& file, const Particles& p,
                                        double time, int frame) {
  const std::size_t m = p.size();
  const std::uint64_t n = sum_all(static_cast<std::uint64_t>(m));
  // This rank's particles in id order, as float rows (the one-rank file's types).
  std::vector<std::size_t> order(m);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return p.id[a] < p.id[b]; });
  std::vector<float> pos(3 * m), vel(3 * m), J(m);
  std::vector<int> object(m);
  std::vector<std::uint32_t> id(m);
  std::vector<Run> runs;
  for (std::size_t k = 0; k < m; ++k) {
    const std::size_t q = order[k];
    for (int a = 0; a < 3; ++a) {
      pos[3 * k + a] = static_cast<float>(p.x[q][a]);
      vel[3 * k + a] = static_cast<float>(p.v[q][a]);
    }
    J[k] = static_cast<float>(to_real(p.F[q]).determinant());
    object[k] = static_cast<int>(p.object[q]);
    id[k] = p.id[q];
    if (!runs.empty() && runs.back().first + runs.back().count == id[k])
      ++runs.back().count;
    else
      runs.push_back({id[k], 1});
  }
  // An id outside 0..N-1 would write outside the datasets: the ids are a permutation.
  if (!id.empty() && id.back() >= n)
    throw std::runtime_error("parallel HDF5: particle id out of range");
  const std::filesystem::path tmp = temporary_path(file);
  std::string why;
  try {
    hdf5::Handle access{H5Pcreate(H5P_FILE_ACCESS), H5Pclose};
    hdf5::check(H5Pset_fapl_mpio(access.id, MPI_COMM_WORLD, MPI_INFO_NULL), "the file access list");
    hdf5::Handle f{H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, access.id), H5Fclose};
    if (f.id < 0) throw std::runtime_error("cannot create frame file '" + tmp.string() + "'");
    const hsize_t rows = n;
    write_rows(f.id, "position", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, rows, 3, runs, m, pos.data());
    write_rows(f.id, "velocity", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, rows, 3, runs, m, vel.data());
    write_rows(f.id, "object_id", H5T_STD_I32LE, H5T_NATIVE_INT, rows, 1, runs, m, object.data());
    write_rows(f.id, "J", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, rows, 1, runs, m, J.data());
    write_rows(f.id, "id", H5T_STD_U32LE, H5T_NATIVE_UINT32, rows, 1, runs, m, id.data());
    hdf5::write_attribute(f.id, "time", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, time);
    hdf5::write_attribute(f.id, "frame", H5T_STD_I32LE, H5T_NATIVE_INT, frame);
    hdf5::check(H5Fflush(f.id, H5F_SCOPE_GLOBAL), "frame file");
  } catch (const std::exception& e) {
    why = e.what();
  }
  // Every rank closed the file (collective) before rank 0 renames it into place; a failure on
  // any rank is every rank's.
  why = first_nonempty(why);
  if (why.empty() && rank() == 0) {
    try {
      replace_file(tmp, file);
    } catch (const std::exception& e) {
      why = e.what();
    }
  }
  why = first_nonempty(why);
  if (!why.empty()) throw std::runtime_error(why);
  return n;
}

#endif

}  // namespace mpm::parallel
