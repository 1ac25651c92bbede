#pragma once
/// \file step_system.hpp
/// `StepSystem<E, C, L>`: the backward Euler system of one step of a concrete simulator,
/// as a `NewtonProblem`, in displacement form with the potential referenced to the start
/// of the step (spec 02 §5.1):
///
///   E_inc(d) = 1/2 d^T M~ d - dt d^T M v_k + dt^2 (V(q_k + d) - V(q_k)),  M~ = (1 + c dt) M
///   f(d) = M~ d - dt M v_k + dt^2 grad V(q_k + d),                       K = M~ + dt^2 H
///
/// (c: mass-proportional damping, whose drag -c M v_{k+1} has the potential c dt/2 d^T M d.)
/// Pinned and scripted vertices take their prescribed displacement in d and are filtered
/// out of f and K.
#include <Eigen/Core>

#include <cmath>
#include <limits>
#include <string_view>

#include "framework/simulator.hpp"
#include "integrators/newton.hpp"

namespace weft::integrators {

template <class E, class C, class L>
class StepSystem final : public NewtonProblem {
 public:
  StepSystem(const E& energy, C& contact, L& linear, StepProblem& p, StageTimes& times)
      : energy_(energy), contact_(contact), linear_(linear), p_(p), times_(times), trial_(p.state) {
    const State& s = p.state;
    const int n = s.num_vertices();
    const double dt = p.dt;
    dt2_ = dt * dt;
    mt_.resize(3 * n);
    mv_.resize(3 * n);
    for (int i = 0; i < n; ++i) {
      mt_.segment<3>(3 * i).setConstant((1.0 + p.mass_damping * dt) * s.mass[i]);
      mv_.segment<3>(3 * i) = dt * s.mass[i] * s.v.segment<3>(3 * i);
      if (!p.fixed[i]) free_mass_ += s.mass[i];
    }
    x0_ = s.x;
    ScopedTimer t(times_, Stage::energy);
    V0_ = energy_.energy(s) + contact_.energy(s);
  }

  double free_mass() const { return free_mass_; }

  double potential(const Eigen::VectorXd& d) override {
    ScopedTimer t(times_, Stage::energy);
    trial_.x = x0_ + d;
    if (!energy_.admissible(trial_)) return std::numeric_limits<double>::infinity();
    const double V = energy_.energy(trial_) + contact_.energy(trial_);
    const double e = 0.5 * d.dot(mt_.cwiseProduct(d)) - d.dot(mv_) + dt2_ * (V - V0_);
    return std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
  }
  void gradient(const Eigen::VectorXd& d, Eigen::VectorXd& f) override {
    ScopedTimer t(times_, Stage::energy);
    trial_.x = x0_ + d;
    g_.setZero(d.size());
    energy_.add_gradient(trial_, g_);
    contact_.add_gradient(trial_, g_);
    f = mt_.cwiseProduct(d) - mv_ + dt2_ * g_;
    p_.state.zero_constrained(f);
  }
  double norm(const Eigen::VectorXd& f) const override { return std::sqrt(f.cwiseAbs2().cwiseQuotient(mt_).sum()); }
  void assemble(const Eigen::VectorXd& d, HessianMode mode, double shift) override {
    ScopedTimer t(times_, Stage::hessian);
    trial_.x = x0_ + d;
    p_.buffer.start(p_.matrix);
    energy_.add_hessian(trial_, p_.buffer, mode);
    contact_.add_hessian(trial_, p_.buffer, mode);
    p_.buffer.finish();
    p_.matrix.scale(dt2_);
    p_.matrix.add_diagonal((1.0 + shift) * mt_);
    p_.matrix.filter_rows(p_.fixed, -1.0);  // fixed rows decoupled, diagonal tr(K_ii)/3
  }
  Status factorize() override {
    ScopedTimer t(times_, Stage::linear_setup);
    Status st = Status::success;
    // Solvers that take a context get the trial positions (the rotation modes of smoothed
    // aggregation); fixed vertices are already filtered out of the matrix above.
    if constexpr (HasSolveContext<L>) linear_.set_context(SolveContext{nullptr, &trial_.x});
    if (!p_.pattern_analyzed) {
      st = linear_.analyze_pattern(p_.matrix);
      p_.pattern_analyzed = st == Status::success;
    }
    return st == Status::success ? linear_.factorize(p_.matrix) : st;
  }
  LinearReport solve(const Eigen::VectorXd& rhs, Eigen::VectorXd& x) override {
    ScopedTimer t(times_, Stage::linear_solve);
    LinearReport r = linear_.solve(rhs, x);
    p_.state.zero_constrained(x);
    return r;
  }
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override { p_.matrix.multiply(x, y); }
  void mass_inverse(const Eigen::VectorXd& f, Eigen::VectorXd& out) const override {
    out = f.cwiseQuotient(mt_);
    p_.state.zero_constrained(out);
  }
  double merit_scale() const override { return dt2_ * std::abs(V0_); }
  double mass_dot(const Eigen::VectorXd& u, const Eigen::VectorXd& v) const override { return u.dot(mt_.cwiseProduct(v)); }

