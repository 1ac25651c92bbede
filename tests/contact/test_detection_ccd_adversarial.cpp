// CCD on constructed worst cases, each with a known time of impact: motion within the
// triangle's plane (an identically zero cubic), edges that stay parallel, a cubic with a
// double root (a tangential touch), grazing an edge, a triangle that flips over a point,
// contact at t = 0. Every case also runs under a rigid motion of the whole scene (rotation
// and a translation of 10 m), which turns exact zeros of the cubic into rounding noise.
//
// With a distance decreasing at speed v to zero at time tc, the guarantee of ccd.hpp
// places toi in [tc - eta / v, tc - eta / (2 v)].
#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "contact/detection/ccd.hpp"
#include "contact/detection/distance.hpp"

using namespace weft::contact::detection;
using Eigen::Vector3d;

namespace {

constexpr double eta = 1e-6;

struct Motion {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Vector3d T = Vector3d::Zero();
  Stencil apply(const Stencil& x) const {
    Stencil y;
    for (int j = 0; j < 4; ++j) y[j] = R * x[j] + T;
    return y;
  }
};

std::vector<Motion> motions() {
  Motion m;
  m.R = Eigen::AngleAxisd(0.7, Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  m.T = Vector3d(10, -7, 4);
  return {Motion{}, m};
}

Impact vf(const Motion& m, const Stencil& x0, const Stencil& x1) {
  return vertex_triangle_ccd(m.apply(x0), m.apply(x1), eta);
}
Impact ee(const Motion& m, const Stencil& x0, const Stencil& x1) {
  return edge_edge_ccd(m.apply(x0), m.apply(x1), eta);
}

// toi in [tc - eta / v, tc - eta / (2 v)], up to rounding.
void check_toi(const Impact& imp, double tc, double v) {
  CAPTURE(imp.toi);
  CAPTURE(tc);
  REQUIRE(imp.hit);
  CHECK_FALSE(imp.conservative);
  CHECK(imp.toi >= tc - eta / v - 1e-12);
  CHECK(imp.toi <= tc - 0.5 * eta / v + 1e-12);
  CHECK(imp.distance <= eta);
}

const Vector3d A(0, 0, 0), B(1, 0, 0), C(0, 1, 0);

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("detection ccd adversarial: vertex moving within the triangle's plane") {
    for (const Motion& m : motions()) {
      // Enters through edge ab at t = 0.5, speed 1.
      check_toi(vf(m, {Vector3d(0.5, -0.5, 0), A, B, C}, {Vector3d(0.5, 0.5, 0), A, B, C}), 0.5, 1.0);
      // Slides along ab outside it at 3 eta: no hit, and cheap (the separating-axis step).
      const Impact slide = vf(m, {Vector3d(-1, -3 * eta, 0), A, B, C}, {Vector3d(2, -3 * eta, 0), A, B, C});
      CHECK_FALSE(slide.hit);
      CHECK(slide.iterations < 50);
      // Slides along ab at 0.4 eta: hit when it reaches a, x(t) = -1 + 3 t.
      const Impact close = vf(m, {Vector3d(-1, -0.4 * eta, 0), A, B, C}, {Vector3d(2, -0.4 * eta, 0), A, B, C});
      REQUIRE(close.hit);
      CHECK(close.toi >= 1.0 / 3 - eta / 3 - 1e-12);
      CHECK(close.toi <= 1.0 / 3 + 1e-12);
      // Coplanar, far outside.
      CHECK_FALSE(vf(m, {Vector3d(2, 2, 0), A, B, C}, {Vector3d(3, -1, 0), A, B, C}).hit);
      // Coplanar and inside for the whole step: contact at t = 0.
      const Impact inside = vf(m, {Vector3d(0.2, 0.2, 0), A, B, C}, {Vector3d(0.3, 0.1, 0), A, B, C});
      REQUIRE(inside.hit);
      CHECK(inside.toi == 0);
    }
  }

  TEST_CASE("detection ccd adversarial: edges that stay parallel") {
    for (const Motion& m : motions()) {
      // b = a + (0, 1 - 2t, 1 - 2t): crosses a at t = 0.5, distance sqrt(2) |1 - 2t|.
      const Stencil x0{A, B, Vector3d(0, 1, 1), Vector3d(1, 1, 1)}, x1{A, B, Vector3d(0, -1, -1), Vector3d(1, -1, -1)};
      check_toi(ee(m, x0, x1), 0.5, 2 * std::sqrt(2.0));
      // The same motion shifted along x beyond a's end: never closer than 1.
      const Vector3d s(2, 0, 0);
      CHECK_FALSE(ee(m, {A, B, x0[2] + s, x0[3] + s}, {A, B, x1[2] + s, x1[3] + s}).hit);
      // Collinear: b slides along a's line and touches a's end at t = 0.2, speed 5.
      check_toi(ee(m, {A, B, Vector3d(2, 0, 0), Vector3d(3, 0, 0)}, {A, B, Vector3d(-3, 0, 0), Vector3d(-2, 0, 0)}), 0.2,
                5.0);
      // Parallel, approaching to 2 eta and stopping: no hit.
      CHECK_FALSE(ee(m, {A, B, Vector3d(0, 0, 1), Vector3d(1, 0, 1)}, {A, B, Vector3d(0, 0, 2 * eta), Vector3d(1, 0, 2 * eta)}).hit);
      // Parallel, approaching to 0.3 eta: hit near the end of the step.
      const Impact near = ee(m, {A, B, Vector3d(0, 0, 1), Vector3d(1, 0, 1)}, {A, B, Vector3d(0, 0, 0.3 * eta), Vector3d(1, 0, 0.3 * eta)});
      REQUIRE(near.hit);
      CHECK(near.toi > 0.999);
    }
  }

  TEST_CASE("detection ccd adversarial: a cubic with a double root is a tangential touch") {
    // a = 0, b = (1, 0, 0), c(t) = (0, 1, s), p(t) = (1/4, 1/4 - s, s / 4 + z) with s = t - 1/2:
    // f(t) = s^2 + z: for z = 0 a double root at t = 1/2, where p touches the triangle's
    // interior from one side; the distance is about s^2, so toi is near 1/2 - sqrt(eta).
    auto run = [](const Motion& m, double z) {
      auto p = [&](double s) { return Vector3d(0.25, 0.25 - s, 0.25 * s + z); };
      const Stencil x0{p(-0.5), A, B, Vector3d(0, 1, -0.5)}, x1{p(0.5), A, B, Vector3d(0, 1, 0.5)};
      return vf(m, x0, x1);
    };
    for (const Motion& m : motions()) {
      // The cubic: zero at 1/2, positive on both sides (no sign change to find).
      auto f = [&](double t) {
        const double s = t - 0.5;
        const Vector3d c(0, 1, s), pv(0.25, 0.25 - s, 0.25 * s);
        return B.cross(c).dot(pv);
      };
      CHECK(std::abs(f(0.5)) < 1e-16);
      CHECK(f(0.499) > 0);
      CHECK(f(0.501) > 0);
      const Impact touch = run(m, 0.0);
      REQUIRE(touch.hit);
      CHECK(touch.toi >= 0.5 - std::sqrt(eta) * 1.01);
      CHECK(touch.toi <= 0.5 - std::sqrt(0.5 * eta) * 0.99);
      CHECK(std::abs(touch.normal.dot(m.R * Vector3d(0, 0, 1))) > 0.99);  // the face normal, about +z
      // Lifted by 10 eta: a near miss.
      CHECK_FALSE(run(m, 10 * eta).hit);
      // Lowered by 1e-8: two simple roots 2e-4 apart; the earliest contact wins.
      const Impact cross = run(m, -1e-8);
      REQUIRE(cross.hit);
      CHECK(cross.toi <= 0.5 - 1e-4);
      CHECK(cross.toi >= 0.5 - std::sqrt(eta + 1e-8) * 1.01);
    }
  }

  TEST_CASE("detection ccd adversarial: a point that grazes an edge") {
    for (const Motion& m : motions()) {
      auto down = [&](double off) {
        return vf(m, {Vector3d(0.5, -off, 1), A, B, C}, {Vector3d(0.5, -off, -1), A, B, C});
      };
      check_toi(down(0), 0.5, 2.0);           // through the edge point (0.5, 0, 0)
      CHECK(down(0.3 * eta).hit);             // within eta/2 of the edge
      CHECK_FALSE(down(1e-3).hit);            // outside by 1e-3
      // Edge b sweeps down across a's endpoint (1, 0, 0).
      auto sweep = [&](double off) {
        return ee(m, {A, B, Vector3d(1 + off, -1, 1), Vector3d(1 + off, 1, 1)},
                  {A, B, Vector3d(1 + off, -1, -1), Vector3d(1 + off, 1, -1)});
      };
      check_toi(sweep(0), 0.5, 2.0);
      CHECK(sweep(0.4 * eta).hit);
      CHECK_FALSE(sweep(1e-4).hit);
    }
  }

  TEST_CASE("detection ccd adversarial: a triangle that flips over a point") {
    // c(t) = (0.5, 1 - 2t, 0) passes through edge ab at t = 0.5 (the triangle degenerates
    // and its normal reverses), then sweeps down over p = (0.5, -0.5, h) at t = 0.75.
    for (const Motion& m : motions()) {
      auto flip = [&](double h) {
        const Vector3d p(0.5, -0.5, h);
        return vf(m, {p, A, B, Vector3d(0.5, 1, 0)}, {p, A, B, Vector3d(0.5, -1, 0)});
      };
      check_toi(flip(0), 0.75, 2.0);
      CHECK(flip(0.3 * eta).hit);
      CHECK_FALSE(flip(1e-3).hit);
    }
    // Out of the plane: a(t) = (0, 0, 0.2 s) and c(t) = (0.5, -2 s, 0), s = t - 1/2. The
    // triangle degenerates at s = 0 (c on line ab) and its plane rotates: the cubic has
    // a root there, with p far away (rejected by the distance test), and another at
    // s = 1/4, where p = (0.5, -0.25, 0.0125) lies in the triangle's interior.
    for (const Motion& m : motions()) {
      const Vector3d p(0.5, -0.25, 0.0125);
      const Stencil x0{p, Vector3d(0, 0, -0.1), B, Vector3d(0.5, 1, 0)}, x1{p, Vector3d(0, 0, 0.1), B, Vector3d(0.5, -1, 0)};
      auto dist = [&](double t) {
        const Vector3d a(0, 0, 0.2 * (t - 0.5)), c(0.5, -2 * (t - 0.5), 0);
        return std::sqrt(point_triangle_distance(p, a, B, c).distance_squared);
      };
      CHECK(dist(0.5) > 0.2);
      CHECK(dist(0.75) < 1e-15);
      const double v = dist(0.75 - 1e-6) / 1e-6;  // approach speed at contact
      const Impact tilt = vf(m, x0, x1);
      REQUIRE(tilt.hit);
      CHECK(tilt.toi >= 0.75 - 1.001 * eta / v);
      CHECK(tilt.toi <= 0.75 - 0.999 * 0.5 * eta / v);
    }
  }

  TEST_CASE("detection ccd adversarial: contact at the start of the step and separating pairs") {
    for (const Motion& m : motions()) {
      // Within eta at t = 0, moving away: hit at 0, normal from the triangle to the vertex.
      const Impact start = vf(m, {Vector3d(0.2, 0.2, 0.3 * eta), A, B, C}, {Vector3d(0.2, 0.2, 1), A, B, C});
      REQUIRE(start.hit);
      CHECK(start.toi == 0);
      CHECK(start.normal.dot(m.R * Vector3d(0, 0, 1)) > 0.999);
      // Crossing edges at t = 0.
      const Impact cross = ee(m, {A, B, Vector3d(0.5, -1, 0), Vector3d(0.5, 1, 0)},
                              {A, B, Vector3d(0.5, -1, 1), Vector3d(0.5, 1, 1)});
      REQUIRE(cross.hit);
      CHECK(cross.toi == 0);
      // Far apart: rejected by the cubic alone, no distance evaluation.
      const Impact far = vf(m, {Vector3d(5, 5, 5), A, B, C}, {Vector3d(6, 5, 5), A, B, C});
      CHECK_FALSE(far.hit);
      CHECK(far.iterations == 0);
    }
  }

  TEST_CASE("detection ccd adversarial: normals point from B to A before contact") {
    for (const Motion& m : motions()) {
      const Vector3d up = m.R * Vector3d(0, 0, 1);
      // Vertex from above and from below the triangle (face normal +z).
      const Impact above = vf(m, {Vector3d(0.2, 0.3, 1), A, B, C}, {Vector3d(0.2, 0.3, -1), A, B, C});
      const Impact below = vf(m, {Vector3d(0.2, 0.3, -1), A, B, C}, {Vector3d(0.2, 0.3, 1), A, B, C});
      REQUIRE(above.hit);
      REQUIRE(below.hit);
      CHECK(above.normal.dot(up) > 1 - 1e-12);
      CHECK(below.normal.dot(up) < -1 + 1e-12);
      CHECK(above.gamma[0] == 1);
      CHECK(above.gamma[1] == doctest::Approx(-0.5).epsilon(1e-6));
      CHECK(above.gamma[2] == doctest::Approx(-0.2).epsilon(1e-6));
      CHECK(above.gamma[3] == doctest::Approx(-0.3).epsilon(1e-6));
      // Edge a comes down onto edge b: the normal points up, from b to a.
      const Impact e = ee(m, {Vector3d(0, 0.5, 1), Vector3d(1, 0.5, 1), Vector3d(0.5, 0, 0), Vector3d(0.5, 1, 0)},
                          {Vector3d(0, 0.5, -1), Vector3d(1, 0.5, -1), Vector3d(0.5, 0, 0), Vector3d(0.5, 1, 0)});
      REQUIRE(e.hit);
      CHECK(e.normal.dot(up) > 1 - 1e-12);
      CHECK(e.toi == doctest::Approx(0.5).epsilon(1e-5));
      CHECK(e.gamma[0] == doctest::Approx(0.5).epsilon(1e-6));
      CHECK(e.gamma[3] == doctest::Approx(-0.5).epsilon(1e-6));
    }
  }
}
