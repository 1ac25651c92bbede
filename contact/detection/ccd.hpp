#pragma once
/// \file ccd.hpp
/// Continuous collision detection for one vertex-triangle (VF) or edge-edge (EE) pair
/// over a step with linear trajectories x_j(t) = x0_j + t (x1_j - x0_j), t in [0, 1].
///
/// Method (methods/integration-and-contact §11.2; Provot 1997, with a distance test and a conservative fallback):
///  1. Coplanarity cubic. With A, B the two spanning vectors and C the offset,
///       VF (p; a, b, c): A = b - a, B = c - a, C = p - a,
///       EE (a0, a1; b0, b1): A = a1 - a0, B = b1 - b0, C = b0 - a0,
///     f(t) = (A(t) x B(t)) . C(t) is a cubic in t (each of A, B, C is linear in t). f = 0
///     is necessary for contact at zero distance, and more generally, since the distance
///     of the primitives is at least |f| / |A x B| (point to plane, line to line),
///       distance(t) <= r  implies  |f(t)| <= r |A(t) x B(t)| <= r N,
///     with N = max|A| max|B| over the step (norms of linear functions peak at an end).
///  2. Candidate times: the band {t : |f(t)| <= delta}, delta = eta N + (a bound on the
///     rounding error of the computed f, from the magnitude of the coordinates), found
///     by `band` (polynomial.hpp): the derivative's roots split [0, 1] into monotone pieces,
///     each piece contributes one interval, bracketed by safeguarded Newton/bisection. This
///     handles nearly vanishing leading coefficients, double roots (a grazing contact is
///     an extremum of f inside the band) and the always-coplanar case (f == 0: the band is
///     all of [0, 1]). Pairs whose f stays away from zero are rejected here, cheaply.
///  3. Within each band interval, in time order, conservative advancement on the actual
///     distance d(t) of the primitives (distance.hpp). From a time t with d(t) > eta the
///     step is the longer of two safe steps, neither of which can pass over a time at
///     which d <= eta/2:
///      - Lipschitz: with L = max over i in A, j in B of |(x1_i - x0_i) - (x1_j - x0_j)|,
///        d is L-Lipschitz in t, so step (d(t) - eta/2) / L (>= eta / (2 L));
///      - separating axis: n = (p^a - p^b) / d at t; the separation along the fixed axis n,
///        min over i in A, j in B of n . (x_i(s) - x_j(s)), is a minimum of linear
///        functions of s, so the time for which it stays >= eta/2 is exact and cheap
///        (infinite when nothing approaches along n: sliding past at a fixed distance).
///     The first t with d(t) <= eta is the time of impact.
///
/// Guarantee (up to rounding of order 1e-15 times the largest coordinate):
///  - No false negatives for contact within eta/2: if the primitives come within eta/2 of
///    each other at some t* in [0, 1] (touching or passing through each other included),
///    a hit is reported with toi <= t*.
///  - False positives only within eta: a reported hit has distance(toi) <= eta, and no
///    time before toi has distance <= eta/2. So toi lies in [t(eta), t(eta/2)], the first
///    times at which the distance reaches eta and eta/2, and pairs that come within
///    (eta/2, eta] but no closer may or may not be reported.
///  - Already within eta at t = 0: hit with toi = 0.
///  - The work is bounded: each band interval of length w costs at most 2 L w / eta + 1
///    distance evaluations (usually a handful: the band of a transversal crossing is short
///    and the axis step covers tangential motion); a pair circling within a few eta of
///    contact without touching is the expensive case. After `max_iterations` evaluations
///    the pair is reported as a hit at the current time with `conservative` set (its
///    distance may exceed eta): still no false negative.
///
/// eta is absolute, in metres. It is a detection tolerance, not a contact thickness: use
/// e.g. 1e-6 times the scene size (1e-6 m for a metre-sized scene); it must exceed the
/// rounding level of the coordinates (about 1e-15 times their magnitude) by orders of
/// magnitude. The time of impact is the first time the pair is within eta, slightly before
/// the exact contact (by about eta / approach speed).
///
/// Weights and normal (methods/integration-and-contact §11.1-11.2) are evaluated at toi: gamma are the stencil
/// weights (g = sum_j gamma_j x_j(toi) = p^a - p^b, sum gamma = 0), VF gamma = (1, -w0, -w1, -w2),
/// EE gamma = (1 - s, s, -(1 - u), -u). The normal is the geometric one, face normal A x B (VF)
/// or A x B of the two edges (EE), oriented so that n . (p^a - p^b) > 0 just before contact
/// (from the sign of f at the start of the band interval in which the hit is found). When
/// the geometric normal is degenerate (collapsed triangle, parallel edges: |A x B| below
/// 1e-8 |A| |B|) the gap direction (p^a - p^b) / |p^a - p^b| is used, and if the gap is zero
/// too, the reversed relative velocity of A with respect to B; failing all, +z.
#include <Eigen/Core>

