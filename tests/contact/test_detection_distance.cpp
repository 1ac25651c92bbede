// Closest-point routines against brute force. Both distances are minima of a convex
// function over two parameters; the brute force minimises over the inner parameter in
// closed form (a clamped projection onto a line, written here independently) and samples
// the outer one densely: the outer function is convex (a partial minimum of a convex
// function), so a 64-point grid zoomed 12 times around its best sample converges to the
// minimum, even for needle triangles, whose 2D parameterisation misleads a 2D grid.
#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>

#include "contact/detection/distance.hpp"

using namespace weft::contact::detection;
using Eigen::Vector3d;

namespace {

// min over s in [0, 1] of g(s), g convex, by zooming a grid around its best sample.
template <class G>
double minimise_convex(const G& g) {
  double lo = 0, hi = 1, best = std::numeric_limits<double>::infinity(), best_s = 0;
  const int n = 64;
  for (int level = 0; level < 12; ++level) {
    for (int i = 0; i <= n; ++i) {
      const double s = lo + (hi - lo) * i / n;
      const double d = g(s);
      if (d < best) {
        best = d;
        best_s = s;
      }
    }
    const double h = 2 * (hi - lo) / n;
    lo = std::max(0.0, best_s - h);
    hi = std::min(1.0, best_s + h);
  }
  return best;
}

// Distance from p to the segment q + u e, u in [0, umax].
double to_segment(const Vector3d& p, const Vector3d& q, const Vector3d& e, double umax) {
  const double ee = e.squaredNorm();
  const double u = ee > 0 ? std::clamp((p - q).dot(e) / ee, 0.0, umax) : 0.0;
  return (p - q - u * e).norm();
}

double brute_point_triangle(const Vector3d& p, Vector3d a, Vector3d b, Vector3d c) {
  // Inner (exact) direction along the longest edge, a -> b.
  for (int k = 0; k < 3 && ((b - a).squaredNorm() < (c - b).squaredNorm() || (b - a).squaredNorm() < (a - c).squaredNorm()); ++k) {
    const Vector3d t = a;
    a = b;
    b = c;
    c = t;
  }
  // Points a + u (b - a) + v (c - a), u in [0, 1 - v]: for fixed v a segment.
  return minimise_convex([&](double v) { return to_segment(p, a + v * (c - a), b - a, 1 - v); });
}

double brute_segment_segment(const Vector3d& a0, const Vector3d& a1, const Vector3d& b0, const Vector3d& b1) {
  return minimise_convex([&](double s) { return to_segment(a0 + s * (a1 - a0), b0, b1 - b0, 1.0); });
}

// Every invariant of a point-triangle result, and the distance against brute force.
void check_point_triangle(const Vector3d& p, const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  CAPTURE(p.transpose());
  CAPTURE(a.transpose());
  CAPTURE(b.transpose());
  CAPTURE(c.transpose());
  const PointTriangle r = point_triangle_distance(p, a, b, c);
  const double scale = std::max({(b - a).norm(), (c - a).norm(), (p - a).norm(), 1e-300});
  const double coord = std::max({p.cwiseAbs().maxCoeff(), a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff(),
                                 c.cwiseAbs().maxCoeff()});
  CHECK(r.weights.minCoeff() >= 0);
  CHECK(std::abs(r.weights.sum() - 1) <= 1e-14);
  CHECK((r.closest - (r.weights[0] * a + r.weights[1] * b + r.weights[2] * c)).norm() <= 1e-13 * (coord + scale));
  CHECK(std::abs(std::sqrt(r.distance_squared) - (p - r.closest).norm()) <= 1e-13 * (coord + scale));
  const double bf = brute_point_triangle(p, a, b, c);
  CAPTURE(bf);
  CAPTURE(std::sqrt(r.distance_squared));
  // The brute force samples actual points, so it can only be above the minimum.
  CHECK(std::sqrt(r.distance_squared) <= bf + 1e-12 * (coord + scale));
  CHECK(std::sqrt(r.distance_squared) >= bf - 1e-9 * scale - 1e-13 * coord);
}

void check_segment_segment(const Vector3d& a0, const Vector3d& a1, const Vector3d& b0, const Vector3d& b1) {
  CAPTURE(a0.transpose());
  CAPTURE(a1.transpose());
  CAPTURE(b0.transpose());
  CAPTURE(b1.transpose());
  const SegmentSegment r = segment_segment_distance(a0, a1, b0, b1);
  const double scale = std::max({(a1 - a0).norm(), (b1 - b0).norm(), (b0 - a0).norm(), 1e-300});
  const double coord = std::max({a0.cwiseAbs().maxCoeff(), a1.cwiseAbs().maxCoeff(), b0.cwiseAbs().maxCoeff(),
                                 b1.cwiseAbs().maxCoeff()});
  CHECK(r.s >= 0);
  CHECK(r.s <= 1);
  CHECK(r.t >= 0);
  CHECK(r.t <= 1);
  CHECK((r.closest_a - (a0 + r.s * (a1 - a0))).norm() <= 1e-14 * (coord + scale));
  CHECK((r.closest_b - (b0 + r.t * (b1 - b0))).norm() <= 1e-14 * (coord + scale));
  CHECK(std::abs(std::sqrt(r.distance_squared) - (r.closest_a - r.closest_b).norm()) <= 1e-13 * (coord + scale));
  const double bf = brute_segment_segment(a0, a1, b0, b1);
  CAPTURE(bf);
  CAPTURE(std::sqrt(r.distance_squared));
  CHECK(std::sqrt(r.distance_squared) <= bf + 1e-12 * (coord + scale));
  CHECK(std::sqrt(r.distance_squared) >= bf - 1e-9 * scale - 1e-13 * coord);
}

Vector3d random_vector(std::mt19937& rng, double lo = -1, double hi = 1) {
  std::uniform_real_distribution<double> u(lo, hi);
  return {u(rng), u(rng), u(rng)};
}

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("detection distance: point-triangle matches brute force on random configurations") {
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> unit(0, 1);
    for (int trial = 0; trial < 300; ++trial) {
      CAPTURE(trial);
      const Vector3d offset = trial % 3 == 0 ? random_vector(rng, -100, 100) : Vector3d::Zero();
      const Vector3d a = offset + random_vector(rng), b = offset + random_vector(rng), c = offset + random_vector(rng);
      // Points above the interior, near edges and vertices, and far away.
      Vector3d p = offset + random_vector(rng, -2, 2);
      if (trial % 4 == 1) {
        const double u = unit(rng), v = unit(rng) * (1 - u);
        p = a + u * (b - a) + v * (c - a) + 0.3 * unit(rng) * (b - a).cross(c - a).normalized();
      }
      check_point_triangle(p, a, b, c);
    }
  }

