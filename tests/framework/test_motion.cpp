// Scripted rigid motion (framework/motion.hpp): a single phase keeps its formula, phases
// compose exactly (checked against a hand-computed sequence of quarter turns and a
// translation), the motion is continuous at phase boundaries, and bad phases are rejected
// by the scene loader with the key and the valid range named.
#include <doctest/doctest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <numbers>

#include "framework/scene.hpp"

using namespace weft;
using Eigen::Vector3d;

namespace {

constexpr double pi = std::numbers::pi;

MotionPhase phase(const Vector3d& v, const Vector3d& w, double start, double end) {
  MotionPhase p;
  p.velocity = v;
  p.angular_velocity = w;
  p.start = start;
  p.end = end;
  return p;
}

/// A rod family held at its root edge, with `motion` (JSON), and a sphere obstacle with
/// `obstacle_motion` (JSON; null for none).
Json rod_scene(const Json& motion, const Json& obstacle_motion = nullptr) {
  Json doc = Json::parse(R"({
    "rods": [{"shape": "straight", "vertices": 5, "length": 0.1, "root": [0.2, 0, 0], "direction": [1, 0, 0], "root_held": "edge"}],
    "obstacles": [{"shape": "sphere", "center": [0, 0, 0], "radius": 0.1}],
    "time": {"dt": 0.01, "duration": 0.1, "frame_rate": 25}
  })");
  doc["rods"][0]["motion"] = motion;
  if (!obstacle_motion.is_null()) doc["obstacles"][0]["motion"] = obstacle_motion;
  return doc;
}

