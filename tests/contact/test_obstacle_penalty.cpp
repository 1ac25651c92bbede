#include <doctest/doctest.h>

#include <random>

#include "framework/scene.hpp"
#include "policies/presets.hpp"
#include "policies/registry.hpp"

using namespace weft;
using contact::ObstaclePose;

namespace {
ObstacleSpec make_obstacle(ObstacleShape shape) {
  ObstacleSpec o;
  o.shape = shape;
  o.center = {0.1, -0.2, 0.3};
  o.radius = 0.4;
  o.half_extents = {0.3, 0.2, 0.5};
  o.normal = Eigen::Vector3d(1, 2, 3).normalized();
  o.motion.angular_velocity = {0.3, -0.2, 0.5};  // a rotated pose at t = 1
  o.motion.center = o.center;
  return o;
}

Scene sheet_over(const std::string& obstacles, const std::string& extra = "{}") {
  Json doc = Json::parse(R"({
    "combo": "cloth_ip_penalty_direct",
    "cloths": [{"mesh": {"source": "rectangle", "size": [0.6, 0.6], "resolution": [9, 9]},
                "material": {"density": 0.1, "youngs_modulus": 1e8, "thickness": 1e-3}}],
    "contact": {"stiffness": 1e7, "thickness": 0.002},
    "time": {"dt": 0.004166666666666667, "duration": 1.0, "frame_rate": 24}
  })");
  doc["obstacles"] = Json::parse(obstacles);
  doc.merge_patch(Json::parse(extra));
  return build_scene(doc, ".", "test");
}
}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("obstacle distance: gradient and Hessian match finite differences for every shape and region") {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (auto shape : {ObstacleShape::sphere, ObstacleShape::box, ObstacleShape::plane}) {
      const ObstaclePose p = ObstaclePose::at(make_obstacle(shape), 1.0);
      int checked = 0;
      for (int trial = 0; trial < 200; ++trial) {
        const Eigen::Vector3d x = p.center + Eigen::Vector3d(u(rng), u(rng), u(rng));
        const auto d = p.distance(x);
        const double h = 1e-6;
        Eigen::Vector3d g_fd;
        Eigen::Matrix3d H_fd;
        bool smooth = true;
        for (int k = 0; k < 3; ++k) {
          const Eigen::Vector3d e = h * Eigen::Vector3d::Unit(k);
          const auto dp = p.distance(x + e), dm = p.distance(x - e);
          g_fd[k] = (dp.phi - dm.phi) / (2 * h);
          H_fd.col(k) = (dp.grad - dm.grad) / (2 * h);
          smooth = smooth && (dp.grad - dm.grad).norm() < 1e-3;  // skip points on a region boundary
        }
        if (!smooth) continue;
        CAPTURE(static_cast<int>(shape));
        CAPTURE(trial);
        REQUIRE(d.grad.norm() > 0.5);
        CHECK((d.grad - g_fd).norm() <= 1e-7);
        CHECK((d.hess - H_fd).norm() <= 1e-5 * std::max(1.0, d.hess.norm()));
        CHECK(std::abs(d.grad.norm() - 1.0) <= 1e-12);  // an exact distance field
        ++checked;
      }
      CHECK(checked > 150);
    }
  }

  TEST_CASE("obstacle distance: box regions give the exact Euclidean distance") {
    ObstacleSpec o;
    o.shape = ObstacleShape::box;
    o.half_extents = {1, 2, 3};
    const ObstaclePose p = ObstaclePose::at(o, 0.0);
    CHECK(p.distance({1.5, 0, 0}).phi == doctest::Approx(0.5));          // face
    CHECK(p.distance({2, 3, 0}).phi == doctest::Approx(std::sqrt(2.0))); // edge
    CHECK(p.distance({2, 3, 4}).phi == doctest::Approx(std::sqrt(3.0))); // corner
    CHECK(p.distance({0.5, 0, 0}).phi == doctest::Approx(-0.5));         // inside, nearest face x
  }

  TEST_CASE("obstacle penalty: energy gradient and Hessian match finite differences") {
    const Scene scene = sheet_over(R"([{"shape": "sphere", "center": [0, 0, -0.38], "radius": 0.4},
                                       {"shape": "box", "center": [0.3, 0.3, -0.2], "half_extents": [0.1, 0.1, 0.2]}])");
    contact::ObstaclePenalty c(scene, {.stiffness = 1e6, .thickness = 0.01});
    AssemblyPlan plan;
    c.declare(plan);
    plan.finalize(scene.mesh.num_vertices());
    State s = scene.initial_state();
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-0.01, 0.01);
    for (int i = 0; i < s.x.size(); ++i) s.x[i] += u(rng);
    c.begin_step(s, 0.0);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(s.x.size());
    c.add_gradient(s, g);
    REQUIRE(g.norm() > 0);  // vertices really are in contact
    const double h = 1e-7;
    Eigen::VectorXd g_fd(s.x.size());
    for (int i = 0; i < s.x.size(); ++i) {
      State a = s, b = s;
      a.x[i] += h;
      b.x[i] -= h;
      g_fd[i] = (c.energy(a) - c.energy(b)) / (2 * h);
    }
    CHECK((g - g_fd).norm() <= 1e-6 * g.norm());
    ElementBuffer buf = plan.make_buffer();
    BlockCsr H = plan.pattern();
    buf.start(H);
    c.add_hessian(s, buf, HessianMode::exact);
    buf.finish();
    const Eigen::MatrixXd Hd = H.to_dense();
    Eigen::MatrixXd H_fd(s.x.size(), s.x.size());
    for (int i = 0; i < s.x.size(); ++i) {
      State a = s, b = s;
      a.x[i] += h;
      b.x[i] -= h;
      Eigen::VectorXd ga = Eigen::VectorXd::Zero(s.x.size()), gb = ga;
      c.add_gradient(a, ga);
      c.add_gradient(b, gb);
      H_fd.col(i) = (ga - gb) / (2 * h);
    }
    REQUIRE(Hd.norm() > 0);
    CHECK((Hd - H_fd).norm() <= 1e-5 * Hd.norm());
  }

  TEST_CASE("obstacle penalty: a sheet dropped on a plane comes to rest on it without sinking") {
    const Scene scene = sheet_over(R"([{"shape": "plane", "center": [0, 0, -0.1], "normal": [0, 0, 1]}])");
    auto sim = make_simulator(scene);
    const double kappa = 1e7, delta = 0.002, g = 9.81;
    double lowest = 1;
    for (int k = 0; k < 240; ++k) {
      const StepReport r = sim->step();
      REQUIRE_MESSAGE(r.ok(), r.message);
      for (int i = 0; i < sim->state().num_vertices(); ++i) lowest = std::min(lowest, sim->state().position(i).z());
    }
    // At rest the penalty balances gravity: the layer is compressed by g / kappa only.
    const double rest_height = -0.1 + delta - g / kappa;
    CHECK(lowest >= -0.1);  // never below the plane itself
    for (int i = 0; i < sim->state().num_vertices(); ++i)
      CHECK(sim->state().position(i).z() == doctest::Approx(rest_height).epsilon(1e-5));
    CHECK(sim->energies().kinetic < 1e-8);
  }

  TEST_CASE("obstacle penalty: the drape never enters the sphere and comes to rest over it") {
    const Scene scene = sheet_over(R"([{"shape": "sphere", "center": [0, 0, -0.3], "radius": 0.2}])",
                                   R"({"damping": {"mass": 2.0}})");
    auto sim = make_simulator(scene);
    double min_phi = 1;
    int max_contacts = 0;
    for (int k = 0; k < 480; ++k) {
      const StepReport r = sim->step();
      REQUIRE_MESSAGE(r.ok(), r.message);
      max_contacts = std::max(max_contacts, r.contact.contacts);
      for (int i = 0; i < sim->state().num_vertices(); ++i)
        min_phi = std::min(min_phi, (sim->state().position(i) - Eigen::Vector3d(0, 0, -0.3)).norm() - 0.2);
    }
    CHECK(max_contacts > 0);
    CHECK(min_phi > 0.0);  // no vertex inside the sphere at any step
    CHECK(min_phi < 0.002);  // and the cloth does lie on it
  }

  TEST_CASE("obstacle penalty: friction and a missing stiffness are configuration errors") {
    Scene scene = sheet_over(R"([{"shape": "plane", "center": [0, 0, -0.1], "friction": 0.3}])");
    CHECK_THROWS_WITH_AS(make_simulator(scene), doctest::Contains("obstacles.0.friction = 0.3 violates"), ConfigError);
    scene = sheet_over(R"([{"shape": "plane", "center": [0, 0, -0.1]}])");
    scene.solver.erase("contact");
    CHECK_THROWS_WITH_AS(make_simulator(scene), doctest::Contains("contact.stiffness = unset violates"), ConfigError);
  }
}