  TEST_CASE("detection distance: point-triangle on needle and degenerate triangles") {
    const Vector3d a(0, 0, 0), b(1, 0, 0);
    std::mt19937 rng(5);
    for (double width : {1e-3, 1e-7, 1e-10, 1e-14, 0.0}) {
      CAPTURE(width);
      // Needle: apex near the middle of ab, and near-collinear with the apex beyond b.
      for (const Vector3d& c : {Vector3d(0.5, width, 0), Vector3d(2.0, width, 0), Vector3d(1e-7, width, 0)}) {
        for (int k = 0; k < 20; ++k) check_point_triangle(random_vector(rng, -1, 2), a, b, c);
        check_point_triangle(Vector3d(0.5, 0.1, 1e-3), a, b, c);
        check_point_triangle(Vector3d(0.3, width / 2, 1e-9), a, b, c);
      }
    }
    // All three vertices at one point, and two coincident vertices.
    for (int k = 0; k < 10; ++k) {
      check_point_triangle(random_vector(rng), a, a, a);
      check_point_triangle(random_vector(rng), a, b, b);
      check_point_triangle(random_vector(rng), a, a, b);
    }
  }

  TEST_CASE("detection distance: point exactly on an edge or a vertex is at distance zero") {
    const Vector3d a(0.1, -0.2, 0.3), b(1.3, 0.4, -0.2), c(-0.4, 1.1, 0.5);
    for (const Vector3d& p : {Vector3d(0.25 * a + 0.75 * b), Vector3d(0.5 * (b + c)), Vector3d(0.6 * c + 0.4 * a), a, b, c}) {
      const PointTriangle r = point_triangle_distance(p, a, b, c);
      CAPTURE(p.transpose());
      CHECK(r.distance_squared <= 1e-30);
      CHECK((r.closest - p).norm() <= 1e-15);
    }
    // On edge ab: the weight of c is zero and the others give the edge parameter.
    const PointTriangle r = point_triangle_distance(0.25 * a + 0.75 * b, a, b, c);
    CHECK(r.weights[2] == doctest::Approx(0).epsilon(1e-14));
    CHECK(r.weights[1] == doctest::Approx(0.75).epsilon(1e-12));
    // Interior point: the weights are its barycentric coordinates.
    const Vector3d w(0.2, 0.5, 0.3);
    const Vector3d n = (b - a).cross(c - a).normalized();
    const PointTriangle s = point_triangle_distance(w[0] * a + w[1] * b + w[2] * c + 0.7 * n, a, b, c);
    CHECK((s.weights - w).norm() <= 1e-14);
    CHECK(std::sqrt(s.distance_squared) == doctest::Approx(0.7).epsilon(1e-14));
  }

