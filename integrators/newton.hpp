#pragma once
/// \file newton.hpp
/// The Newton core shared by the integrators: the nonlinear system of one time step is
/// seen through `NewtonProblem` (a handful of calls per iteration, never per element), so
/// the loop, the Hessian fallbacks and the line searches are compiled once, in newton.cpp,
/// and serve every simulator as well as small test problems (the 1D example of methods/integration-and-contact
/// §5.3).
#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <string>
#include <string_view>

#include "framework/concepts.hpp"
#include "framework/params.hpp"
#include "framework/status.hpp"
#include "integrators/line_search.hpp"

namespace weft::integrators {

/// The nonlinear system of one step in the unknown d (displacement over the step).
/// Merit for minimisation: E(d); its gradient f(d), zero on constrained entries;
/// the Newton matrix K(d) (+ shift * M~), set up by `prepare` and then applied or solved.
class NewtonProblem {
 public:
  virtual ~NewtonProblem() = default;
  /// E_inc(d); +infinity outside the model's domain.
  virtual double potential(const Eigen::VectorXd& d) = 0;
  /// f = grad E_inc(d); zero on constrained entries.
  virtual void gradient(const Eigen::VectorXd& d, Eigen::VectorXd& f) = 0;
  /// ||f||_{M~^-1}.
  virtual double norm(const Eigen::VectorXd& f) const = 0;
  /// Assemble K(d) (exact or projected Hessian) plus shift * M~.
  virtual void assemble(const Eigen::VectorXd& d, HessianMode mode, double shift) = 0;
  /// Set up the linear solver for the assembled K.
  virtual Status factorize() = 0;
  Status prepare(const Eigen::VectorXd& d, HessianMode mode, double shift) {
    assemble(d, mode, shift);
    return factorize();
  }
  /// Solve K p = rhs with the prepared matrix; p is zero on constrained entries.
  virtual LinearReport solve(const Eigen::VectorXd& rhs, Eigen::VectorXd& p) = 0;
  /// y = K x with the prepared matrix.
  virtual void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const = 0;
  /// out = M~^-1 f (zero on constrained entries): the scaled steepest-descent direction is -out.
  virtual void mass_inverse(const Eigen::VectorXd& f, Eigen::VectorXd& out) const = 0;
  /// Magnitude of the terms summed in E (their round-off bounds how finely E resolves).
  virtual double merit_scale() const = 0;
  /// u^T M~ v (the metric of trust regions).
  virtual double mass_dot(const Eigen::VectorXd& u, const Eigen::VectorXd& v) const = 0;
  /// Moves d onto the problem's equality constraints, if it has any, and returns whether d
  /// changed. The iterations call it on every line-search trial and accepted update, so that
  /// trials are judged on the constraints and every Newton direction starts from a feasible
  /// iterate: from an infeasible one the direction also
  /// restores the constraints, which pushes pressed vertices out against their reaction
  /// and can ascend E by more than the rest descends it (the line search then cuts the step
  /// to nothing and the iteration stalls; a partial step or a curved obstacle leaves such
  /// gaps).
  virtual bool make_feasible(Eigen::VectorXd& d) {
    (void)d;
    return false;
  }
  /// Called by `minimize` and `find_root` after every accepted update: a problem whose constraint set grows
  /// during the iteration (contacts re-detected where the iterate crossed an obstacle,
  /// StepSystem) adds them, updates d (their vertices restart from the initial guess) and
  /// returns how many it added; 0 leaves d unchanged (contact.redetect_iterates; found at the
  /// iterate that crosses rather than after convergence, such a contact does not cost the
  /// iterations spent converging a solution that is then discarded for its vertices).
  virtual int update_constraints(Eigen::VectorXd& d) {
    (void)d;
    return 0;
  }
  /// True for a problem whose iterates must stay in a region E_inc cannot leave along a
  /// line (a barrier's domain: no intersection). `minimize` then asks `step_bound` for every
  /// direction and searches only [d, d + bound dir]; the Wolfe searches do not extrapolate
  /// beyond it, and the trust region refuses such a problem.
  virtual bool bounded() const { return false; }
  /// The largest s in (0, 1] such that every point of d + [0, s] dir is admissible (e.g. the
  /// time of impact of a continuous collision detection on that segment, with a safety
  /// margin); 0 when none is. Called once per Newton direction, before the line search.
  virtual double step_bound(const Eigen::VectorXd& d, const Eigen::VectorXd& dir) {
    (void)d;
    (void)dir;
    return 1.0;
  }
  /// The relative tolerance of the next linear solves (an inexact Newton's forcing term;
  /// 0: the solver's own). Iterative solvers stop there when it is looser than their own
  /// tolerance; direct solvers ignore it.
  virtual void set_linear_tolerance(double relative) { (void)relative; }
};

/// Which Hessian the Newton directions use.
enum class HessianChoice {
  adaptive,   ///< exact while K = M~ + dt^2 H is positive definite, else K + tau M~ with the
              ///< smallest tau in {min_shift, 10 min_shift, ..., max_shift} that is, else projection
  exact,      ///< always exact; an ascent direction is reversed (methods/integration-and-contact §16 E1), a zero-slope one
              ///< replaced by -M~^-1 f
  projected,  ///< always per-element PSD projection
};
inline constexpr std::array<std::string_view, 3> hessian_choice_names = {"adaptive", "exact", "projected"};

/// How Newton steps are globalised.
enum class Globalization {
  line_search,   ///< direction from the Hessian choice, step length from the line search
  trust_region,  ///< exact Hessian; Steihaug-Toint truncated CG in the mass norm
};
inline constexpr std::array<std::string_view, 2> globalization_names = {"line_search", "trust_region"};

/// Parameters of the Newton iteration (the flat keys of an integrator's section).
struct NewtonParams {
  int max_iterations = 100;           ///< Newton iterations per step
  double relative_tolerance = 1e-6;   ///< on ||f||_{M^-1} relative to its value at d0
  double length_tolerance = 1e-7;     ///< [m] absolute tolerance, times sqrt(free mass)
  double step_tolerance = 0;          ///< [m] also stop when the full Newton step (before the line search) moves no vertex farther (0: off)
  /// [m/s] also stop when the full Newton step moves no vertex farther than this times the
  /// step's dt: the step test as a velocity, as incremental potential contact states it (Li et
  /// al. 2020, its Newton termination), so it keeps its meaning under step subdivision (0: off).
  double velocity_tolerance = 0;
  double decrease_tolerance = 0;      ///< also stop when an iteration decreases the merit by less than
                                      ///< this fraction of the decrease so far (0: off)
  HessianChoice hessian = HessianChoice::adaptive;
  double min_shift = 1e-4;            ///< adaptive: first shift tried, relative to the mass
  double max_shift = 1e2;             ///< adaptive: beyond this, project per element instead
  LineSearchKind line_search = LineSearchKind::backtracking;
  LineSearchParams search;
  Globalization globalization = Globalization::line_search;
  double trust_radius = 1e-2;         ///< [m] initial trust radius (RMS displacement, mass-weighted)
  /// Inexact Newton (Dembo, Eisenstat and Steihaug 1982): iteration k's linear solve stops at
  /// relative residual eta_k = min(forcing, sqrt(||f_k|| / ||f_0||)), never tighter than the
  /// solver's own tolerance, so early iterations far from the solution take few Krylov
  /// iterations and the last ones converge superlinearly. A step-size or decrease stop met
  /// with a loose solve is confirmed by one more iteration at the solver's tolerance.
  /// Iterative solvers only (0: off, every solve at linear.tolerance).
  double forcing = 0;

