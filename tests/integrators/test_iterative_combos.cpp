// The iterative linear solvers inside the simulator: the Newton iterations of a step solved
// by Diag-PCG or SA+PPCG (tolerance 1e-5 in the M^-1 norm) give the trajectory of the direct
// solver to within the Newton tolerance; so do inexact Newton solves (a forcing term), at
// fewer Krylov iterations.
#include <doctest/doctest.h>

#include <filesystem>

#include "framework/scene.hpp"
#include "policies/registry.hpp"

using namespace weft;

namespace {
std::string scene_path(const char* name) {
  const char* root = std::getenv("WEFT_SOURCE_DIR");
  return (std::filesystem::path(root ? root : ".") / "scenes" / name).string();
}

struct Run {
  Eigen::VectorXd x;
  int newton = 0, linear_iterations = 0, levels = 0;
};

Run run(const std::string& combo, int steps, std::vector<std::string> overrides = {}) {
  overrides.push_back("cloths.0.mesh.resolution=[21,21]");
  overrides.push_back("combo=" + combo);
  const Scene scene = load_scene(scene_path("hanging_cloth.json"), overrides);
  auto sim = make_simulator(scene);
  Run r;
  for (int k = 0; k < steps; ++k) {
    const StepReport s = sim->step();
    REQUIRE_MESSAGE(s.ok(), combo, ": ", s.message);
    r.newton += s.newton.iterations;
    r.linear_iterations += s.linear.iterations;
    r.levels = std::max(r.levels, s.linear.levels);
  }
  r.x = sim->state().x;
  return r;
}
}  // namespace

TEST_SUITE("integrators") {
  TEST_CASE("Diag-PCG and SA+PPCG combinations follow the direct solver on the hanging cloth") {
    const int steps = 24;  // 0.1 s: the cloth swings through large rotations
    for (auto [direct, iterative] : {std::pair{"cloth_ip_direct", "cloth_ip_diag_pcg"}, std::pair{"cloth_ip_direct", "cloth_ip_sa_ppcg"},
                                     std::pair{"cloth_lie_direct", "cloth_lie_sa_ppcg"}}) {
      CAPTURE(std::string(iterative));
      const Run a = run(direct, steps), b = run(iterative, steps);
      const Run start = run(direct, 0);
      const double moved = (a.x - start.x).cwiseAbs().maxCoeff();
      REQUIRE(moved > 0.01);  // the comparison is not vacuous: vertices moved by centimetres
      const double diff = (a.x - b.x).cwiseAbs().maxCoeff();
      MESSAGE(std::string(iterative) << ": max vertex difference " << diff << " m after " << steps << " steps; Newton " << a.newton << " vs "
                        << b.newton << "; linear iterations " << b.linear_iterations << "; SA levels " << b.levels);
      CHECK(diff <= 1e-4 * moved);
      CHECK(b.linear_iterations >= b.newton);  // a Krylov solver did run
      CHECK(std::abs(b.newton - a.newton) <= steps);  // inexact solves cost at most one more Newton step per step
      if (std::string(iterative).find("sa_") != std::string::npos) CHECK(b.levels >= 2);
    }
  }

  TEST_CASE("inexact Newton: a forcing term cuts the Krylov iterations and keeps the trajectory") {
    const int steps = 24;
    const Run start = run("cloth_ip_direct", 0);
    const Run direct = run("cloth_ip_direct", steps);
    const double moved = (direct.x - start.x).cwiseAbs().maxCoeff();
    REQUIRE(moved > 0.01);
    for (const char* combo : {"cloth_ip_sa_ppcg", "cloth_ip_diag_pcg"}) {
      CAPTURE(std::string(combo));
      const Run exact = run(combo, steps), inexact = run(combo, steps, {"integrator.forcing=0.5"});
      const double diff = (inexact.x - direct.x).cwiseAbs().maxCoeff();
      MESSAGE(std::string(combo) << ": linear iterations " << exact.linear_iterations << " exact, " << inexact.linear_iterations
                    << " with forcing 0.5; Newton " << exact.newton << " / " << inexact.newton << "; max difference " << diff << " m");
      CHECK(diff <= 1e-4 * moved);
      CHECK(inexact.linear_iterations < exact.linear_iterations);
    }
    // Direct solvers ignore the forcing term: the same steps to the last bit.
    const Run forced_direct = run("cloth_ip_direct", steps, {"integrator.forcing=0.5"});
    CHECK((forced_direct.x - direct.x).cwiseAbs().maxCoeff() == 0.0);
    CHECK(forced_direct.newton == direct.newton);
  }
}