  TEST_CASE("detection distance: segment-segment matches brute force on random configurations") {
    std::mt19937 rng(12);
    for (int trial = 0; trial < 300; ++trial) {
      CAPTURE(trial);
      const Vector3d offset = trial % 3 == 0 ? random_vector(rng, -100, 100) : Vector3d::Zero();
      check_segment_segment(offset + random_vector(rng), offset + random_vector(rng), offset + random_vector(rng),
                            offset + random_vector(rng));
    }
  }

  TEST_CASE("detection distance: segment-segment on parallel and collinear and zero-length segments") {
    std::mt19937 rng(13);
    const Vector3d a0(0, 0, 0), a1(1, 0, 0);
    // Parallel: overlapping, disjoint, offset, opposite direction.
    for (double shift : {-2.0, -1.0, -0.5, 0.0, 0.3, 1.0, 1.5}) {
      for (const Vector3d& off : {Vector3d(0, 0.2, 0), Vector3d(0, 0, 0), Vector3d(0, 1e-9, 1e-9)}) {
        check_segment_segment(a0, a1, a0 + off + Vector3d(shift, 0, 0), a1 + off + Vector3d(shift, 0, 0));
        check_segment_segment(a0, a1, a1 + off + Vector3d(shift, 0, 0), a0 + off + Vector3d(shift, 0, 0));
        // Nearly parallel.
        check_segment_segment(a0, a1, a0 + off + Vector3d(shift, 0, 0), a1 + off + Vector3d(shift, 1e-8, 0));
      }
    }
    // Parallel overlapping at distance 0.2: distance exact, parameters a consistent pair.
    const SegmentSegment r = segment_segment_distance(a0, a1, Vector3d(0.5, 0.2, 0), Vector3d(1.5, 0.2, 0));
    CHECK(std::sqrt(r.distance_squared) == doctest::Approx(0.2).epsilon(1e-14));
    CHECK(std::abs((r.closest_a - r.closest_b).x()) <= 1e-15);
    // Zero-length segments: point-segment and point-point.
    for (int k = 0; k < 20; ++k) {
      const Vector3d p = random_vector(rng), q = random_vector(rng);
      check_segment_segment(p, p, q, q + random_vector(rng));
      check_segment_segment(p, p + random_vector(rng), q, q);
      check_segment_segment(p, p, q, q);
    }
    // Crossing segments (distance 0) and a T junction.
    const SegmentSegment x = segment_segment_distance(a0, a1, Vector3d(0.4, -1, 0), Vector3d(0.4, 1, 0));
    CHECK(x.distance_squared <= 1e-30);
    CHECK(x.s == doctest::Approx(0.4));
    CHECK(x.t == doctest::Approx(0.5));
    const SegmentSegment tj = segment_segment_distance(a0, a1, Vector3d(0.7, 0, 0), Vector3d(0.7, 1, 1));
    CHECK(tj.distance_squared <= 1e-30);
    CHECK(tj.t == doctest::Approx(0).epsilon(1e-15));
    check_segment_segment(a0, a1, Vector3d(0.7, 0, 0), Vector3d(0.7, 1, 1));
    // Collinear, touching at an endpoint and overlapping.
    check_segment_segment(a0, a1, a1, Vector3d(2, 0, 0));
    check_segment_segment(a0, a1, Vector3d(0.5, 0, 0), Vector3d(3, 0, 0));
  }

  TEST_CASE("detection distance: point-segment clamps and handles a zero-length segment") {
    const Vector3d a(0, 0, 0), b(2, 0, 0);
    CHECK(point_segment_distance(Vector3d(-1, 1, 0), a, b).s == 0);
    CHECK(point_segment_distance(Vector3d(3, 1, 0), a, b).s == 1);
    const PointSegment m = point_segment_distance(Vector3d(0.5, 1, 0), a, b);
    CHECK(m.s == doctest::Approx(0.25));
    CHECK(m.distance_squared == doctest::Approx(1));
    const PointSegment z = point_segment_distance(Vector3d(1, 1, 1), a, a);
    CHECK(z.s == 0);
    CHECK(z.distance_squared == doctest::Approx(3));
  }
}
