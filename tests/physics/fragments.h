#pragma once
/// \file Fragments of a body: particles grouped by occupied cells that share a face.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numeric>
#include <unordered_map>
#include <vector>

#include "engine/core/math.h"

namespace mpm::test {

/// The fragment of each point of `x`, numbered by size (0 the largest; ties in first-point
/// order): the points are binned into cubic cells of edge `cell`, and two points are in one
/// fragment if a chain of occupied cells, each sharing a face with the next, joins their cells.
/// With `cell` about the grid spacing, pieces that no grid node still joins count apart.
inline std::vector<std::size_t> fragment_labels(const std::vector<Vec3>& x, Real cell) {
  auto key = [](std::int64_t i, std::int64_t j, std::int64_t k) {
    return (i & 0x1FFFFF) | ((j & 0x1FFFFF) << 21) | ((k & 0x1FFFFF) << 42);
  };
  std::unordered_map<std::int64_t, std::size_t> cell_id;
  std::vector<std::size_t> point_cell(x.size());
  std::vector<std::array<std::int64_t, 3>> cells;
  for (std::size_t p = 0; p < x.size(); ++p) {
    const std::array<std::int64_t, 3> c{std::llround(std::floor(x[p].x() / cell)),
                                        std::llround(std::floor(x[p].y() / cell)),
                                        std::llround(std::floor(x[p].z() / cell))};
    const auto [it, added] = cell_id.try_emplace(key(c[0], c[1], c[2]), cells.size());
    if (added) cells.push_back(c);
    point_cell[p] = it->second;
  }
  std::vector<std::size_t> parent(cells.size());
  std::iota(parent.begin(), parent.end(), 0);
  const std::function<std::size_t(std::size_t)> root = [&](std::size_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  for (std::size_t a = 0; a < cells.size(); ++a)
    for (int axis = 0; axis < 3; ++axis) {
      std::array<std::int64_t, 3> n = cells[a];
      ++n[axis];
      const auto it = cell_id.find(key(n[0], n[1], n[2]));
      if (it != cell_id.end()) parent[root(a)] = root(it->second);
    }
  // Count the points of each root cell, in first-point order, then number the roots by size.
  std::unordered_map<std::size_t, std::size_t> root_index;
  std::vector<std::size_t> count, label(x.size());
  for (std::size_t p = 0; p < x.size(); ++p) {
    const auto [it, added] = root_index.try_emplace(root(point_cell[p]), count.size());
    if (added) count.push_back(0);
    ++count[it->second];
    label[p] = it->second;
  }
  std::vector<std::size_t> order(count.size()), rank(count.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return count[a] > count[b]; });
  for (std::size_t r = 0; r < order.size(); ++r) rank[order[r]] = r;
  for (std::size_t& l : label) l = rank[l];
  return label;
}

/// Sizes (point counts, largest first) of the fragments that `labels` (from
/// fragment_labels) numbers.
inline std::vector<std::size_t> fragment_sizes(const std::vector<std::size_t>& labels) {
  std::vector<std::size_t> sizes;
  for (const std::size_t l : labels) {
    if (l >= sizes.size()) sizes.resize(l + 1, 0);
    ++sizes[l];
  }
  return sizes;
}

/// Sizes (point counts, largest first) of the fragments of the points `x` (fragment_labels).
inline std::vector<std::size_t> fragment_sizes(const std::vector<Vec3>& x, Real cell) {
  return fragment_sizes(fragment_labels(x, cell));
}

/// How many fragments hold at least `min_fraction` of the points.
inline std::size_t count_pieces(const std::vector<std::size_t>& sizes, std::size_t total,
                                double min_fraction) {
  return std::count_if(sizes.begin(), sizes.end(), [&](std::size_t n) {
    return static_cast<double>(n) >= min_fraction * static_cast<double>(total);
  });
}

/// The shatter criterion (docs/validation.md, section 17): of the fragments `sizes` of
/// `total` points, the largest holds less than 60% and at least 3 hold 2% or more each.
inline bool shattered(const std::vector<std::size_t>& sizes, std::size_t total) {
  return !sizes.empty() && static_cast<double>(sizes[0]) < 0.6 * static_cast<double>(total) &&
         count_pieces(sizes, total, 0.02) >= 3;
}

}  // namespace mpm::test