#include <array>

#include "contact/detection/polynomial.hpp"

namespace weft::contact::detection {

/// Options of a CCD test.
struct CcdOptions {
  int max_iterations = 100000;  ///< distance evaluations per pair before a conservative hit
};

/// Outcome of a CCD test.
struct Impact {
  bool hit = false;                                   ///< the pair comes within eta during the step
  double toi = 1;                                     ///< time of impact in [0, 1] (if hit)
  double distance = 0;                                ///< distance at toi [m] (if hit)
  std::array<double, 4> gamma{};                      ///< stencil weights at toi (if hit)
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();   ///< unit normal from B to A (if hit)
  bool conservative = false;                          ///< hit reported at the iteration cap
  int iterations = 0;                                 ///< distance evaluations
};

/// Four stencil positions: VF (p, a, b, c), EE (a0, a1, b0, b1).
using Stencil = std::array<Eigen::Vector3d, 4>;

/// Vertex p against triangle (a, b, c) over the step; x0, x1 in stencil order (p, a, b, c).
/// \param eta absolute tolerance [m], > 0 (see the file comment).
Impact vertex_triangle_ccd(const Stencil& x0, const Stencil& x1, double eta, const CcdOptions& opt = {});

/// Edge (a0, a1) against edge (b0, b1) over the step; stencil order (a0, a1, b0, b1).
Impact edge_edge_ccd(const Stencil& x0, const Stencil& x1, double eta, const CcdOptions& opt = {});

// ---- building blocks shared with the thick CCD of rods (contact/rods/thick_ccd.hpp) ----

/// Positions at time t of a stencil moving linearly from x0 by dx.
Stencil stencil_at(const Stencil& x0, const Stencil& dx, double t);

/// The coplanarity cubic f(t) = (A x B) . C of a linearly moving stencil (file comment),
/// its spanning vectors A(t) = A0 + t A1 and B(t) = B0 + t B1, their largest norms over the
/// step, and a bound on the rounding error of the computed f (differences of coordinates,
/// then products and sums of the three vectors; 64 eps is generous).
struct Coplanarity {
  Cubic f;
  Eigen::Vector3d A0, A1, B0, B1;
  double a_max = 0, b_max = 0, err = 0;
};
Coplanarity coplanarity(const Stencil& x0, const Stencil& x1, const Stencil& dx, bool vertex_triangle);

/// Lipschitz constant in t of the distance between side a (the first `na` stencil
/// vertices) and side b: the largest relative displacement of a vertex pair.
double distance_lipschitz(const Stencil& dx, int na);

/// A safe conservative-advancement step from configuration xt, where the sides are at
/// distance d with closest-point difference `gap` (p^a - p^b): the longer of the Lipschitz
/// step (d - margin) / lip and the time for which the separation along the fixed axis
/// gap / d (a minimum of linear functions of t, one per vertex pair) stays >= margin; the
/// axis step is checked rather than trusted (rounding of the closest points). Infinite
/// when the sides never get closer.
double advancement_step(const Stencil& xt, const Stencil& dx, int na, const Eigen::Vector3d& gap, double d, double lip,
                        double margin);

}  // namespace weft::contact::detection
