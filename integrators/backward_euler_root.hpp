#pragma once
/// \file backward_euler_root.hpp
/// `BackwardEulerRoot`: backward Euler as root finding on the discrete Euler-Lagrange
/// residual f(d) = 0 (methods/integration-and-contact §4), Newton with the residual merit 1/2 ||f||^2 and its own
/// backtracking (§6.3). The comparison policy of thesis ch. 6: the same Newton matrix as
/// `IncrementalPotential`, a different merit.
#include <cmath>
#include <string_view>

#include "framework/simulator.hpp"
#include "integrators/newton.hpp"
#include "integrators/step_system.hpp"

namespace weft::integrators {

class BackwardEulerRoot {
 public:
  static constexpr std::string_view name = "backward_euler_root";
  static constexpr bool stateless = true;  ///< checkpoints: the displacement is scratch of each step
  static constexpr bool minimizes_potential = false;

  /// As the incremental potential's, but exact Jacobians by default: root finding needs no
  /// definiteness (its Newton direction always descends 1/2 ||f||^2).
  struct Params : NewtonIntegratorParams {
    Params() { hessian = HessianChoice::exact; }
  };

  explicit BackwardEulerRoot(const Params& prm) : prm_(prm) {}

  template <class E, class C, class L>
  StepReport step(const E& energy, C& contact, L& linear, StepProblem& p) {
    static_assert(!HasStepBound<C>, "a barrier contact strategy needs an integrator that keeps its iterates admissible: "
                                    "incremental_potential (its line search is bounded by the CCD)");
    return newton_step(energy, contact, linear, p, prm_.initial_guess, prm_.length_tolerance, d_,
                       [&](NewtonProblem& system, Eigen::VectorXd& d, double tol, StepReport& rep) {
                         return find_root(system, d, tol, prm_.at_step(p.dt), rep.newton, rep.linear, rep.times);
                       });
  }

 private:
  Params prm_;
  Eigen::VectorXd d_;
};

}  // namespace weft::integrators
