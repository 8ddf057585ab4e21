// initial_stress: gravity: an object starts in the state of a layer at rest under its weight.
#include <catch2/catch.hpp>

#include "engine/core/error.h"
#include "engine/run/run.h"
#include "support/float_bounds.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

std::string layer(const std::string& material, double density, const std::string& gravity) {
  return "simulation:\n"
         "  frame_dt: 0.01\n"
         "  cfl: 0.5\n"
         "  gravity: " + gravity + "\n"
         "grid:\n"
         "  max: [1, 1, 1]\n"
         "  dims: 20\n"
         "objects:\n"
         "  - name: layer\n"
         "    mesh: " + test::cube_mesh() + "\n"
         "    scale: [0.4, 0.3, 0.4]\n"
         "    offset: [0.5, 0.4, 0.5]\n"
         "    sampling: regular\n"
         "    density: " + std::to_string(density) + "\n"
         "    initial_stress: gravity\n" + material;
}

/// The largest error of the Cauchy stress along `up`, against the weight above each particle
/// (the layer's top is half a spacing above its highest particles), Pa; and the largest
/// sideways strain.
std::pair<double, double> weight_error(const SceneDesc& scene, const Vec3& up) {
  auto sim = Simulation::create(scene, builtin_registry());
  const Particles& p = sim->particles();
  const MaterialRange& m = sim->materials()[0];
  std::vector<StoredMat3> stress(p.size());
  m.material->compute_stress({p.F.data(), p.size()}, 1, stress);
  const double spacing = std::cbrt(p.object_volume0[0]);
  double top = -1e300, bottom = 1e300;
  for (const Vec3& x : p.x) top = std::max(top, x.dot(up)), bottom = std::min(bottom, x.dot(up));
  top += spacing / 2;
  bottom -= spacing / 2;
  const double g = scene.simulation.gravity.norm(), rho = *scene.objects[0].density;
  double worst = 0, sideways = 0;
  for (std::size_t q = 0; q < p.size(); ++q) {
    const Mat3 F = to_real(p.F[q]);
    const double sigma = -up.dot(to_real(stress[q]) * up) / F.determinant();
    worst = std::max(worst, std::abs(sigma + rho * g * (top - p.x[q].dot(up))));
    sideways = std::max(sideways, (F - Mat3::Identity() - (F - Mat3::Identity()) * up *
                                                              up.transpose()).norm());
  }
  return {worst, sideways};
}

}  // namespace

TEST_CASE("initial_stress gravity: the stress along gravity is the weight above, any material",
          "[physics]") {
  // Water's J-only pressure, corotated and Neo-Hookean solids, sand: each particle's Cauchy
  // stress along gravity equals -rho g d at its depth d, found on the material's own stress.
  // What is left is F's rounding where it is stored (float unless MPM_DOUBLE_PARTICLES): a
  // few units of round-off times the stiffness along gravity, the P-wave modulus
  // E (1 - nu) / ((1 + nu) (1 - 2 nu)), or K for water (2 % of rho g H would be 60 Pa).
  const auto p_wave = [](double E, double nu) { return E * (1 - nu) / ((1 + nu) * (1 - 2 * nu)); };
  const std::vector<std::pair<std::string, double>> materials = {
      {"    material: water\n    bulk_modulus: 4.0e5\n", 4.0e5},
      {"    material: corotated\n    E: 1.0e6\n    nu: 0.3\n", p_wave(1e6, 0.3)},
      {"    material: neo_hookean\n    E: 1.0e6\n    nu: 0.45\n", p_wave(1e6, 0.45)},
      {"    material: sand\n    E: 1.0e7\n    nu: 0.3\n", p_wave(1e7, 0.3)}};
  for (const auto& [mat, stiffness] : materials)
    for (const std::string gravity : {"[0, -9.81, 0]", "[0, 0, 20]"}) {
      INFO(mat << gravity);
      const SceneDesc scene = test::scene_from(layer(mat, 1000, gravity));
      const Vec3 up = -scene.simulation.gravity.normalized();
      const auto [error, sideways] = weight_error(scene, up);
      CHECK(error < 4 * test::kFloatU * stiffness);
      CHECK(sideways < 4 * test::kFloatU);  // uniaxial strain: confined sideways
    }
}

TEST_CASE("initial_stress gravity: a material too soft for its weight, or no gravity, is refused",
          "[physics]") {
  const auto message = [](const std::string& yaml) -> std::string {
    try {
      Simulation::create(test::scene_from(yaml), builtin_registry());
    } catch (const SceneError& e) {
      return e.what();
    }
    return "";
  };
  const std::string soft =
      message(layer("    material: corotated\n    E: 100\n    nu: 0.3\n", 1000, "[0, -9.81, 0]"));
  CHECK_THAT(soft, Catch::Contains("objects[0].initial_stress") &&
                       Catch::Contains("cannot hold the weight"));
  const std::string none =
      message(layer("    material: corotated\n    E: 1.0e6\n    nu: 0.3\n", 1000, "[0, 0, 0]"));
  CHECK_THAT(none, Catch::Contains("nonzero simulation.gravity"));
}

TEST_CASE("a water layer started at rest stays at rest on a slip floor", "[physics]") {
  // The pool of hydrostatic_water, shorter: started in its state at rest it barely moves, with
  // contact at the particles (warm-started) holding it: every particle's pressure stays
  // within 2 % of rho g H of the weight above it after 0.1 s.
  std::string yaml = layer("    material: water\n    bulk_modulus: 4.0e5\n", 1000, "[0, -9.81, 0]");
  yaml += "walls:\n  - plane: {point: [0, 0.25, 0], normal: [0, 1, 0]}\n    boundary: slip\n"
          "  - plane: {point: [0.3, 0, 0], normal: [1, 0, 0]}\n    boundary: slip\n"
          "  - plane: {point: [0.7, 0, 0], normal: [-1, 0, 0]}\n    boundary: slip\n"
          "  - plane: {point: [0, 0, 0.3], normal: [0, 0, 1]}\n    boundary: slip\n"
          "  - plane: {point: [0, 0, 0.7], normal: [0, 0, -1]}\n    boundary: slip\n";
  yaml.replace(yaml.find("simulation:\n"), 12, "simulation:\n  contact: particles\n  damping: 150\n");
  const SceneDesc scene = test::scene_from(yaml);
  auto sim = Simulation::create(scene, builtin_registry());
  const std::vector<Vec3> x0 = sim->particles().x;
  REQUIRE(run_frames(*sim, 10, scene.simulation.frame_dt, {}).status == RunStatus::ok);
  const Particles& p = sim->particles();
  const double rho_g = 1000 * 9.81, H = 0.3, K = 4.0e5;
  // Layer means, one cell (two rows of particles) thick, against the weight above.
  const int layers = 6;
  std::vector<double> pressure(layers, 0), weight(layers, 0);
  for (std::size_t q = 0; q < p.size(); ++q) {
    const double depth = 0.55 - x0[p.id[q]].y();
    const int k = std::min(layers - 1, static_cast<int>(depth / H * layers));
    const double J = to_real(p.F[q]).determinant();
    pressure[k] += K / 7 * (std::pow(J, -7) - 1);
    weight[k] += rho_g * depth;
  }
  for (int k = 0; k < layers; ++k) {
    INFO("layer " << k << " from the top: " << pressure[k] / weight[k]);
    CHECK(std::abs(pressure[k] / weight[k] - 1) < 0.05);
  }
}
