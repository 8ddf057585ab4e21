// Checks every registered material gets for free, the example plugin's included: write a
// material, register it, and these run on it with no new test code. The checks themselves are
// materials/material_checks.h, which the installed `mpm_material_check` also runs on plugins.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cstdio>

#include "materials/material_checks.h"
#include "materials/plugin.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// The built-in materials plus the example plugin.
MaterialRegistry all_materials() {
  MaterialRegistry r = builtin_registry();
  load_plugin(MPM_STVK_PLUGIN, r);
  return r;
}

/// Runs the generic check called `name` on every material; each failure is reported.
void check_every_material(const std::string& name) {
  const MaterialRegistry reg = all_materials();
  for (const checks::Check& c : checks::all_checks()) {
    if (c.name != name) continue;
    for (const MaterialInfo& m : reg.all()) {
      INFO("material " << m.name << ", check '" << c.name << "': " << c.what);
      const checks::Failures failures = c.run(m);
      for (const std::string& f : failures) FAIL_CHECK(f);
      CHECK(failures.empty());
    }
    return;
  }
  FAIL("no generic check called " << name);
}

}  // namespace

TEST_CASE("every material: zero stress at rest and under pure rotation", "[materials]") {
  check_every_material("rest");
}

TEST_CASE("every material: P equals dpsi/dF by central differences", "[materials]") {
  check_every_material("piola");
}

TEST_CASE("every material: frame indifference and isotropy", "[materials]") {
  check_every_material("frame_indifference");
}

TEST_CASE("every material: finite for nearly singular and inverted F", "[materials]") {
  check_every_material("inversion");
}

TEST_CASE("every material: positive wave speed that grows with stiffness", "[materials]") {
  check_every_material("wave_speed");
}

TEST_CASE("every material with a lane kernel: lane_stress equals compute_stress", "[materials]") {
  check_every_material("lane_stress");
}

TEST_CASE("the generic checks catch a wrong material", "[materials]") {
  // A model whose stress is twice its energy's derivative, and not zero under rotation.
  MaterialInfo bad = builtin_registry().all().front();
  const auto good_create = bad.create;
  struct Doubled : MaterialGroup {
    std::unique_ptr<MaterialGroup> inner;
    void compute_stress(std::span<const StoredMat3> F, Real v0,
                        std::span<StoredMat3> out) const override {
      inner->compute_stress(F, v0, out);
      for (auto& s : out) s = to_stored(2 * to_real(s) - v0 * Mat3::Identity());
    }
    Real max_wave_speed(std::span<const StoredMat3> F) const override {
      return inner->max_wave_speed(F);
    }
    Real elastic_energy(std::span<const StoredMat3> F, Real v0) const override {
      return inner->elastic_energy(F, v0);
    }
    bool has_lane_stress() const override { return true; }
    void lane_stress(StressLanes& b, Real v0) const override {
      inner->lane_stress(b, v0);  // the undoubled stress: not what compute_stress gives
    }
  };
  bad.create = [good_create](const ParamValues& v, const GroupInfo& g) {
    auto d = std::make_unique<Doubled>();
    d->inner = good_create(v, g);
    return std::unique_ptr<MaterialGroup>(std::move(d));
  };
  CHECK(!checks::check_rest(bad).empty());
  CHECK(!checks::check_piola(bad).empty());
  CHECK(!checks::check_lane_stress(bad).empty());
}

TEST_CASE("every material: `mpm materials` lists every key with unit, default and range",
          "[materials]") {
  std::string listing;
  {
    FILE* pipe = popen((std::string(MPM_BINARY) + " materials").c_str(), "r");
    REQUIRE(pipe != nullptr);
    char buf[4096];
    while (std::fgets(buf, sizeof buf, pipe)) listing += buf;
    REQUIRE(pclose(pipe) == 0);
  }
  const MaterialRegistry registry = builtin_registry();
  for (const MaterialInfo& m : registry.all()) {
    const std::size_t at = listing.find(m.name + ": " + m.description);
    INFO("material " << m.name);
    REQUIRE(at != std::string::npos);
    for (const ParamSpec& p : m.params) {
      // The key's row: key, unit (or -), default (or "required"), range, in this order.
      const std::size_t row = listing.find("\n  " + p.name + " ", at);
      REQUIRE(row != std::string::npos);
      const std::string line = listing.substr(row + 1, listing.find('\n', row + 1) - row - 1);
      // Columns as printed by engine/cli/cli.cpp: "  %-22s %-8s %-10s %-16s %s".
      const auto column = [&](std::size_t from, std::size_t width) {
        std::string w = line.substr(std::min(from, line.size()), width);
        w.erase(w.find_last_not_of(' ') + 1);
        return w;
      };
      const std::string key = column(2, 22), unit = column(25, 8), def = column(34, 10);
      char expected_def[32];
      std::snprintf(expected_def, sizeof expected_def, "%g", p.default_value);
      INFO("row: " << line);
      CHECK(key == p.name);
      CHECK(unit == (p.unit.empty() ? "-" : p.unit));
      CHECK(def == (p.required ? std::string("required") : std::string(expected_def)));
      CHECK(line.find(range_text(p.min, p.max, p.min_exclusive, p.max_exclusive)) !=
            std::string::npos);
    }
  }
}
