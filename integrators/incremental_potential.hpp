#pragma once
/// \file incremental_potential.hpp
/// `IncrementalPotential`: backward Euler as minimisation of the incremental potential
/// (methods/integration-and-contact §5): Newton on E_inc (step_system.hpp) with the Hessian choice and the line
/// search of `NewtonParams` (newton.hpp). Stops when ||f||_{M~^-1} <= rel ||f(d0)||_{M~^-1}
/// + length_tolerance sqrt(free mass) (methods/integration-and-contact §6.10).
#include <Eigen/Core>

#include <string>
#include <string_view>

#include "framework/checkpoint.hpp"
#include "framework/concepts.hpp"
#include "framework/simulator.hpp"
#include "integrators/newton.hpp"
#include "integrators/step_system.hpp"

namespace weft::integrators {

class IncrementalPotential {
 public:
  static constexpr std::string_view name = "incremental_potential";
  static constexpr bool minimizes_potential = true;

  using Params = NewtonIntegratorParams;

  explicit IncrementalPotential(const Params& prm) : prm_(prm) {}

  template <class E, class C, class L>
  StepReport step(const E& energy, C& contact, L& linear, StepProblem& p) {
    return newton_step(energy, contact, linear, p, prm_.initial_guess, prm_.length_tolerance, d_,
                       [&](NewtonProblem& system, Eigen::VectorXd& d, double tol, StepReport& rep) {
                         return minimize(system, d, tol, prm_.at_step(p.dt), shift_hint_, rep.newton, rep.linear, rep.times);
                       });
  }

  /// Checkpoints: the Levenberg-Marquardt shift hint is the state one step hands the next
  /// (a checkpoint of an integrator without it, e.g. to replay with another: 0, as at the start).
  void save(Checkpoint& c, std::string_view prefix) const { c.put_scalar(std::string(prefix) + "shift_hint", shift_hint_); }
  void restore(const Checkpoint& c, std::string_view prefix) {
    const std::string name = std::string(prefix) + "shift_hint";
    shift_hint_ = c.has(name) ? c.get_scalar(name) : 0.0;
  }

 private:
  Params prm_;
  double shift_hint_ = 0;  // last Levenberg-Marquardt shift that gave a positive definite K
  Eigen::VectorXd d_;
};

}  // namespace weft::integrators
