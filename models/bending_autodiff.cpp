#include "models/bending_autodiff.hpp"

#include "models/autodiff_support.hpp"
#include "models/bending_parallel.hpp"

#include <unsupported/Eigen/AutoDiff>

#include <array>
#include <cmath>

namespace weft::models::bending {
namespace {

using D1 = Eigen::Matrix<double, 12, 1>;
using A1 = Eigen::AutoDiffScalar<D1>;  // value and first derivatives
using D2 = Eigen::Matrix<A1, 12, 1>;
using A2 = Eigen::AutoDiffScalar<D2>;  // forward over forward: second derivatives

using models::detail::ad_atan2;

template <class S>
using V3 = std::array<S, 3>;

template <class S>
V3<S> sub(const V3<S>& a, const V3<S>& b) {
  return {S(a[0] - b[0]), S(a[1] - b[1]), S(a[2] - b[2])};
}
template <class S>
V3<S> cross(const V3<S>& a, const V3<S>& b) {
  return {S(a[1] * b[2] - a[2] * b[1]), S(a[2] * b[0] - a[0] * b[2]), S(a[0] * b[1] - a[1] * b[0])};
}
template <class S>
S dot(const V3<S>& a, const V3<S>& b) {
  return S(a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
}
template <class S>
V3<S> normalized(const V3<S>& a) {
  using std::sqrt;
  const S len = sqrt(dot(a, a));
  return {S(a[0] / len), S(a[1] / len), S(a[2] / len)};
}

/// theta of the hinge, with the same operations as `triangle_frame` / `hinge_angle`:
/// n = (v0 - v2) x (v1 - v0) normalised for T = (x0, x1, x2) and T~ = (x3, x2, x1).
template <class S>
S theta_of(const std::array<V3<S>, 4>& x, V3<S>& n, V3<S>& nt, V3<S>& e_hat) {
  n = normalized(cross(sub(x[0], x[2]), sub(x[1], x[0])));
  nt = normalized(cross(sub(x[3], x[1]), sub(x[2], x[3])));
  e_hat = normalized(sub(x[2], x[1]));
  return ad_atan2(dot(cross(n, nt), e_hat), dot(n, nt));
}

Eigen::Vector3d value_of(const V3<A2>& a) { return {a[0].value().value(), a[1].value().value(), a[2].value().value()}; }

}  // namespace

ThetaDerivatives theta_derivatives_autodiff(const Eigen::Vector3d& x0, const Eigen::Vector3d& x1, const Eigen::Vector3d& x2,
                                            const Eigen::Vector3d& x3) {
  const Eigen::Vector3d* xs[4] = {&x0, &x1, &x2, &x3};
  std::array<V3<A2>, 4> x;
  for (int a = 0; a < 4; ++a)
    for (int c = 0; c < 3; ++c) {
      const int i = 3 * a + c;
      A2& xi = x[a][c];
      xi.value() = A1((*xs[a])[c], D1::Unit(i));
      xi.derivatives() = D2::Zero();
      xi.derivatives()[i] = A1(1.0);
    }
  V3<A2> n, nt, e_hat;
  const A2 theta = theta_of(x, n, nt, e_hat);
  ThetaDerivatives out;
  out.angle = hinge_angle(value_of(n), value_of(nt), value_of(e_hat));
  for (int i = 0; i < 12; ++i) {
    out.grad[i] = theta.derivatives()[i].value();
    out.hess.row(i) = theta.derivatives()[i].derivatives().transpose();
  }
  out.hess = 0.5 * (out.hess + out.hess.transpose()).eval();
  return out;
}

template <class AngleFunction>
void autodiff_evaluate(const HingeBending<AngleFunction>& model, const State& s, Eigen::VectorXd* g, ElementBuffer* buf) {
  const int nh = model.num_hinges();
  auto kernel = [&](int i) {
    const HingeRest& r = model.hinge(i);
    const ThetaDerivatives td = theta_derivatives_autodiff(s.x.segment<3>(3 * r.v[0]), s.x.segment<3>(3 * r.v[1]),
                                                           s.x.segment<3>(3 * r.v[2]), s.x.segment<3>(3 * r.v[3]));
    const Psi p = psi<AngleFunction>(td.angle, r.phi_bar, r.kappa);
    if (buf) {
      Mat12 H = p.d1 * td.hess;
      H.noalias() += p.d2 * td.grad * td.grad.transpose();
      buf->set(model.hinge_group(), i, H);
    }
    if (g)
      for (int k = 0; k < 4; ++k) g->segment<3>(3 * r.v[k]) += p.d1 * td.grad.segment<3>(3 * k);
  };
  if (g) {
    for (int i = 0; i < nh; ++i) kernel(i);  // the gradient scatter is serial
  } else if (buf) {
    buf->for_each(model.hinge_group(), kernel);  // colour by colour in direct mode
  }
  if (buf && model.triangle_group() >= 0) buf->zero_group(model.triangle_group());
}

template void autodiff_evaluate(const HingeBending<ThetaEnergy>&, const State&, Eigen::VectorXd*, ElementBuffer*);
template void autodiff_evaluate(const HingeBending<TanEnergy>&, const State&, Eigen::VectorXd*, ElementBuffer*);

}  // namespace weft::models::bending
