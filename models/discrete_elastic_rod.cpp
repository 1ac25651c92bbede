#include "models/discrete_elastic_rod.hpp"

#include <Eigen/Eigenvalues>
#include <unsupported/Eigen/AutoDiff>

#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include "framework/error.hpp"
#include "framework/params.hpp"
#include "models/autodiff_support.hpp"

namespace weft::models {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kFoldTolerance = 1e-12;     // 1 + t_{i-1}.t_i (fold) and 1 + t.from.t (transport)
constexpr double kLengthTolerance = 1e-12;   // |e_j| relative to |ebar_j|

// Test oracle (rod::stencil_scalars_autodiff): forward-over-forward AD over the two edge vectors of a stencil (e_{i-1}, e_i): six
// variables, fixed size (no heap allocation).
using D6 = Eigen::Matrix<double, 6, 1>;
using A1 = Eigen::AutoDiffScalar<D6>;
using D6A = Eigen::Matrix<A1, 6, 1>;
using A2 = Eigen::AutoDiffScalar<D6A>;

using Vec5 = Eigen::Matrix<double, 5, 1>;
using Mat56 = Eigen::Matrix<double, 5, 6>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec7 = Eigen::Matrix<double, 7, 1>;
using Mat7 = Eigen::Matrix<double, 7, 7>;
using Vec8 = Eigen::Matrix<double, 8, 1>;
using Mat8 = Eigen::Matrix<double, 8, 8>;
using Vec11 = Eigen::Matrix<double, 11, 1>;
using Mat11 = Eigen::Matrix<double, 11, 11>;

using detail::ad_atan2;

template <class S>
using V3 = std::array<S, 3>;

V3<double> arr(const Eigen::Vector3d& v) { return {v[0], v[1], v[2]}; }

template <class S, class T, class U>
V3<S> cross(const V3<T>& a, const V3<U>& b) {
  return {S(a[1] * b[2] - a[2] * b[1]), S(a[2] * b[0] - a[0] * b[2]), S(a[0] * b[1] - a[1] * b[0])};
}
template <class S, class T, class U>
S dot(const V3<T>& a, const V3<U>& b) {
  return S(a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
}

/// P_{a -> b} d = (a.b) d + (a x b) x d + ((a x b).d) / (1 + a.b) (a x b): the minimal rotation
/// taking unit a to unit b, applied to d.
template <class S, class T, class U>
V3<S> parallel_transport(const V3<T>& a, const V3<S>& b, const V3<U>& d) {
  const S c = dot<S>(a, b);
  const V3<S> n = cross<S>(a, b);
  const V3<S> nxd = cross<S>(n, d);
  const S f = S(dot<S>(n, d) / (1.0 + c));
  return {S(c * d[0] + nxd[0] + f * n[0]), S(c * d[1] + nxd[1] + f * n[1]), S(c * d[2] + nxd[2] + f * n[2])};
}

/// The five frame-dependent scalars of stencil i as functions of e0 = e_{i-1}, e1 = e_i:
///   s = (kb . d1_{i-1}, kb . d2_{i-1}, kb . d1_i, kb . d2_i, raw reference twist in (-pi, pi]),
/// d2 = t x d1, d1_j = P_{from.t_j -> t_j} from.d1_j, kb = 2 t0 x t1 / (1 + t0 . t1).
template <class S>
std::array<S, 5> stencil_scalars_t(const V3<S>& e0, const V3<S>& e1, const V3<double>& ta, const V3<double>& da,
                                 const V3<double>& tb, const V3<double>& db) {
  using std::sqrt;
  const S l0 = sqrt(dot<S>(e0, e0)), l1 = sqrt(dot<S>(e1, e1));
  const V3<S> t0 = {S(e0[0] / l0), S(e0[1] / l0), S(e0[2] / l0)};
  const V3<S> t1 = {S(e1[0] / l1), S(e1[1] / l1), S(e1[2] / l1)};
  const S chi = S(1.0 + dot<S>(t0, t1));
  const V3<S> c01 = cross<S>(t0, t1);
  const V3<S> kb = {S(2.0 * c01[0] / chi), S(2.0 * c01[1] / chi), S(2.0 * c01[2] / chi)};
  const V3<S> u0 = parallel_transport<S>(ta, t0, da);
  const V3<S> u1 = parallel_transport<S>(tb, t1, db);
  const V3<S> v0 = cross<S>(t0, u0), v1 = cross<S>(t1, u1);
  const V3<S> w = parallel_transport<S>(t0, t1, u0);
  const S r = ad_atan2(dot<S>(cross<S>(w, u1), t1), dot<S>(w, u1));
  return {dot<S>(kb, u0), dot<S>(kb, v0), dot<S>(kb, u1), dot<S>(kb, v1), r};
}

/// The 2 pi multiple that brings `raw` nearest to `reference`.
double branch(double raw, double reference) { return kTwoPi * std::round((reference - raw) / kTwoPi); }

void edges_of(const Eigen::VectorXd& q, int i, Eigen::Vector3d& e0, Eigen::Vector3d& e1) {
  e0 = q.segment<3>(4 * i) - q.segment<3>(4 * (i - 1));
  e1 = q.segment<3>(4 * (i + 1)) - q.segment<3>(4 * i);
}

rod::StencilFrom stencil_from(const RodFrames& from, int i) {
  return {from.tangent[i - 1], from.director[i - 1], from.tangent[i], from.director[i], from.reference_twist[i - 1]};
}

using Scalars = rod::StencilScalars;

Vec5 scalars_value(const Eigen::VectorXd& q, const RodFrames& from, int i) {
  Eigen::Vector3d e0, e1;
  edges_of(q, i, e0, e1);
  Scalars s;
  rod::stencil_scalars(e0, e1, stencil_from(from, i), rod::Order::value, s);
  return s.s;
}

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0, -v[2], v[1], v[2], 0, -v[0], -v[1], v[0], 0;
  return S;
}

/// Bending of one edge j of stencil i: C |kappa - kappabar|^2 with kappa = (c q - s p, -c p - s q),
/// (c, s) = (cos, sin) theta_j, as a function of (p, q, theta) placed at z indices (ip, iq, ith).
/// Adds its gradient and Hessian over z when fz is given; returns the energy.
double bend_edge(double p, double qq, double theta, double k1bar, double k2bar, double C, int ip, int iq, int ith, Vec7* fz,
                 Mat7* fzz) {
  const double c = std::cos(theta), s = std::sin(theta);
  const double k1 = c * qq - s * p, k2 = -c * p - s * qq;
  const double d1 = k1 - k1bar, d2 = k2 - k2bar;
  if (fz) {
    // Jacobian of kappa over (p, q, theta): columns (-s, -c), (c, -s), (k2, -k1).
    const double J[2][3] = {{-s, c, k2}, {-c, -s, -k1}};
    const int idx[3] = {ip, iq, ith};
    for (int a = 0; a < 3; ++a) (*fz)[idx[a]] += 2.0 * C * (J[0][a] * d1 + J[1][a] * d2);
    if (fzz) {
      // Second derivatives of kappa: K_{p theta} = (-c, s), K_{q theta} = (-s, -c), K_{theta theta} = -kappa.
      double K[3][3][2] = {};
      K[0][2][0] = K[2][0][0] = -c;
      K[0][2][1] = K[2][0][1] = s;
      K[1][2][0] = K[2][1][0] = -s;
      K[1][2][1] = K[2][1][1] = -c;
      K[2][2][0] = -k1;
      K[2][2][1] = -k2;
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
          (*fzz)(idx[a], idx[b]) +=
              2.0 * C * (J[0][a] * J[0][b] + J[1][a] * J[1][b] + d1 * K[a][b][0] + d2 * K[a][b][1]);
    }
  }
  return C * (d1 * d1 + d2 * d2);
}

/// Bending and twisting of stencil i (index k = i - 1 into the rest arrays) for one rest set,
/// as a function of z = (p0, q0, p1, q1, r, theta_{i-1}, theta_i).
void stencil_energy(const Vec5& s, double tha, double thb, const RodRest& R, int k, double& eb, double& et, Vec7* fz,
                    Mat7* fzz) {
  const double Cb = R.kb / (4.0 * R.voronoi[k]);
  const Eigen::Vector4d& kb = R.kappa[k];
  eb += bend_edge(s[0], s[1], tha, kb[0], kb[1], Cb, 0, 1, 5, fz, fzz);
  eb += bend_edge(s[2], s[3], thb, kb[2], kb[3], Cb, 2, 3, 6, fz, fzz);
  const double Ct = R.kt / (2.0 * R.voronoi[k]);
  const double d = thb - tha + s[4] - R.twist[k];
  et += Ct * d * d;
  if (fz) {
    const double w[3] = {1.0, -1.0, 1.0};
    const int idx[3] = {4, 5, 6};
    for (int a = 0; a < 3; ++a) (*fz)[idx[a]] += 2.0 * Ct * d * w[a];
    if (fzz)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) (*fzz)(idx[a], idx[b]) += 2.0 * Ct * w[a] * w[b];
  }
}

