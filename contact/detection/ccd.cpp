#include "contact/detection/ccd.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "contact/detection/distance.hpp"
#include "contact/detection/polynomial.hpp"
#include "framework/error.hpp"

namespace weft::contact::detection {

namespace {
using Eigen::Vector3d;

enum class Kind { vertex_triangle, edge_edge };

// Closest points of the pair at one configuration.
struct Closest {
  double distance_squared;
  std::array<double, 4> gamma;
  Vector3d gap;  // p^a - p^b
};

template <Kind K>
Closest closest(const Stencil& x) {
  if constexpr (K == Kind::vertex_triangle) {
    const PointTriangle r = point_triangle_distance(x[0], x[1], x[2], x[3]);
    return {r.distance_squared, {1, -r.weights[0], -r.weights[1], -r.weights[2]}, x[0] - r.closest};
  } else {
    const SegmentSegment r = segment_segment_distance(x[0], x[1], x[2], x[3]);
    return {r.distance_squared, {1 - r.s, r.s, -(1 - r.t), -r.t}, r.closest_a - r.closest_b};
  }
}

Stencil at(const Stencil& x0, const Stencil& dx, double t) {
  Stencil x;
  for (int j = 0; j < 4; ++j) x[j] = x0[j] + t * dx[j];
  return x;
}

double sign(double v) { return v > 0 ? 1.0 : (v < 0 ? -1.0 : 0.0); }

template <Kind K>
Impact ccd(const Stencil& x0, const Stencil& x1, double eta, const CcdOptions& opt) {
  WEFT_ASSERT(eta > 0 && std::isfinite(eta), "CCD tolerance eta = {} must be > 0 and finite", eta);
  Stencil dx;
  for (int j = 0; j < 4; ++j) dx[j] = x1[j] - x0[j];

  // Spanning vectors A, B and offset C (see ccd.hpp), each X(t) = X0 + t X1.
  constexpr bool vf = K == Kind::vertex_triangle;
  const int o = vf ? 1 : 0;  // origin vertex
  const int ia = vf ? 2 : 1, ja = vf ? 1 : 0, ib = 3, jb = vf ? 1 : 2, ic = vf ? 0 : 2;
  const Vector3d A0 = x0[ia] - x0[ja], A1 = dx[ia] - dx[ja];
  const Vector3d B0 = x0[ib] - x0[jb], B1 = dx[ib] - dx[jb];
  const Vector3d C0 = x0[ic] - x0[o], C1 = dx[ic] - dx[o];

  // f(t) = (A x B) . C, expanded in powers of t.
  const Vector3d n00 = A0.cross(B0), n11 = A1.cross(B1), n01 = A1.cross(B0) + A0.cross(B1);
  Cubic f;
  f.c = {n00.dot(C0), n01.dot(C0) + n00.dot(C1), n11.dot(C0) + n01.dot(C1), n11.dot(C1)};

  // delta = eta N + rounding allowance. The allowance bounds the error of the computed f
  // against the f of the exact input: differences of coordinates (relative to their
  // magnitude M), then products and sums of the three vectors; 64 eps is generous.
  const double a_max = std::max(A0.norm(), (A0 + A1).norm()), b_max = std::max(B0.norm(), (B0 + B1).norm());
  const double pa = A0.norm() + A1.norm(), pb = B0.norm() + B1.norm(), pc = C0.norm() + C1.norm();
  double coord = 0;
  for (int j = 0; j < 4; ++j) coord = std::max({coord, x0[j].cwiseAbs().maxCoeff(), x1[j].cwiseAbs().maxCoeff()});
  const double eps = std::numeric_limits<double>::epsilon();
  const double err = 64 * eps * (pa * pb * pc + coord * (pa * pb + pb * pc + pa * pc));
  const double delta = eta * a_max * b_max * (1 + 1e-12) + err;

  // Lipschitz constant of the distance in t.
  double lip = 0;
  const int na = vf ? 1 : 2;
  for (int i = 0; i < na; ++i)
    for (int j = na; j < 4; ++j) lip = std::max(lip, (dx[i] - dx[j]).norm());

  Impact out;
  const Intervals candidates = band(f, delta);
  for (int k = 0; k < candidates.n; ++k) {
    const double lo = candidates.iv[k][0], hi = candidates.iv[k][1];
    double t = lo;
    while (true) {
      const Stencil xt = at(x0, dx, t);
      const Closest c = closest<K>(xt);
      ++out.iterations;
      const double d = std::sqrt(c.distance_squared);
      const bool capped = out.iterations >= opt.max_iterations;
      if (d <= eta || capped) {
        out.hit = true;
        out.toi = t;
        out.distance = d;
        out.gamma = c.gamma;
        out.conservative = d > eta;
        // Orientation from the side of the plane (VF) or of the two lines (EE) at the
        // start of the band interval: n . (p^a - p^b) = f (VF) or -f (EE).
        const double f_lo = f(lo);
        double s = std::abs(f_lo) > err ? (vf ? sign(f_lo) : -sign(f_lo)) : 0.0;
        const Vector3d n = (A0 + t * A1).cross(B0 + t * B1);
        Vector3d v_rel = Vector3d::Zero();  // velocity of p^a relative to p^b
        for (int j = 0; j < 4; ++j) v_rel += c.gamma[j] * dx[j];
        if (s == 0) s = sign(c.gap.dot(n));
        if (s == 0) s = -sign(v_rel.dot(n));
        if (s == 0) s = 1;
        const double scale = (A0 + t * A1).norm() * (B0 + t * B1).norm();
        if (n.norm() > 1e-8 * scale)
          out.normal = s * n.normalized();
        else if (c.gap.norm() > 0)
          out.normal = c.gap.normalized();
        else if (v_rel.norm() > 0)
          out.normal = -v_rel.normalized();
        else
          out.normal = Vector3d::UnitZ();
        return out;
      }
      // Safe step: the Lipschitz bound, or the time for which the fixed axis n = gap / d
      // keeps A and B at least eta/2 apart (the separation along a fixed axis is a
      // minimum of linear functions of t, one per pair of vertices of A and B), whichever
      // is longer. The axis step makes motion parallel to the gap (sliding) cheap.
      double step = lip > 0 ? (d - 0.5 * eta) / lip : std::numeric_limits<double>::infinity();
      if (d > 0) {
        const Vector3d n = c.gap / d;
        double axis_step = std::numeric_limits<double>::infinity(), separation = axis_step;
        for (int i = 0; i < na; ++i)
          for (int j = na; j < 4; ++j) {
            const double gap_ij = n.dot(xt[i] - xt[j]), rate = n.dot(dx[i] - dx[j]);
            separation = std::min(separation, gap_ij);
            if (rate < 0) axis_step = std::min(axis_step, (gap_ij - 0.5 * eta) / -rate);
          }
        // n separates A and B by d at t when the closest points are exact; check it
        // rather than trust it, so that the step stays safe whatever the rounding.
        if (separation >= 0.5 * eta) step = std::max(step, axis_step);
      }
      t += step;
      if (!(t <= hi)) break;  // also for an infinite step: separated for the rest of the step
    }
  }
  return out;
}
}  // namespace

Impact vertex_triangle_ccd(const Stencil& x0, const Stencil& x1, double eta, const CcdOptions& opt) {
  return ccd<Kind::vertex_triangle>(x0, x1, eta, opt);
}

Impact edge_edge_ccd(const Stencil& x0, const Stencil& x1, double eta, const CcdOptions& opt) {
  return ccd<Kind::edge_edge>(x0, x1, eta, opt);
}

}  // namespace weft::contact::detection
