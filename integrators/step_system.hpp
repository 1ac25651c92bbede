#pragma once
/// \file step_system.hpp
/// `StepSystem<E, C, L>`: the backward Euler system of one step of a concrete simulator,
/// as a `NewtonProblem`, in displacement form with the potential referenced to the start
/// of the step (methods/integration-and-contact §5.1):
///
///   E_inc(d) = 1/2 d^T M~ d - dt d^T M v_k + dt^2 (V(q_k + d) - V(q_k)),  M~ = (1 + c dt) M
///   f(d) = M~ d - dt M v_k + dt^2 grad V(q_k + d),                       K = M~ + dt^2 H
///
/// (c: mass-proportional damping, whose drag -c M v_{k+1} has the potential c dt/2 d^T M d.)
/// Pinned and scripted vertices take their prescribed displacement in d and are filtered
/// out of f and K.
///
/// Contact constraints (a strategy modelling `HasConstraints`, e.g. obstacle_constraints.hpp;
/// BW98, methods/integration-and-contact §10, methods/multigrid §7): min E_inc(d) subject to per-vertex equality constraints
/// on d, linearised at each iterate. The iterate is made feasible first (`make_feasible`:
/// d += z, the targets of the constraints at d, exact for the analytic obstacles); then
///  - `assemble` asks the strategy for the constraints of the Newton direction at x_k + d
///    (values measured from these positions: zero on a feasible iterate, the remaining
///    gap after a partial step or on a curved obstacle), which `factorize` hands to the
///    linear solver with the positions (`SolveContext`); the direction p satisfies
///    S (K p + f) = 0 and (I - S) p = z, so the full step is feasible;
///  - `gradient` returns the filtered S f (S at the trial positions): the residual of the
///    constrained problem, which the stopping tests and the merits read; on a feasible
///    iterate f^T p = -(S f)^T (S K S)^+ (S f) < 0, so p descends E_inc along the
///    constraint manifold and the line searches (E_inc) and the root merit (1/2 |S f|^2)
///    work unchanged; `multiply` applies S K S (trust region, root-finding slope);
///  - `report_reactions` hands the strategy the constraint forces (I - S) f(d) / dt^2 at the
///    accepted d (f = dt^2 R there: the reaction of the equations of motion).
/// The fixed rows of pinned vertices stay filtered out of K as without contact; so are the
/// rows of vertices whose constraints prescribe all three components (exact: their
/// increment is zero on a feasible iterate).
#include <Eigen/Core>
#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "framework/simulator.hpp"
#include "integrators/newton.hpp"