/// Stretching of one edge: E = 1/2 ks lbar (l / lbar - 1)^2, dE/de = ks (l / lbar - 1) t,
/// d2E/de2 = (ks / lbar) t t^T + ks (1 / lbar - 1 / l) (I - t t^T). Returns E; the two
/// Hessian coefficients (along t, transverse) go to a, b.
double stretch_edge(const Eigen::Vector3d& e, double lbar, double ks, Eigen::Vector3d* grad, double* a, double* b) {
  const double l = e.norm();
  const double strain = l / lbar - 1.0;
  if (grad) *grad = ks * strain * (e / l);
  if (a) *a = ks / lbar;
  if (b) *b = ks * (1.0 / lbar - 1.0 / l);
  return 0.5 * ks * lbar * strain * strain;
}

template <int N>
Eigen::Matrix<double, N, N> project_psd(const Eigen::Matrix<double, N, N>& H) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> es(H);
  const Eigen::Matrix<double, N, 1> lambda = es.eigenvalues().cwiseMax(0.0);
  return es.eigenvectors() * lambda.asDiagonal() * es.eigenvectors().transpose();
}

/// y = (e0, e1, theta_{i-1}, theta_i) = T l over the stencil's 11 local DoFs
/// l = (x_{i-1}, theta_{i-1}, x_i, theta_i, x_{i+1}).
Eigen::Matrix<double, 8, 11> stencil_map() {
  Eigen::Matrix<double, 8, 11> T = Eigen::Matrix<double, 8, 11>::Zero();
  for (int c = 0; c < 3; ++c) {
    T(c, 4 + c) = 1.0;
    T(c, c) = -1.0;
    T(3 + c, 8 + c) = 1.0;
    T(3 + c, 4 + c) = -1.0;
  }
  T(6, 3) = 1.0;
  T(7, 7) = 1.0;
  return T;
}

