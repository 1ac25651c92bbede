// Newton with equality constraints that are linearised at each iterate (contact constraints
// on a curved obstacle, integrators/step_system.hpp): the iterations make every accepted
// iterate feasible again (`NewtonProblem::make_feasible`). From an infeasible iterate the
// direction also restores the constraint; where the constraint holds against a pull that
// restoring part ascends E, and once it outweighs what the tangential part descends, the
// line search cuts the step to nothing. A 41 x 41 dropVertical with contact constraints
// stalled this way (||f|| 7x its tolerance for 100 iterations, every step length ~0).
#include <doctest/doctest.h>

#include <Eigen/Core>
#include <cmath>

#include "integrators/newton.hpp"

using namespace weft;
using namespace weft::integrators;

namespace {

// A point x = x0 + d of unit mass on the unit circle |x| = 1 (the constraint), pulled
// towards a target t outside it: E = 1/2 |x - t|^2. The constrained minimiser is t / |t|,
// where the constraint holds the point back with the force |t| - 1. The constraint of the
// Newton direction at x is n^T p = 1 - |x|, n = x / |x|. K is either the Hessian of the
// Lagrangian on the tangent, 1 - lambda / |x| with lambda = n^T (x - t) (the curvature of
// the constraint times its force; Newton converges quadratically on the circle), or the
// Hessian of E alone, 1 (what the cloth's step system assembles).
class PulledOnCircle : public NewtonProblem {
 public:
  PulledOnCircle(Eigen::Vector2d x0, Eigen::Vector2d target, bool project, bool lagrangian)
      : x0_(x0), t_(target), project_(project), lagrangian_(lagrangian) {}
  double potential(const Eigen::VectorXd& d) override { return 0.5 * (x(d) - t_).squaredNorm(); }
  void gradient(const Eigen::VectorXd& d, Eigen::VectorXd& f) override {
    const Eigen::Vector2d n = x(d).normalized(), g = x(d) - t_;
    f = g - n * n.dot(g);  // S f
  }
  double norm(const Eigen::VectorXd& f) const override { return f.norm(); }
  void assemble(const Eigen::VectorXd& d, HessianMode, double shift) override {
    n_ = x(d).normalized();
    gap_ = 1 - x(d).norm();
    k_ = 1 + shift - (lagrangian_ ? n_.dot(x(d) - t_) / x(d).norm() : 0.0);
  }
  Status factorize() override { return Status::success; }
  LinearReport solve(const Eigen::VectorXd& rhs, Eigen::VectorXd& p) override {
    const Eigen::Vector2d r = rhs;
    p = (r - n_ * n_.dot(r)) / k_ + n_ * gap_;  // S (K p + f) = 0, n^T p = 1 - |x|
    return {};
  }
  void multiply(const Eigen::VectorXd& v, Eigen::VectorXd& y) const override {
    const Eigen::Vector2d w = v;
    y = k_ * (w - n_ * n_.dot(w));
  }
  void mass_inverse(const Eigen::VectorXd& f, Eigen::VectorXd& out) const override { out = f; }
  double merit_scale() const override { return 1; }
  double mass_dot(const Eigen::VectorXd& u, const Eigen::VectorXd& v) const override { return u.dot(v); }
  bool make_feasible(Eigen::VectorXd& d) override {
    if (!project_ || x(d).norm() == 1) return false;
    d = x(d).normalized() - x0_;
    return true;
  }
  Eigen::Vector2d x(const Eigen::VectorXd& d) const { return x0_ + Eigen::Vector2d(d); }

 private:
  Eigen::Vector2d x0_, t_;
  bool project_, lagrangian_;
  double k_ = 1, gap_ = 0;
  Eigen::Vector2d n_ = Eigen::Vector2d::UnitX();
};

struct Outcome {
  NewtonFailure failure;
  NewtonReport report;
  Eigen::Vector2d x;
};

// Exact Hessian, the absolute tolerance of `run` only.
NewtonParams exact_newton(int max_iterations) {
  NewtonParams prm;
  prm.hessian = HessianChoice::exact;
  prm.relative_tolerance = 0;
  prm.max_iterations = max_iterations;
  return prm;
}

const Eigen::Vector2d solution = Eigen::Vector2d(-2, 3).normalized();  // t / |t| of `run`

Outcome run(bool project, NewtonParams prm, bool lagrangian = true) {
  const Eigen::Vector2d x0(1, 0), target(-2, 3);
  PulledOnCircle q(x0, target, project, lagrangian);
  Eigen::VectorXd d = Eigen::VectorXd::Zero(2);
  double hint = 0;
  LinearReport lr;
  StageTimes times;
  Outcome o;
  o.failure = minimize(q, d, 1e-7, prm, hint, o.report, lr, times);  // |f|^2 well above E's round-off
  o.x = q.x(d);
  return o;
}

}  // namespace

TEST_SUITE("integrators") {
  TEST_CASE("newton: iterates are made feasible again so a constraint that pulls does not stall the line search") {
    NewtonParams prm = exact_newton(60);
    for (auto search : {LineSearchKind::backtracking, LineSearchKind::more_thuente}) {
      prm.line_search = search;
      CAPTURE(static_cast<int>(search));
      const Outcome with = run(true, prm);
      MESSAGE("with the projection: " << with.report.iterations << " iterations, ||f|| " << with.report.final_residual);
      REQUIRE(with.failure.status == Status::success);
      CHECK(std::abs(with.x.norm() - 1) < 1e-14);
      CHECK((with.x - solution).norm() < 1e-6);
      CHECK(with.report.iterations <= 12);
      // The guard: without it the same iteration stalls on this problem.
      const Outcome without = run(false, prm);
      MESSAGE("without: " << without.report.iterations << " iterations, ||f|| " << without.report.final_residual << ": "
                          << without.failure.message);
      CHECK(without.failure.status != Status::success);
    }
  }

  TEST_CASE("newton: trials are judged made feasible so a Newton matrix blind to the constraint's curvature does not cycle") {
    NewtonParams prm = exact_newton(100);
    for (auto search : {LineSearchKind::hager_zhang, LineSearchKind::more_thuente, LineSearchKind::backtracking}) {
      prm.line_search = search;
      CAPTURE(static_cast<int>(search));
      const Outcome o = run(true, prm, false);
      MESSAGE("K without the curvature term: " << o.report.iterations << " iterations, ||f|| " << o.report.final_residual);
      REQUIRE_MESSAGE(o.failure.status == Status::success, o.failure.message);
      CHECK(std::abs(o.x.norm() - 1) < 1e-14);
      CHECK((o.x - solution).norm() < 1e-6);
      CHECK(o.report.iterations <= 30);
      // The guard: some full step was refused (judged on the straight step every one passes
      // and the iterate cycles; this was the two-cycle before the trials were projected).
      bool cut = false;
      for (const auto& it : o.report.history) cut |= it.step_length < 1;
      CHECK(cut);
    }
  }
}
