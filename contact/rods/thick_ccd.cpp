#include "contact/rods/thick_ccd.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "contact/detection/distance.hpp"
#include "contact/detection/polynomial.hpp"
#include "framework/error.hpp"

namespace weft::contact::rods {

namespace {
using detection::Stencil;
using Eigen::Vector3d;

enum class Kind { vertex_triangle, edge_edge };

Stencil at(const Stencil& x0, const Stencil& dx, double t) {
  Stencil x;
  for (int j = 0; j < 4; ++j) x[j] = x0[j] + t * dx[j];
  return x;
}

Vector3d point(const Stencil& x, int first, double w) { return (1 - w) * x[first] + w * x[first + 1]; }

// Closest points at one configuration: squared distance, (s, t) as in ThickImpact, p^a - p^b.
struct Closest {
  double distance_squared;
  double s, t;
  Vector3d gap;
};

template <Kind K>
Closest closest(const Stencil& x) {
  if constexpr (K == Kind::vertex_triangle) {
    const detection::PointTriangle r = detection::point_triangle_distance(x[0], x[1], x[2], x[3]);
    return {r.distance_squared, r.weights[1], r.weights[2], x[0] - r.closest};
  } else {
    const detection::SegmentSegment r = detection::segment_segment_distance(x[0], x[1], x[2], x[3]);
    return {r.distance_squared, r.s, r.t, r.closest_a - r.closest_b};
  }
}

// Thick CCD for delta > 0 (file comment of thick_ccd.hpp), without the normal.
template <Kind K>
ThickImpact thick_ccd(const Stencil& x0, const Stencil& x1, double delta, double eta, int max_iterations,
                      Vector3d& gap_at_hit) {
  ThickImpact out;
  Stencil dx;
  for (int j = 0; j < 4; ++j) dx[j] = x1[j] - x0[j];
  const double reach = delta + eta, margin = delta + 0.5 * eta;
  auto report = [&](double t, const Closest& c, double d) {
    out.hit = true;
    out.toi = t;
    out.distance = d;
    out.s = c.s;
    out.t = c.t;
    gap_at_hit = c.gap;
    return out;
  };
  auto closest_at = [&](double t, Stencil& xt) {
    xt = at(x0, dx, t);
    ++out.iterations;
    return closest<K>(xt);
  };
  Stencil xt;
  const Closest c0 = closest_at(0, xt);
  const double d0 = std::sqrt(c0.distance_squared);
  if (d0 <= reach) return report(0, c0, d0);

  constexpr bool vf = K == Kind::vertex_triangle;
  const int na = vf ? 1 : 2;  // vertices of side a
  double lip = 0;
  for (int i = 0; i < na; ++i)
    for (int j = na; j < 4; ++j) lip = std::max(lip, (dx[i] - dx[j]).norm());
  if (!(lip > 0)) return out;  // translating together: d stays d(0)
  const double d1 = std::sqrt(closest_at(1, xt).distance_squared);
  if (0.5 * (d0 + d1 - lip) > margin) return out;

  // Candidate intervals from the line (plane) distance; coefficients as in ccd.cpp.
  const int o = vf ? 1 : 0;
  const int ia = vf ? 2 : 1, ja = vf ? 1 : 0, ib = 3, jb = vf ? 1 : 2, ic = vf ? 0 : 2;
  const Vector3d A0 = x0[ia] - x0[ja], A1 = dx[ia] - dx[ja];
  const Vector3d B0 = x0[ib] - x0[jb], B1 = dx[ib] - dx[jb];
  const Vector3d C0 = x0[ic] - x0[o], C1 = dx[ic] - dx[o];
  const Vector3d n00 = A0.cross(B0), n11 = A1.cross(B1), n01 = A1.cross(B0) + A0.cross(B1);
  detection::Cubic f;
  f.c = {n00.dot(C0), n01.dot(C0) + n00.dot(C1), n11.dot(C0) + n01.dot(C1), n11.dot(C1)};
  const double a_max = std::max(A0.norm(), (A0 + A1).norm()), b_max = std::max(B0.norm(), (B0 + B1).norm());
  const double pa = A0.norm() + A1.norm(), pb = B0.norm() + B1.norm(), pc = C0.norm() + C1.norm();
  double coord = 0;
  for (int j = 0; j < 4; ++j) coord = std::max({coord, x0[j].cwiseAbs().maxCoeff(), x1[j].cwiseAbs().maxCoeff()});
  const double eps = std::numeric_limits<double>::epsilon();
  const double err = 64 * eps * (pa * pb * pc + coord * (pa * pb + pb * pc + pa * pc));
  const detection::Intervals candidates = detection::band(f, reach * a_max * b_max * (1 + 1e-12) + err);

  for (int k = 0; k < candidates.n; ++k) {
    const double hi = candidates.iv[k][1];
    double t = candidates.iv[k][0];
    while (true) {
      const Closest c = closest_at(t, xt);
      const double d = std::sqrt(c.distance_squared);
      if (d <= reach || out.iterations >= max_iterations) {
        out.conservative = d > reach;
        return report(t, c, d);
      }
      double step = (d - margin) / lip;
      if (d > 0) {
        // Separation along the fixed axis n: a minimum of linear functions of t. Checked
        // rather than trusted (rounding of the closest points).
        const Vector3d n = c.gap / d;
        double axis_step = std::numeric_limits<double>::infinity(), separation = axis_step;
        for (int i = 0; i < na; ++i)
          for (int j = na; j < 4; ++j) {
            const double gap_ij = n.dot(xt[i] - xt[j]), rate = n.dot(dx[i] - dx[j]);
            separation = std::min(separation, gap_ij);
            if (rate < 0) axis_step = std::min(axis_step, (gap_ij - margin) / -rate);
          }
        if (separation >= margin) step = std::max(step, axis_step);
      }
      t += step;
      if (!(t <= hi)) break;
    }
  }
  return out;
}

}  // namespace

Vector3d segment_contact_normal(const Stencil& x, double s, double t, double distance,
                                const std::array<Vector3d, 2>& hints) {
  const Vector3d ea = x[1] - x[0], eb = x[3] - x[2];
  const double la = ea.norm(), lb = eb.norm();
  const Vector3d gap = point(x, 0, s) - point(x, 2, t);
  if (distance > 1e-8 * std::max(la, lb) && distance > 0) return gap / distance;
  // The closest points (nearly) coincide: the gap direction is rounding noise.
  Vector3d n = ea.cross(eb);
  if (n.norm() > 1e-8 * la * lb && n.norm() > 0) {
    n.normalize();
  } else {
    // Parallel (or zero-length) edges: a perpendicular of the longer one, towards the hints.
    const Vector3d e = la >= lb ? ea : eb;
    const double le = e.norm();
    const Vector3d u = le > 0 ? Vector3d(e / le) : Vector3d::UnitX();
    n = Vector3d::Zero();
    for (const Vector3d& h : hints) {
      const Vector3d p = h - h.dot(u) * u;
      if (p.norm() > 1e-12 * h.norm() && p.norm() > 0) {
        n = p.normalized();
        break;
      }
    }
    if (n.isZero()) {
      int k = 0;
      u.cwiseAbs().minCoeff(&k);
      n = u.cross(Vector3d::Unit(k)).normalized();
    }
  }
  for (const Vector3d& h : hints) {
    const double c = n.dot(h);
    if (std::abs(c) > 1e-12 * h.norm() && c != 0) return c > 0 ? n : Vector3d(-n);
  }
  int k = 0;
  n.cwiseAbs().maxCoeff(&k);
  return n[k] >= 0 ? n : Vector3d(-n);
}

ThickImpact segment_segment_ccd(const Stencil& x0, const Stencil& x1, double thickness, double eta,
                                int max_iterations) {
  WEFT_ASSERT(eta > 0 && std::isfinite(eta), "CCD tolerance eta = {} must be > 0 and finite", eta);
  WEFT_ASSERT(thickness >= 0 && std::isfinite(thickness), "thickness = {} must be >= 0 and finite", thickness);
  if (thickness == 0) {  // zero-thickness edges: the cubic CCD of contact/detection
    const detection::Impact c = detection::edge_edge_ccd(x0, x1, eta, {.max_iterations = max_iterations});
    ThickImpact out;
    out.hit = c.hit;
    out.toi = c.toi;
    out.distance = c.distance;
    out.s = c.gamma[1];
    out.t = -c.gamma[3];
    out.normal = c.normal;
    out.conservative = c.conservative;
    out.iterations = c.iterations;
    return out;
  }
  Vector3d gap;
  ThickImpact out = thick_ccd<Kind::edge_edge>(x0, x1, thickness, eta, max_iterations, gap);
  if (out.hit) {
    Stencil dx, xt;
    for (int j = 0; j < 4; ++j) dx[j] = x1[j] - x0[j];
    xt = at(x0, dx, out.toi);
    const Vector3d g0 = point(x0, 0, out.s) - point(x0, 2, out.t);
    const Vector3d v_rel = point(dx, 0, out.s) - point(dx, 2, out.t);
    out.normal = segment_contact_normal(xt, out.s, out.t, out.distance, {g0, Vector3d(-v_rel)});
  }
  return out;
}

ThickImpact point_triangle_ccd(const Stencil& x0, const Stencil& x1, double thickness, double eta,
                               int max_iterations) {
  WEFT_ASSERT(eta > 0 && std::isfinite(eta), "CCD tolerance eta = {} must be > 0 and finite", eta);
  WEFT_ASSERT(thickness > 0 && std::isfinite(thickness), "thickness = {} must be > 0 and finite", thickness);
  Vector3d gap;
  ThickImpact out = thick_ccd<Kind::vertex_triangle>(x0, x1, thickness, eta, max_iterations, gap);
  if (out.hit && out.distance > 0) out.normal = gap / out.distance;
  return out;
}

}  // namespace weft::contact::rods