namespace weft::integrators {

template <class E, class C, class L>
class StepSystem final : public NewtonProblem {
  static constexpr bool constrained = HasConstraints<C>;
  static_assert(!constrained || HasSolveContext<L>,
                "this contact strategy puts equality constraints into the implicit solve: the linear solver must take "
                "them through set_context (HasSolveContext): use DiagPcg, DiagPpcg, SaPpcg, SaMpcg or Direct");

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
    if constexpr (HasStepHook<L>) linear_.begin_step();
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
    if constexpr (constrained) {
      f_ = f;
      contact_.constraints(trial_, filter_);
      filter_.filter(f);
    }
  }
  double norm(const Eigen::VectorXd& f) const override { return std::sqrt(f.cwiseAbs2().cwiseQuotient(mt_).sum()); }
  void assemble(const Eigen::VectorXd& d, HessianMode mode, double shift) override {
    ScopedTimer t(times_, Stage::hessian);
    trial_.x = x0_ + d;
    if constexpr (HasPatternRefresh<C>) {
      if (contact_.refresh_pattern(p_.plan)) {  // contact pairs the step's pattern lacked
        p_.plan.finalize(p_.state.num_vertices());
        p_.buffer = p_.plan.make_buffer(p_.buffer.mode());
        p_.matrix = p_.plan.pattern();
        p_.pattern_analyzed = false;
      }
    }
    p_.buffer.start(p_.matrix);
    energy_.add_hessian(trial_, p_.buffer, mode);
    contact_.add_hessian(trial_, p_.buffer, mode);
    p_.buffer.finish();
    p_.matrix.scale(dt2_);
    p_.matrix.add_diagonal((1.0 + shift) * mt_);
    if constexpr (constrained) {
      contact_.constraints(trial_, set_);  // of the direction at x_k + d
      // Vertices whose three components are prescribed (static friction) are decoupled like
      // pinned ones: on a feasible iterate their increment is 0, so the solution is the same,
      // and no solver sees their 3x3 blocks (MPCG's block-Jacobi is built from K unfiltered).
      fixed_ = p_.fixed;
      saved_rows_.clear();
      saved_blocks_.clear();
      for (int i = 0; i < set_.num_vertices(); ++i)
        if (set_.count(i) == 3 && !fixed_[i]) {
          fixed_[i] = 1;
          saved_rows_.push_back(i);  // their rows of K, for the reactions of a linearised step
          const auto& vals = p_.matrix.values();
          saved_blocks_.insert(saved_blocks_.end(), vals.begin() + 9 * p_.matrix.row_ptr()[i],
                               vals.begin() + 9 * p_.matrix.row_ptr()[i + 1]);
        }
      p_.matrix.filter_rows(fixed_, -1.0);
    } else {
      p_.matrix.filter_rows(p_.fixed, -1.0);  // fixed rows decoupled, diagonal tr(K_ii)/3
    }
  }
  Status factorize() override {
    ScopedTimer t(times_, Stage::linear_setup);
    Status st = Status::success;
    // Solvers that take a context get the trial positions (the rotation modes of smoothed
    // aggregation) and the contact constraints of the iterate; fixed vertices are already
    // filtered out of the matrix above.
    if constexpr (constrained) linear_.set_context(SolveContext{set_.empty() ? nullptr : &set_, &trial_.x});
    else if constexpr (HasSolveContext<L>) linear_.set_context(SolveContext{nullptr, &trial_.x});
    if (!p_.pattern_analyzed) {
      st = linear_.analyze_pattern(p_.matrix);
      p_.pattern_analyzed = st == Status::success;
    }
    if (st == Status::success) st = linear_.factorize(p_.matrix);
    factorized_ = st == Status::success;
    return st;
  }
  LinearReport solve(const Eigen::VectorXd& rhs, Eigen::VectorXd& x) override {
    ScopedTimer t(times_, Stage::linear_solve);
    LinearReport r = linear_.solve(rhs, x);
    p_.state.zero_constrained(x);
    return r;
  }
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override {
    if constexpr (constrained) {
      if (!set_.empty()) {  // S K S: the Newton matrix on the constraint null space
        tmp_ = x;
        set_.filter(tmp_);
        p_.matrix.multiply(tmp_, y);
        set_.filter(y);
        return;
      }
    }
    p_.matrix.multiply(x, y);
  }
  void mass_inverse(const Eigen::VectorXd& f, Eigen::VectorXd& out) const override {
    out = f.cwiseQuotient(mt_);
    p_.state.zero_constrained(out);
  }
  double merit_scale() const override { return dt2_ * std::abs(V0_); }
  double mass_dot(const Eigen::VectorXd& u, const Eigen::VectorXd& v) const override { return u.dot(mt_.cwiseProduct(v)); }

  /// Iterative solvers take an inexact Newton's forcing term (`NewtonParams::forcing`).
  void set_linear_tolerance(double relative) override {
    if constexpr (requires { linear_.set_tolerance(relative); }) linear_.set_tolerance(relative);
    else (void)relative;
  }
  /// A barrier strategy (`HasStepBound`): the iterates stay in its domain (newton.hpp).
  bool bounded() const override { return HasStepBound<C>; }
  double step_bound(const Eigen::VectorXd& d, const Eigen::VectorXd& dir) override {
    if constexpr (HasStepBound<C>) {
      ScopedTimer t(times_, Stage::contact);
      trial_.x = x0_ + d;
      return contact_.step_bound(trial_, dir);
    } else {
      (void)d;
      (void)dir;
      return 1.0;
    }
  }
  /// The initial guess d of a barrier strategy made admissible: from the start positions
  /// the prescribed (pinned, scripted) displacements first, then the free vertices' part,
  /// each cut at its step bound. Returns false when the prescribed motion alone is cut (it
  /// brings a pair within a fifth of its gap, the bound's margin: `message` says so). No-op
  /// for other strategies.
  bool bound_initial_guess(Eigen::VectorXd& d, std::string& message) {
    if constexpr (HasStepBound<C>) {
      Eigen::VectorXd prescribed = Eigen::VectorXd::Zero(d.size());
      for (int i = 0; i < p_.state.num_vertices(); ++i)
        if (p_.fixed[i]) prescribed.segment<3>(3 * i) = d.segment<3>(3 * i);
      const Eigen::VectorXd free = d - prescribed;
      const Eigen::VectorXd zero = Eigen::VectorXd::Zero(d.size());
      if (prescribed.cwiseAbs().maxCoeff() > 0) {
        const double s = step_bound(zero, prescribed);
        if (s < 1) {
          message = fmt::format("the pinned and scripted vertices' motion alone brings cloth pairs within a fifth of their gap "
                                "(the barrier's step bound: {:.3g} of the step); a smaller dt helps", s);
          return false;
        }
      }
      const double s = step_bound(prescribed, free);
      d = prescribed + s * free;
      return true;
    } else {
      (void)d;
      (void)message;
      return true;
    }
  }

