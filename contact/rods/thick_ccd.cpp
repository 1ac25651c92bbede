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
    xt = detection::stencil_at(x0, dx, t);
    ++out.iterations;
    return closest<K>(xt);
  };
  Stencil xt;
  const Closest c0 = closest_at(0, xt);
  const double d0 = std::sqrt(c0.distance_squared);
  if (d0 <= reach) return report(0, c0, d0);

  constexpr bool vf = K == Kind::vertex_triangle;
  const int na = vf ? 1 : 2;  // vertices of side a
  const double lip = detection::distance_lipschitz(dx, na);
  if (!(lip > 0)) return out;  // translating together: d stays d(0)
  const double d1 = std::sqrt(closest_at(1, xt).distance_squared);
  if (0.5 * (d0 + d1 - lip) > margin) return out;

  // Candidate intervals from the line (plane) distance (ccd.hpp, coplanarity).
  const detection::Coplanarity cp = detection::coplanarity(x0, x1, dx, vf);
  const detection::Intervals candidates = detection::band(cp.f, reach * cp.a_max * cp.b_max * (1 + 1e-12) + cp.err);

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
      const double step = detection::advancement_step(xt, dx, na, c.gap, d, lip, margin);
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
    xt = detection::stencil_at(x0, dx, out.toi);
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
