#include "engine/scene/sampling.h"

#include <algorithm>
#include <cmath>

#include "engine/core/hash.h"

namespace mpm {

double hash_uniform(std::uint64_t key) { return unit_from_bits(splitmix64(key)); }

std::vector<Vec3> sample_inside(const TriangleMesh& mesh, const GridDesc& gd, int per_cell, bool regular,
                                std::uint64_t seed, std::uint64_t stream) {
  const InsideTester tester(mesh);
  const Vec3 h = gd.spacing();
  // The lattice's cells: from the sampling origin, clipped to the grid's box.
  const Vec3 origin = gd.sampling_origin.value_or(gd.origin);
  const Eigen::AlignedBox<Real, 3> box =
      tester.bounds().intersection(Eigen::AlignedBox<Real, 3>(gd.origin, gd.max));
  if (box.isEmpty()) return {};
  Vec3i lo, hi;
  for (int a = 0; a < 3; ++a) {
    lo[a] = static_cast<int>(std::floor((box.min()[a] - origin[a]) / h[a]));
    hi[a] = static_cast<int>(std::floor((box.max()[a] - origin[a]) / h[a]));
  }
  if ((hi - lo).minCoeff() < 0) return {};
  const int strata = static_cast<int>(std::lround(std::cbrt(per_cell)));
  const bool stratified = strata * strata * strata == per_cell;
  const std::uint64_t base_key = splitmix64(splitmix64(seed) ^ (stream * 0x632be59bd9b4e019ull));

  // One list per x slice, filled in parallel and joined in order.
  const int nx = hi.x() - lo.x() + 1;
  std::vector<std::vector<Vec3>> slices(nx);
#pragma omp parallel for schedule(dynamic, 1)
  for (int i = lo.x(); i <= hi.x(); ++i) {
    std::vector<Vec3>& out = slices[i - lo.x()];
    for (int j = lo.y(); j <= hi.y(); ++j)
      for (int k = lo.z(); k <= hi.z(); ++k) {
        const std::uint64_t cell =
            (static_cast<std::uint64_t>(i) * gd.dims.y() + j) * gd.dims.z() + k;
        const Vec3 corner = origin + Vec3(i, j, k).cwiseProduct(h);
        for (int s = 0; s < per_cell; ++s) {
          const std::uint64_t key = splitmix64(base_key ^ splitmix64(cell * 1024 + s));
          Vec3 u(hash_uniform(key), hash_uniform(key + 1), hash_uniform(key + 2));
          if (stratified) {
            const Vec3 sub(s / (strata * strata), (s / strata) % strata, s % strata);
            u = (sub + (regular ? Vec3::Constant(0.5) : u)) / strata;
          }
          const Vec3 x = corner + u.cwiseProduct(h);
          if (box.contains(x) && tester.inside(x)) out.push_back(x);
        }
      }
  }
  std::vector<Vec3> points;
  for (const auto& s : slices) points.insert(points.end(), s.begin(), s.end());
  return points;
}

}  // namespace mpm
