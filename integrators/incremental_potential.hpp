#pragma once
/// \file incremental_potential.hpp
/// `IncrementalPotential`: backward Euler as minimisation of the incremental potential
/// (spec 02 §5), in displacement form with the potential referenced to the start of the
/// step to avoid cancellation:
///
///   E_inc(d) = 1/2 d^T M~ d - dt d^T M v_k + dt^2 (V(q_k + d) - V(q_k)),  M~ = (1 + c dt) M
///   f(d) = grad E_inc = M~ d - dt M v_k + dt^2 grad V(q_k + d),           K = M~ + dt^2 H
///
/// (c: mass-proportional damping, whose drag -c M v_{k+1} has the potential c dt/2 d^T M d.)
/// Newton directions solve K p = -f on the free vertices; pinned and scripted vertices
/// take their prescribed displacement in d and are filtered out of the system. The step
/// is globalised by a line search on E_inc. Stops when ||f||_{M~^-1} <= rel ||f(d0)||_{M~^-1}
/// + length_tolerance sqrt(free mass) (spec 02 §6.10).
#include <Eigen/Core>

#include <cmath>
#include <string>
#include <string_view>

#include "framework/concepts.hpp"
#include "framework/simulator.hpp"
#include "integrators/line_search.hpp"

namespace weft::integrators {

/// Which Hessian the Newton directions use.
enum class HessianChoice {
  adaptive,   ///< exact while K = M~ + dt^2 H is positive definite, else K + tau M~ with the
              ///< smallest tau in {min_shift, 10 min_shift, ..., max_shift} that is, else projection
  exact,      ///< always exact (falls back to -M^-1 f when the direction does not descend)
  projected,  ///< always per-element PSD projection
};
inline constexpr std::array<std::string_view, 3> hessian_choice_names = {"adaptive", "exact", "projected"};

enum class InitialGuess {
  inertial,  ///< d0 = dt v_k (free vertices)
  zero,      ///< d0 = 0
};
inline constexpr std::array<std::string_view, 2> initial_guess_names = {"inertial", "zero"};

class IncrementalPotential {
 public:
  static constexpr std::string_view name = "incremental_potential";
  static constexpr bool minimizes_potential = true;

  struct Params {
    int max_iterations = 100;           ///< Newton iterations per step
    double relative_tolerance = 1e-6;   ///< on ||f||_{M^-1} relative to its value at d0
    double length_tolerance = 1e-7;     ///< [m] absolute tolerance, times sqrt(free mass)
    HessianChoice hessian = HessianChoice::adaptive;
    LineSearchKind line_search = LineSearchKind::backtracking;
    LineSearchParams search;
    InitialGuess initial_guess = InitialGuess::inertial;
    double min_shift = 1e-4;            ///< adaptive: first shift tried, relative to the mass
    double max_shift = 1e2;             ///< adaptive: beyond this, project per element instead
    template <class V>
    void visit(V& v) {
      v.field("max_iterations", max_iterations, {Unit::none, Range::closed(1, 10000), "Newton iterations per step before failing"});
      v.field("relative_tolerance", relative_tolerance,
              {Unit::none, Range::closed(0, 1), "stop when ||f||_M^-1 <= relative_tolerance ||f(d0)||_M^-1 + absolute"});
      v.field("length_tolerance", length_tolerance,
              {Unit::length, Range::ge(0), "absolute tolerance = length_tolerance * sqrt(free mass)"});
      v.choice("hessian", hessian, hessian_choice_names,
               "adaptive: exact while K is positive definite, else shifted K + tau M~, else per-element projection");
      v.choice("line_search", line_search, line_search_names, "globalisation on E_inc");
      v.section("search", search);
      v.choice("initial_guess", initial_guess, initial_guess_names, "start of the Newton iteration");
      v.field("min_shift", min_shift, {Unit::none, Range::gt(0), "adaptive: smallest shift tau of K + tau M~ tried when K is indefinite"});
      v.field("max_shift", max_shift, {Unit::none, Range::gt(0), "adaptive: largest shift before falling back to per-element projection"});
    }
    static Checker validate(const Params& p) {
      Checker c("integrator");
      c.require(p.relative_tolerance > 0 || p.length_tolerance > 0, "relative_tolerance", p.relative_tolerance,
                "> 0 when length_tolerance = 0 (else the iteration can never stop)");
      c.require(p.max_shift >= p.min_shift, "max_shift", p.max_shift, fmt::format(">= min_shift = {}", p.min_shift));
      return c;
    }
  };

  explicit IncrementalPotential(const Params& prm) : prm_(prm) {}

  template <class E, class C, class L>
  StepReport step(const E& energy, C& contact, L& linear, StepProblem& p);

