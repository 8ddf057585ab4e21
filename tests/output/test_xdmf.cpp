// The XDMF index as ParaView's default reader needs it: a connectivity shared by all frames,
// every per-particle dataset of the frame files an attribute, checked in ParaView itself.
#include <catch2/catch.hpp>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <numeric>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include <hdf5.h>

#include "engine/io/xdmf.h"
#include "output/output_checks.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

std::string slurp(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/// Writes dataset `name` of `rows` x `width` (width 0: rank 1) values of HDF5 type `type`.
template <class T>
void put(hid_t file, const char* name, hid_t type, hid_t mem, std::size_t rows, int width,
         const std::vector<T>& values) {
  const hsize_t dims[2] = {rows, static_cast<hsize_t>(width)};
  const hid_t space = H5Screate_simple(width > 0 ? 2 : 1, dims, nullptr);
  const hid_t set = H5Dcreate2(file, name, type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  REQUIRE(set >= 0);
  REQUIRE(H5Dwrite(set, mem, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) >= 0);
  H5Dclose(set);
  H5Sclose(space);
}

/// A frame file as a run writes it (position, velocity, object_id, J, a `time` attribute)
/// plus `temperature` (N, float64), `flags` (N, uint32) and `tail` (N + 1 values: not
/// per-particle). Values are simple functions of the index, so they can be checked.
void write_frame(const std::filesystem::path& file, std::size_t n, double time) {
  const hid_t f = H5Fcreate(file.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  REQUIRE(f >= 0);
  std::vector<float> xyz(3 * n), J(n);
  std::vector<int> object(n);
  std::vector<double> temperature(n);
  std::vector<std::uint32_t> flags(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) xyz[3 * i + a] = static_cast<float>(0.001 * i + a + time);
    J[i] = static_cast<float>(1 + 1e-4 * i);
    object[i] = static_cast<int>(i % 3);
    temperature[i] = 300 + 0.5 * i;
    flags[i] = static_cast<std::uint32_t>(7 * i);
  }
  put(f, "position", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, n, 3, xyz);
  put(f, "velocity", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, n, 3, xyz);
  put(f, "object_id", H5T_STD_I32LE, H5T_NATIVE_INT, n, 0, object);
  put(f, "J", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, n, 0, J);
  put(f, "temperature", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, n, 0, temperature);
  put(f, "flags", H5T_STD_U32LE, H5T_NATIVE_UINT32, n, 0, flags);
  put(f, "tail", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, n + 1, 0, std::vector<float>(n + 1, 1.0f));
  const hid_t scalar = H5Screate(H5S_SCALAR);
  const hid_t attr = H5Acreate2(f, "time", H5T_IEEE_F64LE, scalar, H5P_DEFAULT, H5P_DEFAULT);
  REQUIRE(H5Awrite(attr, H5T_NATIVE_DOUBLE, &time) >= 0);
  H5Aclose(attr);
  H5Sclose(scalar);
  H5Fclose(f);
}

/// Dataset `connectivity` of `file` as int32, or nothing if absent.
std::vector<std::int32_t> read_connectivity(const std::filesystem::path& file) {
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(f >= 0);
  const hid_t set = H5Dopen2(f, "connectivity", H5P_DEFAULT);
  REQUIRE(set >= 0);
  const hid_t space = H5Dget_space(set);
  std::vector<std::int32_t> v(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)));
  const hid_t type = H5Dget_type(set);
  CHECK(H5Tequal(type, H5T_STD_I32LE) > 0);
  if (!v.empty()) REQUIRE(H5Dread(set, H5T_NATIVE_INT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) >= 0);
  H5Tclose(type);
  H5Sclose(space);
  H5Dclose(set);
  H5Fclose(f);
  return v;
}

/// The frames of a run whose third frame has fewer particles than the first two.
std::vector<XdmfFrame> write_frames(const std::filesystem::path& dir) {
  const std::vector<std::size_t> sizes = {1000, 1000, 600};
  std::vector<XdmfFrame> frames;
  for (int k = 0; k < 3; ++k) {
    const std::string name = "frame_0000" + std::to_string(k) + ".h5";
    write_frame(dir / name, sizes[k], k / 24.0);
    frames.push_back({name, k / 24.0, sizes[k]});
  }
  return frames;
}

}  // namespace

