#pragma once
/// \file Checks the output tests share: preview pixel colours and the grids of an XDMF file.

#include <cmath>
#include <regex>
#include <string>
#include <vector>

#include "engine/io/preview.h"

namespace mpm::test {

/// Whether `pixel` is `base` scaled by some factor in [0.3, 1] (up to rounding).
inline bool is_shade_of(const Rgb& pixel, const Rgb& base) {
  const double k = double(pixel[0] + pixel[1] + pixel[2]) / (base[0] + base[1] + base[2]);
  if (k < 0.3 || k > 1.01) return false;
  for (int c = 0; c < 3; ++c)
    if (std::abs(pixel[c] - k * base[c]) > 2.5) return false;
  return true;
}

/// The bodies of every uniform <Grid> of an XDMF text, in file order (one per frame).
inline std::vector<std::string> uniform_grids(const std::string& xdmf_text) {
  const std::regex grid_re("<Grid [^>]*GridType=\"Uniform\">([\\s\\S]*?)</Grid>");
  std::vector<std::string> grids;
  for (auto it = std::sregex_iterator(xdmf_text.begin(), xdmf_text.end(), grid_re);
       it != std::sregex_iterator(); ++it)
    grids.push_back((*it)[1].str());
  return grids;
}

}  // namespace mpm::test
