#pragma once
// The linear algebra of the small Newton test problems (tests/integrators/test_newton_*.cpp):
// a diagonal stiffness k (the problem's `assemble` sets it) and the identity as M~, so a
// problem writes only its potential, gradient, Hessian diagonal and merit scale.
#include <Eigen/Core>

#include "integrators/newton.hpp"

namespace weft::support {

class DiagonalProblem : public integrators::NewtonProblem {
 public:
  explicit DiagonalProblem(int n, double k0 = 1) : k_(Eigen::VectorXd::Constant(n, k0)) {}
  double norm(const Eigen::VectorXd& f) const override { return f.norm(); }
  /// Fails on an exactly zero diagonal entry (a singular K).
  Status factorize() override { return (k_.array() != 0).all() ? Status::success : Status::numerical_issue; }
  LinearReport solve(const Eigen::VectorXd& rhs, Eigen::VectorXd& p) override {
    LinearReport r;
    r.indefinite = k_.minCoeff() < 0;
    p = rhs.cwiseQuotient(k_);
    return r;
  }
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override { y = k_.cwiseProduct(x); }
  void mass_inverse(const Eigen::VectorXd& f, Eigen::VectorXd& out) const override { out = f; }
  double mass_dot(const Eigen::VectorXd& u, const Eigen::VectorXd& v) const override { return u.dot(v); }

 protected:
  Eigen::VectorXd k_;  ///< diagonal of K (of K + shift M~ once `assemble` added the shift)
};

}  // namespace weft::support
