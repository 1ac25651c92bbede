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

enum class InitialGuess {
  inertial,  ///< d0 = dt v_k (free vertices)
  zero,      ///< d0 = 0
};
inline constexpr std::array<std::string_view, 2> initial_guess_names = {"inertial", "zero"};

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
    State& s = p.state;
    const int n = s.num_vertices();
    StepSystem<E, C, L> system(energy, contact, linear, p, rep.times);
    d_.resize(3 * n);
    for (int i = 0; i < n; ++i)
      d_.segment<3>(3 * i) = p.fixed[i] ? Eigen::Vector3d(p.target.segment<3>(3 * i) - s.x.segment<3>(3 * i))
                             : prm_.initial_guess == InitialGuess::inertial ? Eigen::Vector3d(p.dt * s.v.segment<3>(3 * i))
                                                                           : Eigen::Vector3d::Zero();
    if (!std::isfinite(system.potential(d_))) {
      // The inertial guess may leave the model's domain; start from rest instead.
      for (int i = 0; i < n; ++i)
        if (!p.fixed[i]) d_.segment<3>(3 * i).setZero();
    }
    const NewtonFailure f = minimize(system, d_, prm_.length_tolerance * std::sqrt(system.free_mass()), prm_,
                                     shift_hint_, rep.newton, rep.linear, rep.times);
    if (f.status != Status::success) {
      rep.status = f.status;
      rep.failed_stage = f.stage;
      rep.message = f.message;
      return rep;
    }
    // Commit: q_{k+1} = q_k + d, v_{k+1} = d / dt.
    s.x += d_;
    s.v = d_ / p.dt;
    rep.status = Status::success;
    return rep;
  }

 private:
  Params prm_;
  double shift_hint_ = 0;  // last Levenberg-Marquardt shift that gave a positive definite K
  Eigen::VectorXd d_;
};

}  // namespace weft::integrators