Eigen::Vector3d any_orthogonal(const Eigen::Vector3d& t) {
  int k = 0;
  for (int c = 1; c < 3; ++c)
    if (std::abs(t[c]) < std::abs(t[k])) k = c;
  return t.cross(Eigen::Vector3d::Unit(k)).normalized();
}

Eigen::Vector3d transport_vector(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& d) {
  const V3<double> r = parallel_transport<double>(arr(a), arr(b), arr(d));
  return {r[0], r[1], r[2]};
}

}  // namespace

namespace rod {

void stencil_scalars_autodiff(const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, const StencilFrom& f, Order order,
                              StencilScalars& out) {
  const V3<double> ta = arr(f.ta), da = arr(f.da), tb = arr(f.tb), db = arr(f.db);
  if (order == Order::value) {
    const auto s = stencil_scalars_t<double>(arr(e0), arr(e1), ta, da, tb, db);
    for (int k = 0; k < 5; ++k) out.s[k] = s[k];
  } else if (order == Order::gradient) {
    V3<A1> a0, a1;
    for (int c = 0; c < 3; ++c) {
      a0[c] = A1(e0[c], D6::Unit(c));
      a1[c] = A1(e1[c], D6::Unit(3 + c));
    }
    const auto s = stencil_scalars_t<A1>(a0, a1, ta, da, tb, db);
    for (int k = 0; k < 5; ++k) {
      out.s[k] = s[k].value();
      out.G.row(k) = s[k].derivatives().transpose();
    }
  } else {
    V3<A2> a0, a1;
    for (int c = 0; c < 6; ++c) {
      A2& x = c < 3 ? a0[c] : a1[c - 3];
      x.value() = A1(c < 3 ? e0[c] : e1[c - 3], D6::Unit(c));
      x.derivatives() = D6A::Zero();
      x.derivatives()[c] = A1(1.0);
    }
    const auto s = stencil_scalars_t<A2>(a0, a1, ta, da, tb, db);
    for (int k = 0; k < 5; ++k) {
      out.s[k] = s[k].value().value();
      out.G.row(k) = s[k].value().derivatives().transpose();
      for (int a = 0; a < 6; ++a) out.H[k].row(a) = s[k].derivatives()[a].derivatives().transpose();
      out.H[k] = (0.5 * (out.H[k] + out.H[k].transpose())).eval();
    }
  }
  out.s[4] += branch(out.s[4], f.reference_twist);
}

void stencil_scalars(const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, const StencilFrom& f, Order order,
                     StencilScalars& out) {
  using Mat3 = Eigen::Matrix3d;
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  using Mat36 = Eigen::Matrix<double, 3, 6>;
  // Values by the same kernel as the automatic differentiation (bit-identical energies).
  {
    const auto s = stencil_scalars_t<double>(arr(e0), arr(e1), arr(f.ta), arr(f.da), arr(f.tb), arr(f.db));
    for (int k = 0; k < 5; ++k) out.s[k] = s[k];
    out.s[4] += branch(out.s[4], f.reference_twist);
  }
  if (order == Order::value) return;
  const double p0 = out.s[0], q0 = out.s[1], p1 = out.s[2], q1 = out.s[3];
  const double l0 = e0.norm(), l1 = e1.norm();
  const Eigen::Vector3d t0 = e0 / l0, t1 = e1 / l1;
  const double chi = l0 * l1 + e0.dot(e1);
  const Eigen::Vector3d kb = 2.0 * e0.cross(e1) / chi;
  const Eigen::Vector3d u0 = transport_vector(f.ta, t0, f.da), u1 = transport_vector(f.tb, t1, f.db);
  const Eigen::Vector3d v0 = t0.cross(u0), v1 = t1.cross(u1);
  // kb = 2 N / chi, N = e0 x e1, chi = l0 l1 + e0 . e1, c = dchi/d(e0, e1) = (l1 t0 + e1, l0 t1 + e0).
  Vec6 c;
  c << l1 * t0 + e1, l0 * t1 + e0;
  Mat36 JN;
  JN << -skew(e1), skew(e0);
  const Mat36 Jkb = (2.0 / chi) * JN - kb * c.transpose() / chi;
  // Holonomy: grad alpha_j over e_j = h_j / l_j, h = (t x T0) / (1 + T0 . t).
  const double w0 = 1.0 / (1.0 + f.ta.dot(t0)), w1 = 1.0 / (1.0 + f.tb.dot(t1));
  const Eigen::Vector3d h0 = w0 * t0.cross(f.ta), h1 = w1 * t1.cross(f.tb);
  Vec6 ga0 = Vec6::Zero(), ga1 = Vec6::Zero();
  ga0.head<3>() = h0 / l0;
  ga1.tail<3>() = h1 / l1;
  out.G.row(0) = (Jkb.transpose() * u0 + q0 * ga0).transpose();
  out.G.row(1) = (Jkb.transpose() * v0 - p0 * ga0).transpose();
  out.G.row(2) = (Jkb.transpose() * u1 + q1 * ga1).transpose();
  out.G.row(3) = (Jkb.transpose() * v1 - p1 * ga1).transpose();
  out.G.block<1, 3>(4, 0) = (kb / (2.0 * l0) - h0 / l0).transpose();
  out.G.block<1, 3>(4, 3) = (kb / (2.0 * l1) + h1 / l1).transpose();
  if (order == Order::gradient) return;

  const Mat3 I = Mat3::Identity();
  const Mat3 P0 = I - t0 * t0.transpose(), P1 = I - t1 * t1.transpose();
  // Hessians of kb_k: (2/chi) Hess N_k - (2/chi^2)(grad N_k c^T + c grad N_k^T) - (kb_k/chi) dc + (2 kb_k/chi^2) c c^T.
  Mat6 dc;
  dc << (l1 / l0) * P0, I + t0 * t1.transpose(), I + t1 * t0.transpose(), (l0 / l1) * P1;
  std::array<Mat6, 3> Hkb;
  for (int k = 0; k < 3; ++k) {
    Mat6 HN = Mat6::Zero();  // d2 (e0 x e1)_k / de0_i de1_j = eps_kij
    const Mat3 E = skew(Eigen::Vector3d::Unit(k)).transpose();  // E_ij = eps_kij
    HN.topRightCorner<3, 3>() = E;
    HN.bottomLeftCorner<3, 3>() = E.transpose();
    const Vec6 gN = JN.row(k).transpose();
    Hkb[k] = (2.0 / chi) * HN - (2.0 / (chi * chi)) * (gN * c.transpose() + c * gN.transpose()) - (kb[k] / chi) * dc +
             (2.0 * kb[k] / (chi * chi)) * c * c.transpose();
  }
  // Jacobians of the holonomy gradients: d(h/l)/de = (dh/dt) P / l^2 - h t^T / l^2,
  // dh/dt = -[T0]x / (1 + T0 . t) - (t x T0) T0^T / (1 + T0 . t)^2. Not symmetric (alpha is not closed).
  const Mat3 dh0 = -w0 * skew(f.ta) - w0 * h0 * f.ta.transpose();
  const Mat3 dh1 = -w1 * skew(f.tb) - w1 * h1 * f.tb.transpose();
  Mat6 HA0 = Mat6::Zero(), HA1 = Mat6::Zero();
  HA0.topLeftCorner<3, 3>() = (dh0 * P0 - h0 * t0.transpose()) / (l0 * l0);
  HA1.bottomRightCorner<3, 3>() = (dh1 * P1 - h1 * t1.transpose()) / (l1 * l1);
  // Jacobians of the directors: du = -t (u . de) / l + v dalpha, dv = -[u]x P de / l - u dalpha.
  Mat36 Ju0 = v0 * ga0.transpose(), Jv0 = -u0 * ga0.transpose();
  Ju0.leftCols<3>() -= t0 * u0.transpose() / l0;
  Jv0.leftCols<3>() -= skew(u0) * P0 / l0;
  Mat36 Ju1 = v1 * ga1.transpose(), Jv1 = -u1 * ga1.transpose();
  Ju1.rightCols<3>() -= t1 * u1.transpose() / l1;
  Jv1.rightCols<3>() -= skew(u1) * P1 / l1;
  const Vec6 Gp0 = out.G.row(0).transpose(), Gq0 = out.G.row(1).transpose();
  const Vec6 Gp1 = out.G.row(2).transpose(), Gq1 = out.G.row(3).transpose();
  Mat6 Hu0 = Mat6::Zero(), Hv0 = Mat6::Zero(), Hu1 = Mat6::Zero(), Hv1 = Mat6::Zero();
  for (int k = 0; k < 3; ++k) {
    Hu0 += u0[k] * Hkb[k];
    Hv0 += v0[k] * Hkb[k];
    Hu1 += u1[k] * Hkb[k];
    Hv1 += v1[k] * Hkb[k];
  }
  out.H[0] = Hu0 + Jkb.transpose() * Ju0 + ga0 * Gq0.transpose() + q0 * HA0;
  out.H[1] = Hv0 + Jkb.transpose() * Jv0 - ga0 * Gp0.transpose() - p0 * HA0;
  out.H[2] = Hu1 + Jkb.transpose() * Ju1 + ga1 * Gq1.transpose() + q1 * HA1;
  out.H[3] = Hv1 + Jkb.transpose() * Jv1 - ga1 * Gp1.transpose() - p1 * HA1;
  // Reference twist: d/de of (kb / (2 l0) - h0 / l0, kb / (2 l1) + h1 / l1).
  Mat6& Hr = out.H[4];
  Hr.topRows<3>() = Jkb / (2.0 * l0);
  Hr.bottomRows<3>() = Jkb / (2.0 * l1);
  Hr.topLeftCorner<3, 3>() -= kb * t0.transpose() / (2.0 * l0 * l0);
  Hr.bottomRightCorner<3, 3>() -= kb * t1.transpose() / (2.0 * l1 * l1);
  Hr += HA1 - HA0;
  for (Mat6& H : out.H) H = (0.5 * (H + H.transpose())).eval();
}

}  // namespace rod