TEST_CASE("XDMF: one connectivity file for all frames, and every per-particle dataset",
          "[output][xdmf]") {
  const auto dir = test::temp_dir("xdmf_connectivity");
  const std::vector<XdmfFrame> frames = write_frames(dir);
  const auto xmf = dir / "particles.xmf";
  write_xdmf(xmf, frames);
  const auto conn = dir / "particles_connectivity.h5";
  CHECK(xdmf_connectivity_path(xmf) == conn);
  CHECK_FALSE(std::filesystem::exists(dir / "particles_connectivity.h5.tmp"));

  // 0 .. 999 once: as long as the largest frame.
  std::vector<std::int32_t> want(1000);
  std::iota(want.begin(), want.end(), 0);
  CHECK(read_connectivity(conn) == want);

  const std::string text = slurp(xmf);
  const std::vector<std::string> grids = test::uniform_grids(text);
  REQUIRE(grids.size() == 3);
  const std::string whole =
      "<Topology TopologyType=\"Polyvertex\" NumberOfElements=\"1000\" NodesPerElement=\"1\">\n"
      "          <DataItem Dimensions=\"1000\" NumberType=\"Int\" Precision=\"4\" "
      "Format=\"HDF\">particles_connectivity.h5:/connectivity</DataItem>\n"
      "        </Topology>";
  CHECK(grids[0].find(whole) != std::string::npos);
  CHECK(grids[1].find(whole) != std::string::npos);
  // The smaller frame takes the first 600 entries.
  const std::string slab =
      "<Topology TopologyType=\"Polyvertex\" NumberOfElements=\"600\" NodesPerElement=\"1\">\n"
      "          <DataItem ItemType=\"HyperSlab\" Dimensions=\"600\" Type=\"HyperSlab\">\n"
      "            <DataItem Dimensions=\"3 1\" Format=\"XML\">0 1 600</DataItem>\n"
      "            <DataItem Dimensions=\"1000\" NumberType=\"Int\" Precision=\"4\" "
      "Format=\"HDF\">particles_connectivity.h5:/connectivity</DataItem>\n"
      "          </DataItem>\n"
      "        </Topology>";
  CHECK(grids[2].find(slab) != std::string::npos);

  // Every dataset with one row per particle is an attribute, of its own type; the known
  // ones first. `tail` (N + 1 rows) and position (the geometry) are not.
  for (int k = 0; k < 3; ++k) {
    INFO("frame " << k);
    const std::string n = std::to_string(frames[k].particles);
    const std::string h5 = frames[k].h5_file_name;
    const auto attribute = [&](const std::string& name, const std::string& kind,
                               const std::string& dims, const std::string& type, int bytes) {
      return "        <Attribute Name=\"" + name + "\" AttributeType=\"" + kind +
             "\" Center=\"Node\">\n          <DataItem Dimensions=\"" + dims +
             "\" NumberType=\"" + type + "\" Precision=\"" + std::to_string(bytes) +
             "\" Format=\"HDF\">" + h5 + ":/" + name + "</DataItem>\n        </Attribute>\n";
    };
    const std::string want_attributes =
        attribute("velocity", "Vector", n + " 3", "Float", 4) +
        attribute("object_id", "Scalar", n, "Int", 4) + attribute("J", "Scalar", n, "Float", 4) +
        attribute("flags", "Scalar", n, "UInt", 4) +
        attribute("temperature", "Scalar", n, "Float", 8);
    CHECK(grids[k].find(want_attributes) != std::string::npos);
    CHECK(grids[k].find("tail") == std::string::npos);
  }

  SECTION("the connectivity is rewritten when it is not 0 .. N-1, and left alone when it is") {
    const auto before = std::filesystem::last_write_time(conn);
    write_xdmf(xmf, frames);
    CHECK(std::filesystem::last_write_time(conn) == before);
    write_xdmf(xmf, {frames[2]});  // the largest frame now has 600
    CHECK(read_connectivity(conn) == std::vector<std::int32_t>(want.begin(), want.begin() + 600));
    std::filesystem::remove(conn);
    write_frame(conn, 1000, 0);  // a connectivity-less HDF5 file in its place
    write_xdmf(xmf, frames);
    CHECK(read_connectivity(conn) == want);
  }
  SECTION("an XDMF name with ':' is refused before anything is written") {
    CHECK_THROWS_AS(write_xdmf(dir / "a:b.xmf", frames), std::invalid_argument);
    CHECK_FALSE(std::filesystem::exists(dir / "a:b_connectivity.h5"));
    CHECK_FALSE(std::filesystem::exists(dir / "a:b.xmf"));
  }
  SECTION("without a readable frame file, the attributes a run writes") {
    write_xdmf(dir / "other.xmf", {{"missing.h5", 0, 10}});
    const std::string other = slurp(dir / "other.xmf");
    for (const char* a : {"velocity", "object_id", "J"})
      CHECK(other.find(std::string("Name=\"") + a + "\"") != std::string::npos);
    CHECK(other.find("temperature") == std::string::npos);
    CHECK(read_connectivity(dir / "other_connectivity.h5").size() == 10);
  }
}

TEST_CASE("XDMF: ParaView's default reader shows every particle of frames of unequal size",
          "[output][xdmf][paraview]") {
  const std::filesystem::path pvpython = "/usr/bin/pvpython";
  INFO("needs ParaView's pvpython: install it with scripts/install-deps.sh");
  REQUIRE(std::filesystem::exists(pvpython));
  const auto dir = test::temp_dir("xdmf_paraview");
  write_xdmf(dir / "particles.xmf", write_frames(dir));
  const std::string command = "cd '" + dir.string() + "' && " + pvpython.string() + " '" +
                              (test::source_dir() / "tests/output/check_xdmf_paraview.py").string() +
                              "' ./particles.xmf > check.log 2>&1";
  const int status = std::system(command.c_str());
  INFO(slurp(dir / "check.log"));
  CHECK(status == 0);
}
