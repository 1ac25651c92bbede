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

double sign(double v) { return v > 0 ? 1.0 : (v < 0 ? -1.0 : 0.0); }

template <Kind K>
Impact ccd(const Stencil& x0, const Stencil& x1, double eta, const CcdOptions& opt) {
  WEFT_ASSERT(eta > 0 && std::isfinite(eta), "CCD tolerance eta = {} must be > 0 and finite", eta);
  Stencil dx;
  for (int j = 0; j < 4; ++j) dx[j] = x1[j] - x0[j];

  constexpr bool vf = K == Kind::vertex_triangle;
  const Coplanarity cp = coplanarity(x0, x1, dx, vf);
  const Cubic& f = cp.f;
  const Vector3d &A0 = cp.A0, &A1 = cp.A1, &B0 = cp.B0, &B1 = cp.B1;
  const double err = cp.err;
  // delta = eta N + rounding allowance.
  const double delta = eta * cp.a_max * cp.b_max * (1 + 1e-12) + err;
  const int na = vf ? 1 : 2;
  const double lip = distance_lipschitz(dx, na);

  Impact out;
  const Intervals candidates = band(f, delta);
  for (int k = 0; k < candidates.n; ++k) {
    const double lo = candidates.iv[k][0], hi = candidates.iv[k][1];
    double t = lo;
    while (true) {
      const Stencil xt = stencil_at(x0, dx, t);
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
      // Safe step (ccd.hpp, advancement_step): the axis step makes sliding cheap.
      const double step = advancement_step(xt, dx, na, c.gap, d, lip, 0.5 * eta);
      t += step;
      if (!(t <= hi)) break;  // also for an infinite step: separated for the rest of the step
    }
  }
  return out;
}
}  // namespace

Stencil stencil_at(const Stencil& x0, const Stencil& dx, double t) {
  Stencil x;
  for (int j = 0; j < 4; ++j) x[j] = x0[j] + t * dx[j];
  return x;
}

Coplanarity coplanarity(const Stencil& x0, const Stencil& x1, const Stencil& dx, bool vf) {
  // Spanning vectors A, B and offset C (file comment of ccd.hpp), each X(t) = X0 + t X1.
  const int o = vf ? 1 : 0;  // origin vertex
  const int ia = vf ? 2 : 1, ja = vf ? 1 : 0, ib = 3, jb = vf ? 1 : 2, ic = vf ? 0 : 2;
  Coplanarity cp;
  cp.A0 = x0[ia] - x0[ja], cp.A1 = dx[ia] - dx[ja];
  cp.B0 = x0[ib] - x0[jb], cp.B1 = dx[ib] - dx[jb];
  const Vector3d C0 = x0[ic] - x0[o], C1 = dx[ic] - dx[o];
  // f(t) = (A x B) . C, expanded in powers of t.
  const Vector3d n00 = cp.A0.cross(cp.B0), n11 = cp.A1.cross(cp.B1), n01 = cp.A1.cross(cp.B0) + cp.A0.cross(cp.B1);
  cp.f.c = {n00.dot(C0), n01.dot(C0) + n00.dot(C1), n11.dot(C0) + n01.dot(C1), n11.dot(C1)};
  cp.a_max = std::max(cp.A0.norm(), (cp.A0 + cp.A1).norm());
  cp.b_max = std::max(cp.B0.norm(), (cp.B0 + cp.B1).norm());
  const double pa = cp.A0.norm() + cp.A1.norm(), pb = cp.B0.norm() + cp.B1.norm(), pc = C0.norm() + C1.norm();
  double coord = 0;
  for (int j = 0; j < 4; ++j) coord = std::max({coord, x0[j].cwiseAbs().maxCoeff(), x1[j].cwiseAbs().maxCoeff()});
  cp.err = 64 * std::numeric_limits<double>::epsilon() * (pa * pb * pc + coord * (pa * pb + pb * pc + pa * pc));
  return cp;
}

double distance_lipschitz(const Stencil& dx, int na) {
  double lip = 0;
  for (int i = 0; i < na; ++i)
    for (int j = na; j < 4; ++j) lip = std::max(lip, (dx[i] - dx[j]).norm());
  return lip;
}

double advancement_step(const Stencil& xt, const Stencil& dx, int na, const Vector3d& gap, double d, double lip, double margin) {
  double step = lip > 0 ? (d - margin) / lip : std::numeric_limits<double>::infinity();
  if (d > 0) {
    const Vector3d n = gap / d;
    double axis_step = std::numeric_limits<double>::infinity(), separation = axis_step;
    for (int i = 0; i < na; ++i)
      for (int j = na; j < 4; ++j) {
        const double gap_ij = n.dot(xt[i] - xt[j]), rate = n.dot(dx[i] - dx[j]);
        separation = std::min(separation, gap_ij);
        if (rate < 0) axis_step = std::min(axis_step, (gap_ij - margin) / -rate);
      }
    // n separates the sides by d at t when the closest points are exact; check it.
    if (separation >= margin) step = std::max(step, axis_step);
  }
  return step;
}

Impact vertex_triangle_ccd(const Stencil& x0, const Stencil& x1, double eta, const CcdOptions& opt) {
  return ccd<Kind::vertex_triangle>(x0, x1, eta, opt);
}

Impact edge_edge_ccd(const Stencil& x0, const Stencil& x1, double eta, const CcdOptions& opt) {
  return ccd<Kind::edge_edge>(x0, x1, eta, opt);
}

}  // namespace weft::contact::detection