  /// Hands a compliance-based strategy (`HasSystemCompliance`) solves with the last
  /// Newton matrix factorised in this step; when the iteration converged without one (or
  /// the factorisation failed), the matrix at the accepted d, projected to positive
  /// semi-definite, is assembled and factorised first. No-op for other strategies.
  void report_system(const Eigen::VectorXd& d) {
    if constexpr (HasSystemCompliance<C>) {
      if (!factorized_) {
        assemble(d, HessianMode::projected, 0.0);
        factorize();
      }
      // The solver, not this StepSystem: the system is a local of the step and is gone
      // when the strategy's end_step uses the solve.
      contact_.accept_system(SystemSolve{[&lin = linear_](const Eigen::VectorXd& rhs, Eigen::VectorXd& x) { return lin.solve(rhs, x); },
                                         &p_.matrix, p_.dt});
    }
  }
  /// The step's feasible initial guess, where re-detected vertices restart (`redetect`);
  /// unset, no re-detection.
  void set_initial_guess(const Eigen::VectorXd& d0) { d0_ = d0; }
  /// Hands a strategy that re-detects (`HasRedetection`) the start state and the positions
  /// x_k + d (`converged`: a converged solution, else an accepted Newton iterate); returns
  /// the number of contacts it added (0: none) and sets the displacement of their vertices
  /// back to the initial guess.
  int redetect(Eigen::VectorXd& d, bool converged)
    requires HasRedetection<C>
  {
    if (d0_.size() != d.size()) return 0;
    trial_.x = x0_ + d;
    redetected_.clear();
    const int added = contact_.redetect(p_.state, trial_, p_.dt, redetected_, converged);
    for (int i : redetected_) d.segment<3>(3 * i) = d0_.segment<3>(3 * i);
    return added;
  }
  /// Re-detection at every accepted Newton update (NewtonProblem::update_constraints), for
  /// strategies that re-detect; the strategy decides whether it acts on iterates and bounds
  /// the rounds per step.
  int update_constraints(Eigen::VectorXd& d) override {
    if constexpr (HasRedetection<C>) {
      return redetect(d, false);
    } else {
      (void)d;
      return 0;
    }
  }
  /// d += z, the targets of the contact constraints at x_k + d: the iterate then meets
  /// them (exactly for the analytic obstacles). Returns whether d changed; no-op without
  /// constraints. Called at the start of the step and after every accepted Newton update.
  bool make_feasible(Eigen::VectorXd& d) override {
    if constexpr (constrained) {
      trial_.x = x0_ + d;
      contact_.constraints(trial_, filter_);
      if (filter_.empty()) return false;
      const Eigen::VectorXd& z = filter_.target();
      if (!(z.cwiseAbs().maxCoeff() > 0)) return false;
      d += z;
      return true;
    } else {
      (void)d;
      return false;
    }
  }
  /// At the accepted d: hands the strategy the constraint forces (I - S) f(d) / dt^2 [N],
  /// S the filter of the constraints at d. With `d0` (a linearly implicit step, one solve
  /// from d0), the forces of the linear system that step solved instead,
  /// (I - S) (f(d0) + K (d - d0)) / dt^2 with K and S of that solve (BW98 take the
  /// constraint forces from the residual of the linear system): f(d) would add the
  /// nonlinear error of the single step. No-op without constraints.
  void report_reactions(const Eigen::VectorXd& d, const Eigen::VectorXd* d0 = nullptr) {
    if constexpr (constrained) {
      Eigen::VectorXd f, force;
      if (!d0) {
        gradient(d, f);  // leaves f(d) unfiltered in f_ and the constraints at d in filter_
        force = f_ - f;  // (I - S) f: S f is what gradient returned
      } else {
        gradient(*d0, f);
        const Eigen::VectorXd step = d - *d0;
        p_.matrix.multiply(step, force);  // K step; the rows filtered out below are restored
        const auto& rp = p_.matrix.row_ptr();
        const auto& col = p_.matrix.col();
        size_t b = 0;
        for (int i : saved_rows_) {
          Eigen::Vector3d y = Eigen::Vector3d::Zero();
          for (int k = rp[i]; k < rp[i + 1]; ++k, ++b)
            y += Eigen::Map<const Block3>(saved_blocks_.data() + 9 * b) * step.segment<3>(3 * col[k]);
          force.segment<3>(3 * i) = y;
        }
        force += f_;
        f = force;
        set_.filter(f);
        force -= f;  // (I - S) with the constraints of the solve
      }
      p_.state.zero_constrained(force);
      force /= dt2_;
      contact_.accept_reactions(force);
    }
  }

