// Impulse contact between cloth sheets: the impulse kernels conserve momentum; sheets
// colliding or falling onto each other end every step without intersection (exact check
// of contact/verify, independent of the detection code); the impact-zone failsafe
// resolves what impulses are not allowed to (ccd_sweeps = 0) and reports its iteration
// cap; pinned sheets are never moved; results do not depend on the number of threads.
#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdlib>
#include <random>
#include <string>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "../support/cloth_scenes.hpp"
#include "contact/impulse.hpp"
#include "contact/impulse_kernels.hpp"
#include "framework/scene.hpp"
#include "policies/presets.hpp"
#include "policies/registry.hpp"

using namespace weft;
using Eigen::Vector3d;
using support::below;
using support::intersections;
using support::sheet;

namespace {

/// Total linear momentum sum m v and angular momentum sum m x0 x v about the origin.
std::pair<Vector3d, Vector3d> momenta(const Eigen::VectorXd& x0, const State& s) {
  Vector3d p = Vector3d::Zero(), l = Vector3d::Zero();
  for (int i = 0; i < s.num_vertices(); ++i) {
    p += s.mass[i] * s.velocity(i);
    l += s.mass[i] * Vector3d(x0.segment<3>(3 * i)).cross(Vector3d(s.velocity(i)));
  }
  return {p, l};
}

Scene scene_of(const std::vector<Json>& cloths, const std::string& extra = "{}") {
  return support::cloth_scene(cloths, "cloth_ip_impulse_direct", extra);
}

/// Free flight of every vertex (no elasticity; without gravity momentum is conserved by
/// the "integrator"), then `Impulse::end_step`. Keeps the uncorrected end positions.
struct Flight {
  const Scene& scene;
  contact::Impulse impulse;
  State s;
  Eigen::VectorXd x0, x1_free;
  Flight(const Scene& sc, const contact::Impulse::Params& prm) : scene(sc), impulse(sc, prm), s(sc.initial_state()) {}
  ContactReport step(double dt, const Vector3d& g = Vector3d::Zero()) {
    x0 = s.x;
    impulse.begin_step(s, dt);
    for (int i = 0; i < s.num_vertices(); ++i)
      if (s.is_free(i)) {
        s.velocity(i) += dt * g;
        s.position(i) += dt * s.velocity(i);
      }
    x1_free = s.x;
    const ContactReport r = impulse.end_step(s, dt);
    s.t += dt;
    return r;
  }
};

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("impulse kernels: a stencil impulse changes the relative velocity as asked and conserves linear momentum") {
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1, 1), pos(0.1, 1);
    int checked = 0;
    for (int trial = 0; trial < 200; ++trial) {
      const int n = 6;
      Eigen::VectorXd v(3 * n), mass(n), inv(n);
      for (int i = 0; i < 3 * n; ++i) v[i] = u(rng);
      for (int i = 0; i < n; ++i) mass[i] = pos(rng), inv[i] = 1 / mass[i];
      const bool pinned = trial % 4 == 3;  // one infinite-mass stencil vertex
      if (pinned) inv[2] = 0;
      std::array<int, 4> ids{1, 2, 4, 5};
      std::array<double, 4> gamma;
      if (trial % 2 == 0) {  // vertex-triangle
        const double a = pos(rng), b = pos(rng), c = pos(rng), s = a + b + c;
        gamma = {1, -a / s, -b / s, -c / s};
      } else {  // edge-edge
        const double s = pos(rng) - 0.1, t = pos(rng) - 0.1;
        gamma = {1 - s, s, -(1 - t), -t};
      }
      const Vector3d nrm = Vector3d(u(rng), u(rng), u(rng)).normalized();
      const double dun = pos(rng), mu = trial % 3 == 0 ? 0.0 : 0.3;
      auto rel = [&](const Eigen::VectorXd& w) {
        Vector3d r = Vector3d::Zero();
        for (int j = 0; j < 4; ++j) r += gamma[j] * w.segment<3>(3 * ids[j]);
        return r;
      };
      auto momentum = [&](const Eigen::VectorXd& w) {
        Vector3d p = Vector3d::Zero();
        for (int i = 0; i < n; ++i) p += mass[i] * w.segment<3>(3 * i);
        return p;
      };
      const Eigen::VectorXd v0 = v;
      const auto r = contact::impulse::apply_stencil_impulse(ids, gamma, nrm, dun, mu, inv, v);
      REQUIRE(r.applied);
      const Vector3d du = rel(v) - rel(v0), ut = rel(v0) - rel(v0).dot(nrm) * nrm;
      CAPTURE(trial);
      CHECK(du.dot(nrm) == doctest::Approx(dun).epsilon(1e-12));
      const Vector3d dut = du - du.dot(nrm) * nrm;
      CHECK(dut.norm() == doctest::Approx(std::min(ut.norm(), mu * dun)).epsilon(1e-10));  // Coulomb bound
      if (mu > 0) CHECK(dut.normalized().dot(ut.normalized()) == doctest::Approx(-1).epsilon(1e-12));  // opposes sliding
      CHECK(v.segment<3>(0) == v0.segment<3>(0));  // not in the stencil
      if (pinned) {
        CHECK(v.segment<3>(6) == v0.segment<3>(6));  // infinite mass
      } else {
        CHECK((momentum(v) - momentum(v0)).norm() <= 1e-14 * (1 + momentum(v0).norm() + du.norm()));
        ++checked;
      }
    }
    CHECK(checked > 100);
  }

  TEST_CASE("impulse kernels: an impact zone moves rigidly and keeps its linear and angular momentum") {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1, 1), pos(0.1, 1);
    for (int trial = 0; trial < 50; ++trial) {
      const int n = 12;
      Eigen::VectorXd x(3 * n), v(3 * n), mass(n);
      for (int i = 0; i < 3 * n; ++i) x[i] = u(rng), v[i] = u(rng);
      for (int i = 0; i < n; ++i) mass[i] = pos(rng);
      std::vector<int> members{0, 2, 3, 5, 7, 8, 11};
      if (trial % 5 == 0) {  // a collinear zone: no inertia about its line
        for (int i : members) x.segment<3>(3 * i) = Vector3d(1, 2, 3) * u(rng);
      }
      auto moments = [&](const Eigen::VectorXd& w) {
        Vector3d p = Vector3d::Zero(), l = Vector3d::Zero();
        for (int i : members) {
          p += mass[i] * w.segment<3>(3 * i);
          l += mass[i] * Vector3d(x.segment<3>(3 * i)).cross(Vector3d(w.segment<3>(3 * i)));
        }
        return std::make_pair(p, l);
      };
      const auto [p0, l0] = moments(v);
      contact::impulse::rigidify_zone(members, {}, x, mass, v);
      const auto [p1, l1] = moments(v);
      CAPTURE(trial);
      CHECK((p1 - p0).norm() <= 1e-13 * (1 + p0.norm()));
      CHECK((l1 - l0).norm() <= 1e-12 * (1 + l0.norm()));
      for (int i : members)  // a rigid velocity field: no pair changes its distance
        for (int j : members)
          CHECK(std::abs((v.segment<3>(3 * i) - v.segment<3>(3 * j)).dot(x.segment<3>(3 * i) - x.segment<3>(3 * j))) <= 1e-12);
    }
    // Anchors: the zone follows them (a single static anchor holds it still).
    Eigen::VectorXd x = Eigen::VectorXd::Random(9), v = Eigen::VectorXd::Random(9), m = Eigen::VectorXd::Ones(3);
    v.segment<3>(3).setZero();
    const std::vector<int> members{0, 2}, anchors{1};
    contact::impulse::rigidify_zone(members, anchors, x, m, v);
    CHECK(v.norm() == 0.0);
  }

  TEST_CASE("impulse cloth: sheets crossing in free flight are stopped without intersection and momentum is conserved") {
    // Two sheets 6 mm apart approach at 2 m/s: 8 mm per step, so they would pass each other.
    const Scene scene = scene_of({sheet(0.1, 6, Vector3d(0, 0, 0), Vector3d(0, 0, 1)),
                                  sheet(0.08, 6, Vector3d(0.005, 0.003, 0.006), Vector3d(0, 0, -1), true)});
    for (int sweeps : {2, 0}) {  // impulses (zones only as failsafe), then zones alone
      CAPTURE(sweeps);
      Flight f(scene, {.thickness = 1e-3, .ccd_sweeps = sweeps});
      const double dt = 0.004;
      bool any_zone = false;
      for (int k = 0; k < 5; ++k) {
        const auto [p0, l0] = momenta(f.s.x, f.s);
        const ContactReport r = f.step(dt);
        REQUIRE_MESSAGE(r.status == Status::success, r.message);
        const auto [p1, l1] = momenta(f.x0, f.s);
        CAPTURE(k);
        if (k == 0) {
          CHECK(r.ccd_hits > 0);                           // the free flight collides
          CHECK(r.impulses + r.zone_vertices > 0);         // and something acted
          MESSAGE("ccd_sweeps = " << sweeps << ": " << r.ccd_hits << " CCD hits, " << r.impulses << " impulses in "
                                  << r.ccd_sweeps << " sweeps, " << r.zone_iterations << " zone iterations, "
                                  << r.impact_zones << " zones of " << r.zone_vertices << " vertices");
        }
        any_zone = any_zone || r.impact_zones > 0;
        CHECK((p1 - p0).norm() <= 1e-13 * p0.norm() + 1e-16);
        if (sweeps == 0 && r.impulses == 0) CHECK((l1 - l0).norm() <= 1e-12 * (l0.norm() + 1e-6));  // zones alone
        CHECK(intersections(scene, f.s.x) == 0);
        // No vertex of sheet 2 (upper) below sheet 1 (lower): they did not pass each other.
        if (k == 0) CHECK(below(scene, f.x1_free, 0, 36, 36, 72) > 0);  // as they would in free flight
        CHECK(below(scene, f.s.x, 0, 36, 36, 72) == 0);
      }
      if (sweeps == 0) CHECK(any_zone);
    }
  }

  TEST_CASE("impulse cloth: a pair within eta at the start that turns through its plane is not taken as resolved") {
    // A vertex 0.5 um (eta / 2) above the centroid q of a triangle: the triangle turns about
    // an axis through q while the vertex slides along the slope. Its separation along the
    // start normal (at the start weights) stays 0.5 um, yet it ends below the turned plane:
    // the twisted sheet crossed this way. Repulsion is off so that only CCD can act.
    const Scene scene = scene_of({sheet(0.1, 2, Vector3d(0, 0, 0), Vector3d::Zero()),
                                  sheet(0.02, 2, Vector3d(0, 0, 0.05), Vector3d::Zero())});
    Flight f(scene, {.thickness = 1e-3, .repulsion_sweeps = 0});
    const Eigen::MatrixX3i& F = scene.mesh.faces();
    const int lower_face = 0, up = scene.cloth_vertex_offset[1];
    REQUIRE(F(lower_face, 0) < up);
    Vector3d q = Vector3d::Zero();
    for (int j = 0; j < 3; ++j) q += f.s.position(F(lower_face, j)) / 3;
    const double dt = 0.004, w = 10, u = 1;  // the slope rises dt^2 w u = 160 um under the vertex
    for (int i = 0; i < up; ++i) f.s.velocity(i) = Vector3d(w, 0, 0).cross(f.s.position(i) - q);
    // The upper sheet: one corner at q + 0.5 um, the rest tilted up and away, sliding along y.
    const Vector3d corner = q + Vector3d(0, 0, 5e-7);
    const Vector3d shift = corner - f.s.position(up);
    for (int i = up; i < f.s.num_vertices(); ++i) {
      f.s.position(i) += shift + Vector3d(0, 0, 0.5 * (f.s.position(i) - f.s.position(up)).norm());
      f.s.velocity(i) = Vector3d(0, u, 0);
    }
    f.s.position(up) = corner;
    REQUIRE(intersections(scene, f.s.x) == 0);
    const ContactReport r = f.step(dt);
    REQUIRE_MESSAGE(r.status == Status::success, r.message);
    auto side = [&](const Eigen::VectorXd& x) {  // the corner's signed distance to the lower triangle's plane
      const Vector3d a = x.segment<3>(3 * F(lower_face, 0)), b = x.segment<3>(3 * F(lower_face, 1)),
                     c = x.segment<3>(3 * F(lower_face, 2));
      const Vector3d n = (b - a).cross(c - a).normalized();
      return n.dot(x.segment<3>(3 * up) - a) * (n.z() > 0 ? 1 : -1);
    };
    CHECK(side(f.x1_free) < 0);  // free flight crosses: the case is not vacuous
    CHECK(r.ccd_hits > 0);
    CHECK(side(f.s.x) > 0);
    CHECK(intersections(scene, f.s.x) == 0);
  }

  TEST_CASE("impulse cloth: the impact-zone failsafe stops at its iteration cap with a failing report") {
    // A fast sheet (2) hits a large resting sheet (1): the first zone drags the triangles of
    // sheet 1 it crossed along, and those reach beyond sheet 2 into a third sheet resting
    // 5 mm above sheet 1, which sheet 2's own path misses: a second iteration is needed.
    const Scene scene = scene_of({sheet(0.2, 9, Vector3d(0, 0, 0.01), Vector3d::Zero()),
                                  sheet(0.05, 4, Vector3d(0.01, 0.005, 0), Vector3d(0, 0, 5)),
                                  sheet(0.064, 4, Vector3d(0.068, 0, 0.015), Vector3d::Zero())});
    const double dt = 0.01;
    Flight ok(scene, {.thickness = 1e-3, .repulsion_sweeps = 0, .ccd_sweeps = 0, .max_zone_iterations = 100});
    const ContactReport r = ok.step(dt);
    REQUIRE_MESSAGE(r.status == Status::success, r.message);
    REQUIRE(r.zone_iterations >= 2);
    CHECK(intersections(scene, ok.s.x) == 0);
    MESSAGE("zones: " << r.zone_iterations << " iterations, " << r.impact_zones << " zone(s), " << r.zone_vertices
                      << " vertices");
    Flight capped(scene, {.thickness = 1e-3, .repulsion_sweeps = 0, .ccd_sweeps = 0, .max_zone_iterations = 1});
    const ContactReport c = capped.step(dt);
    CHECK(c.status == Status::no_convergence);
    CHECK_MESSAGE(c.message.find("remain after 1 impact-zone iterations in the step from t = 0 s") != std::string::npos,
                  c.message);
  }

  TEST_CASE("impulse cloth: a sheet dropped on another one resting on a plane never intersects it") {
    const Scene scene = scene_of({sheet(0.16, 9, Vector3d(0, 0, 0.001), Vector3d::Zero()),
                                  sheet(0.1, 8, Vector3d(0.011, 0.007, 0.02), Vector3d(0, 0, -1.5), true)},
                                 R"({"obstacles": [{"shape": "plane", "center": [0, 0, 0], "friction": 0.4}],
                                     "contact": {"thickness": 0.001, "cloth_friction": 0.3}})");
    auto sim = make_simulator(scene);
    const int lower = scene.cloth_vertex_offset[1];
    int contacts = 0;
    for (int k = 0; k < 72; ++k) {
      const StepReport r = sim->step();
      REQUIRE_MESSAGE(r.ok(), r.message);
      CAPTURE(k);
      REQUIRE(intersections(scene, sim->state().x) == 0);
      contacts += r.contact.contacts;
      double top = -1, bottom = 1;
      for (int i = 0; i < lower; ++i) top = std::max(top, sim->state().position(i).z());
      for (int i = lower; i < sim->state().num_vertices(); ++i) bottom = std::min(bottom, sim->state().position(i).z());
      CHECK(bottom > top);  // the upper sheet stays above the lower one
    }
    CHECK(contacts > 0);
    // At rest: the upper sheet lies on the lower one, about one thickness above it.
    double top = -1, bottom = 1;
    for (int i = 0; i < lower; ++i) top = std::max(top, sim->state().position(i).z());
    for (int i = lower; i < sim->state().num_vertices(); ++i) bottom = std::min(bottom, sim->state().position(i).z());
    CHECK(bottom - top < 2e-3);
  }

  TEST_CASE("impulse cloth: a pinned sheet is never moved by the sheet falling onto it") {
    // Every vertex of the lower sheet (cloth 0) pinned.
    Json lower_sheet = sheet(0.16, 9, Vector3d(0, 0, 0), Vector3d::Zero());
    lower_sheet["pins"] = Json::parse(R"([{"box_min": [-1, -1, -1], "box_max": [1, 1, 1]}])");
    const Scene pinned = scene_of({lower_sheet, sheet(0.1, 8, Vector3d(0.011, 0.007, 0.015), Vector3d(0, 0, -2), true)},
                                  R"({"contact": {"thickness": 0.001, "cloth_friction": 0.3}})");
    auto sim = make_simulator(pinned);
    const int lower = pinned.cloth_vertex_offset[1];
    const Eigen::VectorXd x_lower = sim->state().x.head(3 * lower);
    int contacts = 0;
    for (int k = 0; k < 48; ++k) {
      const StepReport r = sim->step();
      REQUIRE_MESSAGE(r.ok(), r.message);
      contacts += r.contact.contacts;
      CAPTURE(k);
      CHECK(sim->state().x.head(3 * lower) == x_lower);  // bitwise
      CHECK(sim->state().v.head(3 * lower).norm() == 0.0);
      REQUIRE(intersections(pinned, sim->state().x) == 0);
      double bottom = 1;
      for (int i = lower; i < sim->state().num_vertices(); ++i) bottom = std::min(bottom, sim->state().position(i).z());
      CHECK(bottom > 0);
    }
    CHECK(contacts > 0);
  }

  TEST_CASE("impulse cloth: the same result on 1 and 2 OpenMP threads") {
#ifdef _OPENMP
    // 2401 + 100 vertices (the obstacle pass runs in parallel above 2048 vertices): a sheet
    // falling on a sphere and on a smaller sheet, in free flight with gravity.
    const Scene scene = scene_of({sheet(0.16, 10, Vector3d(0.011, 0.007, 0.004), Vector3d::Zero(), true),
                                  sheet(0.5, 49, Vector3d(0, 0, 0.01), Vector3d(0, 0, -1))},
                                 R"({"obstacles": [{"shape": "sphere", "center": [0, 0, -0.2], "radius": 0.2, "friction": 0.4}]})");
    const int saved = omp_get_max_threads();
    Eigen::VectorXd result[2];
    int contacts = 0;
    for (int t = 0; t < 2; ++t) {
      omp_set_num_threads(t + 1);
      Flight f(scene, {.thickness = 2e-3, .cloth_friction = 0.3});
      for (int k = 0; k < 8; ++k) {
        const ContactReport r = f.step(1.0 / 240, Vector3d(0, 0, -9.81));
        REQUIRE_MESSAGE(r.status == Status::success, r.message);
        contacts += r.obstacle_contacts + r.proximity_contacts;
      }
      result[t] = f.s.x;
    }
    omp_set_num_threads(saved);
    CHECK(contacts > 500);
    CHECK(result[0] == result[1]);  // bitwise
#else
    MESSAGE("built without OpenMP");
#endif
  }

  TEST_CASE("impulse cloth: invalid parameters and scenes without contact are refused") {
    const Scene scene = scene_of({sheet(0.1, 4, Vector3d::Zero(), Vector3d::Zero())});
    CHECK_THROWS_WITH_AS(contact::Impulse(scene, {.thickness = 1e-3, .eta = 1e-3}), doctest::Contains("contact.eta = 0.001 violates"),
                         ConfigError);
    CHECK_THROWS_WITH_AS(contact::Impulse(scene, {.thickness = 1e-3, .ccd_sweeps = -1}),
                         doctest::Contains("contact.ccd_sweeps = -1 violates"), ConfigError);
    // Friction > 0 is accepted (the penalty stand-in refuses it).
    Scene with_friction = scene_of({sheet(0.1, 4, Vector3d::Zero(), Vector3d::Zero())},
                                   R"({"obstacles": [{"shape": "plane", "center": [0, 0, -0.1], "friction": 0.3}]})");
    CHECK_NOTHROW(make_simulator(with_friction));
    // No obstacles and no self contact: nothing for the impulse combo to do.
    const ComboInfo* combo = nullptr;
    for (const auto& c : combos())
      if (c.key == "cloth_ip_impulse_direct") combo = &c;
    REQUIRE(combo != nullptr);
    CHECK(not_applicable_reason(*combo, scene).empty());  // self contact (the default)
    Scene alone = scene_of({sheet(0.1, 4, Vector3d::Zero(), Vector3d::Zero())}, R"({"contact": {"self_contact": false}})");
    CHECK_THROWS_WITH_AS(make_simulator(alone), doctest::Contains("self_contact = false"), ConfigError);
  }
}