  template <class V>
  void visit_newton(V& v) {
    v.field("max_iterations", max_iterations, {Unit::none, Range::closed(1, 10000), "Newton iterations per step before failing"});
    v.field("relative_tolerance", relative_tolerance,
            {Unit::none, Range::closed(0, 1), "stop when ||f||_M^-1 <= relative_tolerance ||f(d0)||_M^-1 + absolute"});
    v.field("length_tolerance", length_tolerance,
            {Unit::length, Range::ge(0), "absolute tolerance = length_tolerance * sqrt(free mass)"});
    v.field("step_tolerance", step_tolerance,
            {Unit::length, Range::ge(0), "also stop when the full Newton step (before the line search) moves no vertex farther than this (0: off)"});
    v.field("velocity_tolerance", velocity_tolerance,
            {Unit::velocity, Range::ge(0), "also stop when the full Newton step moves no vertex farther than this times dt (the larger of this and step_tolerance applies; 0: off)"});
    v.field("decrease_tolerance", decrease_tolerance,
            {Unit::none, Range::closed(0, 1), "also stop when an iteration decreases the merit by less than this fraction of the decrease so far (0: off)"});
    v.choice("hessian", hessian, hessian_choice_names,
             "adaptive: exact while K is positive definite, else shifted K + tau M~, else per-element projection");
    v.choice("line_search", line_search, line_search_names, "globalisation on E_inc");
    v.section("search", search);
    v.choice("globalization", globalization, globalization_names,
             "line_search (with the Hessian choice) or trust_region (exact Hessian, Steihaug-Toint CG)");
    v.field("trust_radius", trust_radius, {Unit::length, Range::gt(0), "trust_region: initial radius, as an RMS displacement"});
    v.field("forcing", forcing,
            {Unit::none, Range::closed_open(0, 1), "inexact Newton with a line search (minimisation; not the trust region or root finding): iterative linear solves stop at min(forcing, sqrt(||f_k||/||f_0||)) relative residual (0: at linear.tolerance)"});
    v.field("min_shift", min_shift, {Unit::none, Range::gt(0), "adaptive: smallest shift tau of K + tau M~ tried when K is indefinite"});
    v.field("max_shift", max_shift, {Unit::none, Range::gt(0), "adaptive: largest shift before falling back to per-element projection"});
  }
  /// The parameters of a step of length dt: the step test at the larger of step_tolerance
  /// and velocity_tolerance * dt.
  NewtonParams at_step(double dt) const {
    NewtonParams q = *this;
    q.step_tolerance = std::max(step_tolerance, velocity_tolerance * dt);
    return q;
  }
  static Checker validate_newton(const NewtonParams& p) {
    Checker c("integrator");
    c.require(p.relative_tolerance > 0 || p.length_tolerance > 0, "relative_tolerance", p.relative_tolerance,
              "> 0 when length_tolerance = 0 (else the iteration can never stop)");
    c.require(p.max_shift >= p.min_shift, "max_shift", p.max_shift, fmt::format(">= min_shift = {}", p.min_shift));
    return c;
  }
};

/// Where a failed Newton iteration stopped.
struct NewtonFailure {
  Status status = Status::success;
  std::string stage;    ///< "newton", "line_search", "linear_setup", "linear_solve", "energy"
  std::string message;
};

/// Minimise E from d (updated in place) until ||f||_{M~^-1} <= tolerance: Newton with the
/// Hessian choice of `prm` and a line search on E. `shift_hint` carries the last successful
/// Levenberg-Marquardt shift between calls. Fills `report` (history, residuals) and adds
/// the linear solves to `linear` and the line-search time to `times`.
NewtonFailure minimize(NewtonProblem& problem, Eigen::VectorXd& d, double absolute_tolerance, const NewtonParams& prm,
                       double& shift_hint, NewtonReport& report, LinearReport& linear, StageTimes& times);

/// Trust-region Newton on E (used by `minimize` when prm.globalization = trust_region):
/// exact Hessian; the Newton step when K is positive definite and it fits in the region,
/// the dogleg when it does not, Steihaug-Toint truncated CG (mass-preconditioned, following
/// negative curvature to the boundary) when K is indefinite. Radius in the M~-norm.
NewtonFailure minimize_trust_region(NewtonProblem& problem, Eigen::VectorXd& d, double absolute_tolerance,
                                    const NewtonParams& prm, NewtonReport& report, LinearReport& linear);

/// One Newton step from d with a full step (the linearly implicit method when d = 0,
/// methods/integration-and-contact §4 "LIE"); the direction uses the Hessian choice of `prm`. Never fails for lack
/// of convergence: the residual after the step is reported, not enforced.
NewtonFailure linearized_step(NewtonProblem& problem, Eigen::VectorXd& d, const NewtonParams& prm, double& shift_hint,
                              NewtonReport& report, LinearReport& linear);

/// Root finding on f(d) = 0 (methods/integration-and-contact §4): Newton with the exact Jacobian K (shifted by
/// tau M~ only where it is singular) and backtracking on the residual merit 1/2 ||f||^2
/// (§6.3; each trial costs a gradient, no energy). The comparison policy of the thesis.
/// `prm.hessian` and `prm.line_search` apply (full_step = pure Newton).
NewtonFailure find_root(NewtonProblem& problem, Eigen::VectorXd& d, double absolute_tolerance, const NewtonParams& prm,
                        NewtonReport& report, LinearReport& linear, StageTimes& times);

}  // namespace weft::integrators
