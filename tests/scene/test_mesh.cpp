// Mesh loading, the closedness check, the inside test and particle sampling.
#include <catch2/catch.hpp>

#include <fstream>

#include "engine/scene/mesh.h"
#include "engine/scene/sampling.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// Volume enclosed by a closed, outward-oriented mesh (divergence theorem).
double mesh_volume(const TriangleMesh& m) {
  double v = 0;
  for (const auto& t : m.triangles)
    v += m.vertices[t[0]].dot(m.vertices[t[1]].cross(m.vertices[t[2]])) / 6;
  return std::abs(v);
}

}  // namespace

TEST_CASE("mesh: the cube loads closed and welded", "[scene]") {
  const TriangleMesh m = load_mesh(test::cube_mesh());
  CHECK(m.vertices.size() == 8);
  CHECK(m.triangles.size() == 12);
  CHECK(closedness_problem(m).empty());
  CHECK(mesh_volume(m) == Approx(1.0));
}

TEST_CASE("mesh: an open mesh is reported", "[scene]") {
  TriangleMesh m = load_mesh(test::cube_mesh());
  m.triangles.pop_back();
  CHECK_THAT(closedness_problem(m), Catch::Matchers::Contains("not closed"));
}

TEST_CASE("mesh: a file that is not a mesh is reported", "[scene]") {
  const auto dir = test::temp_dir("badmesh");
  std::ofstream(dir / "bad.obj") << "this is not an obj file\nf 1 2 x\n";
  CHECK_THROWS_AS(load_mesh(dir / "bad.obj"), MeshError);
}

TEST_CASE("inside test: rays through edges and vertices count once", "[scene]") {
  const TriangleMesh m = load_mesh(test::cube_mesh());
  const InsideTester t(m);
  // The ray from the centre along +x passes exactly through the diagonal edge of the +x face.
  CHECK(t.inside(Vec3(0, 0, 0)));
  CHECK(t.inside(Vec3(0.2, 0.3, -0.1)));
  // From outside, the ray crosses both diagonals: twice, so outside.
  CHECK_FALSE(t.inside(Vec3(-1, 0, 0)));
  // Rays through the cube's edges (y = z = 0.5 is an edge of the top and back faces).
  CHECK_FALSE(t.inside(Vec3(-1, 0.5, 0.5)));
  CHECK_FALSE(t.inside(Vec3(0.7, 0, 0)));
  CHECK_FALSE(t.inside(Vec3(0, 0.7, 0)));
  // Along a vertex line: (y, z) = (-0.5, -0.5) touches the corner vertices.
  CHECK_FALSE(t.inside(Vec3(-2, -0.5, -0.5)));
}

TEST_CASE("inside test: bunny sampling fills its volume", "[scene]") {
  TriangleMesh m = load_mesh(test::source_dir() / "scenes/meshes/bunny.obj");
  REQUIRE(closedness_problem(m).empty());
  transform_mesh(m, Vec3::Constant(0.05), Vec3(0, 0, 0), Vec3(0.5, 0.1, 0.5));
  GridDesc g;
  g.dims = Vec3i::Constant(80);
  const int ppc = 8;
  const auto pts = sample_inside(m, g, ppc, false, 1, 0);
  const double sampled = pts.size() * g.spacing().prod() / ppc;
  // Sampling error: a relative deviation of about (boundary cells / inside cells) / sqrt(ppc).
  CHECK(sampled == Approx(mesh_volume(m)).epsilon(0.02));
}

TEST_CASE("sampling is deterministic for a seed and differs between seeds", "[scene]") {
  TriangleMesh m = load_mesh(test::cube_mesh());
  transform_mesh(m, Vec3::Constant(0.2), Vec3(0, 30, 0), Vec3(0.5, 0.5, 0.5));
  GridDesc g;
  g.dims = Vec3i::Constant(40);
  const auto a = sample_inside(m, g, 8, false, 1, 0), b = sample_inside(m, g, 8, false, 1, 0);
  const auto c = sample_inside(m, g, 8, false, 2, 0);
  CHECK(a == b);
  CHECK(a != c);
  CHECK(static_cast<double>(a.size()) == Approx(0.008 / g.spacing().prod() * 8).epsilon(0.03));
}

TEST_CASE("a grid moved with its sampling origin kept samples the same particles", "[scene]") {
  // Issue 30's offset sweeps move the node rows against the walls, not the particles.
  TriangleMesh m = load_mesh(test::cube_mesh());
  transform_mesh(m, Vec3::Constant(0.2), Vec3(0, 30, 0), Vec3(0.5, 0.5, 0.5));
  GridDesc g;
  g.dims = Vec3i::Constant(40);
  for (const bool regular : {true, false}) {
    const auto before = sample_inside(m, g, 8, regular, 1, 0);
    GridDesc moved = g;
    const Vec3 shift = Vec3(0.3, 0.55, 0.8) * g.spacing().x();
    moved.origin -= shift;
    moved.max -= shift;
    CHECK(sample_inside(m, moved, 8, regular, 1, 0) != before);  // the lattice moved with it
    moved.sampling_origin = g.origin;
    CHECK(sample_inside(m, moved, 8, regular, 1, 0) == before);
  }
}
