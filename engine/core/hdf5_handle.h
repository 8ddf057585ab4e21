#pragma once
/// \file Small helpers for the HDF5 C API shared by the writers and readers: a handle closed
/// at scope exit, a checked call, a scalar attribute.

#include <hdf5.h>

#include <stdexcept>
#include <string>

namespace mpm::hdf5 {

/// Closes an HDF5 handle when it goes out of scope.
struct Handle {
  hid_t id;                ///< The handle; negative when the call that made it failed.
  herr_t (*close)(hid_t);  ///< H5Fclose, H5Dclose, ...
  ~Handle() {
    if (id >= 0) close(id);
  }
};

/// Throws "HDF5: cannot write <what>" when an HDF5 call returned an error.
inline void check(herr_t status, const std::string& what) {
  if (status < 0) throw std::runtime_error("HDF5: cannot write " + what);
}

/// Creates dataset `name` in `file` with no modification times in its header, so the same
/// state gives the same file; the caller closes it. Throws when HDF5 cannot create it.
inline hid_t create_dataset(hid_t file, const char* name, hid_t file_type, hid_t space) {
  Handle props{H5Pcreate(H5P_DATASET_CREATE), H5Pclose};
  H5Pset_obj_track_times(props.id, false);
  const hid_t set = H5Dcreate2(file, name, file_type, space, H5P_DEFAULT, props.id, H5P_DEFAULT);
  if (set < 0) throw std::runtime_error(std::string("HDF5: cannot create dataset ") + name);
  return set;
}

/// Writes the scalar attribute `name` (stored as `file_type`) on `object`.
template <class T>
void write_attribute(hid_t object, const char* name, hid_t file_type, hid_t mem_type, T value) {
  Handle space{H5Screate(H5S_SCALAR), H5Sclose};
  Handle attr{H5Acreate2(object, name, file_type, space.id, H5P_DEFAULT, H5P_DEFAULT), H5Aclose};
  if (attr.id < 0) throw std::runtime_error(std::string("HDF5: cannot create attribute ") + name);
  check(H5Awrite(attr.id, mem_type, &value), name);
}

}  // namespace mpm::hdf5
