#include <doctest/doctest.h>

#include <cmath>

#include "integrators/newton.hpp"
#include "tests/support/diagonal_problem.hpp"

using namespace weft;
using namespace weft::integrators;

namespace {
// The 1D counterexample of methods/integration-and-contact §5.3 (thesis Fig. 6.1, typo fixed):
// W(x) = x^4 - 6x^2 - 72x, W'(x) = 4x^3 - 12x - 72 = 4(x - 3)(x^2 + 3x + 6), W'' = 12x^2 - 12.
double W(double x) { return x * x * x * x - 6 * x * x - 72 * x; }
double dW(double x) { return 4 * x * x * x - 12 * x - 72; }
double ddW(double x) { return 12 * x * x - 12; }

class Quartic final : public support::DiagonalProblem {
 public:
  Quartic() : DiagonalProblem(1, 0) {}
  double potential(const Eigen::VectorXd& d) override { return W(d[0]); }
  void gradient(const Eigen::VectorXd& d, Eigen::VectorXd& f) override { f = Eigen::VectorXd::Constant(1, dW(d[0])); }
  void assemble(const Eigen::VectorXd& d, HessianMode mode, double shift) override {
    k_[0] = ddW(d[0]);
    if (mode == HessianMode::projected) k_[0] = std::max(k_[0], 0.0);
    k_[0] += shift;  // M~ = 1
  }
  double merit_scale() const override { return 0; }
};
// E(d) = C + (d - 1)^4 / 4 + (d - 1)^2 / 2 with a large constant C: near the minimum the
// decrease of E is far below the round-off of E itself (methods/integration-and-contact §6.6).
class OffsetQuartic final : public support::DiagonalProblem {
 public:
  explicit OffsetQuartic(double c) : DiagonalProblem(1), c_(c) {}
  double potential(const Eigen::VectorXd& d) override {
    const double u = d[0] - 1;
    return c_ + 0.25 * u * u * u * u + 0.5 * u * u;
  }
  void gradient(const Eigen::VectorXd& d, Eigen::VectorXd& f) override {
    const double u = d[0] - 1;
    f = Eigen::VectorXd::Constant(1, u * u * u + u);
  }
  void assemble(const Eigen::VectorXd& d, HessianMode, double shift) override { k_[0] = 3 * (d[0] - 1) * (d[0] - 1) + 1 + shift; }
  double merit_scale() const override { return 0; }

 private:
  double c_;
};

/// minimize() from x (updated in place) with fresh reports.
struct Minimized {
  NewtonFailure failure;
  NewtonReport report;
};
Minimized run_minimize(NewtonProblem& q, Eigen::VectorXd& x, const NewtonParams& prm) {
  Minimized m;
  double hint = 0;
  LinearReport lr;
  StageTimes times;
  m.failure = minimize(q, x, 0.0, prm, hint, m.report, lr, times);
  return m;
}
}  // namespace