 private:
  Params prm_;
  double shift_hint_ = 0;  // last Levenberg-Marquardt shift that gave a positive definite K
  Eigen::VectorXd x0_, xt_, d_, f_, g_, dir_, mt_, mv_, rhs_;
  State trial_;
};

template <class E, class C, class L>
StepReport IncrementalPotential::step(const E& energy, C& contact, L& linear, StepProblem& p) {
  StepReport rep;
  NewtonReport& nr = rep.newton;
  State& s = p.state;
  const int n = s.num_vertices();
  const double dt = p.dt, dt2 = dt * dt;
  auto fail = [&](std::string stage, Status st, std::string msg) {
    rep.status = nr.status = st;
    rep.failed_stage = std::move(stage);
    rep.message = nr.message = std::move(msg);
    return rep;
  };

  // Masses per scalar dof, damped masses, free mass.
  mt_.resize(3 * n);
  mv_.resize(3 * n);
  double free_mass = 0;
  for (int i = 0; i < n; ++i) {
    mt_.segment<3>(3 * i).setConstant((1.0 + p.mass_damping * dt) * s.mass[i]);
    mv_.segment<3>(3 * i) = dt * s.mass[i] * s.v.segment<3>(3 * i);
    if (!p.fixed[i]) free_mass += s.mass[i];
  }
  x0_ = s.x;
  trial_ = s;
  d_.resize(3 * n);
  for (int i = 0; i < n; ++i)
    d_.segment<3>(3 * i) = p.fixed[i] ? Eigen::Vector3d(p.target.segment<3>(3 * i) - x0_.segment<3>(3 * i))
                           : prm_.initial_guess == InitialGuess::inertial ? Eigen::Vector3d(dt * s.v.segment<3>(3 * i))
                                                                         : Eigen::Vector3d::Zero();
  double V0 = 0;
  {
    ScopedTimer t(rep.times, Stage::energy);
    V0 = energy.energy(s) + contact.energy(s);
  }
  // E_inc(d) and its gradient f(d) (free entries only).
  auto merit = [&](const Eigen::VectorXd& d) {
    ScopedTimer t(rep.times, Stage::energy);
    trial_.x = x0_ + d;
    if (!energy.admissible(trial_)) return std::numeric_limits<double>::infinity();
    const double V = energy.energy(trial_) + contact.energy(trial_);
    const double e = 0.5 * d.dot(mt_.cwiseProduct(d)) - d.dot(mv_) + dt2 * (V - V0);
    return std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
  };
  auto gradient = [&](const Eigen::VectorXd& d, Eigen::VectorXd& f) {
    ScopedTimer t(rep.times, Stage::energy);
    trial_.x = x0_ + d;
    g_.setZero(3 * n);
    energy.add_gradient(trial_, g_);
    contact.add_gradient(trial_, g_);
    f = mt_.cwiseProduct(d) - mv_ + dt2 * g_;
    s.zero_constrained(f);
  };
  auto norm_minv = [&](const Eigen::VectorXd& f) { return std::sqrt(f.cwiseAbs2().cwiseQuotient(mt_).sum()); };

  double e_inc = merit(d_);
  if (!std::isfinite(e_inc)) {
    // The inertial guess may leave the model's domain; start from rest instead.
    for (int i = 0; i < n; ++i)
      if (!p.fixed[i]) d_.segment<3>(3 * i).setZero();
    e_inc = merit(d_);
    if (!std::isfinite(e_inc)) return fail("energy", Status::numerical_issue, "the state at the start of the step is not admissible (non-finite energy)");
  }
  gradient(d_, f_);
  double r = norm_minv(f_);
  nr.initial_residual = r;
  nr.tolerance = prm_.relative_tolerance * r + prm_.length_tolerance * std::sqrt(free_mass);
  if (!std::isfinite(r)) return fail("energy", Status::numerical_issue, "non-finite gradient at the start of the step");

  for (int it = 0;; ++it) {
    nr.final_residual = r;
    if (r <= nr.tolerance) {
      nr.stop_reason = "residual";
      break;
    }
    if (it == prm_.max_iterations) {
      nr.stop_reason = "max_iterations";
      return fail("newton", Status::no_convergence,
                  fmt::format("Newton did not reach ||f|| <= {:.3e} in {} iterations (||f|| = {:.3e}, initial {:.3e})",
                              nr.tolerance, it, r, nr.initial_residual));
    }
    NewtonIteration rec;
    rec.merit = e_inc;
    rec.residual = r;
    // K = M~ + dt^2 (H + contact terms), filtered to the free vertices. The adaptive choice
    // keeps Newton's quadratic convergence where K is positive definite and projects only
    // the iterations where the exact K is indefinite (or gives no descent direction).
    HessianMode mode = prm_.hessian == HessianChoice::projected ? HessianMode::projected : HessianMode::exact;
    double shift = 0, applied_shift = 0;  // K + shift * M~ (Levenberg-Marquardt in the mass metric)
    bool assembled = false;
    double slope = 0;
    for (;;) {
      if (!assembled) {
        ScopedTimer t(rep.times, Stage::hessian);
        trial_.x = x0_ + d_;
        energy.add_hessian(trial_, p.buffer, mode);
        contact.add_hessian(trial_, p.buffer, mode);
        p.plan.gather(p.buffer, p.matrix);
        p.matrix.scale(dt2);
        p.matrix.add_diagonal(mt_);
        p.matrix.filter_rows(p.fixed, 1.0);
        assembled = true;
        applied_shift = 0;
      }
      if (shift > applied_shift) {
        p.matrix.add_diagonal((shift - applied_shift) * mt_);
        applied_shift = shift;
      }
      Status st = Status::success;
      {
        ScopedTimer t(rep.times, Stage::linear_setup);
        if (!p.pattern_analyzed) {
          st = linear.analyze_pattern(p.matrix);
          p.pattern_analyzed = st == Status::success;
        }
        if (st == Status::success) st = linear.factorize(p.matrix);
      }
      LinearReport lr;
      if (st == Status::success) {
        rhs_ = -f_;
        dir_.setZero(3 * n);
        {
          ScopedTimer t(rep.times, Stage::linear_solve);
          lr = linear.solve(rhs_, dir_);
        }
        rep.linear.accumulate(lr);
        rec.linear_iterations += lr.iterations;
        s.zero_constrained(dir_);
        slope = f_.dot(dir_);
      } else {
        lr.status = st;
        lr.message = "the linear solver could not set up the Newton matrix";
      }
      const bool usable = lr.status == Status::success && !lr.indefinite && slope < 0;
      if (usable || prm_.hessian != HessianChoice::adaptive || mode != HessianMode::exact) {
        if (lr.status != Status::success) return fail(st != Status::success ? "linear_setup" : "linear_solve", lr.status, lr.message);
        break;
      }
      // Adaptive: the exact K is indefinite here. Shift it towards the mass matrix, the
      // smallest shift first (the last one that worked in this step, divided by 10), and
      // fall back to the per-element projection only if even a large shift fails.
      shift = shift == 0 ? std::max(prm_.min_shift, shift_hint_ / 10) : 10 * shift;
      if (shift > prm_.max_shift) {
        mode = HessianMode::projected;
        shift = 0;
        assembled = false;
      }
    }
    if (shift > 0) shift_hint_ = shift;
    rec.shift = shift;
    rec.projected = mode == HessianMode::projected;
    if (!(slope < 0)) {
      // Not a descent direction (indefinite K with the exact Hessian): fall back to the
      // scaled steepest descent -M~^-1 f, which always descends.
      dir_ = -f_.cwiseQuotient(mt_);
      slope = f_.dot(dir_);
    }
    rec.directional_derivative = slope;
    // Line search on E_inc.
    LineSearchResult ls;
    {
      ScopedTimer t(rep.times, Stage::line_search);
      if (prm_.line_search == LineSearchKind::full_step) {
        ls = {true, 1.0, merit(d_ + dir_), 1};
      } else {
        Eigen::VectorXd trial_d;
        ls = backtracking([&](double step) { trial_d = d_ + step * dir_; return merit(trial_d); }, e_inc, slope, prm_.search);
      }
    }
    rec.line_search_evaluations = ls.evaluations;
    if (!ls.accepted) {
      // Below round-off the decrease of E_inc cannot be resolved: converged to precision.
      const double resolvable = 1e-12 * (std::abs(e_inc) + dt2 * std::abs(V0)) + 1e-300;
      if (std::abs(slope) < resolvable) {
        nr.history.push_back(rec);
        nr.iterations = it + 1;
        nr.stop_reason = "precision";
        break;
      }
      nr.history.push_back(rec);
      nr.iterations = it + 1;
      return fail("line_search", Status::numerical_issue,
                  fmt::format("line search found no decrease of E_inc in {} trials (slope {:.3e}, ||f|| {:.3e})",
                              ls.evaluations, slope, r));
    }
    rec.step_length = ls.step;
    rec.step_norm = ls.step * dir_.cwiseAbs().maxCoeff();
    d_ += ls.step * dir_;
    e_inc = ls.value;
    gradient(d_, f_);
    r = norm_minv(f_);
    nr.history.push_back(rec);
    nr.iterations = it + 1;
    if (!std::isfinite(r)) return fail("energy", Status::numerical_issue, "non-finite gradient after the Newton update");
  }
  // Commit: q_{k+1} = q_k + d, v_{k+1} = d / dt.
  s.x = x0_ + d_;
  s.v = d_ / dt;
  rep.status = nr.status = Status::success;
  return rep;
}

}  // namespace weft::integrators
