#include "engine/io/xdmf.h"

#include <hdf5.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <numeric>
#include <stdexcept>
#include <system_error>

#include "engine/core/atomic_file.h"
#include "engine/core/hdf5_handle.h"

namespace mpm {

namespace {

/// `text` with the five XML special characters replaced by entities.
std::string xml_escape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

/// Shortest text that reads back as exactly `value`.
std::string exact_text(double value) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, value);
  return std::string(buf, r.ptr);
}

/// One HDF5 DataItem: `dims` values of `type` (Float, Int or UInt), `bytes` each, at
/// file:/dataset.
std::string data_item(const std::string& dims, const std::string& type, int bytes,
                      const std::string& h5, const std::string& dataset,
                      const std::string& indent) {
  return indent + "<DataItem Dimensions=\"" + dims + "\" NumberType=\"" + type +
         "\" Precision=\"" + std::to_string(bytes) + "\" Format=\"HDF\">" + h5 + ":/" +
         xml_escape(dataset) + "</DataItem>\n";
}

/// A node attribute: a dataset of the frame files with one row per particle.
struct AttributeSpec {
  std::string name;  ///< Dataset and attribute name.
  bool vector;       ///< N x 3 (Vector) or N (Scalar).
  std::string type;  ///< XDMF NumberType: Float, Int or UInt.
  int bytes;         ///< XDMF Precision.
};

/// The attributes write_frame_hdf5 writes, for when no frame file can be read.
const std::vector<AttributeSpec> kDefaultAttributes = {
    {"velocity", true, "Float", 4}, {"object_id", false, "Int", 4}, {"J", false, "Float", 4}};

/// Rank 1 (or N x 1) datasets and N x 3 datasets of `file` other than position, with N rows;
/// velocity, object_id, J first, then the others by name. Empty if the file cannot be read.
std::vector<AttributeSpec> frame_attributes(const std::filesystem::path& file, hsize_t n) {
  std::vector<AttributeSpec> out;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) return out;
  H5E_auto2_t old_func = nullptr;
  void* old_data = nullptr;
  H5Eget_auto2(H5E_DEFAULT, &old_func, &old_data);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  {
    hdf5::Handle f{H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
    H5G_info_t info{};
    if (f.id >= 0 && H5Gget_info(f.id, &info) >= 0) {
      for (hsize_t k = 0; k < info.nlinks; ++k) {
        char name[256];
        const ssize_t length = H5Lget_name_by_idx(f.id, ".", H5_INDEX_NAME, H5_ITER_INC, k, name,
                                                  sizeof name, H5P_DEFAULT);
        if (length <= 0 || length >= static_cast<ssize_t>(sizeof name)) continue;
        if (std::string(name) == "position") continue;
        hdf5::Handle set{H5Dopen2(f.id, name, H5P_DEFAULT), H5Dclose};
        if (set.id < 0) continue;
        hdf5::Handle space{H5Dget_space(set.id), H5Sclose};
        hdf5::Handle type{H5Dget_type(set.id), H5Tclose};
        hsize_t dims[3] = {0, 0, 0};
        const int rank = H5Sget_simple_extent_ndims(space.id);
        if (rank < 1 || rank > 2) continue;
        H5Sget_simple_extent_dims(space.id, dims, nullptr);
        if (dims[0] != n || (rank == 2 && dims[1] != 1 && dims[1] != 3)) continue;
        const H5T_class_t cls = H5Tget_class(type.id);
        const int bytes = static_cast<int>(H5Tget_size(type.id));
        std::string number;
        if (cls == H5T_FLOAT && (bytes == 4 || bytes == 8)) number = "Float";
        else if (cls == H5T_INTEGER && (bytes == 4 || bytes == 8))
          number = H5Tget_sign(type.id) == H5T_SGN_NONE ? "UInt" : "Int";
        else continue;
        out.push_back({name, rank == 2 && dims[1] == 3, number, bytes});
      }
    }
  }
  H5Eset_auto2(H5E_DEFAULT, old_func, old_data);
  const auto rank = [](const std::string& name) {
    const char* known[] = {"velocity", "object_id", "J"};
    for (int k = 0; k < 3; ++k)
      if (name == known[k]) return k;
    return 3;
  };
  std::sort(out.begin(), out.end(), [&](const AttributeSpec& a, const AttributeSpec& b) {
    return std::make_pair(rank(a.name), a.name) < std::make_pair(rank(b.name), b.name);
  });
  return out;
}

/// Whether `file` holds dataset `connectivity` with exactly the values 0 .. n-1 as int32.
bool holds_connectivity(const std::filesystem::path& file, std::size_t n) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) return false;
  H5E_auto2_t old_func = nullptr;
  void* old_data = nullptr;
  H5Eget_auto2(H5E_DEFAULT, &old_func, &old_data);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  bool ok = false;
  {
    hdf5::Handle f{H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
    hdf5::Handle set{f.id >= 0 ? H5Dopen2(f.id, "connectivity", H5P_DEFAULT) : -1, H5Dclose};
    if (set.id >= 0) {
      hdf5::Handle space{H5Dget_space(set.id), H5Sclose};
      hdf5::Handle type{H5Dget_type(set.id), H5Tclose};
      hsize_t dims[1] = {0};
      if (H5Sget_simple_extent_ndims(space.id) == 1 &&
          H5Sget_simple_extent_dims(space.id, dims, nullptr) == 1 && dims[0] == n &&
          H5Tequal(type.id, H5T_STD_I32LE) > 0) {
        std::vector<std::int32_t> values(n);
        ok = n == 0 || H5Dread(set.id, H5T_NATIVE_INT32, H5S_ALL, H5S_ALL, H5P_DEFAULT,
                               values.data()) >= 0;
        for (std::size_t i = 0; ok && i < n; ++i) ok = values[i] == static_cast<std::int32_t>(i);
      }
    }
  }
  H5Eset_auto2(H5E_DEFAULT, old_func, old_data);
  return ok;
}

