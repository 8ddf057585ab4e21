#include "engine/io/xdmf.h"

#include "engine/io/atomic_file.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <system_error>

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

/// One HDF5 DataItem: `dims` values of `type` (Float or Int), 4 bytes each, at file:/dataset.
std::string data_item(const std::string& dims, const char* type, const std::string& h5,
                      const char* dataset, const std::string& indent) {
  return indent + "<DataItem Dimensions=\"" + dims + "\" NumberType=\"" + type +
         "\" Precision=\"4\" Format=\"HDF\">" + h5 + ":/" + dataset + "</DataItem>\n";
}

}  // namespace

void write_xdmf(const std::filesystem::path& xmf_file, const std::vector<XdmfFrame>& frames) {
  for (const XdmfFrame& f : frames) {
    if (f.h5_file_name.empty()) throw std::invalid_argument("XDMF frame without a file name");
    if (f.h5_file_name.find(':') != std::string::npos)
      throw std::invalid_argument("XDMF frame file name '" + f.h5_file_name +
                                  "' contains ':', which separates file and dataset");
    if (!std::isfinite(f.time))
      throw std::invalid_argument("XDMF frame '" + f.h5_file_name + "' has a non-finite time");
  }

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
    x += "        <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" + n +
         "\" NodesPerElement=\"1\"/>\n";
    x += "        <Geometry GeometryType=\"XYZ\">\n";
    x += data_item(n + " 3", "Float", h5, "position", in);
    x += "        </Geometry>\n";
    x += "        <Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">\n";
    x += data_item(n + " 3", "Float", h5, "velocity", in);
    x += "        </Attribute>\n";
    x += "        <Attribute Name=\"object_id\" AttributeType=\"Scalar\" Center=\"Node\">\n";
    x += data_item(n, "Int", h5, "object_id", in);
    x += "        </Attribute>\n";
    x += "        <Attribute Name=\"J\" AttributeType=\"Scalar\" Center=\"Node\">\n";
    x += data_item(n, "Float", h5, "J", in);
    x += "        </Attribute>\n";
    x += "      </Grid>\n";
  }
  x += "    </Grid>\n";
  x += "  </Domain>\n";
  x += "</Xdmf>\n";

  write_file_whole(xmf_file, x);
}

}  // namespace mpm
