// Impulse contact against analytic obstacles: vertices dropped on every obstacle kind end
// no step inside and come to rest; fast vertices and fast obstacles do not tunnel; the
// incline of methods/integration-and-contact E7 sticks below tan(alpha) = mu and slides above it with
// acceleration g (sin alpha - mu cos alpha); pinned vertices are never moved.
#include <doctest/doctest.h>

#include <cmath>
#include <string>

#include "contact/impulse.hpp"
#include "framework/scene.hpp"
#include "policies/presets.hpp"
#include "policies/registry.hpp"

using namespace weft;
using Eigen::Vector3d;

namespace {

/// The four vertices of a tiny 2x2 sheet, moved as independent particles by a backward
/// Euler free fall (v += dt g, x += dt v) and corrected by `Impulse::end_step`.
struct Particles {
  Scene scene;
  contact::Impulse impulse;
  State s;
  Particles(const std::string& obstacles, const Vector3d& center, const Vector3d& velocity,
            const contact::Impulse::Params& prm, const std::string& pins = "[]")
      : scene(make(obstacles, center, velocity, pins)), impulse(scene, prm), s(scene.initial_state()) {}
  static Scene make(const std::string& obstacles, const Vector3d& c, const Vector3d& v, const std::string& pins) {
    Json doc = Json::parse(R"({
      "combo": "cloth_ip_impulse_direct",
      "cloths": [{"mesh": {"source": "rectangle", "size": [0.02, 0.02], "resolution": [2, 2]}}],
      "time": {"dt": 0.004166666666666667, "duration": 1.0, "frame_rate": 24}
    })");
    doc["cloths"][0]["mesh"]["center"] = {c.x(), c.y(), c.z()};
    doc["cloths"][0]["initial_velocity"] = {v.x(), v.y(), v.z()};
    doc["cloths"][0]["pins"] = Json::parse(pins);
    doc["obstacles"] = Json::parse(obstacles);
    return build_scene(doc, ".", "test");
  }
  ContactReport step(double dt, const Vector3d& g = Vector3d(0, 0, -9.81)) {
    impulse.begin_step(s, dt);
    for (int i = 0; i < s.num_vertices(); ++i)
      if (s.is_free(i)) {
        s.velocity(i) += dt * g;
        s.position(i) += dt * s.velocity(i);
      }
    const ContactReport r = impulse.end_step(s, dt);
    s.t += dt;
    return r;
  }
};

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("impulse obstacles: a vertex dropped on a plane or sphere or box or moving sphere never ends inside and comes to rest") {
    const double h = 1e-3, dt = 1.0 / 240, tol = 1e-9;
    struct Case {
      const char* name;
      std::string obstacle;
      Vector3d obstacle_velocity;  // of its material points near the top [m/s]
      double top;                  // z of the surface at t = 0 under the particles
    };
    const Case cases[] = {
        {"plane", R"({"shape": "plane", "center": [0, 0, 0], "normal": [0, 0, 1], "friction": 0.5})", Vector3d::Zero(), 0.0},
        {"sphere", R"({"shape": "sphere", "center": [0, 0, -0.3], "radius": 0.3, "friction": 0.5})", Vector3d::Zero(), 0.0},
        {"box", R"({"shape": "box", "center": [0, 0, -0.1], "half_extents": [0.2, 0.2, 0.1], "friction": 0.5})",
         Vector3d::Zero(), 0.0},
        {"rising sphere",
         R"({"shape": "sphere", "center": [0, 0, -0.5], "radius": 0.3, "friction": 0.5, "motion": {"velocity": [0, 0, 0.2]}})",
         Vector3d(0, 0, 0.2), -0.2},
    };
    for (const Case& c : cases) {
      for (double speed : {0.0, 4.0}) {  // 4 m/s: 17 mm per step, far into the obstacle
        CAPTURE(c.name);
        CAPTURE(speed);
        Particles p("[" + c.obstacle + "]", Vector3d(0, 0, 0.05), Vector3d(0, 0, -speed), {.thickness = h, .self_contact = false});
        const ObstacleSpec& spec = p.scene.spec.obstacles[0];
        double worst = 0;
        int contacts = 0;
        for (int k = 0; k < 240; ++k) {
          const ContactReport r = p.step(dt);
          REQUIRE(r.status == Status::success);
          contacts += r.obstacle_contacts;
          const contact::ObstaclePose pose = contact::ObstaclePose::at(spec, p.s.t);
          for (int i = 0; i < p.s.num_vertices(); ++i) worst = std::max(worst, h - pose.distance(p.s.position(i)).phi);
          CHECK(r.max_penetration <= tol);
        }
        CHECK(contacts > 0);
        CHECK(worst <= tol);  // never closer than the thickness, at the end of any step
        const contact::ObstaclePose pose = contact::ObstaclePose::at(spec, p.s.t);
        for (int i = 0; i < p.s.num_vertices(); ++i) {
          CHECK(pose.distance(p.s.position(i)).phi == doctest::Approx(h).epsilon(1e-6));  // resting on the thickness
          CHECK((p.s.velocity(i) - c.obstacle_velocity).norm() <= 1e-6);  // at rest on the obstacle (g dt = 0.04 m/s)
        }
      }
    }
  }

  TEST_CASE("impulse obstacles: a fast vertex does not pass through a thin box and a fast sphere pushes a vertex ahead") {
    const double h = 1e-3, dt = 0.01;
    {  // 10 m/s through a 1 cm thick plate: 10 cm per step
      Particles p(R"([{"shape": "box", "center": [0, 0, 0], "half_extents": [0.2, 0.2, 0.005]}])", Vector3d(0, 0, 0.03),
                  Vector3d(0, 0, -10), {.thickness = h, .self_contact = false});
      for (int k = 0; k < 20; ++k) REQUIRE(p.step(dt).status == Status::success);
      for (int i = 0; i < p.s.num_vertices(); ++i) {
        CHECK(p.s.position(i).z() == doctest::Approx(0.005 + h).epsilon(1e-9));  // on top, not below the plate
        CHECK(p.s.velocity(i).norm() <= 1e-9);
      }
    }
    {  // a sphere of radius 5 cm at 20 m/s sweeps through resting vertices: 20 cm per step
      Particles p(R"([{"shape": "sphere", "center": [-0.1, 0, 0], "radius": 0.05, "motion": {"velocity": [20, 0, 0]}}])",
                  Vector3d(0, 0, 0), Vector3d::Zero(), {.thickness = h, .self_contact = false});
      const ContactReport r = p.step(dt, Vector3d::Zero());
      REQUIRE(r.status == Status::success);
      CHECK(r.obstacle_contacts >= 4);
      const Vector3d centre(0.1, 0, 0);  // at the end of the step
      for (int i = 0; i < p.s.num_vertices(); ++i) {
        CAPTURE(i);
        CHECK(p.s.position(i).x() > centre.x());                         // ahead of the sphere, not left behind
        CHECK((p.s.position(i) - centre).norm() >= 0.05 + h - 1e-9);     // and outside it
      }
    }
  }

  TEST_CASE("impulse obstacles: a pinned vertex inside the thickness is never moved") {
    const double dt = 1.0 / 240;
    Particles p(R"([{"shape": "plane", "center": [0, 0, 0], "normal": [0, 0, 1], "friction": 0.3}])", Vector3d(0, 0, 0.0002),
                Vector3d::Zero(), {.thickness = 1e-3, .self_contact = false}, R"([{"vertices": [0]}])");
    const Vector3d pinned = p.s.position(0);
    for (int k = 0; k < 20; ++k) REQUIRE(p.step(dt).status == Status::success);
    CHECK(p.s.position(0) == pinned);  // bitwise
    CHECK(p.s.velocity(0).norm() == 0.0);
    for (int i = 1; i < 4; ++i) CHECK(p.s.position(i).z() == doctest::Approx(1e-3).epsilon(1e-9));
  }

  TEST_CASE("impulse obstacles: sheet on an incline sticks below tan(alpha) = mu and slides above it at g (sin alpha - mu cos alpha)") {
    // methods/integration-and-contact E7 with a 3x3-vertex sheet on the plane z = 0, the incline given by tilting
    // gravity: g = 9.81 (sin alpha, 0, -cos alpha). Through the full simulator.
    const double mu = 0.5, h = 1e-3, g = 9.81, dt = 1.0 / 240;
    const double alpha_c = std::atan(mu);
    for (double factor : {0.95, 0.98, 1.02, 1.05}) {
      const double alpha = factor * alpha_c;
      CAPTURE(factor);
      Json doc = Json::parse(R"({
        "combo": "cloth_ip_impulse_direct",
        "cloths": [{"mesh": {"source": "rectangle", "size": [0.1, 0.1], "resolution": [3, 3], "center": [0, 0, 0.001]},
                    "material": {"density": 0.1, "youngs_modulus": 1e6, "thickness": 1e-3}}],
        "obstacles": [{"shape": "plane", "center": [0, 0, 0], "normal": [0, 0, 1], "friction": 0.5}],
        "contact": {"thickness": 0.001},
        "time": {"dt": 0.004166666666666667, "duration": 1.0, "frame_rate": 24}
      })");
      doc["gravity"] = {g * std::sin(alpha), 0.0, -g * std::cos(alpha)};
      const Scene scene = build_scene(doc, ".", "test");
      auto sim = make_simulator(scene);
      const Eigen::VectorXd x_start = sim->state().x;
      const int steps = 60;
      for (int k = 0; k < steps; ++k) {
        const StepReport r = sim->step();
        REQUIRE_MESSAGE(r.ok(), r.message);
        REQUIRE(r.contact.contacts == 9);
      }
      const State& s = sim->state();
      for (int i = 0; i < s.num_vertices(); ++i) {
        CHECK(s.position(i).z() == doctest::Approx(h).epsilon(1e-9));  // on the plane at the thickness
        CHECK(std::abs(s.velocity(i).z()) <= 1e-9);
        CHECK(std::abs(s.velocity(i).y()) <= 1e-9);
      }
      const double a_expected = g * (std::sin(alpha) - mu * std::cos(alpha));
      const double vx = s.velocity(4).x(), dx = s.position(4).x() - x_start[3 * 4];
      if (std::tan(alpha) < mu) {
        CHECK(std::abs(dx) <= 1e-9);  // sticks
        CHECK(std::abs(vx) <= 1e-9);
      } else {
        // Slides: after j steps v = j dt a (methods/integration-and-contact E7), x = dt^2 a j (j + 1) / 2.
        CHECK(vx == doctest::Approx(steps * dt * a_expected).epsilon(0.05));
        CHECK(dx == doctest::Approx(dt * dt * a_expected * steps * (steps + 1) / 2).epsilon(0.05));
        MESSAGE("alpha / alpha_c = " << factor << ": a = " << vx / (steps * dt) << " m/s^2, expected " << a_expected);
      }
    }
  }
}
