#include "contact/barrier_potential.hpp"

#include <cmath>
#include <limits>

#include "framework/distance.hpp"

namespace weft::contact::barrier {

namespace {

constexpr double inf = std::numeric_limits<double>::infinity();

// A second-order forward-mode dual number over the twelve stencil coordinates: value,
// gradient and Hessian, propagated exactly by the product and chain rules.
struct Jet {
  double v = 0;
  Vec12 g = Vec12::Zero();
  Mat12 h = Mat12::Zero();
};

Jet operator+(const Jet& a, const Jet& b) { return {a.v + b.v, a.g + b.g, a.h + b.h}; }
Jet operator-(const Jet& a, const Jet& b) { return {a.v - b.v, a.g - b.g, a.h - b.h}; }
Jet operator*(double k, const Jet& a) { return {k * a.v, k * a.g, k * a.h}; }
Jet operator*(const Jet& a, const Jet& b) {
  Jet r;
  r.v = a.v * b.v;
  r.g = a.v * b.g + b.v * a.g;
  r.h = a.v * b.h + b.v * a.h;
  r.h.noalias() += a.g * b.g.transpose();
  r.h.noalias() += b.g * a.g.transpose();
  return r;
}
// f(a) for f with value and derivatives fa at a.v.
Jet chain(const Jet& a, const Value2& fa) {
  Jet r;
  r.v = fa.f;
  r.g = fa.df * a.g;
  r.h = fa.df * a.h;
  r.h.noalias() += fa.d2f * a.g * a.g.transpose();
  return r;
}
Jet operator/(const Jet& a, const Jet& b) {
  const double ib = 1.0 / b.v;
  return a * chain(b, {ib, -ib * ib, 2 * ib * ib * ib});
}
Jet jet_sqrt(const Jet& a) {
  const double r = std::sqrt(a.v);
  return chain(a, {r, 0.5 / r, -0.25 / (r * a.v)});
}

using J3 = std::array<Jet, 3>;
J3 sub(const J3& a, const J3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Jet dot(const J3& a, const J3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
J3 cross(const J3& a, const J3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

std::array<J3, 4> variables(const Stencil& x) {
  std::array<J3, 4> X;
  for (int j = 0; j < 4; ++j)
    for (int k = 0; k < 3; ++k) {
      X[j][k].v = x[j][k];
      X[j][k].g[3 * j + k] = 1;
    }
  return X;
}

// The squared distance of the typed formula (file comment of the header).
Jet squared_distance(const TypedDistance& t, const std::array<J3, 4>& X) {
  const auto& i = t.idx;
  switch (t.type) {
    case DistanceType::point_point: {
      const J3 d = sub(X[i[0]], X[i[1]]);
      return dot(d, d);
    }
    case DistanceType::point_edge: {
      const J3 e = sub(X[i[2]], X[i[1]]);
      const J3 c = cross(sub(X[i[0]], X[i[1]]), e);
      return dot(c, c) / dot(e, e);
    }
    case DistanceType::point_plane: {
      const J3 n = cross(sub(X[i[2]], X[i[1]]), sub(X[i[3]], X[i[1]]));
      const Jet a = dot(sub(X[i[0]], X[i[1]]), n);
      return (a * a) / dot(n, n);
    }
    case DistanceType::line_line: {
      const J3 n = cross(sub(X[i[1]], X[i[0]]), sub(X[i[3]], X[i[2]]));
      const Jet a = dot(sub(X[i[2]], X[i[0]]), n);
      return (a * a) / dot(n, n);
    }
  }
  return {};
}

double edge_cross_squared(const Stencil& x) { return (x[1] - x[0]).cross(x[3] - x[2]).squaredNorm(); }

}  // namespace

Value2 log_barrier(double s, double s_hat) {
  if (!(s > 0)) return {inf, -inf, inf};
  if (s >= s_hat) return {};
  const double r = s - s_hat, l = std::log(s / s_hat);
  return {-r * r * l, -2 * r * l - r * r / s, -2 * l - 4 * r / s + r * r / (s * s)};
}

Value2 friction_f0(double y, double eps) {
  if (y >= eps) return {y, 1, 0};
  return {-y * y * y / (3 * eps * eps) + y * y / eps + eps / 3, -y * y / (eps * eps) + 2 * y / eps, -2 * y / (eps * eps) + 2 / eps};
}

Value2 edge_mollifier(double c, double eps_x) {
  if (c >= eps_x) return {1, 0, 0};
  const double q = c / eps_x;
  return {(2 - q) * q, (2 - 2 * q) / eps_x, -2 / (eps_x * eps_x)};
}

TypedDistance point_triangle_type(const Stencil& x) {
  const PointTriangle pt = point_triangle_distance(x[0], x[1], x[2], x[3]);
  TypedDistance t;
  t.s = pt.distance_squared;
  t.gamma = {1, -pt.weights[0], -pt.weights[1], -pt.weights[2]};
  int nonzero[3], n = 0;
  for (std::uint8_t k = 0; k < 3; ++k)
    if (pt.weights[k] != 0) nonzero[n++] = k;
  if (n == 3) {
    t.type = DistanceType::point_plane;
    t.idx = {0, 1, 2, 3};
  } else if (n == 2) {
    t.type = DistanceType::point_edge;
    t.idx = {0, static_cast<std::uint8_t>(1 + nonzero[0]), static_cast<std::uint8_t>(1 + nonzero[1]), 0};
  } else {
    t.type = DistanceType::point_point;
    t.idx = {0, static_cast<std::uint8_t>(1 + (n == 1 ? nonzero[0] : 0)), 0, 0};
  }
  return t;
}

TypedDistance edge_edge_type(const Stencil& x) {
  const SegmentSegment ss = segment_segment_distance(x[0], x[1], x[2], x[3]);
  TypedDistance t;
  t.s = ss.distance_squared;
  t.gamma = {1 - ss.s, ss.s, -(1 - ss.t), -ss.t};
  const bool s_in = ss.s > 0 && ss.s < 1, t_in = ss.t > 0 && ss.t < 1;
  const std::uint8_t sa = ss.s < 0.5 ? 0 : 1, tb = ss.t < 0.5 ? 2 : 3;
  if (s_in && t_in) {
    t.type = DistanceType::line_line;
    t.idx = {0, 1, 2, 3};
  } else if (t_in) {
    t.type = DistanceType::point_edge;
    t.idx = {sa, 2, 3, 0};
  } else if (s_in) {
    t.type = DistanceType::point_edge;
    t.idx = {tb, 0, 1, 0};
  } else {
    t.type = DistanceType::point_point;
    t.idx = {sa, tb, 0, 0};
  }
  return t;
}

double pair_gap(const Stencil& x, const PairConstants& c) {
  switch (c.kind) {
    case PairKind::point_triangle: return std::sqrt(point_triangle_type(x).s);
    case PairKind::edge_edge: return std::sqrt(edge_edge_type(x).s);
    case PairKind::sphere_triangle: return std::sqrt(point_triangle_type(x).s) - c.radius;
    case PairKind::point_plane: return c.normal.dot(x[0] - x[1]);
  }
  return inf;
}

double pair_energy(const Stencil& x, const PairConstants& c) {
  const double g = pair_gap(x, c);
  if (!(g > 0)) return inf;
  const double s = g * g;
  if (s >= c.s_hat) return 0;
  double m = 1;
  if (c.kind == PairKind::edge_edge && c.eps_x > 0) m = edge_mollifier(edge_cross_squared(x), c.eps_x).f;
  return c.kappa * m * log_barrier(s, c.s_hat).f;
}

bool pair_derivatives(const Stencil& x, const PairConstants& c, double& value, Vec12& grad, Mat12* hessian) {
  grad.setZero();
  if (hessian) hessian->setZero();
  value = 0;
  const double g0 = pair_gap(x, c);
  if (!(g0 > 0)) {
    value = inf;
    return false;
  }
  if (g0 * g0 >= c.s_hat) return false;
  const std::array<J3, 4> X = variables(x);
  Jet s;
  switch (c.kind) {
    case PairKind::point_triangle: s = squared_distance(point_triangle_type(x), X); break;
    case PairKind::edge_edge: s = squared_distance(edge_edge_type(x), X); break;
    case PairKind::sphere_triangle: {
      const Jet d = jet_sqrt(squared_distance(point_triangle_type(x), X));
      const Jet gap = d - Jet{c.radius, Vec12::Zero(), Mat12::Zero()};
      s = gap * gap;
      break;
    }
    case PairKind::point_plane: {
      Jet gap;
      gap.v = c.normal.dot(x[0] - x[1]);
      gap.g.segment<3>(0) = c.normal;
      gap.g.segment<3>(3) = -c.normal;
      s = gap * gap;
      break;
    }
  }
  Jet e = chain(s, log_barrier(s.v, c.s_hat));
  if (c.kind == PairKind::edge_edge && c.eps_x > 0 && edge_cross_squared(x) < c.eps_x) {
    const J3 n = cross(sub(X[1], X[0]), sub(X[3], X[2]));
    const Jet cc = dot(n, n);
    e = chain(cc, edge_mollifier(cc.v, c.eps_x)) * e;
  }
  value = c.kappa * e.v;
  grad = c.kappa * e.g;
  if (hessian) *hessian = c.kappa * e.h;
  return true;
}

double pair_normal_force(const Stencil& x, const PairConstants& c) {
  const double g = pair_gap(x, c);
  if (!(g > 0) || g * g >= c.s_hat) return 0;
  double m = 1;
  if (c.kind == PairKind::edge_edge && c.eps_x > 0) m = edge_mollifier(edge_cross_squared(x), c.eps_x).f;
  return -c.kappa * m * log_barrier(g * g, c.s_hat).df * 2 * g;
}

Eigen::Matrix<double, 3, 2> tangent_basis(const Eigen::Vector3d& n) {
  // The coordinate axis least aligned with n, made orthogonal to it.
  Eigen::Index k;
  n.cwiseAbs().minCoeff(&k);
  Eigen::Vector3d t1 = Eigen::Vector3d::Unit(k) - n[k] * n;
  t1.normalize();
  Eigen::Matrix<double, 3, 2> T;
  T.col(0) = t1;
  T.col(1) = n.cross(t1);
  return T;
}

Eigen::Vector2d tangential_displacement(const FrictionPair& f, const Stencil& dx) {
  Eigen::Vector3d r = Eigen::Vector3d::Zero();
  for (int j = 0; j < 4; ++j) r += f.gamma[j] * dx[j];
  return f.basis.transpose() * r + f.offset;
}

double friction_energy(const FrictionPair& f, const Stencil& dx) {
  return f.mu_lambda * friction_f0(tangential_displacement(f, dx).norm(), f.eps).f;
}

void friction_derivatives(const FrictionPair& f, const Stencil& dx, Vec12& grad, Mat12* hessian) {
  const Eigen::Vector2d u = tangential_displacement(f, dx);
  const double y = u.norm();
  const Value2 f0 = friction_f0(y, f.eps);
  // f1 / y, finite at y = 0 (its limit 2 / eps).
  const double f1_over_y = y < f.eps ? 2 / f.eps - y / (f.eps * f.eps) : 1 / y;
  const Eigen::Vector3d gu = f.mu_lambda * f1_over_y * (f.basis * u);
  for (int j = 0; j < 4; ++j) grad.segment<3>(3 * j) = f.gamma[j] * gu;
  if (!hessian) return;
  Eigen::Matrix2d H = f1_over_y * Eigen::Matrix2d::Identity();
  if (y > 0) H += (f0.d2f - f1_over_y) * (u / y) * (u / y).transpose();
  const Eigen::Matrix3d B = f.mu_lambda * f.basis * H * f.basis.transpose();
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b) hessian->block<3, 3>(3 * a, 3 * b) = (f.gamma[a] * f.gamma[b]) * B;
}

}  // namespace weft::contact::barrier
