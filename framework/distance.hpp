#pragma once
/// \file distance.hpp
/// Closest points between the primitives of a triangle mesh: point-segment,
/// point-triangle and segment-segment, with the weights (barycentric coordinates or
/// segment parameters) of the closest points.
///
/// Method. The minimum of a distance over a convex polytope is reached either in the
/// relative interior of the polytope (a critical point of the unconstrained problem) or
/// on its boundary. Each routine therefore takes the minimum over
///  - the unconstrained candidate (orthogonal projection onto the triangle's plane, or
///    the common perpendicular of the two lines), kept only when it lies inside the
///    parameter domain and the 2x2 normal equations are well conditioned, and
///  - the boundary candidates: point-triangle falls back to the three edges,
///    segment-segment to the four endpoint-to-segment distances.
/// Every candidate is an actual point of the primitive (weights in [0, 1], summing to 1)
/// and its distance is measured directly from the points, never from a formula that
/// assumes non-degeneracy. A badly conditioned unconstrained candidate is thus only ever
/// an upper bound that the boundary candidates beat, and needle triangles, collinear
/// triangles, parallel or collinear segments and zero-length segments need no special
/// case: their minimum lies on the boundary. The result is exact up to rounding
/// (a few ulps of the coordinates' magnitude).
///
/// Ties (parallel segments, a point equidistant from two edges) are resolved by the fixed
/// order of the candidates, so the weights are deterministic functions of the input.
#include <Eigen/Core>

namespace weft {

/// Closest point of a segment x(s) = a + s (b - a), s in [0, 1], to a point.
struct PointSegment {
  double distance_squared = 0;                      ///< |p - x(s)|^2 [m^2]
  double s = 0;                                     ///< parameter of the closest point
  Eigen::Vector3d closest = Eigen::Vector3d::Zero();  ///< x(s)
};

/// Closest point of a triangle (a, b, c) to a point.
struct PointTriangle {
  double distance_squared = 0;                       ///< |p - closest|^2 [m^2]
  Eigen::Vector3d weights = Eigen::Vector3d::Zero();  ///< barycentric (w0, w1, w2) >= 0, sum 1
  Eigen::Vector3d closest = Eigen::Vector3d::Zero();  ///< w0 a + w1 b + w2 c
};

/// Closest points of two segments xa(s) = a0 + s (a1 - a0) and xb(t) = b0 + t (b1 - b0).
struct SegmentSegment {
  double distance_squared = 0;                          ///< |xa(s) - xb(t)|^2 [m^2]
  double s = 0;                                         ///< parameter on segment a, in [0, 1]
  double t = 0;                                         ///< parameter on segment b, in [0, 1]
  Eigen::Vector3d closest_a = Eigen::Vector3d::Zero();  ///< xa(s)
  Eigen::Vector3d closest_b = Eigen::Vector3d::Zero();  ///< xb(t)
};

/// Point to segment [a, b]; a zero-length segment gives s = 0.
PointSegment point_segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b);

/// Point to the (closed, solid) triangle (a, b, c), degenerate triangles included.
PointTriangle point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                      const Eigen::Vector3d& b, const Eigen::Vector3d& c);

/// Segment [a0, a1] to segment [b0, b1]; parallel, collinear and zero-length segments included.
SegmentSegment segment_segment_distance(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1,
                                        const Eigen::Vector3d& b0, const Eigen::Vector3d& b1);

}  // namespace weft
