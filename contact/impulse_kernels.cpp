#include "contact/impulse_kernels.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace weft::contact::impulse {

Eigen::Vector3d coulomb(const Eigen::Vector3d& ut, double mu, double dun) {
  const double len = ut.norm();
  const double bound = mu * std::max(dun, 0.0);
  if (len <= bound) return Eigen::Vector3d::Zero();
  return (1.0 - bound / len) * ut;
}

StencilImpulse apply_stencil_impulse(const std::array<int, 4>& ids, const std::array<double, 4>& gamma,
                                     const Eigen::Vector3d& n, double dun, double mu,
                                     const Eigen::Ref<const Eigen::VectorXd>& inv_mass, Eigen::Ref<Eigen::VectorXd> v) {
  StencilImpulse r;
  double denom = 0;
  Eigen::Vector3d u = Eigen::Vector3d::Zero();
  for (int j = 0; j < 4; ++j) {
    denom += gamma[j] * gamma[j] * inv_mass[ids[j]];
    u += gamma[j] * v.segment<3>(3 * ids[j]);
  }
  if (!(denom > 0)) return r;
  const Eigen::Vector3d ut = u - u.dot(n) * n;
  const Eigen::Vector3d dut = coulomb(ut, mu, dun) - ut;
  // The relative velocity change du, spread as gamma_j w_j du / denom.
  const Eigen::Vector3d du = dun * n + dut;
  for (int j = 0; j < 4; ++j) v.segment<3>(3 * ids[j]) += (gamma[j] * inv_mass[ids[j]] / denom) * du;
  r.applied = true;
  r.normal = dun;
  r.tangential = dut.norm();
  r.sticking = ut.norm() > 0 && dut.norm() >= ut.norm() * (1 - 1e-12);
  return r;
}

void rigidify_zone(std::span<const int> members, std::span<const int> anchors,
                   const Eigen::Ref<const Eigen::VectorXd>& x0, const Eigen::Ref<const Eigen::VectorXd>& mass,
                   Eigen::Ref<Eigen::VectorXd> v) {
  if (members.empty()) return;
  // Pseudo-inverse of a symmetric 3x3 matrix, dropping eigenvalues below a relative
  // threshold (a collinear zone, or anchors on one line).
  auto pinv_apply = [](const Eigen::Matrix3d& A, const Eigen::Vector3d& b) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(A);
    const Eigen::Vector3d ev = es.eigenvalues();
    const double cut = 1e-12 * std::max(ev.cwiseAbs().maxCoeff(), 1e-300);
    Eigen::Vector3d y = es.eigenvectors().transpose() * b;
    for (int k = 0; k < 3; ++k) y[k] = std::abs(ev[k]) > cut ? y[k] / ev[k] : 0.0;
    return Eigen::Vector3d(es.eigenvectors() * y);
  };
  Eigen::Vector3d c = Eigen::Vector3d::Zero(), vc = Eigen::Vector3d::Zero(), omega = Eigen::Vector3d::Zero();
  if (anchors.empty()) {
    double M = 0;
    for (int i : members) {
      M += mass[i];
      c += mass[i] * x0.segment<3>(3 * i);
      vc += mass[i] * v.segment<3>(3 * i);
    }
    c /= M;
    vc /= M;
    Eigen::Vector3d L = Eigen::Vector3d::Zero();
    Eigen::Matrix3d I = Eigen::Matrix3d::Zero();
    for (int i : members) {
      const Eigen::Vector3d r = x0.segment<3>(3 * i) - c;
      L += mass[i] * r.cross(Eigen::Vector3d(v.segment<3>(3 * i) - vc));
      I += mass[i] * (r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose());
    }
    omega = pinv_apply(I, L);
  } else {
    // Least squares: min sum_a |v_c + omega x r_a - v_a|^2 with r_a = x0_a - a_c, sum r_a = 0,
    // decouples into v_c = mean v_a and (sum [r_a]_x^T [r_a]_x) omega = sum r_a x v_a.
    for (int a : anchors) {
      c += x0.segment<3>(3 * a);
      vc += v.segment<3>(3 * a);
    }
    c /= static_cast<double>(anchors.size());
    vc /= static_cast<double>(anchors.size());
    Eigen::Vector3d L = Eigen::Vector3d::Zero();
    Eigen::Matrix3d I = Eigen::Matrix3d::Zero();
    for (int a : anchors) {
      const Eigen::Vector3d r = x0.segment<3>(3 * a) - c;
      L += r.cross(Eigen::Vector3d(v.segment<3>(3 * a) - vc));
      I += r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose();
    }
    if (anchors.size() > 1) omega = pinv_apply(I, L);
  }
  for (int i : members) v.segment<3>(3 * i) = vc + omega.cross(Eigen::Vector3d(x0.segment<3>(3 * i) - c));
}

}  // namespace weft::contact::impulse
