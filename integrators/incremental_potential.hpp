#pragma once
/// \file incremental_potential.hpp
/// `IncrementalPotential`: backward Euler as minimisation of the incremental potential
/// (spec 02 §5): Newton on E_inc (step_system.hpp) with the Hessian choice and the line
/// search of `NewtonParams` (newton.hpp). Stops when ||f||_{M~^-1} <= rel ||f(d0)||_{M~^-1}
/// + length_tolerance sqrt(free mass) (spec 02 §6.10).
#include <Eigen/Core>

#include <string>
#include <string_view>

#include "framework/concepts.hpp"
#include "framework/simulator.hpp"
#include "integrators/newton.hpp"
#include "integrators/step_system.hpp"

namespace weft::integrators {

class IncrementalPotential {
 public:
  static constexpr std::string_view name = "incremental_potential";
  static constexpr bool minimizes_potential = true;

  struct Params : NewtonParams {
    InitialGuess initial_guess = InitialGuess::inertial;
    template <class V>
    void visit(V& v) {
      visit_newton(v);
      v.choice("initial_guess", initial_guess, initial_guess_names, "start of the Newton iteration");
    }
    static Checker validate(const Params& p) { return validate_newton(p); }
  };

  explicit IncrementalPotential(const Params& prm) : prm_(prm) {}

  template <class E, class C, class L>
  StepReport step(const E& energy, C& contact, L& linear, StepProblem& p) {
    StepReport rep;
    StepSystem<E, C, L> system(energy, contact, linear, p, rep.times);
    initial_displacement(p, prm_.initial_guess, d_);
    // The inertial guess may leave the model's domain; start from rest instead.
    if (!std::isfinite(system.potential(d_))) initial_displacement(p, InitialGuess::zero, d_);
    const NewtonFailure f = minimize(system, d_, prm_.length_tolerance * std::sqrt(system.free_mass()), prm_,
                                     shift_hint_, rep.newton, rep.linear, rep.times);
    if (f.status == Status::success) commit(p, d_);
    return finish(rep, f);
  }

 private:
  Params prm_;
  double shift_hint_ = 0;  // last Levenberg-Marquardt shift that gave a positive definite K
  Eigen::VectorXd d_;
};

}  // namespace weft::integrators