DiscreteElasticRod::DiscreteElasticRod(const Eigen::VectorXd& rest_q, const RodMaterial& m) : mat_(m) {
  Checker c("DiscreteElasticRod");
  const Eigen::Index n = rest_q.size();
  c.require(n >= 11 && (n + 1) % 4 == 0, "rest_q.size()", n, "4V - 1 with V >= 3 vertices");
  c.require(m.radius > 0, "radius", m.radius, "> 0")
      .require(m.youngs > 0, "youngs", m.youngs, "> 0")
      .require(m.shear > 0, "shear", m.shear, "> 0")
      .require(m.density > 0, "density", m.density, "> 0")
      .require(m.viscosity >= 0, "viscosity", m.viscosity, ">= 0");
  c.require(rest_q.allFinite(), "rest_q", "(non-finite entries)", "finite");
  c.throw_if_failed();
  V_ = static_cast<int>((n + 1) / 4);
  // Rest frames: space-parallel transport along the rod from a deterministic first director.
  rest_frames_.tangent.resize(V_ - 1);
  rest_frames_.director.resize(V_ - 1);
  rest_frames_.reference_twist.assign(V_ - 2, 0.0);
  for (int j = 0; j + 1 < V_; ++j) {
    const Eigen::Vector3d e = rest_q.segment<3>(4 * (j + 1)) - rest_q.segment<3>(4 * j);
    if (!(e.norm() > 0)) c.fail(fmt::format("rest edge {} has zero length", j));
    rest_frames_.tangent[j] = e.normalized();
  }
  for (int i = 1; i + 1 < V_; ++i)
    if (1.0 + rest_frames_.tangent[i - 1].dot(rest_frames_.tangent[i]) <= kFoldTolerance)
      c.fail(fmt::format("the rest shape folds back on itself at vertex {}", i));
  c.throw_if_failed();
  rest_frames_.director[0] = any_orthogonal(rest_frames_.tangent[0]);
  for (int j = 1; j + 1 < V_; ++j) {
    Eigen::Vector3d d = transport_vector(rest_frames_.tangent[j - 1], rest_frames_.tangent[j], rest_frames_.director[j - 1]);
    d -= d.dot(rest_frames_.tangent[j]) * rest_frames_.tangent[j];
    rest_frames_.director[j] = d.normalized();
  }
  // The reference twists of the rest frames (0 up to round-off), by the energy's own kernel.
  for (int i = 1; i + 1 < V_; ++i) rest_frames_.reference_twist[i - 1] = scalars_value(rest_q, rest_frames_, i)[4];
  const double r2 = m.radius * m.radius, pi = std::numbers::pi;
  rest_ = make_rest(rest_q, rest_frames_, m.youngs * pi * r2, m.youngs * pi * r2 * r2 / 4.0, m.shear * pi * r2 * r2 / 2.0);
}

