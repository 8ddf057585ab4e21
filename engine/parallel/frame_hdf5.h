#pragma once
/// \file One HDF5 frame file written by every rank at once (parallel HDF5, MPI-IO driver):
/// each rank writes its own particles at their id rows, so the file is the one-rank file
/// (docs/distributed.md "Output"). Built only with MPM_PARALLEL_HDF5; otherwise unavailable.

#include <cstddef>
#include <filesystem>

namespace mpm {
struct Particles;
}

namespace mpm::parallel {

/// True when this build links the MPI flavour of HDF5 (MPM_PARALLEL_HDF5=ON).
bool collective_hdf5();

/// Collective (every rank calls it): writes the frame file `file` with the datasets and
/// attributes of write_frame_hdf5 (engine/io/output.h) from each rank's `local` particles, the
/// rows in id order over all ranks; rank 0 renames the temporary file into place. Returns the
/// particle count over all ranks. Throws std::runtime_error (on every rank) on failure, or if
/// collective_hdf5() is false.
std::size_t write_frame_hdf5_collective(const std::filesystem::path& file, const Particles& local,
                                        double time, int frame);

}  // namespace mpm::parallel
