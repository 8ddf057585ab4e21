#pragma once
/// \file Files that appear whole or not at all: written under a temporary name, then renamed.

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string_view>

namespace mpm {

/// Where `file` is written before it is renamed into place: the same name plus ".tmp".
inline std::filesystem::path temporary_path(const std::filesystem::path& file) {
  std::filesystem::path tmp = file;
  tmp += ".tmp";
  return tmp;
}

/// Renames `tmp` over `file` (atomic within one file system); throws std::runtime_error.
inline void replace_file(const std::filesystem::path& tmp, const std::filesystem::path& file) {
  std::error_code ec;
  std::filesystem::rename(tmp, file, ec);
  if (ec) throw std::runtime_error("cannot rename '" + tmp.string() + "': " + ec.message());
}

/// Writes `bytes` to `file` whole or not at all; throws std::runtime_error on failure.
inline void write_file_whole(const std::filesystem::path& file, std::string_view bytes) {
  const std::filesystem::path tmp = temporary_path(file);
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) {
      std::error_code ignore;
      std::filesystem::remove(tmp, ignore);
      throw std::runtime_error("cannot write '" + tmp.string() + "'");
    }
  }
  replace_file(tmp, file);
}

}  // namespace mpm
