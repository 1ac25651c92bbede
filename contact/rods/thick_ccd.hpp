#pragma once
/// \file thick_ccd.hpp
/// Continuous collision detection with a thickness: the first time two primitives moving
/// linearly over a step (x_j(t) = x0_j + t (x1_j - x0_j), t in [0, 1]) come within a
/// distance delta of each other. Edge-edge: rod edges (thick segments) against each other
/// and against the sharp edges of box and mesh obstacles; point-triangle: rod vertices
/// against the triangles of mesh obstacles (rod_detection.hpp). contact/detection/ccd.hpp
/// is the zero-thickness version (for cloth); `segment_segment_ccd` with delta = 0 calls it.
///
/// Method, for delta > 0 (d(t) the distance of the primitives, distance.hpp):
///  1. d(0) <= delta + eta: hit at toi = 0 (the pair already touches or overlaps).
///  2. Rejection: d is L-Lipschitz in t, L = max over i in A, j in B of |(x1_i - x0_i) -
///     (x1_j - x0_j)| (the relative velocity of any two material points is a convex
///     combination of those), so d(t) >= (d(0) + d(1) - L) / 2 on [0, 1].
///  3. Candidate times: the distance of the primitives is at least that of their lines
///     (EE) or of the point to the triangle's plane (VF), |f(t)| / |A(t) x B(t)| with f the
///     coplanarity cubic of ccd.hpp, so d <= delta + eta implies
///     |f| <= (delta + eta) max|A| max|B|: `detection::band` gives the (at most three)
///     intervals of [0, 1] where that can hold.
///  4. In each interval, in time order, conservative advancement on d - delta, as in
///     ccd.hpp: from a time with d > delta + eta the step is the longer of the Lipschitz
///     step (d - delta - eta/2) / L and the separating-axis step (the time for which the
///     separation of the primitives along the fixed axis n = (p^a - p^b) / d, a minimum of
///     linear functions of t, stays >= delta + eta/2; it is exact for a translation and
///     makes sliding past each other, or along a face, one step). The first t with
///     d <= delta + eta is the time of impact.
/// Guarantee (up to rounding): a pair whose distance comes within delta + eta/2 at some
/// t* is reported with toi <= t*; a reported pair has d(toi) <= delta + eta and no time
/// before toi with d <= delta + eta/2. The time of impact is thus early by at most about
/// eta / (approach speed) (in fractions of the step). After `max_iterations` distance
/// evaluations the pair is reported at the current time with `conservative` set.
///
/// Edge-edge normal (from b to a, methods/rod-contact §4.1): the direction of the closest points'
/// difference p^a - p^b when their distance exceeds 1e-8 times the longer edge: for a thick
/// pair at its time of impact that distance is about delta, so this is the limit
/// t -> toi^-, and it is the cross product of the edges when the closest points are
/// interior to both. For (nearly) intersecting centrelines (zero thickness, or an overlap
/// at the start) it is the normalised cross product of the edges, or for parallel edges
/// the perpendicular of the longer edge nearest to the orientation hints; its sign comes
/// from the hints (first nonzero n . hint wins): the CCD passes the gap of the same material
/// points at the start of the step, then the reversed relative motion (where a came from);
/// the fixed rule "largest component positive" makes the result a deterministic function
/// of the input.
#include <Eigen/Core>

#include <array>

#include "contact/detection/ccd.hpp"

namespace weft::contact::rods {

/// Outcome of a thick CCD test.
struct ThickImpact {
  bool hit = false;                                   ///< the pair comes within thickness + eta during the step
  double toi = 1;                                     ///< time of impact in [0, 1] (if hit)
  double distance = 0;                                ///< distance at toi [m] (if hit)
  /// Closest points at toi: EE the parameters s on a, t on b; VF the barycentric
  /// coordinates (w1, w2) of the triangle's closest point (w0 = 1 - w1 - w2).
  double s = 0, t = 0;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< EE: unit, from b to a (if hit); VF: (p - closest) / distance
  bool conservative = false;                          ///< reported at the iteration cap
  int iterations = 0;                                 ///< distance evaluations
};

/// Segments (a0, a1) and (b0, b1) over the step; stencil order (a0, a1, b0, b1).
/// \param thickness delta [m], >= 0: contact when the centreline distance reaches it.
/// \param eta absolute tolerance [m], > 0 (file comment).
ThickImpact segment_segment_ccd(const detection::Stencil& x0, const detection::Stencil& x1, double thickness,
                                double eta, int max_iterations = 10000);

/// Point p against triangle (a, b, c) over the step; stencil order (p, a, b, c).
/// \param thickness delta [m], > 0. The normal is left to the caller when the distance is 0.
ThickImpact point_triangle_ccd(const detection::Stencil& x0, const detection::Stencil& x1, double thickness,
                               double eta, int max_iterations = 10000);

/// Unit normal from b to a of the segments (a0, a1), (b0, b1) at configuration x, for
/// closest points with parameters s (on a) and t (on b) at distance `distance` (file
/// comment). `hints` orient it when the closest points (nearly) coincide; zero hints are skipped.
Eigen::Vector3d segment_contact_normal(const detection::Stencil& x, double s, double t, double distance,
                                       const std::array<Eigen::Vector3d, 2>& hints);

}  // namespace weft::contact::rods