RodRest DiscreteElasticRod::make_rest(const Eigen::VectorXd& q, const RodFrames& frames, double ks, double kb,
                                      double kt) const {
  RodRest R;
  R.ks = ks;
  R.kb = kb;
  R.kt = kt;
  R.length.resize(V_ - 1);
  for (int j = 0; j + 1 < V_; ++j) R.length[j] = (q.segment<3>(4 * (j + 1)) - q.segment<3>(4 * j)).norm();
  R.voronoi.resize(V_ - 2);
  R.kappa.resize(V_ - 2);
  R.twist.resize(V_ - 2);
  for (int i = 1; i + 1 < V_; ++i) {
    const int k = i - 1;
    R.voronoi[k] = 0.5 * (R.length[i - 1] + R.length[i]);
    const Vec5 s = scalars_value(q, frames, i);
    // kappa = (c q - s p, -c p - s q) of each edge, as in bend_edge.
    const double tha = q[4 * (i - 1) + 3], thb = q[4 * i + 3];
    const double ca = std::cos(tha), sa = std::sin(tha), cb = std::cos(thb), sb = std::sin(thb);
    R.kappa[k] = Eigen::Vector4d(ca * s[1] - sa * s[0], -ca * s[0] - sa * s[1], cb * s[3] - sb * s[2], -cb * s[2] - sb * s[3]);
    R.twist[k] = thb - tha + s[4];
  }
  return R;
}

