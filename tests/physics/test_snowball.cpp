// Snow that shatters: the paper-parameter snowball (Stomakhin et al. 2013) breaks into pieces
// against a wall, where an elastic ball of the same stiffness stays whole.
#include <catch2/catch.hpp>

#include "engine/run/run.h"
#include "materials/snow.h"
#include "physics/fragments.h"
#include "support/helpers.h"

using namespace mpm;

TEST_CASE("fragment_sizes: face-connected cells make one fragment, a gap of a cell two",
          "[physics][snow]") {
  std::vector<Vec3> x;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) x.emplace_back(0.05 + 0.1 * i, 0.05 + 0.1 * j, 0.05);
  CHECK(test::fragment_sizes(x, 0.1) == std::vector<std::size_t>{16});
  // A second block one empty cell away, and a lone point touching it only by an edge.
  for (int i = 0; i < 2; ++i) x.emplace_back(0.55 + 0.1 * i, 0.05, 0.05);
  x.emplace_back(0.75, 0.15, 0.05);
  CHECK(test::fragment_sizes(x, 0.1) == std::vector<std::size_t>{16, 2, 1});
  CHECK(test::count_pieces(test::fragment_sizes(x, 0.1), x.size(), 0.1) == 2);
}
