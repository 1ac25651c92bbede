#include "framework/distance.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <limits>

namespace weft {

namespace {
using Eigen::Vector3d;

// Below this squared sine of the angle between the two spanning vectors, the interior
// candidate is still tried but never trusted alone: the boundary candidates are compared too.
constexpr double well_conditioned_sin2 = 1e-6;
}  // namespace

PointSegment point_segment_distance(const Vector3d& p, const Vector3d& a, const Vector3d& b) {
  const Vector3d e = b - a;
  const Vector3d d = p - a;
  const double ee = e.squaredNorm();
  double s = 0;
  if (ee > 0) s = std::clamp(d.dot(e) / ee, 0.0, 1.0);
  PointSegment r;
  r.s = s;
  r.distance_squared = (d - s * e).squaredNorm();
  r.closest = a + s * e;
  return r;
}

PointTriangle point_triangle_distance(const Vector3d& p, const Vector3d& a, const Vector3d& b,
                                      const Vector3d& c) {
  const Vector3d e1 = b - a, e2 = c - a, d = p - a;
  const Vector3d n = e1.cross(e2);
  const double nn = n.squaredNorm();
  PointTriangle best;
  best.distance_squared = std::numeric_limits<double>::infinity();
  bool trusted = false;
  if (nn > 0) {
    // Barycentric coordinates of the projection of p onto the plane, in the cross-product
    // form (better cancellation than the Gram-matrix form of the same Cramer rule).
    const double u = d.cross(e2).dot(n) / nn;
    const double v = e1.cross(d).dot(n) / nn;
    if (u >= 0 && v >= 0 && u + v <= 1) {
      best.weights = Vector3d(1 - u - v, u, v);
      best.distance_squared = (d - u * e1 - v * e2).squaredNorm();
      best.closest = a + u * e1 + v * e2;
      trusted = nn > well_conditioned_sin2 * e1.squaredNorm() * e2.squaredNorm();
    }
  }
  if (trusted) return best;
  // Boundary: edges ab, bc, ca in this order (ties keep the earlier one).
  const PointSegment ab = point_segment_distance(p, a, b);
  if (ab.distance_squared < best.distance_squared) {
    best.distance_squared = ab.distance_squared;
    best.weights = Vector3d(1 - ab.s, ab.s, 0);
    best.closest = ab.closest;
  }
  const PointSegment bc = point_segment_distance(p, b, c);
  if (bc.distance_squared < best.distance_squared) {
    best.distance_squared = bc.distance_squared;
    best.weights = Vector3d(0, 1 - bc.s, bc.s);
    best.closest = bc.closest;
  }
  const PointSegment ca = point_segment_distance(p, c, a);
  if (ca.distance_squared < best.distance_squared) {
    best.distance_squared = ca.distance_squared;
    best.weights = Vector3d(ca.s, 0, 1 - ca.s);
    best.closest = ca.closest;
  }
  return best;
}

SegmentSegment segment_segment_distance(const Vector3d& a0, const Vector3d& a1, const Vector3d& b0,
                                        const Vector3d& b1) {
  const Vector3d da = a1 - a0, db = b1 - b0, r = b0 - a0;
  const Vector3d n = da.cross(db);
  const double nn = n.squaredNorm();
  SegmentSegment best;
  best.distance_squared = std::numeric_limits<double>::infinity();
  bool trusted = false;
  if (nn > 0) {
    // Common perpendicular of the two lines: a0 + s da - b0 - t db is orthogonal to da and db.
    const double s = r.cross(db).dot(n) / nn;
    const double t = r.cross(da).dot(n) / nn;
    if (s >= 0 && s <= 1 && t >= 0 && t <= 1) {
      best.s = s;
      best.t = t;
      best.distance_squared = (s * da - r - t * db).squaredNorm();
      trusted = nn > well_conditioned_sin2 * da.squaredNorm() * db.squaredNorm();
    }
  }
  if (!trusted) {
    // Boundary of the parameter square: s = 0, s = 1, t = 0, t = 1, in this order.
    auto take = [&](double s, double t, double d2) {
      if (d2 < best.distance_squared) {
        best.distance_squared = d2;
        best.s = s;
        best.t = t;
      }
    };
    const PointSegment s0 = point_segment_distance(a0, b0, b1);
    take(0, s0.s, s0.distance_squared);
    const PointSegment s1 = point_segment_distance(a1, b0, b1);
    take(1, s1.s, s1.distance_squared);
    const PointSegment t0 = point_segment_distance(b0, a0, a1);
    take(t0.s, 0, t0.distance_squared);
    const PointSegment t1 = point_segment_distance(b1, a0, a1);
    take(t1.s, 1, t1.distance_squared);
  }
  best.closest_a = a0 + best.s * da;
  best.closest_b = b0 + best.t * db;
  return best;
}

}  // namespace weft
