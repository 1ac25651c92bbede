#pragma once
/// \file linearly_implicit.hpp
/// `LinearlyImplicit`: one Newton step of backward Euler from d = 0 (the Baraff-Witkin
/// baseline, methods/integration-and-contact §4 "LIE"): (M~ + dt^2 H(q_k)) d = dt M v_k - dt^2 grad V(q_k).
/// No iteration and no line search; the residual left after the step is reported.
/// With contact constraints (`HasConstraints`) the step starts from d0 = z, the vertices
/// in contact moved onto their constraints (BW98's position correction), and solves the
/// constrained system from there (step_system.hpp); the constraint forces handed to the
/// strategy are those of that linear system.
#include <string_view>

#include "framework/checkpoint.hpp"
#include "framework/concepts.hpp"
#include "framework/simulator.hpp"
#include "integrators/newton.hpp"
#include "integrators/step_system.hpp"

namespace weft::integrators {

class LinearlyImplicit {
 public:
  static constexpr std::string_view name = "linearly_implicit";
  static constexpr bool minimizes_potential = false;

  struct Params {
    HessianChoice hessian = HessianChoice::adaptive;
    double min_shift = 1e-4;
    double max_shift = 1e2;
    template <class V>
    void visit(V& v) {
      v.choice("hessian", hessian, hessian_choice_names,
               "adaptive: exact while K is positive definite, else shifted K + tau M~, else per-element projection");
      v.field("min_shift", min_shift, {Unit::none, Range::gt(0), "adaptive: smallest shift tau of K + tau M~ tried"});
      v.field("max_shift", max_shift, {Unit::none, Range::gt(0), "adaptive: largest shift before projecting per element"});
    }
  };

  explicit LinearlyImplicit(const Params& prm) : prm_(prm) {
    newton_.hessian = prm.hessian;
    newton_.min_shift = prm.min_shift;
    newton_.max_shift = prm.max_shift;
  }

  template <class E, class C, class L>
  StepReport step(const E& energy, C& contact, L& linear, StepProblem& p) {
    static_assert(!HasStepBound<C>, "a barrier contact strategy needs an integrator that keeps its iterates admissible: "
                                    "incremental_potential (its line search is bounded by the CCD)");
    StepReport rep;
    StepSystem<E, C, L> system(energy, contact, linear, p, rep.times);
    initial_displacement(p, InitialGuess::zero, d_);
    system.make_feasible(d_);
    if constexpr (HasConstraints<C>) d0_ = d_;
    const NewtonFailure f = linearized_step(system, d_, newton_, shift_hint_, rep.newton, rep.linear);
    if (f.status == Status::success) {
      system.report_reactions(d_, &d0_);  // the forces of the linear system solved
      system.report_system(d_);
      commit(p, d_);
    }
    return finish(rep, f);
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
  NewtonParams newton_;
  double shift_hint_ = 0;
  Eigen::VectorXd d_, d0_;
};

}  // namespace weft::integrators