TEST_SUITE("slow") {
  TEST_CASE("impulse cloth: a soft sheet dropped on its edge crumples onto itself without intersection") {
    // dropVertical in small: a vertical sheet falls on a floor with friction, buckles and
    // piles up in layers (heavy self contact: 211,778 contacts over the 300 steps at 21 x 21).
    Json cloth = sheet(0.5, 21, Vector3d(0, 0, 0.3), Vector3d(0, 0.02, -1.0));
    cloth["mesh"]["plane"] = "xz";
    cloth["material"] = Json::parse(R"({"density": 0.1, "youngs_modulus": 2e6, "poisson_ratio": 0.3, "thickness": 3e-4})");
    const Scene scene = scene_of({cloth}, R"({"obstacles": [{"shape": "plane", "center": [0, 0, 0], "friction": 0.6}],
                                             "contact": {"thickness": 0.002, "cloth_friction": 0.3}})");
    auto sim = make_simulator(scene);
    int hits = 0;
    for (int k = 0; k < 300; ++k) {
      const StepReport r = sim->step();
      REQUIRE_MESSAGE(r.ok(), r.message);
      CAPTURE(k);
      REQUIRE(intersections(scene, sim->state().x) == 0);
      for (int i = 0; i < sim->state().num_vertices(); ++i) REQUIRE(sim->state().position(i).z() >= 0.002 - 1e-12);
      hits += r.contact.contacts;
    }
    MESSAGE("21 x 21 sheet, 300 steps: " << hits << " contacts");
    CHECK(hits > 10000);
  }

  TEST_CASE("impulse cloth: the shipped two sheets on a sphere run without intersection") {
    const char* root = std::getenv("WEFT_SOURCE_DIR");
    const Scene scene = load_scene((std::string(root ? root : ".") + "/scenes/sheets_on_sphere.json"));
    auto sim = make_simulator(scene);
    const ObstacleSpec& sphere = scene.spec.obstacles[0];
    for (int k = 0; k < 240; ++k) {
      const StepReport r = sim->step();
      REQUIRE_MESSAGE(r.ok(), r.message);
      CAPTURE(k);
      REQUIRE(intersections(scene, sim->state().x) == 0);
      for (int i = 0; i < sim->state().num_vertices(); ++i)
        REQUIRE((sim->state().position(i) - sphere.center).norm() >= sphere.radius + 0.003 - 1e-9);
    }
  }
}
