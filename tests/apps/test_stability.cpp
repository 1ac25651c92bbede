#include <doctest/doctest.h>

#include "apps/stability.hpp"
#include "cli_support.hpp"

using namespace weft::app;
using namespace weft::test;

namespace {
StabilityOptions small_grid(const std::string& name) {
  StabilityOptions o;
  o.scene = std::string(WEFT_SOURCE_DIR) + "/scenes/hanging_cloth.json";
  o.overrides = {"cloths.0.mesh.resolution=[7,7]"};
  o.duration = 0.25;
  o.dts = {1.0 / 240, 1.0 / 24};
  o.vary_key = "cloths.0.material.youngs_modulus";
  o.vary_values = {"1e6", "1e8"};
  o.out_dir = temp_dir(name).string();
  o.quiet = true;
  return o;
}
}  // namespace

TEST_SUITE("apps") {
  TEST_CASE("stability: one classified row per grid cell in the CSV and the map") {
    StabilityOptions o = small_grid("stab_grid");
    std::vector<StabilityResult> r;
    REQUIRE(run_stability(o, &r) == 0);
    REQUIRE(r.size() == 4);
    const std::string csv = slurp(std::filesystem::path(o.out_dir) / "stability.csv");
    CHECK(std::count(csv.begin(), csv.end(), '\n') == 5);  // header + 4 rows
    for (const auto& c : r) {
      CAPTURE(c.dt);
      CAPTURE(c.value);
      CHECK(c.outcome == Stability::stable);  // this small grid is benign for the default combination
      CHECK(c.steps == c.steps_planned);
      CHECK(c.energy_ratio <= 0.1);
    }
    CHECK(slurp(std::filesystem::path(o.out_dir) / "stability_map.txt").find("cloth_ip_direct") != std::string::npos);
  }

  TEST_CASE("stability: failures are classified by kind") {
    StabilityOptions o = small_grid("stab_kinds");
    o.dts = {1.0 / 24};
    o.vary_values = {"1e8"};
    std::vector<StabilityResult> r;
    o.strain_threshold = 1e-9;  // any stretch at all is "excessive"
    REQUIRE(run_stability(o, &r) == 0);
    CHECK(r.at(0).outcome == Stability::excessive_strain);
    o.strain_threshold = 0.5;
    o.overrides.push_back("integrator.max_iterations=1");
    o.overrides.push_back("integrator.relative_tolerance=1e-12");
    REQUIRE(run_stability(o, &r) == 0);
    CHECK(r.at(0).outcome == Stability::not_converged);
    CHECK(r.at(0).message.find("newton") != std::string::npos);
  }

  TEST_CASE("stability: an invalid grid is reported before any run") {
    StabilityOptions o = small_grid("stab_invalid");
    o.combos = {"no_such_combo"};
    CHECK(run_stability(o) == 2);
    CHECK_FALSE(std::filesystem::exists(std::filesystem::path(o.out_dir) / "stability.csv"));
  }
}
