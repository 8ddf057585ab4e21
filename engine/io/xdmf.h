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

/// Name of the file, beside `xmf_file`, that holds the connectivity write_xdmf shares
/// between frames: `<stem>_connectivity.h5` (frames.xmf: frames_connectivity.h5).
std::filesystem::path xdmf_connectivity_path(const std::filesystem::path& xmf_file);

/// Writes `xmf_file`: an XDMF 3 temporal collection with one grid per frame, in the given
/// order, that ParaView's default reader (Xdmf3ReaderS) shows as one vertex cell per particle.
/// Geometry XYZ is `<h5>:/position` (float32, N x 3). The topology is Polyvertex, one node per
/// element, whose connectivity (indices 0 .. N-1) all frames share: dataset `connectivity`
/// (int32, as long as the largest frame) in xdmf_connectivity_path, written when missing or
/// not exactly that, 4 bytes per particle once per run; a smaller frame takes its first N
/// entries through a HyperSlab. Node attributes are the frame file's other datasets of N rows:
/// N values a Scalar, N x 3 a Vector (velocity, object_id, J first, as write_frame_hdf5 writes
/// them, then any others by name), read from the last frame's file; if that file cannot be
/// read, velocity (float32, N x 3), object_id (int32) and J (float32). Writes both files to
/// `*.tmp` and renames them, so each is whole or absent. Throws std::invalid_argument for an
/// empty frame file name, a frame file or `xmf_file` name containing ':', or a non-finite
/// time, and std::runtime_error if a file cannot be written.
void write_xdmf(const std::filesystem::path& xmf_file, const std::vector<XdmfFrame>& frames);

}  // namespace mpm
