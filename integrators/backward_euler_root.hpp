#pragma once
/// \file backward_euler_root.hpp
/// `BackwardEulerRoot`: backward Euler as root finding on the discrete Euler-Lagrange
/// residual f(d) = 0 (spec 02 §4), Newton with the residual merit 1/2 ||f||^2 and its own
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
  static constexpr bool minimizes_potential = false;

  struct Params : NewtonParams {
    InitialGuess initial_guess = InitialGuess::inertial;
    Params() { hessian = HessianChoice::exact; }  // root finding needs no definiteness
    template <class V>
    void visit(V& v) {
      visit_newton(v);
      v.choice("initial_guess", initial_guess, initial_guess_names, "start of the Newton iteration");
    }
    static Checker validate(const Params& p) { return validate_newton(p); }
  };

  explicit BackwardEulerRoot(const Params& prm) : prm_(prm) {}

  template <class E, class C, class L>
  StepReport step(const E& energy, C& contact, L& linear, StepProblem& p) {
    StepReport rep;
    StepSystem<E, C, L> system(energy, contact, linear, p, rep.times);
    initial_displacement(p, prm_.initial_guess, d_);
    if (!std::isfinite(system.potential(d_))) initial_displacement(p, InitialGuess::zero, d_);
    const NewtonFailure f = find_root(system, d_, prm_.length_tolerance * std::sqrt(system.free_mass()), prm_,
                                      rep.newton, rep.linear, rep.times);
    if (f.status == Status::success) commit(p, d_);
    return finish(rep, f);
  }

 private:
  Params prm_;
  Eigen::VectorXd d_;
};

}  // namespace weft::integrators