std::string errors_of(const Json& doc) {
  try {
    build_scene(doc, ".", "test.json");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

}  // namespace

TEST_SUITE("framework") {
  TEST_CASE("motion: a single phase keeps its formula and its keys") {
    Motion m;
    m.velocity = {0.1, -0.2, 0.3};
    m.angular_velocity = {0.4, 0.5, -0.6};
    m.center = {1, 2, 3};
    m.start = 0.5;
    m.end = 2.0;
    const Vector3d x0(0.3, -0.7, 1.1);
    for (double t : {0.0, 0.5, 0.9, 1.7, 2.0, 3.0}) {
      CAPTURE(t);
      const double tau = std::clamp(t, 0.5, 2.0) - 0.5;
      const Eigen::AngleAxisd R(m.angular_velocity.norm() * tau, m.angular_velocity.normalized());
      const Vector3d expected = tau > 0 ? Vector3d(m.center + m.velocity * tau + R * (x0 - m.center)) : x0;
      CHECK((m.apply(x0, t) - expected).norm() == 0);  // the historical code path, bit for bit
      const Motion::Transform T = m.transform(t);
      CHECK((T.rotation * x0 + T.translation - expected).norm() < 1e-14);
    }
    // The same motion as one phase of a multi-phase motion.
    const Motion p = Motion::phased(m.center, {phase(m.velocity, m.angular_velocity, 0.5, 2.0)});
    for (double t : {0.0, 0.7, 1.3, 2.0, 5.0}) CHECK((p.apply(x0, t) - m.apply(x0, t)).norm() < 1e-14);
    CHECK(!m.multi_phase());
    CHECK(m.validate("m").ok());
    CHECK(Motion{}.is_static());

    // A single-phase scene keeps its keys and meaning.
    const char* root = std::getenv("WEFT_SOURCE_DIR");
    REQUIRE(root);
    const Scene whip = load_scene(std::string(root) + "/scenes/whip.json");
    const Motion& wm = whip.spec.rods[0].motion;
    CHECK(!wm.multi_phase());
    CHECK(wm.angular_velocity == Vector3d(0, 0, 5));
    CHECK(wm.start == 0);
    CHECK(std::isinf(wm.end));
    CHECK((wm.apply(Vector3d(0.05, 0, 0), pi / 10) - Vector3d(0, 0.05, 0)).norm() < 1e-15);  // a quarter turn at 5 rad/s
  }

  TEST_CASE("motion: phases compose exactly against a hand-computed sequence") {
    // Centre c; translate by (1, 0, 0) over [0, 1]; rest; a quarter turn about x over [2, 3]
    // (about the moved centre c + (1, 0, 0)); rest; a quarter turn about y over [4, 6].
    const Vector3d c(1, 2, 3), x0(2, 4, 7);
    const Motion m = Motion::phased(c, {phase({1, 0, 0}, {0, 0, 0}, 0, 1), phase({0, 0, 0}, {pi / 2, 0, 0}, 2, 3),
                                        phase({0, 0, 0}, {0, pi / 4, 0}, 4, 6)});
    REQUIRE(m.validate("m").ok());
    Eigen::Matrix3d Rx, Ry;  // quarter turns, by hand
    Rx << 1, 0, 0, 0, 0, -1, 0, 1, 0;
    Ry << 0, 0, 1, 0, 1, 0, -1, 0, 0;
    const Vector3d c1 = c + Vector3d(1, 0, 0);
    const Vector3d after_translation = x0 + Vector3d(1, 0, 0);     // (3, 4, 7)
    const Vector3d after_x = c1 + Rx * (after_translation - c1);    // (3, 2 - 4, 3 + 2) = (3, -2, 5)
    const Vector3d after_y = c1 + Ry * (after_x - c1);              // (2 + 2, -2, 3 - 1) = (4, -2, 2)
    CHECK(after_x == Vector3d(3, -2, 5));
    CHECK(after_y == Vector3d(4, -2, 2));
    const double eps = 1e-14;
    CHECK((m.apply(x0, 0) - x0).norm() == 0);
    CHECK((m.apply(x0, 0.5) - (x0 + Vector3d(0.5, 0, 0))).norm() < eps);
    CHECK((m.apply(x0, 1.5) - after_translation).norm() < eps);
    CHECK((m.apply(x0, 3.0) - after_x).norm() < eps);
    CHECK((m.apply(x0, 3.5) - after_x).norm() < eps);
    CHECK((m.apply(x0, 6.0) - after_y).norm() < eps);
    CHECK((m.apply(x0, 100.0) - after_y).norm() < eps);
    // Mid-phase: an eighth turn about x, by hand: (y, z) - c1 = (2, 4) -> (2 cos - 4 sin, 2 sin + 4 cos).
    const double s = std::sqrt(0.5);
    CHECK((m.apply(x0, 2.5) - Vector3d(3, 2 + (2 - 4) * s, 3 + (2 + 4) * s)).norm() < eps);
    // The centre moves with the body: it is a fixed point of the rotations.
    CHECK((m.apply(c, 5.0) - c1).norm() < eps);
    // The transform agrees with apply, and its rotation is a rotation.
    for (double t : {0.3, 2.2, 4.9, 7.0}) {
      const Motion::Transform T = m.transform(t);
      CHECK((T.rotation * x0 + T.translation - m.apply(x0, t)).norm() < eps);
      CHECK((T.rotation.transpose() * T.rotation - Eigen::Matrix3d::Identity()).norm() < eps);
    }
    // The envelope: the span of the phases and the fastest velocities.
    CHECK(m.start == 0);
    CHECK(m.end == 6);
    CHECK(m.velocity == Vector3d(1, 0, 0));
    CHECK(m.angular_velocity == Vector3d(pi / 2, 0, 0));
    CHECK(!m.is_static());
  }

  TEST_CASE("motion: continuous at phase boundaries") {
    const Motion m = Motion::phased({0.1, -0.2, 0.05}, {phase({0.2, 0, 0}, {0, 0, 3}, 0.2, 0.7), phase({0, 0, 0}, {3, 0, 0}, 1.2, 1.7),
                                                      phase({0, -0.1, 0}, {0, 3, 0}, 1.7, 2.7)});
    const Vector3d x0(0.05, 0.09, 0.02);
    // Speed bound: |v| + |omega| (|x - c| + travel) < 2 m/s here.
    for (double tb : {0.2, 0.7, 1.2, 1.7, 2.7}) {
      CAPTURE(tb);
      for (double h : {1e-3, 1e-6, 1e-9}) {
        CHECK((m.apply(x0, tb + h) - m.apply(x0, tb)).norm() <= 2 * h);
        CHECK((m.apply(x0, tb - h) - m.apply(x0, tb)).norm() <= 2 * h);
      }
    }
    // At rest between phases.
    CHECK((m.apply(x0, 0.8) - m.apply(x0, 1.1)).norm() == 0);
  }

  TEST_CASE("motion: a multi-phase scene loads with its envelope") {
    const Json motion = Json::parse(R"({"center": [0, 0, 0], "phases": [
      {"angular_velocity": [3, 0, 0], "start": 0.2, "end": 0.7}, {"angular_velocity": [0, 0, 4], "start": 1.2, "end": "1.7 s"}]})");
    const Scene s = build_scene(rod_scene(motion, motion), ".", "test.json");
    const Motion& m = s.spec.obstacles[0].motion;
    REQUIRE(m.phases.size() == 2);
    CHECK(m.phases[1].end == 1.7);
    CHECK(m.start == 0.2);
    CHECK(m.end == 1.7);
    CHECK(m.angular_velocity == Vector3d(0, 0, 4));
    CHECK(m.validate("m").ok());  // the envelope is accepted
    REQUIRE(s.rods.motions.size() == 1);
    const Vector3d x0 = s.rods.rest[0].segment<3>(0);
    for (double t : {0.0, 0.5, 1.0, 1.5, 3.0}) CHECK((s.rods.motions[0].apply(x0, t) - m.apply(x0, t)).norm() == 0);
  }

  TEST_CASE("motion: bad phases are rejected with the key and the valid range") {
    auto phases = [](const char* list) { return Json::parse(std::string(R"({"center": [0, 0, 0], "phases": )") + list + "}"); };
    // Overlapping.
    std::string e = errors_of(rod_scene(phases(R"([{"angular_velocity": [1, 0, 0], "start": 0, "end": 1},
                                                    {"angular_velocity": [0, 1, 0], "start": 0.5, "end": 2}])")));
    CAPTURE(e);
    CHECK(contains(e, "rods.0.motion.phases.1.start = 0.5 violates '>= phases.0.end = 1"));
    // Out of order.
    e = errors_of(rod_scene(phases(R"([{"angular_velocity": [1, 0, 0], "start": 2, "end": 3},
                                       {"angular_velocity": [0, 1, 0], "start": 0, "end": 1}])")));
    CHECK(contains(e, "rods.0.motion.phases.1.start = 0 violates '>= phases.0.end = 3"));
    // Empty or reversed phase.
    e = errors_of(rod_scene(phases(R"([{"angular_velocity": [1, 0, 0], "start": 1, "end": 1}])")));
    CHECK(contains(e, "rods.0.motion.phases.0.end = 1 violates '> phases.0.start = 1'"));
    // An open phase before another.
    e = errors_of(rod_scene(phases(R"([{"angular_velocity": [1, 0, 0], "start": 0}, {"angular_velocity": [0, 1, 0], "start": 5, "end": 6}])")));
    CHECK(contains(e, "rods.0.motion.phases.1.start = 5 violates '>= phases.0.end = inf"));
    // Missing start; negative start.
    e = errors_of(rod_scene(phases(R"([{"angular_velocity": [1, 0, 0], "end": 1}])")));
    CHECK(contains(e, "rods.0.motion.phases.0.start is required"));
    e = errors_of(rod_scene(phases(R"([{"angular_velocity": [1, 0, 0], "start": -1, "end": 1}])")));
    CHECK(contains(e, "rods.0.motion.phases.0.start = -1 s is out of range: valid >= 0 s"));
    // Single-phase keys next to phases.
    Json both = phases(R"([{"angular_velocity": [1, 0, 0], "start": 0, "end": 1}])");
    both["velocity"] = {1, 0, 0};
    both["end"] = 4;
    e = errors_of(rod_scene(both));
    CHECK(contains(e, "rods.0.motion.velocity = [1, 0, 0] violates 'unset when `phases` is given"));
    CHECK(contains(e, "rods.0.motion.end = 4 violates 'unset when `phases` is given"));
    // Unknown key inside a phase.
    e = errors_of(rod_scene(phases(R"([{"angular_velocity": [1, 0, 0], "start": 0, "end": 1, "center": [0, 0, 0]}])")));
    CHECK(contains(e, "rods.0.motion.phases.0.center is not a known key"));
    // Obstacles: phases may only rotate (their CCD bounds the motion by one fixed centre).
    e = errors_of(rod_scene(Json::object(), phases(R"([{"velocity": [0, 0, 1], "start": 0, "end": 1}])")));
    CHECK(contains(e, "obstacles.0.motion.phases.0.velocity = [0, 0, 1] violates 'zero for an obstacle"));
    // A sphere whose fastest phase spins it about its centre while another phase swings it.
    Json swing = phases(R"([{"angular_velocity": [0, 0, 5], "start": 0, "end": 1}, {"angular_velocity": [1, 0, 0], "start": 1, "end": 2}])");
    swing["center"] = {0, 0, -1};
    e = errors_of(rod_scene(Json::object(), swing));
    CHECK(contains(e, "obstacles.0.motion.phases.1.angular_velocity = [1, 0, 0] violates 'an axis through the sphere's centre"));
    // A single-phase motion that ends before it starts (rods were not checked before).
    e = errors_of(rod_scene(Json::parse(R"({"velocity": [1, 0, 0], "start": 2, "end": 1})")));
    CHECK(contains(e, "rods.0.motion.end = 1 violates '>= start = 2'"));
  }
}