 private:
  const E& energy_;
  C& contact_;
  L& linear_;
  StepProblem& p_;
  StageTimes& times_;
  State trial_;
  Eigen::VectorXd x0_, mt_, mv_, g_;
  double dt2_ = 0, V0_ = 0, free_mass_ = 0;
  bool factorized_ = false;  // a factorisation succeeded in this step
  // Contact constraints: of the prepared Newton matrix (handed to the solver), and of the
  // last gradient evaluation (its filter); f_ is the last unfiltered gradient.
  ConstraintSet set_, filter_;
  std::vector<unsigned char> fixed_;  // pinned, scripted, or fully constrained by contact
  std::vector<int> saved_rows_;       // rows of fully constrained free vertices, before the filter
  std::vector<double> saved_blocks_;  // their blocks, 9 per pattern entry, row by row
  std::vector<int> redetected_;       // vertices of the contacts the last re-detection added
  Eigen::VectorXd d0_;                // the step's feasible initial guess (set_initial_guess)
  Eigen::VectorXd f_;
  mutable Eigen::VectorXd tmp_;
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
/// the initial guess (falling back to d = 0 when the guess leaves the model's domain),
/// made feasible for the contact constraints if any; commits the state only on success
/// (after handing the strategy its constraint forces).
template <class E, class C, class L, class Solve>
StepReport newton_step(const E& energy, C& contact, L& linear, StepProblem& p, InitialGuess guess, double length_tolerance,
                       Eigen::VectorXd& d, Solve&& solve) {
  StepReport rep;
  StepSystem<E, C, L> system(energy, contact, linear, p, rep.times);
  // The guess, feasible for the constraints; for a barrier (whose potential is exact on the
  // segments step_bound saw) reached along them, cut where it would bring the cloth into
  // contact. False (and the report says why) when the prescribed motion alone cannot be taken.
  const auto prepare_guess = [&](InitialGuess g) {
    initial_displacement(p, g, d);
    system.make_feasible(d);
    if constexpr (HasStepBound<C>) {
      std::string why;
      if (!system.bound_initial_guess(d, why)) {
        rep.status = Status::numerical_issue;
        rep.failed_stage = "contact";
        rep.message = why;
        return false;
      }
    }
    return true;
  };
  if (!prepare_guess(guess)) return rep;
  if (!std::isfinite(system.potential(d)) && !prepare_guess(InitialGuess::zero)) return rep;
  if constexpr (HasRedetection<C>) system.set_initial_guess(d);  // feasible for the start-of-step contacts
  NewtonFailure f = solve(system, d, length_tolerance * std::sqrt(system.free_mass()), rep);
  if constexpr (HasRedetection<C>) {
    // Contacts the converged solution crossed: their vertices back to the initial guess,
    // then continue the iteration with them (the strategy bounds the rounds). The report
    // sums the iterations of every round and keeps the first round's initial residual; the
    // tolerance is the first round's, absolute.
    while (f.status == Status::success && system.redetect(d, true) > 0) {
      const NewtonReport first = rep.newton;
      system.make_feasible(d);
      f = solve(system, d, first.tolerance, rep);
      rep.newton.iterations += first.iterations;
      rep.newton.initial_residual = first.initial_residual;
      rep.newton.round_off_steps += first.round_off_steps;
    }
  }
  if (f.status == Status::success) {
    system.report_reactions(d);
    system.report_system(d);
    commit(p, d);
  }
  return finish(rep, f);
}

}  // namespace weft::integrators
