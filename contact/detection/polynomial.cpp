#include "contact/detection/polynomial.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace weft::contact::detection {

namespace {
void push_unique(Roots& r, double t) {
  if (r.n > 0 && r.t[r.n - 1] == t) return;
  if (r.n < 3) r.t[r.n++] = t;
}
}  // namespace

Roots quadratic_roots_in_unit(double a, double b, double c) {
  double cand[2];
  int m = 0;
  if (a == 0) {
    if (b != 0) cand[m++] = -c / b;
  } else {
    const double disc = b * b - 4 * a * c;
    if (disc == 0) {
      cand[m++] = -b / (2 * a);
    } else if (disc > 0) {
      // q has the sign of -b, so b + sign(b) sqrt(disc) never cancels.
      const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
      cand[m++] = q / a;
      if (q != 0) cand[m++] = c / q;
    }
  }
  Roots r;
  if (m == 2 && cand[1] < cand[0]) std::swap(cand[0], cand[1]);
  for (int i = 0; i < m; ++i)
    if (std::isfinite(cand[i]) && cand[i] > 0 && cand[i] < 1) push_unique(r, cand[i]);
  return r;
}

Breaks monotone_pieces(const Cubic& p) {
  const Roots crit = quadratic_roots_in_unit(3 * p.c[3], 2 * p.c[2], p.c[1]);
  Breaks b;
  b.t[b.n++] = 0;
  for (int i = 0; i < crit.n; ++i) {
    // Polish on p' (Newton with p'' = 6 c3 t + 2 c2); keep a step only if it reduces |p'|.
    double t = crit.t[i];
    for (int k = 0; k < 3; ++k) {
      const double d2 = 6 * p.c[3] * t + 2 * p.c[2];
      if (d2 == 0) break;
      const double tn = t - p.derivative(t) / d2;
      if (!(tn > 0 && tn < 1) || std::abs(p.derivative(tn)) >= std::abs(p.derivative(t))) break;
      t = tn;
    }
    if (t > b.t[b.n - 1]) b.t[b.n++] = t;
  }
  b.t[b.n++] = 1;
  return b;
}

std::array<double, 2> solve_monotone(const Cubic& p, double y, double l, double r) {
  const double fl = p(l) - y, fr = p(r) - y;
  if (fl == 0) return {l, l};
  if (fr == 0) return {r, r};
  // Orient so that f < 0 at lo and f > 0 at hi: f is then non-decreasing on [l, r].
  const bool increasing = fl < 0;
  auto f = [&](double t) { return increasing ? p(t) - y : y - p(t); };
  auto df = [&](double t) { return increasing ? p.derivative(t) : -p.derivative(t); };
  double lo = l, hi = r;
  // Start from the secant point (exact for a linear p).
  double t = (l * fr - r * fl) / (fr - fl);
  if (!(t > lo && t < hi)) t = 0.5 * (lo + hi);
  double width_1 = hi - lo, width_2 = hi - lo;  // bracket widths one and two iterations ago
  auto shrink = [&](double s, double fs) {
    if (fs < 0)
      lo = s;
    else
      hi = s;
  };
  for (int it = 0; it < 100; ++it) {
    const double mid = 0.5 * (lo + hi);
    if (hi - lo <= 1e-15 || mid <= lo || mid >= hi) break;
    const double ft = f(t);
    if (ft == 0) return {t, t};
    shrink(t, ft);
    // Newton step from t; a probe slightly beyond the Newton point closes the bracket from
    // the far side (Newton alone approaches a convex root from one side only).
    const double d = df(t);
    double tn = d > 0 ? t - ft / d : mid;
    if (tn > lo && tn < hi) {
      const double tp = tn + 0.25 * (tn - t);
      if (tp > lo && tp < hi) {
        const double fp = f(tp);
        if (fp == 0) return {tp, tp};
        shrink(tp, fp);
      }
    }
    // Safeguard: bisect when Newton leaves the bracket or the bracket stopped halving.
    if (!(tn > lo && tn < hi) || hi - lo > 0.5 * width_2) tn = 0.5 * (lo + hi);
    width_2 = width_1;
    width_1 = hi - lo;
    t = tn;
  }
  return {lo, hi};
}

Roots cubic_roots_in_unit(const Cubic& p) {
  const Breaks b = monotone_pieces(p);
  Roots r;
  for (int i = 0; i + 1 < b.n; ++i) {
    const double l = b.t[i], h = b.t[i + 1];
    const double fl = p(l), fh = p(h);
    if ((fl < 0 && fh < 0) || (fl > 0 && fh > 0)) continue;
    if (fl == 0 && fh == 0) {  // a zero polynomial on this piece: report its start
      push_unique(r, l);
      continue;
    }
    const auto br = solve_monotone(p, 0, l, h);
    push_unique(r, 0.5 * (br[0] + br[1]));
  }
  return r;
}

Intervals band(const Cubic& p, double delta) {
  const Breaks b = monotone_pieces(p);
  Intervals out;
  for (int i = 0; i + 1 < b.n; ++i) {
    const double l = b.t[i], h = b.t[i + 1];
    const double fl = p(l), fh = p(h);
    double lo, hi;
    if (fl <= fh) {  // increasing
      if (fh < -delta || fl > delta) continue;
      lo = fl >= -delta ? l : solve_monotone(p, -delta, l, h)[0];
      hi = fh <= delta ? h : solve_monotone(p, delta, l, h)[1];
    } else {  // decreasing
      if (fl < -delta || fh > delta) continue;
      lo = fl <= delta ? l : solve_monotone(p, delta, l, h)[0];
      hi = fh >= -delta ? h : solve_monotone(p, -delta, l, h)[1];
    }
    if (out.n > 0 && lo <= out.iv[out.n - 1][1]) {
      out.iv[out.n - 1][1] = std::max(out.iv[out.n - 1][1], hi);
    } else {
      out.iv[out.n++] = {lo, hi};
    }
  }
  return out;
}

}  // namespace weft::contact::detection
