// The back ends as a scene's `linear.solver`: the same motion as the sparse LDL^T.
#include <doctest/doctest.h>

#include <cmath>

#include "framework/error.hpp"
#include "framework/scene.hpp"
#include "policies/registry.hpp"

using namespace weft;

namespace {

/// A 9 x 9 sheet pinned along one edge, swinging under gravity for ten steps.
Scene swinging_sheet(const std::string& solver) {
  Json doc = Json::parse(R"({
    "combo": "cloth_ip_direct",
    "cloths": [{"mesh": {"source": "rectangle", "size": [0.5, 0.5], "resolution": [9, 9]},
                "material": {"density": 0.15, "youngs_modulus": "20 MPa", "thickness": "0.3 mm"},
                "pins": [{"box_min": [-1, 0.24, -1], "box_max": [1, 1, 1]}]}],
    "time": {"dt": 0.01, "duration": 0.1, "frame_rate": 100}
  })");
  if (!solver.empty()) doc["linear"] = {{"solver", solver}};
  return build_scene(doc, ".", "swinging_sheet");
}

Eigen::VectorXd run(const Scene& scene, std::string_view expect_combo) {
  auto sim = make_simulator(scene);
  CHECK(sim->combo() == expect_combo);
  for (int k = 0; k < 10; ++k) {
    const StepReport r = sim->step();
    REQUIRE_MESSAGE(r.status == Status::success, r.failed_stage << ": " << r.message);
  }
  return sim->state().x;
}

}  // namespace

TEST_SUITE("backends") {
  TEST_CASE("linear.solver = cholmod / petsc_gamg run the pre-built sibling to the same positions as LDL^T") {
    const Eigen::VectorXd x0 = swinging_sheet("").initial_state().x;
    const Eigen::VectorXd ref = run(swinging_sheet(""), "cloth_ip_direct");
    const double motion = (ref - x0).lpNorm<Eigen::Infinity>();
    REQUIRE(motion > 1e-2);  // guard: the sheet swings, so agreement says something
    std::vector<std::string> solvers;
#ifdef WEFT_WITH_CHOLMOD
    solvers.emplace_back("cholmod");
#endif
#ifdef WEFT_WITH_PETSC
    solvers.emplace_back("petsc_gamg");
#endif
    REQUIRE_FALSE(solvers.empty());
    for (const std::string& s : solvers) {
      CAPTURE(s);
      const Eigen::VectorXd x = run(swinging_sheet(s), "cloth_ip_" + s);
      CHECK((x - ref).lpNorm<Eigen::Infinity>() <= 1e-3 * motion);
    }
#ifdef WEFT_WITH_CHOLMOD
    // The barrier family has CHOLMOD too (the contact default on large cloth).
    Scene barrier = swinging_sheet("cholmod");
    barrier.spec.combo = "cloth_ip_barrier_direct";
    CHECK(resolve_combo(barrier).key == "cloth_ip_barrier_cholmod");
    // A family without CHOLMOD in a build that has it: the family is named, not the build.
    Scene impulse = swinging_sheet("cholmod");
    impulse.spec.combo = "cloth_ip_impulse_direct";
    try {
      resolve_combo(impulse);
      FAIL("cholmod for the impulse family was accepted");
    } catch (const ConfigError& e) {
      const std::string what = e.what();
      CAPTURE(what);
      CHECK(what.find("no pre-built combination has the energy, integrator and contact") != std::string::npos);
      CHECK(what.find("back end") == std::string::npos);
    }
#endif
  }
}
