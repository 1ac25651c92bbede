#include "integrators/line_search.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace weft::integrators {
namespace {

// One safeguarded step of Moré & Thuente (1994), "Line search algorithms with guaranteed
// sufficient decrease", §4: updates the interval [stx, sty] that contains a step
// satisfying the conditions, and returns the next trial step from cubic and quadratic
// interpolation of the function values and derivatives at stx and stp.
struct Interval {
  double stx, fx, dx;  // best step so far
  double sty, fy, dy;  // other endpoint
  bool bracketed = false;
};

double cubic_gamma(double theta, double a, double b, bool negate) {
  const double s = std::max({std::abs(theta), std::abs(a), std::abs(b)});
  const double disc = (theta / s) * (theta / s) - (a / s) * (b / s);
  const double g = s * std::sqrt(std::max(0.0, disc));
  return negate ? -g : g;
}

double more_thuente_step(Interval& I, double stp, double fp, double dp, double stpmin, double stpmax) {
  const double sgnd = dp * (I.dx / std::abs(I.dx));
  double stpf;
  if (fp > I.fx) {
    // Case 1: higher value: the minimum is bracketed; cubic step if closer to stx, else average.
    const double theta = 3.0 * (I.fx - fp) / (stp - I.stx) + I.dx + dp;
    const double gamma = cubic_gamma(theta, I.dx, dp, stp < I.stx);
    const double p = (gamma - I.dx) + theta, q = ((gamma - I.dx) + gamma) + dp;
    const double stpc = I.stx + (p / q) * (stp - I.stx);
    const double stpq = I.stx + ((I.dx / ((I.fx - fp) / (stp - I.stx) + I.dx)) / 2.0) * (stp - I.stx);
    stpf = std::abs(stpc - I.stx) < std::abs(stpq - I.stx) ? stpc : stpc + (stpq - stpc) / 2.0;
    I.bracketed = true;
  } else if (sgnd < 0.0) {
    // Case 2: lower value, derivatives of opposite sign: bracketed; the step farther from stp.
    const double theta = 3.0 * (I.fx - fp) / (stp - I.stx) + I.dx + dp;
    const double gamma = cubic_gamma(theta, I.dx, dp, stp > I.stx);
    const double p = (gamma - dp) + theta, q = ((gamma - dp) + gamma) + I.dx;
    const double stpc = stp + (p / q) * (I.stx - stp);
    const double stpq = stp + (dp / (dp - I.dx)) * (I.stx - stp);
    stpf = std::abs(stpc - stp) > std::abs(stpq - stp) ? stpc : stpq;
    I.bracketed = true;
  } else if (std::abs(dp) < std::abs(I.dx)) {
    // Case 3: lower value, same sign, smaller derivative magnitude.
    const double theta = 3.0 * (I.fx - fp) / (stp - I.stx) + I.dx + dp;
    const double gamma = cubic_gamma(theta, I.dx, dp, stp > I.stx);
    const double p = (gamma - dp) + theta, q = (gamma + (I.dx - dp)) + gamma;
    const double r = p / q;
    double stpc;
    if (r < 0.0 && gamma != 0.0) stpc = stp + r * (I.stx - stp);
    else stpc = stp > I.stx ? stpmax : stpmin;
    const double stpq = stp + (dp / (dp - I.dx)) * (I.stx - stp);
    if (I.bracketed) {
      stpf = std::abs(stpc - stp) < std::abs(stpq - stp) ? stpc : stpq;
      stpf = stp > I.stx ? std::min(stp + 0.66 * (I.sty - stp), stpf) : std::max(stp + 0.66 * (I.sty - stp), stpf);
    } else {
      stpf = std::abs(stpc - stp) > std::abs(stpq - stp) ? stpc : stpq;
      stpf = std::clamp(stpf, stpmin, stpmax);
    }
  } else {
    // Case 4: lower value, same sign, derivative not decreasing in magnitude.
    if (I.bracketed) {
      const double theta = 3.0 * (fp - I.fy) / (I.sty - stp) + I.dy + dp;
      const double gamma = cubic_gamma(theta, I.dy, dp, stp > I.sty);
      const double p = (gamma - dp) + theta, q = ((gamma - dp) + gamma) + I.dy;
      stpf = stp + (p / q) * (I.sty - stp);
    } else {
      stpf = stp > I.stx ? stpmax : stpmin;
    }
  }
  // Update the interval.
  if (fp > I.fx) {
    I.sty = stp, I.fy = fp, I.dy = dp;
  } else {
    if (sgnd < 0.0) I.sty = I.stx, I.fy = I.fx, I.dy = I.dx;
    I.stx = stp, I.fx = fp, I.dx = dp;
  }
  return stpf;
}

}  // namespace