RodFrames DiscreteElasticRod::transport(const RodFrames& from, const Eigen::VectorXd& q) const {
  WEFT_ASSERT(admissible(q, from), "DiscreteElasticRod::transport: q is not admissible for these frames");
  RodFrames out;
  out.tangent.resize(V_ - 1);
  out.director.resize(V_ - 1);
  out.reference_twist.resize(V_ - 2);
  for (int j = 0; j + 1 < V_; ++j) {
    const Eigen::Vector3d t = (q.segment<3>(4 * (j + 1)) - q.segment<3>(4 * j)).normalized();
    Eigen::Vector3d d = transport_vector(from.tangent[j], t, from.director[j]);
    d -= d.dot(t) * t;  // round-off drift only
    out.tangent[j] = t;
    out.director[j] = d.normalized();
  }
  for (int i = 1; i + 1 < V_; ++i) {
    const Eigen::Vector3d w = transport_vector(out.tangent[i - 1], out.tangent[i], out.director[i - 1]);
    const double r = std::atan2(w.cross(out.director[i]).dot(out.tangent[i]), w.dot(out.director[i]));
    out.reference_twist[i - 1] = r + branch(r, from.reference_twist[i - 1]);
  }
  return out;
}

bool DiscreteElasticRod::admissible(const Eigen::VectorXd& q, const RodFrames& from) const {
  if (q.size() != num_dofs() || !q.allFinite()) return false;
  if (static_cast<int>(from.tangent.size()) != V_ - 1 || static_cast<int>(from.director.size()) != V_ - 1 ||
      static_cast<int>(from.reference_twist.size()) != V_ - 2)
    return false;
  Eigen::Vector3d prev;
  double prev_len = 0;
  for (int j = 0; j + 1 < V_; ++j) {
    const Eigen::Vector3d e = q.segment<3>(4 * (j + 1)) - q.segment<3>(4 * j);
    const double l = e.norm();
    if (!(l > kLengthTolerance * rest_.length[j])) return false;
    if (1.0 + from.tangent[j].dot(e) / l <= kFoldTolerance) return false;
    if (j > 0 && e.dot(prev) <= -(1.0 - kFoldTolerance) * l * prev_len) return false;
    prev = e;
    prev_len = l;
  }
  return true;
}

DiscreteElasticRod::Sums DiscreteElasticRod::energies(const Eigen::VectorXd& q, const RodFrames& from) const {
  Sums S;
  for (int j = 0; j + 1 < V_; ++j) {
    const Eigen::Vector3d e = q.segment<3>(4 * (j + 1)) - q.segment<3>(4 * j);
    S.stretch += stretch_edge(e, rest_.length[j], rest_.ks, nullptr, nullptr, nullptr);
    if (viscous_) S.viscous += stretch_edge(e, visc_.length[j], visc_.ks, nullptr, nullptr, nullptr);
  }
  for (int i = 1; i + 1 < V_; ++i) {
    const Vec5 s = scalars_value(q, from, i);
    const double tha = q[4 * (i - 1) + 3], thb = q[4 * i + 3];
    stencil_energy(s, tha, thb, rest_, i - 1, S.bend, S.twist, nullptr, nullptr);
    if (viscous_) stencil_energy(s, tha, thb, visc_, i - 1, S.viscous, S.viscous, nullptr, nullptr);
  }
  return S;
}

