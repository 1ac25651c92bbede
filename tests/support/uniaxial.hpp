#pragma once
// The exact uniaxial-stretch check of methods/shells §9 item 22, shared by the isotropic and
// orthotropic membrane tests.
#include <doctest/doctest.h>

#include <Eigen/Core>

#include "tests/support/fd.hpp"
#include "tests/support/model_fixtures.hpp"

namespace weft::support {

/// Rest grid m (length L along x, width along y, z = 0) mapped by (X, Y) -> (s X, t Y),
/// then rigidly by x -> R x + c; stacked #V*3.
inline Eigen::VectorXd uniaxial_positions(const MeshData& m, double s, double t, const Eigen::Matrix3d& R,
                                          const Eigen::Vector3d& c) {
  Eigen::VectorXd x(3 * m.V.rows());
  for (Eigen::Index i = 0; i < m.V.rows(); ++i) x.segment<3>(3 * i) = R * Eigen::Vector3d(s * m.V(i, 0), t * m.V(i, 1), 0) + c;
  return x;
}

/// For a patch built on uniaxial_positions(m, s, t, R, c) with the lateral contraction t of
/// the material along x (modulus Y): energy L Bw h Y E11^2 / 2, zero force on every node
/// off the ends X = 0 and X = L, and internal x-forces on the end X = L summing to
/// -h Bw s Y E11 (E11 = (s^2 - 1) / 2).
template <class Patch>
void check_uniaxial_stretch(const Patch& p, const MeshData& m, const Eigen::Matrix3d& R, double L, double Bw, double h,
                            double s, double Y) {
  const double E11 = 0.5 * (s * s - 1);
  const double W = p.model.energy(p.state), W_exact = L * Bw * h * 0.5 * Y * E11 * E11;
  CHECK(std::abs(W - W_exact) <= 1e-12 * W_exact);
  const Eigen::VectorXd f = -gradient(p.model, p.state);
  const double element_force = f.cwiseAbs().maxCoeff();
  REQUIRE(element_force > 0);
  double end_force = 0;
  for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
    const double X = m.V(i, 0);
    CAPTURE(i);
    if (X > 1e-12 && X < L - 1e-12) CHECK(f.segment<3>(3 * i).norm() <= 1e-12 * element_force);
    if (X > L - 1e-12) end_force += f.segment<3>(3 * i).dot(R.col(0));
  }
  CHECK(std::abs(end_force - (-h * Bw * s * Y * E11)) <= 1e-12 * h * Bw * s * Y * E11);
}

}  // namespace weft::support