LineSearchResult more_thuente(const PhiWithSlope& phi, double phi0, double slope0, const LineSearchParams& prm) {
  LineSearchResult res;
  const double ftol = prm.c1, gtol = prm.c2, xtol = 1e-12;
  const double stpmin = 0.0, stpmax = prm.max_step;
  double stp = 1.0;
  Interval I{0.0, phi0, slope0, 0.0, phi0, slope0, false};
  bool stage1 = true;
  double width = stpmax - stpmin, width1 = 2.0 * width;
  double stmin = 0.0, stmax = stp + 4.0 * stp;
  const double gtest = ftol * slope0;
  for (res.evaluations = 1; res.evaluations <= prm.max_evaluations; ++res.evaluations) {
    const auto [f, g] = phi(stp);
    if (!std::isfinite(f) || !std::isfinite(g)) {
      // Outside the domain: shrink towards the best step.
      stp = I.stx + 0.1 * (stp - I.stx);
      I.bracketed = true;
      I.sty = stp * 10.0, I.fy = std::numeric_limits<double>::max(), I.dy = 0.0;
      continue;
    }
    const double ftest = phi0 + stp * gtest;
    if (f <= ftest && std::abs(g) <= gtol * (-slope0)) {
      res.accepted = true;
      res.step = stp;
      res.value = f;
      return res;
    }
    if (I.bracketed && (stp <= stmin || stp >= stmax || stmax - stmin <= xtol * stmax)) break;
    if (stp == stpmax && f <= ftest && g <= gtest) break;  // the largest step is as good as it gets
    if (stage1 && f <= ftest && g >= std::min(ftol, gtol) * slope0) stage1 = false;
    if (stage1 && f <= I.fx && f > ftest) {
      // Modified function psi(s) = phi(s) - phi0 - s gtest while no step decreases enough.
      Interval M{I.stx, I.fx - I.stx * gtest, I.dx - gtest, I.sty, I.fy - I.sty * gtest, I.dy - gtest, I.bracketed};
      stp = more_thuente_step(M, stp, f - stp * gtest, g - gtest, stmin, stmax);
      I = {M.stx, M.fx + M.stx * gtest, M.dx + gtest, M.sty, M.fy + M.sty * gtest, M.dy + gtest, M.bracketed};
    } else {
      stp = more_thuente_step(I, stp, f, g, stmin, stmax);
    }
    if (I.bracketed) {
      if (std::abs(I.sty - I.stx) >= 0.66 * width1) stp = I.stx + 0.5 * (I.sty - I.stx);
      width1 = width;
      width = std::abs(I.sty - I.stx);
      stmin = std::min(I.stx, I.sty);
      stmax = std::max(I.stx, I.sty);
    } else {
      stmin = stp + 1.1 * (stp - I.stx);
      stmax = stp + 4.0 * (stp - I.stx);
    }
    stp = std::clamp(stp, stpmin, stpmax);
    if (I.bracketed && (stp <= stmin || stp >= stmax || stmax - stmin <= xtol * stmax)) stp = I.stx;
  }
  // No strong-Wolfe step: accept the best sufficient-decrease step seen, if any.
  res.evaluations = std::min(res.evaluations, prm.max_evaluations);
  if (I.stx > 0 && I.fx <= phi0 + I.stx * gtest) {
    res.accepted = true;
    res.step = I.stx;
    res.value = I.fx;
  }
  return res;
}

