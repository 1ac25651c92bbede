#pragma once
/// \file line_search.hpp
/// Line searches on phi(s) = merit(d + s p). They see only the 1D function, so the same
/// code serves every integrator and merit (methods/integration-and-contact §6).
#include <array>
#include <cmath>
#include <functional>
#include <utility>
#include <limits>
#include <string_view>

#include "framework/params.hpp"

namespace weft::integrators {

enum class LineSearchKind {
  backtracking,  ///< Armijo sufficient decrease, safeguarded quadratic backtracking
  full_step,     ///< s = 1 always (plain Newton)
  more_thuente,  ///< strong Wolfe conditions, Moré & Thuente (1994) bracketing
  hager_zhang,   ///< Wolfe or approximate Wolfe (derivative-based), Hager & Zhang (2005)
};
inline constexpr std::array<std::string_view, 4> line_search_names = {"backtracking", "full_step", "more_thuente",
                                                                      "hager_zhang"};

struct LineSearchParams {
  double c1 = 1e-4;          ///< Armijo constant (Hager-Zhang: delta = max(c1, 0.1))
  double c2 = 0.9;           ///< curvature constant of the (strong) Wolfe conditions
  double max_step = 10.0;    ///< largest step the Wolfe searches may try
  double shrink = 0.5;       ///< upper bound of the step reduction factor per trial
  int max_evaluations = 40;  ///< trials before giving up
  bool interpolate = true;   ///< quadratic interpolation of the next trial; false: plain s *= shrink
  template <class V>
  void visit(V& v) {
    v.field("c1", c1, {Unit::none, Range::open(0, 0.5), "Armijo sufficient-decrease constant"});
    v.field("c2", c2, {Unit::none, Range::open(0, 1), "curvature constant of the Wolfe conditions (more_thuente, hager_zhang)"});
    v.field("max_step", max_step, {Unit::none, Range::ge(1), "largest step length the Wolfe searches may try"});
    v.field("shrink", shrink, {Unit::none, Range::open(0, 1), "largest step reduction factor per backtracking trial"});
    v.field("max_evaluations", max_evaluations, {Unit::none, Range::closed(1, 200), "trial steps before the search fails"});
    v.field("interpolate", interpolate, {Unit::none, Range::any(), "next trial from a quadratic fit (else s *= shrink)"});
  }
};

struct LineSearchResult {
  bool accepted = false;
  double step = 0;   ///< accepted s
  double value = 0;  ///< phi(s)
  int evaluations = 0;
};

/// Armijo backtracking from s = 1: accept the first s with phi(s) <= phi0 + c1 s slope.
/// Trial steps come from the minimiser of the quadratic through phi0, slope and phi(s),
/// clamped to [0.1 s, shrink s]; a non-finite phi(s) shrinks by 0.1.
template <class Phi>
LineSearchResult backtracking(Phi&& phi, double phi0, double slope, const LineSearchParams& prm) {
  LineSearchResult r;
  double s = 1.0;
  for (r.evaluations = 1; r.evaluations <= prm.max_evaluations; ++r.evaluations) {
    const double value = phi(s);
    if (std::isfinite(value) && value <= phi0 + prm.c1 * s * slope) {
      r.accepted = true;
      r.step = s;
      r.value = value;
      return r;
    }
    double next = 0.1 * s;
    if (!prm.interpolate) {
      next = prm.shrink * s;
    } else if (std::isfinite(value)) {
      const double denom = 2.0 * (value - phi0 - slope * s);
      if (denom > 0) next = -slope * s * s / denom;
      next = std::clamp(next, 0.1 * s, prm.shrink * s);
    }
    s = next;
  }
  r.evaluations = prm.max_evaluations;
  return r;
}

/// phi(s) and phi'(s) together (one gradient evaluation per trial).
using PhiWithSlope = std::function<std::pair<double, double>(double)>;

/// Strong Wolfe line search of Moré & Thuente (1994): phi(s) <= phi0 + c1 s phi'(0) and
/// |phi'(s)| <= c2 |phi'(0)|, from s = 1 with s <= max_step. If no such step is found within
/// max_evaluations, the best sufficient-decrease step seen is accepted.
LineSearchResult more_thuente(const PhiWithSlope& phi, double phi0, double slope0, const LineSearchParams& prm);

/// Hager & Zhang (2005) line search: Wolfe or approximate Wolfe conditions. The
/// approximate conditions test derivatives only, so the search still decides where
/// phi(s) - phi(0) is below round-off (the cancellation of methods/integration-and-contact §6.6).
LineSearchResult hager_zhang(const PhiWithSlope& phi, double phi0, double slope0, const LineSearchParams& prm);

}  // namespace weft::integrators
