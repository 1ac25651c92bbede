// The step-size stopping test (integrators/newton.cpp, `step_tolerance`) measures the full
// Newton step, not what the line search kept of it: a line search cut to almost nothing
// by the edge of the model's domain is a stall, and must end in a failure with a report,
// not in a "converged" step far above the tolerance.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>

#include "integrators/newton.hpp"
#include "tests/support/diagonal_problem.hpp"

using namespace weft;
using namespace weft::integrators;

namespace {
// E(x) = (x - 1)^2 / 2 on x < wall, +infinity beyond (outside the model's domain, as an
// inverted element): from just below the wall every Newton step towards 1 is cut to the
// sliver left before the wall.
class Walled final : public support::DiagonalProblem {
 public:
  explicit Walled(double wall) : DiagonalProblem(1), wall_(wall) {}
  double potential(const Eigen::VectorXd& d) override {
    return d[0] < wall_ ? 0.5 * (d[0] - 1) * (d[0] - 1) : std::numeric_limits<double>::infinity();
  }
  void gradient(const Eigen::VectorXd& d, Eigen::VectorXd& f) override { f = Eigen::VectorXd::Constant(1, d[0] - 1); }
  void assemble(const Eigen::VectorXd&, HessianMode, double shift) override { k_[0] = 1 + shift; }
  double merit_scale() const override { return 1; }

 private:
  double wall_;
};

NewtonFailure run(double start, double wall, NewtonReport& nr) {
  Walled q(wall);
  Eigen::VectorXd d = Eigen::VectorXd::Constant(1, start);
  NewtonParams prm;
  prm.hessian = HessianChoice::exact;
  prm.relative_tolerance = 1e-8;
  prm.length_tolerance = 0;
  prm.step_tolerance = 1e-6;
  prm.max_iterations = 50;
  double hint = 0;
  LinearReport lr;
  StageTimes times;
  return minimize(q, d, 0.0, prm, hint, nr, lr, times);
}
}  // namespace

TEST_SUITE("integrators") {
  TEST_CASE("newton: a line search cut to a sliver by the domain's edge is a stall and not a converged step") {
    NewtonReport nr;
    const NewtonFailure f = run(0.5, 0.5 + 1e-12, nr);
    MESSAGE("status " << static_cast<int>(f.status) << " after " << nr.iterations << " iterations: " << f.message);
    REQUIRE(!nr.history.empty());
    CHECK(nr.history.front().step_norm < 1e-6);  // the guard: the accepted step was below step_tolerance
    CHECK(f.status != Status::success);
    CHECK(nr.stop_reason != "step_size");
  }

  TEST_CASE("newton: a full Newton step below step_tolerance still stops the iteration") {
    NewtonReport nr;
    const NewtonFailure f = run(1 - 1e-7, 2.0, nr);
    CHECK(f.status == Status::success);
    CHECK(nr.iterations == 1);
    CHECK(nr.stop_reason == "step_size");
  }
}
