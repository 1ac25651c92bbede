// CCD against brute force on random trajectories. The oracle samples the distance at
// 2001 times and, between samples where the coplanarity function changes sign, bisects
// it to the crossing and measures the distance there: a contact (distance <= 1e-9) at
// any sample or crossing is a collision at that time. The cases are built to pass close
// to contact at a random time, so that a good fraction collides (checked, so the
// comparison is not vacuous), and the rest are near misses.
//
// Checked against ccd.hpp's guarantee, eta = 1e-6:
//  - no false negative: every oracle collision is a hit with toi <= its time;
//  - hits are within eta at toi, and no sample before toi is within eta/2;
//  - no hit means no sample within eta/2;
//  - the time of impact is within 1.1 eta / (normal approach speed) of the collision
//    (first order: the plane or line distance reaches eta that long before contact).
#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "contact/detection/ccd.hpp"
#include "contact/detection/distance.hpp"

using namespace weft::contact::detection;
using Eigen::Vector3d;

namespace {

enum class Kind { vf, ee };
constexpr double eta = 1e-6;
constexpr double touch = 1e-9;  // the oracle's contact distance
constexpr int samples = 2000;

Stencil at(const Stencil& x0, const Stencil& x1, double t) {
  Stencil x;
  for (int j = 0; j < 4; ++j) x[j] = x0[j] + t * (x1[j] - x0[j]);
  return x;
}

double distance(Kind k, const Stencil& x) {
  if (k == Kind::vf) return std::sqrt(point_triangle_distance(x[0], x[1], x[2], x[3]).distance_squared);
  return std::sqrt(segment_segment_distance(x[0], x[1], x[2], x[3]).distance_squared);
}

// Unnormalised normal n and coplanarity f = n . (offset), as in ccd.hpp.
std::pair<Vector3d, double> coplanarity(Kind k, const Stencil& x) {
  if (k == Kind::vf) {
    const Vector3d n = (x[2] - x[1]).cross(x[3] - x[1]);
    return {n, n.dot(x[0] - x[1])};
  }
  const Vector3d n = (x[1] - x[0]).cross(x[3] - x[2]);
  return {n, n.dot(x[2] - x[0])};
}

struct Oracle {
  bool collides = false;
  double t = 2;                // earliest collision time
  std::vector<double> d;       // distance at the samples t_k = k / samples
};

Oracle oracle(Kind k, const Stencil& x0, const Stencil& x1) {
  Oracle o;
  o.d.resize(samples + 1);
  auto f = [&](double t) { return coplanarity(k, at(x0, x1, t)).second; };
  for (int i = 0; i <= samples; ++i) {
    const double t = double(i) / samples;
    o.d[i] = distance(k, at(x0, x1, t));
    if (o.d[i] <= touch && t < o.t) o.t = t;
  }
  for (int i = 0; i < samples && double(i) / samples < o.t; ++i) {
    double lo = double(i) / samples, hi = double(i + 1) / samples;
    double flo = f(lo);
    if ((flo > 0) == (f(hi) > 0)) continue;
    for (int it = 0; it < 80; ++it) {
      const double mid = 0.5 * (lo + hi);
      const double fm = f(mid);
      if ((fm > 0) == (flo > 0)) {
        lo = mid;
        flo = fm;
      } else {
        hi = mid;
      }
    }
    for (double t : {lo, hi})
      if (distance(k, at(x0, x1, t)) <= touch && t < o.t) o.t = t;
  }
  o.collides = o.t <= 1;
  return o;
}

Vector3d random_vector(std::mt19937& rng, double a) {
  std::uniform_real_distribution<double> u(-a, a);
  return {u(rng), u(rng), u(rng)};
}

// A random pair whose closest features pass within ~0.05 of each other at a random time.
void random_case(Kind k, std::mt19937& rng, Stencil& x0, Stencil& x1) {
  std::uniform_real_distribution<double> unit(0, 1);
  for (int j = 0; j < 4; ++j) {
    x0[j] = random_vector(rng, 1);
    x1[j] = x0[j] + random_vector(rng, 0.5);
  }
  const double tm = unit(rng);
  const Stencil xm = at(x0, x1, tm);
  const auto [n, f] = coplanarity(k, xm);
  (void)f;
  const Vector3d nh = n.normalized();
  const Vector3d offset = (unit(rng) - 0.5) * 0.1 * nh + random_vector(rng, 0.15);
  if (k == Kind::vf) {
    // Put the vertex near a random point of the triangle at tm; it moves with its own velocity.
    double u = unit(rng), v = unit(rng);
    if (u + v > 1) {
      u = 1 - u;
      v = 1 - v;
    }
    const Vector3d pm = xm[1] + u * (xm[2] - xm[1]) + v * (xm[3] - xm[1]) + offset;
    const Vector3d vel = random_vector(rng, 1.5);
    x0[0] = pm - tm * vel;
    x1[0] = x0[0] + vel;
  } else {
    // Translate edge b so that a point of it sits near a point of edge a at tm.
    const Vector3d qa = xm[0] + unit(rng) * (xm[1] - xm[0]);
    const Vector3d qb = xm[2] + unit(rng) * (xm[3] - xm[2]);
    const Vector3d shift = qa + offset - qb;
    for (int j = 2; j < 4; ++j) {
      x0[j] += shift;
      x1[j] += shift;
    }
  }
}

// Normal approach speed at a collision time t: the rate of |f| / |n| (plane or line distance).
double approach_speed(Kind k, const Stencil& x0, const Stencil& x1, double t) {
  const double h = 1e-7;
  auto plane = [&](double s) {
    const auto [n, f] = coplanarity(k, at(x0, x1, s));
    return f / n.norm();
  };
  return std::abs(plane(t + h) - plane(t - h)) / (2 * h);
}

struct Tally {
  int cases = 0, collisions = 0, hits = 0, within_bound = 0, transversal = 0;
  double worst_lag = 0;
};

void check_case(Kind k, const Stencil& x0, const Stencil& x1, Tally& tally) {
  const Oracle o = oracle(k, x0, x1);
  const Impact imp = k == Kind::vf ? vertex_triangle_ccd(x0, x1, eta) : edge_edge_ccd(x0, x1, eta);
  ++tally.cases;
  tally.collisions += o.collides;
  tally.hits += imp.hit;
  CAPTURE(o.collides);
  CAPTURE(o.t);
  CAPTURE(imp.hit);
  CAPTURE(imp.toi);
  CAPTURE(imp.iterations);
  if (o.collides) {
    REQUIRE(imp.hit);  // no false negative
    CHECK(imp.toi <= o.t + 1e-12);
    const double speed = approach_speed(k, x0, x1, o.t);
    if (speed > 1e-2 && o.t > 1e-3 && o.t < 1 - 1e-3) {
      ++tally.transversal;
      const double lag = (o.t - imp.toi) * speed / eta;  // in units of eta / speed
      tally.worst_lag = std::max(tally.worst_lag, lag);
      tally.within_bound += lag <= 1.1;
    }
  }
  if (imp.hit) {
    CHECK_FALSE(imp.conservative);
    const double d = distance(k, at(x0, x1, imp.toi));
    CHECK(d <= eta * (1 + 1e-9));
    CHECK(imp.distance == doctest::Approx(d).epsilon(1e-12));
    CHECK(std::abs(imp.normal.norm() - 1) < 1e-12);
    CHECK(std::abs(imp.gamma[0] + imp.gamma[1] + imp.gamma[2] + imp.gamma[3]) < 1e-14);
    int early = 0;
    for (int i = 0; i <= samples && double(i) / samples < imp.toi; ++i) early += o.d[i] <= 0.5 * eta;
    CHECK(early == 0);
  } else {
    int close = 0;
    for (double d : o.d) close += d <= 0.5 * eta;
    CHECK(close == 0);
  }
}

void run_random(Kind k, int cases, unsigned seed) {
  std::mt19937 rng(seed);
  Tally tally;
  for (int trial = 0; trial < cases; ++trial) {
    CAPTURE(trial);
    Stencil x0, x1;
    random_case(k, rng, x0, x1);
    check_case(k, x0, x1, tally);
  }
  CAPTURE(tally.collisions);
  CAPTURE(tally.hits);
  CAPTURE(tally.transversal);
  CAPTURE(tally.worst_lag);
  // Not vacuous: a good fraction collides, and a good fraction does not.
  CHECK(tally.collisions >= cases / 5);
  CHECK(tally.collisions <= cases * 4 / 5);
  // Time of impact: within 1.1 eta / speed of the collision for transversal crossings.
  CHECK(tally.transversal >= tally.collisions / 2);
  CHECK(tally.within_bound == tally.transversal);
  // Hits that the oracle does not see are near misses within eta (checked per case).
  CHECK(tally.hits >= tally.collisions);
}

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("detection ccd: vertex-triangle matches brute force on random trajectories") {
    run_random(Kind::vf, 400, 31);
  }

  TEST_CASE("detection ccd: edge-edge matches brute force on random trajectories") {
    run_random(Kind::ee, 400, 32);
  }
}

TEST_SUITE("slow") {
  TEST_CASE("detection ccd: brute force comparison on many random trajectories") {
    run_random(Kind::vf, 20000, 33);
    run_random(Kind::ee, 20000, 34);
  }
}