TEST_SUITE("integrators") {
  TEST_CASE("newton: below the round-off of E the full step is taken on the derivative test") {
    for (auto kind : {LineSearchKind::backtracking, LineSearchKind::more_thuente, LineSearchKind::hager_zhang}) {
      CAPTURE(static_cast<int>(kind));
      OffsetQuartic q(1e12);  // one ulp of E is 1.2e-4: the last Newton decreases are invisible
      REQUIRE(q.potential(Eigen::VectorXd::Constant(1, 1.01)) == q.potential(Eigen::VectorXd::Constant(1, 1.0)));
      NewtonParams prm;
      prm.line_search = kind;
      prm.relative_tolerance = 1e-14;
      prm.length_tolerance = 0;
      Eigen::VectorXd x = Eigen::VectorXd::Constant(1, 3.0);
      const auto [f, nr] = run_minimize(q, x, prm);
      REQUIRE_MESSAGE(f.status == Status::success, f.message);
      CHECK(nr.final_residual <= nr.tolerance);
      CHECK(std::abs(x[0] - 1) <= 1e-13);
      CHECK(nr.round_off_steps >= 1);  // the rule was exercised
      CHECK(nr.iterations <= 10);      // and Newton kept its quadratic pace
    }
  }

  TEST_CASE("1D example: the two merits disagree on the descent directions at x = 0") {
    // Direction +1 descends W but no step in (0, 1] reduces |W'|.
    CHECK(dW(0) * 1.0 < 0);
    // Direction -1 descends |W'|^2 = W'^2 (derivative 2 W' W'' * (-1) < 0) but raises W.
    CHECK(2 * dW(0) * ddW(0) * -1.0 < 0);
    for (int k = 1; k <= 1000; ++k) {
      const double s = k / 1000.0;
      CHECK(std::abs(dW(s)) > 72);
      CHECK(W(-s) > W(0));
    }
    // The Newton direction -W'/W'' = -6 ascends W and descends W'^2.
    const double p = -dW(0) / ddW(0);
    CHECK(p == doctest::Approx(-6));
    CHECK(dW(0) * p > 0);
    CHECK(dW(0) * ddW(0) * p < 0);
    // x = -1 minimises |W'| locally without being a root.
    CHECK(ddW(-1) == doctest::Approx(0));
    CHECK(std::abs(dW(-1)) == doctest::Approx(64));
  }

  // Reference behaviour of methods/integration-and-contact §16 E1: from x0 = 0 both merits reach x = 3 (the energy
  // merit in one step once the direction descends, the residual merit after a detour
  // towards x = -1); from x0 = -0.5 and +0.5 the energy merit needs fewer iterations
  // (spec: 5 vs 11 and 6 vs 9 with plain halving; our backtracking interpolates).
  TEST_CASE("1D example: both merits reach x = 3 and minimisation needs fewer iterations") {
    for (double x0 : {0.0, -0.5, 0.5}) {
      CAPTURE(x0);
      NewtonParams prm;
      prm.relative_tolerance = 1e-12;
      prm.length_tolerance = 0;
      int iterations[2];
      for (int root = 0; root < 2; ++root) {
        Quartic q;
        Eigen::VectorXd x = Eigen::VectorXd::Constant(1, x0);
        double hint = 0;
        NewtonReport nr;
        LinearReport lr;
        StageTimes times;
        const NewtonFailure f = root ? find_root(q, x, 0.0, prm, nr, lr, times) : minimize(q, x, 0.0, prm, hint, nr, lr, times);
        REQUIRE_MESSAGE(f.status == Status::success, f.message);
        CHECK(x[0] == doctest::Approx(3.0).epsilon(1e-12));
        iterations[root] = nr.iterations;
        if (!root)
          for (size_t i = 0; i + 1 < nr.history.size(); ++i) CHECK(nr.history[i + 1].merit < nr.history[i].merit);
        if (root && x0 == 0.0) {
          // The residual merit first moves towards the spurious minimum of |W'| at x = -1.
          CHECK(nr.history.size() >= 2);
        }
      }
      MESSAGE("x0 = " << x0 << ": minimisation " << iterations[0] << " iterations, root finding " << iterations[1]);
      CHECK(iterations[0] <= iterations[1]);
    }
  }

  TEST_CASE("1D example: the reference iteration counts of methods/integration-and-contact E1 with plain halving") {
    // Halving (rho = 1/2, c1 = 1e-4), exact Hessian, ascent directions reversed.
    struct Case { double x0; int energy, residual; };
    for (const Case c : {Case{0.0, 1, 2}, Case{-0.5, 5, 11}, Case{0.5, 6, 9}}) {
      CAPTURE(c.x0);
      NewtonParams prm;
      prm.hessian = HessianChoice::exact;
      prm.search.interpolate = false;
      prm.relative_tolerance = 1e-12;
      prm.length_tolerance = 0;
      int iterations[2];
      for (int root = 0; root < 2; ++root) {
        Quartic q;
        Eigen::VectorXd x = Eigen::VectorXd::Constant(1, c.x0);
        double hint = 0;
        NewtonReport nr;
        LinearReport lr;
        StageTimes times;
        const NewtonFailure f = root ? find_root(q, x, 0.0, prm, nr, lr, times) : minimize(q, x, 0.0, prm, hint, nr, lr, times);
        REQUIRE(f.status == Status::success);
        CHECK(x[0] == doctest::Approx(3.0).epsilon(1e-12));
        iterations[root] = nr.iterations;
        if (c.x0 == 0.0 && root) CHECK(nr.history.front().step_length == 0.25);  // x = -1.5 first
      }
      MESSAGE("x0 = " << c.x0 << ": energy merit " << iterations[0] << ", residual merit " << iterations[1]);
      CHECK(iterations[0] <= c.energy);
      CHECK(std::abs(iterations[1] - c.residual) <= 1);  // stopping tests differ by at most one iteration
    }
  }

  TEST_CASE("1D example: the linearised step ascends W with the exact Hessian and descends with the adaptive one") {
    for (auto choice : {HessianChoice::exact, HessianChoice::adaptive}) {
      Quartic q;
      Eigen::VectorXd x = Eigen::VectorXd::Zero(1);
      NewtonParams prm;
      prm.hessian = choice;
      double hint = 0;
      NewtonReport nr;
      LinearReport lr;
      REQUIRE(linearized_step(q, x, prm, hint, nr, lr).status == Status::success);
      if (choice == HessianChoice::exact) {
        CHECK(x[0] == doctest::Approx(-6.0));  // the Newton step -W'/W''
        CHECK(W(x[0]) > W(0));
      } else {
        CHECK(nr.history.front().shift > 12);  // shifted until K + tau > 0
        CHECK(x[0] > 0);
        CHECK(W(x[0]) < W(0));
      }
    }
  }
}

TEST_SUITE("integrators") {
  TEST_CASE("1D example: the trust region follows negative curvature to the root x = 3") {
    Quartic q;
    Eigen::VectorXd x = Eigen::VectorXd::Zero(1);
    NewtonParams prm;
    prm.globalization = Globalization::trust_region;
    prm.trust_radius = 1.0;
    prm.relative_tolerance = 1e-12;
    prm.length_tolerance = 0;
    const auto [f, nr] = run_minimize(q, x, prm);
    REQUIRE_MESSAGE(f.status == Status::success, f.message);
    CHECK(x[0] == doctest::Approx(3.0).epsilon(1e-12));
    CHECK(nr.history.front().directional_derivative < 0);  // W''(0) < 0: the first step still descends
    for (size_t i = 0; i + 1 < nr.history.size(); ++i) CHECK(nr.history[i + 1].merit <= nr.history[i].merit);
    MESSAGE("trust region: " << nr.iterations << " iterations");
  }
}
