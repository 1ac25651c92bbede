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
}  // namespace

TEST_SUITE("integrators") {
  // The demo scene, coarser and more strongly damped so it settles within the test budget.
  TEST_CASE("hanging cloth: reaches static equilibrium with pinned corners fixed and a physical sag") {
    for (const char* combo : {"cloth_ip_direct", "cloth_tan_ip_direct"}) {
      CAPTURE(std::string(combo));
      const Scene scene = load_scene(scene_path("hanging_cloth.json"),
                                     {"cloths.0.mesh.resolution=[11,11]", "time.dt=0.020833333333333332", "damping.mass=2.0",
                                      std::string("combo=") + combo});
      auto sim = make_simulator(scene);
      const State s0 = sim->state();
      const double weight = s0.mass.sum() * 9.81;
      const double dt = scene.spec.time.dt;
      double ke_early = 0, ke_late = 0;
      int newton_total = 0;
      const int steps = static_cast<int>(std::round(12.0 / dt));
      for (int k = 1; k <= steps; ++k) {
        const StepReport r = sim->step();
        REQUIRE_MESSAGE(r.ok(), r.message);
        newton_total += r.newton.iterations;
        const double t = k * dt;
        if (t > 0.5 && t <= 3.0) ke_early = std::max(ke_early, r.energy.kinetic);
        if (t > 10.0) ke_late = std::max(ke_late, r.energy.kinetic);
      }
      const State& s = sim->state();
      // Kinetic energy decays by orders of magnitude (swinging early, at rest late).
      REQUIRE(ke_early > 1e-3 * weight);
      CHECK(ke_late < 1e-6 * ke_early);
      // Static equilibrium: elastic + gravity forces balance on every free vertex.
      const Eigen::VectorXd residual = sim->potential_gradient();
      CHECK(residual.norm() <= 1e-4 * weight);
      // Pinned corners have not moved at all.
      int pinned = 0;
      for (int i = 0; i < s.num_vertices(); ++i)
        if (s.dof[i] == Dof::pinned) {
          ++pinned;
          CHECK((s.position(i) - s0.position(i)).norm() == 0.0);
        }
      CHECK(pinned == 2);
      // Sag: the sheet hangs below its pins. The lowest point lies between the straight
      // drop of the side edges (1 m) and the geodesic from a pin to the middle of the
      // bottom edge (sqrt(1 + 0.5^2) = 1.118 m), allowing 1% stretch.
      double lowest = 0;
      for (int i = 0; i < s.num_vertices(); ++i) lowest = std::min(lowest, s.position(i).z());
      CHECK(-lowest >= 0.99);
      CHECK(-lowest <= 1.118 * 1.01);
      // Nearly inextensible cloth: every edge within 1% of its rest length.
      double max_strain = 0;
      for (const auto& e : scene.mesh.edges()) {
        const double l = (s.position(e[0]) - s.position(e[1])).norm();
        const double l0 = (scene.mesh.rest().row(e[0]) - scene.mesh.rest().row(e[1])).norm();
        max_strain = std::max(max_strain, std::abs(l / l0 - 1));
      }
      CHECK(max_strain < 0.01);
      MESSAGE(std::string(combo) << ": " << steps << " steps, " << newton_total << " Newton iterations, sag " << -lowest
                    << " m, max strain " << max_strain << ", |residual|/weight " << residual.norm() / weight);
    }
  }
}

TEST_SUITE("integrators") {
  TEST_CASE("shipped scenes: every file in scenes/ validates and runs its first step") {
    const char* root = std::getenv("WEFT_SOURCE_DIR");
    int scenes = 0;
    for (const auto& e : std::filesystem::directory_iterator(std::filesystem::path(root ? root : ".") / "scenes")) {
      if (e.path().extension() != ".json") continue;
      CAPTURE(e.path().string());
      ++scenes;
      const Scene scene = load_scene(e.path().string());
      auto sim = make_simulator(scene);
      const StepReport r = sim->step();
      REQUIRE_MESSAGE(r.ok(), r.message);
      CHECK(sim->state().x.allFinite());
    }
    CHECK(scenes >= 3);
  }
}

TEST_SUITE("integrators") {
  TEST_CASE("orthotropic sheet: hanging along its stiff warp it stretches about eta times less than along its weft") {
    // A vertical 0.5 m x 0.5 m sheet hangs from its top edge; gravity stretches it.
    // With warp along the vertical (warp_angle 90 deg) the vertical modulus is Y_warp, with
    // warp horizontal it is Y_weft = Y_warp / 4: the vertical strain should differ ~4x.
    double drop[2];
    for (int k = 0; k < 2; ++k) {
      Json doc = Json::parse(R"({
        "combo": "cloth_ortho_ip_direct",
        "cloths": [{"mesh": {"source": "rectangle", "size": [0.5, 0.5], "resolution": [9, 9], "plane": "xz"},
                    "material": {"model": "orthotropic", "density": 0.15, "thickness": 3e-4,
                                 "youngs_modulus_warp": 4e5, "youngs_modulus_weft": 1e5, "shear_modulus": 5e4,
                                 "poisson_ratio": 0.1, "warp_angle": 0.0},
                    "pins": [{"box_min": [-1, -1, 0.2499], "box_max": [1, 1, 1]}]}],
        "damping": {"mass": 5.0},
        "time": {"dt": 0.02, "duration": 4.0, "frame_rate": 50}
      })");
      doc["cloths"][0]["material"]["warp_angle"] = k == 0 ? M_PI / 2 : 0.0;
      auto sim = make_simulator(build_scene(doc, ".", "test"));
      for (int s = 0; s < 200; ++s) REQUIRE(sim->step().ok());
      CHECK(sim->energies().kinetic < 1e-10);
      double lowest = 1;
      for (int i = 0; i < sim->state().num_vertices(); ++i) lowest = std::min(lowest, sim->state().position(i).z());
      drop[k] = -0.25 - lowest;  // extension of the sheet below its rest bottom edge
    }
    REQUIRE(drop[0] > 0);
    const double ratio = drop[1] / drop[0];
    MESSAGE("extension: warp vertical " << drop[0] << " m, weft vertical " << drop[1] << " m, ratio " << ratio);
    CHECK(ratio > 3.0);
    CHECK(ratio < 5.0);
  }
}
