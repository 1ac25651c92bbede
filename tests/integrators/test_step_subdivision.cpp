// time.max_subdivisions: a cloth step that fails is retried from its start as two half
// steps (recursively). The failures are forced with a Newton iteration cap that the full
// step needs more than and the half steps do not.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "framework/error.hpp"
#include "framework/reports.hpp"
#include "framework/scene.hpp"
#include "policies/registry.hpp"

using namespace weft;

namespace {
std::string scene_path(const char* name) {
  const char* root = std::getenv("WEFT_SOURCE_DIR");
  return (std::filesystem::path(root ? root : ".") / "scenes" / name).string();
}

// The hanging cloth, coarse, at dt = 1/48 s with at most `newton_max` Newton iterations.
std::unique_ptr<AnySimulator> hanging(double dt, int newton_max, int subdivisions) {
  return make_simulator(load_scene(scene_path("hanging_cloth.json"),
                                   {"cloths.0.mesh.resolution=[11,11]", "combo=cloth_ip_direct", fmt::format("time.dt={}", dt),
                                    fmt::format("integrator.max_iterations={}", newton_max),
                                    fmt::format("time.max_subdivisions={}", subdivisions)}));
}

constexpr double frame = 1.0 / 24;
constexpr double dt = frame / 2;  // 1/48 s: the first step needs 5 Newton iterations, its halves at most 4
constexpr int cap = 4;
}  // namespace

TEST_SUITE("integrators") {
  TEST_CASE("step subdivision: a failed step is retried as half steps that match a run at dt/2") {
    // Without subdivision the first step fails (what makes the rest of the test meaningful).
    auto plain = hanging(dt, cap, 0);
    const StepReport failed = plain->step();
    REQUIRE_FALSE(failed.ok());
    CHECK(failed.failed_stage == "newton");
    CHECK(failed.substeps == 1);
    CHECK(plain->state().t == 0.0);

    auto sub = hanging(dt, cap, 3);
    auto half = hanging(dt / 2, cap, 0);
    const Eigen::VectorXd x0 = sub->state().x;
    for (int k = 1; k <= 3; ++k) {
      CAPTURE(k);
      const StepReport r = sub->step();
      REQUIRE_MESSAGE(r.ok(), r.message);
      CHECK(r.step == k);
      CHECK(r.dt == dt);
      CHECK(r.time == doctest::Approx(k * dt).epsilon(1e-14));
      CHECK(sub->state().t == doctest::Approx(k * dt).epsilon(1e-14));
      if (k == 1) {
        // The first step: one failed attempt (cap iterations, discarded), then two halves.
        CHECK(r.substeps == 2);
        CHECK(r.subdivisions == 1);
        CHECK(r.discarded_newton_iterations == cap);
        CHECK(r.retry_reason.find("newton") != std::string::npos);
        CHECK(r.newton.iterations <= 2 * cap);
        CHECK(r.newton.iterations >= 2);
        const Json j = to_json(r);
        CHECK(j.at("substeps") == 2);
        CHECK(j.at("retry_reason").get<std::string>() == r.retry_reason);
      }
      // The reference: plain steps of dt/2, as many as the subdivided step took.
      for (int s = 0; s < r.substeps; ++s) REQUIRE(half->step().ok());
      // Each run stops Newton at its tolerance, from different initial guesses after the
      // failed attempt: the states agree to that tolerance, far below the step's motion.
      const double motion = (sub->state().x - x0).cwiseAbs().maxCoeff();
      CHECK((sub->state().x - half->state().x).cwiseAbs().maxCoeff() <= 1e-5 * motion);
      CHECK((sub->state().v - half->state().v).cwiseAbs().maxCoeff() <= 1e-5 * sub->state().v.cwiseAbs().maxCoeff());
    }
  }

  TEST_CASE("step subdivision: a step that fails at every depth reports the substep and the first failure") {
    auto sim = hanging(dt, 1, 2);  // one Newton iteration is too few even at dt/4
    const StepReport r = sim->step();
    REQUIRE_FALSE(r.ok());
    CHECK(r.failed_stage == "newton");
    CHECK(r.subdivisions == 2);
    CHECK(r.message.find("substep of dt/4") != std::string::npos);
    CHECK(r.retry_reason.find(fmt::format("at dt = {} s", dt)) != std::string::npos);
    CHECK(r.discarded_newton_iterations >= 1);
    // The state is that of the last completed substep, never a failed attempt's: finite and
    // at a multiple of dt/4 no later than the end of the step.
    CHECK(sim->state().x.allFinite());
    const double quarters = sim->state().t / (dt / 4);
    CHECK(quarters == doctest::Approx(std::round(quarters)).epsilon(1e-12));
    CHECK(sim->state().t < dt);
  }

  TEST_CASE("step subdivision: rod scenes reject it by name") {
    CHECK_THROWS_WITH_AS(load_scene(scene_path("whip.json"), {"time.max_subdivisions=1"}),
                         doctest::Contains("time.max_subdivisions"), ConfigError);
    CHECK_THROWS_WITH_AS(load_scene(scene_path("hanging_cloth.json"), {"time.max_subdivisions=11"}),
                         doctest::Contains("time.max_subdivisions"), ConfigError);
  }
}