double DiscreteElasticRod::energy(const Eigen::VectorXd& q, const RodFrames& from) const {
  if (!admissible(q, from)) return std::numeric_limits<double>::infinity();
  const Sums S = energies(q, from);
  return S.stretch + S.bend + S.twist + S.viscous;
}

void DiscreteElasticRod::energy_terms(const Eigen::VectorXd& q, const RodFrames& from, weft::EnergyTerms& terms) const {
  if (!admissible(q, from)) {
    const double inf = std::numeric_limits<double>::infinity();
    terms.emplace_back("stretch", inf);
    terms.emplace_back("bend", inf);
    terms.emplace_back("twist", inf);
    if (viscous_) terms.emplace_back("viscous", inf);
    return;
  }
  const Sums S = energies(q, from);
  terms.emplace_back("stretch", S.stretch);
  terms.emplace_back("bend", S.bend);
  terms.emplace_back("twist", S.twist);
  if (viscous_) terms.emplace_back("viscous", S.viscous);
}

void DiscreteElasticRod::add_gradient(const Eigen::VectorXd& q, const RodFrames& from, Eigen::VectorXd& g) const {
  evaluate(q, from, &g, nullptr, HessianMode::exact);
}

void DiscreteElasticRod::add_hessian(const Eigen::VectorXd& q, const RodFrames& from, BandMatrix& H,
                                     weft::HessianMode mode) const {
  evaluate(q, from, nullptr, &H, mode);
}

void DiscreteElasticRod::evaluate(const Eigen::VectorXd& q, const RodFrames& from, Eigen::VectorXd* g, BandMatrix* H,
                                  weft::HessianMode mode) const {
  WEFT_ASSERT(admissible(q, from), "DiscreteElasticRod: derivatives requested at an inadmissible configuration");
  WEFT_ASSERT(!g || g->size() == num_dofs(), "DiscreteElasticRod: g has {} entries, expected {}", g ? g->size() : 0,
              num_dofs());
  WEFT_ASSERT(!H || (H->rows() == num_dofs() && H->bandwidth() >= bandwidth),
              "DiscreteElasticRod: H must be {} square with bandwidth >= {}", num_dofs(), bandwidth);
  // Stretching, per edge (elastic + viscous).
  for (int j = 0; j + 1 < V_; ++j) {
    const Eigen::Vector3d e = q.segment<3>(4 * (j + 1)) - q.segment<3>(4 * j);
    Eigen::Vector3d ge, gv;
    double a = 0, b = 0, av = 0, bv = 0;
    stretch_edge(e, rest_.length[j], rest_.ks, &ge, &a, &b);
    if (viscous_) {
      stretch_edge(e, visc_.length[j], visc_.ks, &gv, &av, &bv);
      ge += gv;
      a += av;
      b += bv;
    }
    if (g) {
      g->segment<3>(4 * j) -= ge;
      g->segment<3>(4 * (j + 1)) += ge;
    }
    if (H) {
      if (mode == HessianMode::projected) b = std::max(b, 0.0);  // a > 0 always
      const Eigen::Vector3d t = e.normalized();
      const Eigen::Matrix3d He = (a - b) * t * t.transpose() + b * Eigen::Matrix3d::Identity();
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          const double h = He(r, c);
          (*H)(4 * j + r, 4 * j + c) += h;
          (*H)(4 * j + 4 + r, 4 * j + 4 + c) += h;
          (*H)(4 * j + r, 4 * j + 4 + c) -= h;
          (*H)(4 * j + 4 + r, 4 * j + c) -= h;
        }
    }
  }
  // Bending and twisting, per interior vertex.
  static const Eigen::Matrix<double, 8, 11> T = stencil_map();
  Scalars sc;
  for (int i = 1; i + 1 < V_; ++i) {
    Eigen::Vector3d e0, e1;
    edges_of(q, i, e0, e1);
    rod::stencil_scalars(e0, e1, stencil_from(from, i), H ? rod::Order::hessian : rod::Order::gradient, sc);
    const double tha = q[4 * (i - 1) + 3], thb = q[4 * i + 3];
    Vec7 fz = Vec7::Zero();
    Mat7 fzz = Mat7::Zero();
    double eb = 0, et = 0;
    stencil_energy(sc.s, tha, thb, rest_, i - 1, eb, et, &fz, H ? &fzz : nullptr);
    if (viscous_) stencil_energy(sc.s, tha, thb, visc_, i - 1, eb, et, &fz, H ? &fzz : nullptr);
    const int o = 4 * (i - 1);
    if (g) {
      Vec8 gy;
      gy.head<6>() = sc.G.transpose() * fz.head<5>();
      gy[6] = fz[5];
      gy[7] = fz[6];
      g->segment<11>(o) += T.transpose() * gy;
    }
    if (H) {
      // H_y = J^T fzz J + sum_k fz_k Hess(s_k), J = dz/dy = blockdiag(G, I2).
      Eigen::Matrix<double, 7, 8> J = Eigen::Matrix<double, 7, 8>::Zero();
      J.topLeftCorner<5, 6>() = sc.G;
      J(5, 6) = 1.0;
      J(6, 7) = 1.0;
      Mat8 Hy = J.transpose() * fzz * J;
      for (int k = 0; k < 5; ++k) Hy.topLeftCorner<6, 6>() += fz[k] * sc.H[k];
      Mat11 Hl = T.transpose() * Hy * T;
      Hl = (0.5 * (Hl + Hl.transpose())).eval();
      if (mode == HessianMode::projected) Hl = project_psd<11>(Hl);
      for (int c = 0; c < 11; ++c)
        for (int r = 0; r < 11; ++r) (*H)(o + r, o + c) += Hl(r, c);
    }
  }
}