LineSearchResult hager_zhang(const PhiWithSlope& phi, double phi0, double slope0, const LineSearchParams& prm) {
  // Hager & Zhang (2005, 2006): accept a step that satisfies the Wolfe conditions, or the
  // approximate Wolfe conditions (2 delta - 1) phi'(0) >= phi'(s) >= sigma phi'(0) with
  // phi(s) <= phi(0) + eps |phi(0)|, which rely on derivatives where function values are
  // too close to resolve. Bracketing by the sign of phi', secant^2 steps, bisection.
  const double delta = prm.c1 < 0.5 ? std::max(prm.c1, 0.1) : 0.1, sigma = prm.c2, eps = 1e-6, gamma = 0.66;
  const double eps_k = eps * std::abs(phi0);
  LineSearchResult res;
  res.evaluations = 0;
  struct Pt { double s, f, g; };
  auto eval = [&](double s) {
    ++res.evaluations;
    const auto [f, g] = phi(s);
    return Pt{s, f, g};
  };
  auto acceptable = [&](const Pt& p) {
    if (!std::isfinite(p.f) || !std::isfinite(p.g)) return false;
    const bool wolfe = p.f - phi0 <= delta * p.s * slope0 && p.g >= sigma * slope0;
    const bool approx = (2 * delta - 1) * slope0 >= p.g && p.g >= sigma * slope0 && p.f <= phi0 + eps_k;
    return wolfe || approx;
  };
  auto accept = [&](const Pt& p) {
    res.accepted = true;
    res.step = p.s;
    res.value = p.f;
    return res;
  };
  const Pt zero{0.0, phi0, slope0};
  // U3: lo has phi <= phi0 + eps_k and phi' < 0, hi has phi > phi0 + eps_k (or is outside
  // the domain): bisect until an opposite-slope bracket is found.
  auto bisect = [&](Pt lo, Pt hi) -> std::pair<Pt, Pt> {
    while (res.evaluations < prm.max_evaluations) {
      const Pt d = eval(0.5 * (lo.s + hi.s));
      if (!std::isfinite(d.f) || !std::isfinite(d.g)) hi = d;
      else if (d.g >= 0) return {lo, d};
      else if (d.f <= phi0 + eps_k) lo = d;
      else hi = d;
    }
    return {lo, hi};
  };
  // HZ "update" of the bracket [a, b] with a trial c.
  auto update = [&](Pt a, Pt b, Pt c) -> std::pair<Pt, Pt> {
    if (c.s <= a.s || c.s >= b.s) return {a, b};
    if (!std::isfinite(c.f) || !std::isfinite(c.g)) return bisect(a, c);
    if (c.g >= 0) return {a, c};
    if (c.f <= phi0 + eps_k) return {c, b};
    return bisect(a, c);
  };
  auto secant = [](const Pt& a, const Pt& b) {
    return a.g == b.g ? 0.5 * (a.s + b.s) : (a.s * b.g - b.s * a.g) / (b.g - a.g);
  };

  // Bracket: expand from s = 1 by 5x until phi' >= 0 or phi rises above phi0 + eps_k.
  Pt a = zero, b = zero;
  Pt c = eval(1.0);
  for (;;) {
    if (acceptable(c)) return accept(c);
    if (res.evaluations >= prm.max_evaluations) return res;
    if (!std::isfinite(c.f) || !std::isfinite(c.g) || c.f > phi0 + eps_k) {
      std::tie(a, b) = bisect(a, c);
      break;
    }
    if (c.g >= 0) {
      b = c;
      break;
    }
    a = c;
    if (c.s >= prm.max_step) return res;
    c = eval(std::min(5.0 * c.s, prm.max_step));
  }
  // secant^2 iterations with bisection when the bracket does not shrink by gamma.
  while (res.evaluations < prm.max_evaluations) {
    if (acceptable(a) && a.s > 0) return accept(a);
    const double width = b.s - a.s;
    const Pt cs = eval(std::clamp(secant(a, b), a.s, b.s));
    if (acceptable(cs)) return accept(cs);
    auto [A, B] = update(a, b, cs);
    if (cs.s == B.s || cs.s == A.s) {
      const Pt c2 = eval(std::clamp(cs.s == B.s ? secant(b, B) : secant(a, A), A.s, B.s));
      if (acceptable(c2)) return accept(c2);
      std::tie(A, B) = update(A, B, c2);
    }
    if (B.s - A.s > gamma * width) {
      const Pt mid = eval(0.5 * (A.s + B.s));
      if (acceptable(mid)) return accept(mid);
      std::tie(A, B) = update(A, B, mid);
    }
    if (B.s - A.s <= 1e-14 * B.s) break;
    a = A, b = B;
  }
  return res;
}

}  // namespace weft::integrators