/// Writes `file` (via `<file>.tmp`) with dataset `connectivity`: int32 0 .. n-1.
void write_connectivity(const std::filesystem::path& file, std::size_t n) {
  if (n > static_cast<std::size_t>(INT32_MAX))
    throw std::runtime_error("XDMF connectivity: " + std::to_string(n) +
                             " particles do not fit int32 indices");
  std::vector<std::int32_t> values(n);
  std::iota(values.begin(), values.end(), 0);
  const std::filesystem::path tmp = temporary_path(file);
  {
    hdf5::Handle f{H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose};
    if (f.id < 0) throw std::runtime_error("cannot create '" + tmp.string() + "'");
    const hsize_t dims[1] = {n};
    hdf5::Handle space{H5Screate_simple(1, dims, nullptr), H5Sclose};
    hdf5::Handle set{hdf5::create_dataset(f.id, "connectivity", H5T_STD_I32LE, space.id),
                     H5Dclose};
    if ((n > 0 && H5Dwrite(set.id, H5T_NATIVE_INT32, H5S_ALL, H5S_ALL, H5P_DEFAULT,
                           values.data()) < 0) ||
        H5Fflush(f.id, H5F_SCOPE_GLOBAL) < 0)
      throw std::runtime_error("cannot write '" + tmp.string() + "'");
  }
  replace_file(tmp, file);
}

}  // namespace

std::filesystem::path xdmf_connectivity_path(const std::filesystem::path& xmf_file) {
  std::filesystem::path p = xmf_file;
  p.replace_filename(xmf_file.stem().string() + "_connectivity.h5");
  return p;
}

void write_xdmf(const std::filesystem::path& xmf_file, const std::vector<XdmfFrame>& frames) {
  for (const XdmfFrame& f : frames) {
    if (f.h5_file_name.empty()) throw std::invalid_argument("XDMF frame without a file name");
    if (f.h5_file_name.find(':') != std::string::npos)
      throw std::invalid_argument("XDMF frame file name '" + f.h5_file_name +
                                  "' contains ':', which separates file and dataset");
    if (!std::isfinite(f.time))
      throw std::invalid_argument("XDMF frame '" + f.h5_file_name + "' has a non-finite time");
  }

  if (xmf_file.filename().string().find(':') != std::string::npos)
    throw std::invalid_argument("XDMF file name '" + xmf_file.filename().string() +
                                "' contains ':', which would separate the connectivity file "
                                "from its dataset");

  std::size_t largest = 0;
  for (const XdmfFrame& f : frames) largest = std::max(largest, f.particles);
  const std::filesystem::path connectivity = xdmf_connectivity_path(xmf_file);
  if (!holds_connectivity(connectivity, largest)) write_connectivity(connectivity, largest);
  const std::string connectivity_h5 = xml_escape(connectivity.filename().string());

  std::vector<AttributeSpec> attributes;
  if (!frames.empty()) {
    const std::filesystem::path last = xmf_file.parent_path() / frames.back().h5_file_name;
    attributes = frame_attributes(last, frames.back().particles);
  }
  if (attributes.empty()) attributes = kDefaultAttributes;

  std::string x;
  x += "<?xml version=\"1.0\" ?>\n";
  x += "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n";
  x += "<Xdmf Version=\"3.0\">\n";
  x += "  <Domain>\n";
  x += "    <Grid Name=\"particles\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  const std::string in = "          ";  // indent of DataItems
  for (const XdmfFrame& f : frames) {
    const std::string h5 = xml_escape(f.h5_file_name);
    const std::string n = std::to_string(f.particles);
    const std::string name = xml_escape(std::filesystem::path(f.h5_file_name).stem().string());
    x += "      <Grid Name=\"" + name + "\" GridType=\"Uniform\">\n";
    x += "        <Time Value=\"" + exact_text(f.time) + "\"/>\n";
    // One vertex cell per particle: without a connectivity array Xdmf3 makes no cells.
    x += "        <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" + n +
         "\" NodesPerElement=\"1\">\n";
    if (f.particles == largest) {
      x += data_item(n, "Int", 4, connectivity_h5, "connectivity", in);
    } else if (f.particles > 0) {  // the first n entries: start 0, stride 1, count n
      x += in + "<DataItem ItemType=\"HyperSlab\" Dimensions=\"" + n + "\" Type=\"HyperSlab\">\n";
      x += in + "  <DataItem Dimensions=\"3 1\" Format=\"XML\">0 1 " + n + "</DataItem>\n";
      x += data_item(std::to_string(largest), "Int", 4, connectivity_h5, "connectivity",
                     in + "  ");
      x += in + "</DataItem>\n";
    }
    x += "        </Topology>\n";
    x += "        <Geometry GeometryType=\"XYZ\">\n";
    x += data_item(n + " 3", "Float", 4, h5, "position", in);
    x += "        </Geometry>\n";
    for (const AttributeSpec& a : attributes) {
      x += "        <Attribute Name=\"" + xml_escape(a.name) + "\" AttributeType=\"" +
           (a.vector ? "Vector" : "Scalar") + "\" Center=\"Node\">\n";
      x += data_item(a.vector ? n + " 3" : n, a.type, a.bytes, h5, a.name, in);
      x += "        </Attribute>\n";
    }
    x += "      </Grid>\n";
  }
  x += "    </Grid>\n";
  x += "  </Domain>\n";
  x += "</Xdmf>\n";

  write_file_whole(xmf_file, x);
}

}  // namespace mpm