double DiscreteElasticRod::stretch_energy(const Eigen::VectorXd& q) const {
  double E = 0;
  for (int j = 0; j + 1 < V_; ++j)
    E += stretch_edge(q.segment<3>(4 * (j + 1)) - q.segment<3>(4 * j), rest_.length[j], rest_.ks, nullptr, nullptr, nullptr);
  return E;
}

void DiscreteElasticRod::add_stretch_gradient(const Eigen::VectorXd& q, Eigen::VectorXd& g) const {
  for (int j = 0; j + 1 < V_; ++j) {
    Eigen::Vector3d ge;
    stretch_edge(q.segment<3>(4 * (j + 1)) - q.segment<3>(4 * j), rest_.length[j], rest_.ks, &ge, nullptr, nullptr);
    g.segment<3>(4 * j) -= ge;
    g.segment<3>(4 * (j + 1)) += ge;
  }
}

void DiscreteElasticRod::add_stretch_hessian(const Eigen::VectorXd& q, BandMatrix& H, weft::HessianMode mode) const {
  for (int j = 0; j + 1 < V_; ++j) {
    const Eigen::Vector3d e = q.segment<3>(4 * (j + 1)) - q.segment<3>(4 * j);
    double a = 0, b = 0;
    stretch_edge(e, rest_.length[j], rest_.ks, nullptr, &a, &b);
    if (mode == HessianMode::projected) b = std::max(b, 0.0);
    const Eigen::Vector3d t = e.normalized();
    const Eigen::Matrix3d He = (a - b) * t * t.transpose() + b * Eigen::Matrix3d::Identity();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        H(4 * j + r, 4 * j + c) += He(r, c);
        H(4 * j + 4 + r, 4 * j + 4 + c) += He(r, c);
        H(4 * j + r, 4 * j + 4 + c) -= He(r, c);
        H(4 * j + 4 + r, 4 * j + c) -= He(r, c);
      }
  }
}

Eigen::VectorXd DiscreteElasticRod::mass() const {
  const double pi = std::numbers::pi, r2 = mat_.radius * mat_.radius;
  const double line = mat_.density * pi * r2;               // [kg/m]
  const double twist = 0.5 * mat_.density * pi * r2 * r2;   // [kg m]
  Eigen::VectorXd m = Eigen::VectorXd::Zero(num_dofs());
  for (int j = 0; j + 1 < V_; ++j) {
    const double half = 0.5 * line * rest_.length[j];
    m.segment<3>(4 * j).array() += half;
    m.segment<3>(4 * (j + 1)).array() += half;
    m[4 * j + 3] = twist * rest_.length[j];
  }
  return m;
}

double DiscreteElasticRod::stretch(const Eigen::VectorXd& q) const {
  double s = -std::numeric_limits<double>::infinity();
  for (int j = 0; j + 1 < V_; ++j)
    s = std::max(s, (q.segment<3>(4 * (j + 1)) - q.segment<3>(4 * j)).norm() / rest_.length[j] - 1.0);
  return s;
}

void DiscreteElasticRod::set_viscous_rest(const Eigen::VectorXd& q_start, const RodFrames& frames_start, double dt) {
  if (mat_.viscosity == 0) return;
  WEFT_ASSERT(dt > 0, "DiscreteElasticRod::set_viscous_rest: dt = {} must be > 0", dt);
  WEFT_ASSERT(admissible(q_start, frames_start), "DiscreteElasticRod::set_viscous_rest: q_start is not admissible");
  const double eta = mat_.viscosity, pi = std::numbers::pi, r2 = mat_.radius * mat_.radius;
  visc_ = make_rest(q_start, frames_start, 3.0 * eta * pi * r2 / dt, 3.0 * eta * (pi * r2 * r2 / 4.0) / dt,
                    eta * pi * r2 * r2 / (2.0 * dt));
  viscous_ = true;
}

}  // namespace weft::models
