#include "apps/references.hpp"

#include <cmath>
#include <numbers>

namespace weft::app::reference {

namespace {

/// theta(1), theta'(1) and the tip position for theta'(0) = kappa0, in units of L.
struct Shot {
  double theta, dtheta, x, z;
};

Shot shoot(double alpha, double kappa0) {
  constexpr int n = 4000;
  const double h = 1.0 / n;
  // y = (theta, theta', x, z); theta'' = -alpha (1 - s) cos theta; x' = cos theta; z' = sin theta.
  auto f = [alpha](double s, const double y[4], double d[4]) {
    d[0] = y[1];
    d[1] = -alpha * (1.0 - s) * std::cos(y[0]);
    d[2] = std::cos(y[0]);
    d[3] = std::sin(y[0]);
  };
  double y[4] = {0.0, kappa0, 0.0, 0.0}, k1[4], k2[4], k3[4], k4[4], t[4];
  for (int i = 0; i < n; ++i) {
    const double s = i * h;
    f(s, y, k1);
    for (int j = 0; j < 4; ++j) t[j] = y[j] + 0.5 * h * k1[j];
    f(s + 0.5 * h, t, k2);
    for (int j = 0; j < 4; ++j) t[j] = y[j] + 0.5 * h * k2[j];
    f(s + 0.5 * h, t, k3);
    for (int j = 0; j < 4; ++j) t[j] = y[j] + h * k3[j];
    f(s + h, t, k4);
    for (int j = 0; j < 4; ++j) y[j] += h / 6.0 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]);
  }
  return {y[0], y[1], y[2], y[3]};
}

}  // namespace

Elastica cantilever_elastica(double alpha) {
  if (!(alpha > 0)) return {0.0, 1.0, 0.0};
  // theta'(1) grows with theta'(0) on [0, alpha / 2] (the linear beam's root moment is the
  // upper end: the curved beam's lever arms are shorter), negative at 0 and >= 0 at the top.
  double lo = 0.0, hi = 0.5 * alpha;
  for (int it = 0; it < 200 && hi - lo > 1e-15 * alpha; ++it) {
    const double mid = 0.5 * (lo + hi);
    (shoot(alpha, mid).dtheta < 0 ? lo : hi) = mid;
  }
  const Shot s = shoot(alpha, 0.5 * (lo + hi));
  return {s.z, s.x, s.theta};
}

double elastica_alpha_at_chord_angle(double chord_angle) {
  // The chord angle atan(drop / reach) grows with alpha from 0 towards pi / 2.
  double lo = 0.0, hi = 1.0;
  auto angle = [](double a) {
    const Elastica e = cantilever_elastica(a);
    return std::atan2(e.drop, e.reach);
  };
  while (angle(hi) < chord_angle && hi < 1e6) hi *= 2;
  for (int it = 0; it < 100 && hi - lo > 1e-12 * hi; ++it) {
    const double mid = 0.5 * (lo + hi);
    (angle(mid) < chord_angle ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

double arc_cantilever_deflection(double phi, double R, double q, double bending, double torsion) {
  const double b = 1.0 - std::cos(phi), t = phi - std::sin(phi);
  return q * R * R * R * R * (b * b / (2.0 * bending) + t * t / (2.0 * torsion));
}

double stvk_uniaxial_lateral_stretch(double lambda, double nu) { return std::sqrt(1.0 - nu * (lambda * lambda - 1.0)); }

double incline_acceleration(double g, double angle, double mu) {
  const double a = g * (std::sin(angle) - mu * std::cos(angle));
  return a > 0 ? a : 0.0;
}

}  // namespace weft::app::reference
