#pragma once
/// \file polynomial.hpp
/// Robust real-root isolation for the cubics of continuous collision detection, on [0, 1].
///
/// A cubic p(t) = c0 + c1 t + c2 t^2 + c3 t^3 is monotone between consecutive roots of its
/// derivative p'(t) = c1 + 2 c2 t + 3 c3 t^2. The derivative's roots are computed with the
/// cancellation-free quadratic formula (q = -(b + sign(b) sqrt(b^2 - 4ac)) / 2, roots q/a and
/// c/q), which stays accurate when the leading coefficient nearly vanishes (the cubic is
/// then nearly a quadratic, and the large root simply falls outside [0, 1]), and are
/// polished by Newton steps on p'. They split [0, 1] into at most three monotone pieces.
/// On a monotone piece [l, r], the level set {p = y} is one point or empty (or the whole
/// piece where p is constant), and the band {|p| <= delta} is one interval or empty; their
/// ends are found by a safeguarded Newton iteration that keeps a sign-changing bracket,
/// probes a little beyond each Newton point to close the bracket from the far side (Newton
/// alone approaches a convex root from one side), and bisects whenever Newton leaves the
/// bracket or the bracket stops halving: it always converges, to a bracket of width 1e-15
/// (or the floating-point resolution) in about ten evaluations.
///
/// `band` is what CCD uses: the times at which |p(t)| <= delta, as at most three disjoint
/// closed intervals. A zero polynomial (the always-coplanar case) gives [0, 1]. Bracket
/// ends are rounded outwards: each returned interval contains the exact band of the
/// computed polynomial up to the error of evaluating p (which callers fold into delta).
#include <array>

namespace weft::contact::detection {

/// c0 + c1 t + c2 t^2 + c3 t^3.
struct Cubic {
  std::array<double, 4> c{};  ///< c0, c1, c2, c3

  double operator()(double t) const { return ((c[3] * t + c[2]) * t + c[1]) * t + c[0]; }
  double derivative(double t) const { return (3 * c[3] * t + 2 * c[2]) * t + c[1]; }
};

/// Up to three sorted values in [0, 1].
struct Roots {
  std::array<double, 3> t{};
  int n = 0;
};

/// Up to three disjoint, sorted, closed intervals in [0, 1].
struct Intervals {
  std::array<std::array<double, 2>, 3> iv{};
  int n = 0;
};

/// Distinct real roots of a t^2 + b t + c in the open interval (0, 1), sorted; a double
/// root counts once. All-zero coefficients give no roots.
Roots quadratic_roots_in_unit(double a, double b, double c);

/// Break points 0 = t[0] < ... < t[n-1] = 1 of [0, 1] into monotone pieces of a cubic.
struct Breaks {
  std::array<double, 4> t{};
  int n = 0;
};

/// 0, the roots of p' in (0, 1) (polished by Newton steps on p'), and 1.
Breaks monotone_pieces(const Cubic& p);

/// The root of the monotone function p on [l, r] given that p(l) and p(r) bracket y
/// (p(l) <= y <= p(r) or p(l) >= y >= p(r)). \returns a bracket [lo, hi] of width within
/// a few ulps (or after at most 200 iterations) with the exact crossing inside.
std::array<double, 2> solve_monotone(const Cubic& p, double y, double l, double r);

/// Roots of p in [0, 1] (sign changes, and zeros at the ends of monotone pieces), sorted.
Roots cubic_roots_in_unit(const Cubic& p);

/// {t in [0, 1] : |p(t)| <= delta}, delta >= 0, as at most three disjoint closed intervals.
Intervals band(const Cubic& p, double delta);

}  // namespace weft::contact::detection