 private:
  const E& energy_;
  C& contact_;
  L& linear_;
  StepProblem& p_;
  StageTimes& times_;
  State trial_;
  Eigen::VectorXd x0_, mt_, mv_, g_;
  double dt2_ = 0, V0_ = 0, free_mass_ = 0;
};

enum class InitialGuess {
  inertial,  ///< d0 = dt v_k (free vertices)
  zero,      ///< d0 = 0
};
inline constexpr std::array<std::string_view, 2> initial_guess_names = {"inertial", "zero"};

/// d0: the prescribed displacement on constrained vertices, the guess elsewhere.
inline void initial_displacement(const StepProblem& p, InitialGuess guess, Eigen::VectorXd& d) {
  const State& s = p.state;
  d.resize(s.x.size());
  for (int i = 0; i < s.num_vertices(); ++i)
    d.segment<3>(3 * i) = p.fixed[i] ? Eigen::Vector3d(p.target.segment<3>(3 * i) - s.x.segment<3>(3 * i))
                          : guess == InitialGuess::inertial ? Eigen::Vector3d(p.dt * s.v.segment<3>(3 * i))
                                                            : Eigen::Vector3d::Zero();
}

/// q_{k+1} = q_k + d, v_{k+1} = d / dt (backward Euler).
inline void commit(StepProblem& p, const Eigen::VectorXd& d) {
  p.state.x += d;
  p.state.v = d / p.dt;
}

/// Parameters of the Newton-based backward Euler integrators: the Newton iteration and
/// the initial guess.
struct NewtonIntegratorParams : NewtonParams {
  InitialGuess initial_guess = InitialGuess::inertial;
  template <class V>
  void visit(V& v) {
    visit_newton(v);
    v.choice("initial_guess", initial_guess, initial_guess_names, "start of the Newton iteration");
  }
  static Checker validate(const NewtonIntegratorParams& p) { return validate_newton(p); }
};

/// The step report of a Newton outcome.
inline StepReport& finish(StepReport& rep, const NewtonFailure& f) {
  rep.status = f.status;
  rep.failed_stage = f.stage;
  rep.message = f.message;
  return rep;
}

/// One backward Euler step solved by `solve(system, d, absolute_tolerance, report)` from
/// the initial guess (falling back to d = 0 when the guess leaves the model's domain);
/// commits the state only on success.
template <class E, class C, class L, class Solve>
StepReport newton_step(const E& energy, C& contact, L& linear, StepProblem& p, InitialGuess guess, double length_tolerance,
                       Eigen::VectorXd& d, Solve&& solve) {
  StepReport rep;
  StepSystem<E, C, L> system(energy, contact, linear, p, rep.times);
  initial_displacement(p, guess, d);
  if (!std::isfinite(system.potential(d))) initial_displacement(p, InitialGuess::zero, d);
  const NewtonFailure f = solve(system, d, length_tolerance * std::sqrt(system.free_mass()), rep);
  if (f.status == Status::success) commit(p, d);
  return finish(rep, f);
}

}  // namespace weft::integrators
