#pragma once
/// \file An XDMF 3 index over the HDF5 frame files, so ParaView opens a run as a time series.

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

namespace mpm {

/// One frame of an XDMF time series: a file written by write_frame_hdf5, its time and size.
struct XdmfFrame {
  std::string h5_file_name;   ///< Relative to the .xmf file's folder, e.g. frame_00003.h5.
  double time = 0;            ///< Simulation time, s.
  std::size_t particles = 0;  ///< Number of particles in the file.
};

/// Writes `xmf_file`: an XDMF 3 temporal collection with one Polyvertex grid per frame, in
/// the given order. Geometry XYZ is `<h5>:/position` (float32, N x 3); node attributes are
/// velocity (Vector, float32, N x 3), object_id (Scalar, int32) and J (Scalar, float32), the
/// datasets write_frame_hdf5 writes. The topology has no connectivity array: ParaView's
/// "XDMF Reader" makes one vertex cell per particle, its "Xdmf3 Reader" loads the points and
/// their attributes without cells (show them with the Point Gaussian representation). Writes
/// `<xmf_file>.tmp` and renames it, so the file is whole or absent. Throws
/// std::invalid_argument for an empty file name, one containing ':', or a non-finite time,
/// and std::runtime_error if the file cannot be written.
void write_xdmf(const std::filesystem::path& xmf_file, const std::vector<XdmfFrame>& frames);

}  // namespace mpm
