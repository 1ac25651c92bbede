#include "integrators/newton.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "framework/interrupt.hpp"

namespace weft::integrators {

namespace {

NewtonFailure failure(NewtonReport& nr, std::string stage, Status st, std::string msg) {
  nr.status = st;
  nr.message = msg;
  return NewtonFailure{st, std::move(stage), std::move(msg)};
}

// The stopping test shared by every Newton loop: converged (true, no failure), out of
// iterations (a failure), or go on (false, no failure).
bool should_stop(NewtonReport& nr, double r, int it, int max_iterations, const char* method, NewtonFailure& out) {
  nr.final_residual = r;
  if (stop_requested()) {  // a signal: the step stops here and is reported as interrupted
    nr.stop_reason = "interrupted";
    out = failure(nr, "newton", Status::interrupted, fmt::format("{} interrupted at iteration {} by a stop request", method, it));
    return true;
  }
  if (r <= nr.tolerance) {
    nr.stop_reason = "residual";
    return true;
  }
  if (it < max_iterations) return false;
  nr.stop_reason = "max_iterations";
  out = failure(nr, "newton", Status::no_convergence,
                fmt::format("{} did not reach ||f|| <= {:.3e} in {} iterations (||f|| = {:.3e}, initial {:.3e})", method,
                            nr.tolerance, it, r, nr.initial_residual));
  return true;
}

// The optional stopping tests on the accepted step: its size, and the merit decrease of
// the iteration relative to the decrease since the start. The size is that of the full
// step (the Newton direction before the line search): a step the line search cut to almost
// nothing is a stall, not convergence (a 41 x 41 dropVertical accepted steps of 1e-13 m this
// way with ||f|| 175-6300 times its tolerance, and blew up four steps later).
bool small_step(NewtonReport& nr, const NewtonParams& prm, double step_norm, double decrease, double total_decrease) {
  if (prm.step_tolerance > 0 && step_norm <= prm.step_tolerance) {
    nr.stop_reason = "step_size";
    return true;
  }
  if (prm.decrease_tolerance > 0 && decrease >= 0 && decrease <= prm.decrease_tolerance * total_decrease) {
    nr.stop_reason = "decrease";
    return true;
  }
  return false;
}

// A descent direction of E at d. The adaptive choice keeps Newton's quadratic convergence
// where K is positive definite; where the exact K is indefinite it shifts K towards the
// mass matrix (the smallest shift first: the last one that worked, divided by 10), and
// projects per element only if even a large shift fails; a direction that still does not
// descend is replaced by the scaled steepest descent -M~^-1 f.
NewtonFailure descent_direction(NewtonProblem& problem, const Eigen::VectorXd& d, const Eigen::VectorXd& f,
                                const NewtonParams& prm, double& shift_hint, NewtonIteration& rec, LinearReport& linear,
                                Eigen::VectorXd& dir, double& slope, bool require_descent = true) {
  HessianMode mode = prm.hessian == HessianChoice::projected ? HessianMode::projected : HessianMode::exact;
  double shift = 0;
  slope = 0;
  for (;;) {
    const Status st = problem.prepare(d, mode, shift);
    LinearReport lr;
    if (st == Status::success) {
      dir.setZero(d.size());
      lr = problem.solve(-f, dir);
      linear.accumulate(lr);
      rec.linear_iterations += lr.iterations;
      slope = f.dot(dir);
    } else {
      lr.status = st;
      lr.message = "the linear solver could not set up the Newton matrix";
    }
    const bool usable = lr.status == Status::success && !lr.indefinite && slope < 0;
    if (usable || prm.hessian != HessianChoice::adaptive || mode != HessianMode::exact) {
      if (lr.status != Status::success)
        return {lr.status, st != Status::success ? "linear_setup" : "linear_solve", lr.message};
      break;
    }
    shift = shift == 0 ? std::max(prm.min_shift, shift_hint / 10) : 10 * shift;
    if (shift > prm.max_shift) {
      mode = HessianMode::projected;
      shift = 0;
    }
  }
  if (shift > 0) shift_hint = shift;
  rec.shift = shift;
  rec.projected = mode == HessianMode::projected;
  if (require_descent && slope > 0) {
    // Ascent along a direction of negative curvature: the reversed direction descends.
    dir = -dir;
    slope = -slope;
  } else if (require_descent && !(slope < 0)) {
    problem.mass_inverse(f, dir);
    dir = -dir;
    slope = f.dot(dir);
  }
  return {};
}

}  // namespace

NewtonFailure linearized_step(NewtonProblem& problem, Eigen::VectorXd& d, const NewtonParams& prm, double& shift_hint,
                              NewtonReport& nr, LinearReport& linear) {
  Eigen::VectorXd f(d.size()), dir(d.size());
  nr.method = fmt::format("one linearised step, Hessian {}", enum_name(prm.hessian, hessian_choice_names));
  problem.gradient(d, f);
  NewtonIteration rec;
  rec.merit = problem.potential(d);
  rec.residual = nr.initial_residual = problem.norm(f);
  double slope = 0;
  // No descent requirement: with the exact Hessian this is the textbook linearly implicit
  // step, whatever the sign of K.
  if (NewtonFailure df = descent_direction(problem, d, f, prm, shift_hint, rec, linear, dir, slope, false);
      df.status != Status::success) {
    nr.status = df.status;
    nr.message = df.message;
    return df;
  }
  rec.directional_derivative = slope;
  rec.step_length = 1.0;
  rec.step_norm = dir.cwiseAbs().maxCoeff();
  rec.line_search_evaluations = 0;
  d += dir;
  nr.iterations = 1;
  if (!std::isfinite(problem.potential(d))) {
    nr.history.push_back(rec);
    nr.status = Status::numerical_issue;
    nr.message = "the linearised step left the model's domain (non-finite energy or a degenerate element)";
    return {Status::numerical_issue, "energy", nr.message};
  }
  problem.gradient(d, f);
  nr.final_residual = problem.norm(f);
  nr.history.push_back(rec);
  nr.stop_reason = "single_step";
  nr.status = Status::success;
  return {};
}

namespace {

// Largest tau >= 0 with ||z + tau p||_M = radius.
double to_boundary(NewtonProblem& problem, const Eigen::VectorXd& z, const Eigen::VectorXd& p, double radius) {
  const double a = problem.mass_dot(p, p), b = 2 * problem.mass_dot(z, p), c = problem.mass_dot(z, z) - radius * radius;
  const double disc = std::max(0.0, b * b - 4 * a * c);
  return a > 0 ? (-b + std::sqrt(disc)) / (2 * a) : 0.0;
}

// Steihaug-Toint truncated CG on min f^T p + 1/2 p^T K p, ||p||_M <= radius, preconditioned
// by M~ (so the CG iterates grow monotonically in the M-norm). Stops on the boundary, at
// negative curvature (following it to the boundary), or when the model gradient is small.
Eigen::VectorXd steihaug(NewtonProblem& problem, const Eigen::VectorXd& f, double radius, double rel_tol, int max_iter,
                         int& iterations, bool& negative_curvature) {
  const Eigen::Index n = f.size();
  Eigen::VectorXd z = Eigen::VectorXd::Zero(n), r = f, y(n), p(n), Kp(n);
  problem.mass_inverse(r, y);
  p = -y;
  double ry = r.dot(y);
  const double r0 = std::sqrt(std::max(ry, 0.0));
  negative_curvature = false;
  for (iterations = 0; iterations < max_iter; ++iterations) {
    problem.multiply(p, Kp);
    const double kappa = p.dot(Kp);
    if (kappa <= 0) {
      negative_curvature = true;
      return z + to_boundary(problem, z, p, radius) * p;
    }
    const double alpha = ry / kappa;
    const Eigen::VectorXd z_next = z + alpha * p;
    if (problem.mass_dot(z_next, z_next) >= radius * radius) return z + to_boundary(problem, z, p, radius) * p;
    z = z_next;
    r += alpha * Kp;
    problem.mass_inverse(r, y);
    const double ry_next = r.dot(y);
    if (std::sqrt(std::max(ry_next, 0.0)) <= rel_tol * r0) {
      ++iterations;
      break;
    }
    p = -y + (ry_next / ry) * p;
    ry = ry_next;
  }
  return z;
}

}  // namespace

NewtonFailure minimize_trust_region(NewtonProblem& problem, Eigen::VectorXd& d, double absolute_tolerance,
                                    const NewtonParams& prm, NewtonReport& nr, LinearReport& linear) {
  const Eigen::Index n = d.size();
  Eigen::VectorXd f(n), p(n), Kp(n), trial(n), g(n);
  auto fail = [&](std::string stage, Status st, std::string msg) { return failure(nr, std::move(stage), st, std::move(msg)); };
  double e = problem.potential(d);
  if (!std::isfinite(e)) return fail("energy", Status::numerical_issue, "the initial guess is not admissible (non-finite energy)");
  const double e0 = e;
  problem.gradient(d, f);
  double r = problem.norm(f);
  nr.initial_residual = r;
  nr.tolerance = prm.relative_tolerance * r + absolute_tolerance;
  // The radius is an RMS displacement: ||p||_M = radius * sqrt(total mass).
  nr.method = "minimise E_inc, trust region (exact Hessian, Steihaug-Toint CG)";
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(n);
  const double max_radius = 1e3 * prm.trust_radius * std::sqrt(problem.mass_dot(ones, ones) / 3.0);
  double radius = prm.trust_radius * std::sqrt(problem.mass_dot(ones, ones) / 3.0);
  int rejected = 0;
  for (int it = 0;; ++it) {
    if (NewtonFailure stop; should_stop(nr, r, it, prm.max_iterations, "trust-region Newton", stop)) {
      if (stop.status != Status::success) return stop;
      break;
    }
    NewtonIteration rec;
    rec.merit = e;
    rec.residual = r;
    // Step: the Newton step when K is positive definite and the step fits, the dogleg
    // when it does not fit, Steihaug-Toint CG when K is indefinite.
    problem.assemble(d, HessianMode::exact, 0.0);
    const Status st = problem.factorize();
    LinearReport lr;
    bool have_newton = false;
    if (st == Status::success) {
      p.setZero();
      lr = problem.solve(-f, p);
      linear.accumulate(lr);
      have_newton = lr.status == Status::success && !lr.indefinite && f.dot(p) < 0;
    }
    if (have_newton && problem.mass_dot(p, p) > radius * radius) {
      // Dogleg between the Cauchy point along -M~^-1 f and the Newton point.
      problem.mass_inverse(f, g);
      problem.multiply(g, Kp);
      const Eigen::VectorXd pc = -(f.dot(g) / std::max(g.dot(Kp), 1e-300)) * g;
      if (problem.mass_dot(pc, pc) >= radius * radius) {
        p = pc * (radius / std::sqrt(problem.mass_dot(pc, pc)));
      } else {
        const Eigen::VectorXd seg = p - pc;
        p = pc + to_boundary(problem, pc, seg, radius) * seg;
      }
    } else if (!have_newton) {
      int cg = 0;
      bool negative = false;
      p = steihaug(problem, f, radius, 1e-6, 500, cg, negative);
      rec.linear_iterations += cg;
      rec.projected = false;
      linear.iterations += cg;
    }
    problem.multiply(p, Kp);
    const double predicted = -(f.dot(p) + 0.5 * p.dot(Kp));
    trial = d + p;
    problem.make_feasible(trial);  // the model is judged on the constraints (see minimize)
    const double e_trial = problem.potential(trial);
    const double actual = e - e_trial;
    const double rho = predicted > 0 ? actual / predicted : -1.0;
    rec.directional_derivative = f.dot(p);
    rec.line_search_evaluations = 1;
    const double pnorm = std::sqrt(problem.mass_dot(p, p));
    if (!std::isfinite(e_trial) || rho < 0.25) radius = 0.25 * pnorm;
    else if (rho > 0.75 && pnorm >= 0.99 * radius) radius = std::min(2 * radius, max_radius);
    nr.iterations = it + 1;
    if (std::isfinite(e_trial) && rho > 1e-4) {
      d = trial;  // made feasible above
      e = e_trial;
      problem.gradient(d, f);
      r = problem.norm(f);
      rec.step_length = 1.0;
      rec.step_norm = p.cwiseAbs().maxCoeff();
      rejected = 0;
      if (small_step(nr, prm, rec.step_norm, actual, e0 - e)) {
        nr.history.push_back(rec);
        nr.final_residual = r;
        break;
      }
    } else {
      rec.step_length = 0.0;
      // A step rejected because its decrease is below round-off: converged to precision.
      if (predicted < 1e-12 * (std::abs(e) + problem.merit_scale())) {
        nr.history.push_back(rec);
        nr.stop_reason = "precision";
        break;
      }
      if (++rejected > 60) return fail("trust_region", Status::numerical_issue, "the trust region collapsed");
    }
    nr.history.push_back(rec);
    if (!std::isfinite(r)) return fail("energy", Status::numerical_issue, "non-finite gradient after the step");
  }
  nr.status = Status::success;
  return {};
}

NewtonFailure minimize(NewtonProblem& problem, Eigen::VectorXd& d, double absolute_tolerance, const NewtonParams& prm,
                       double& shift_hint, NewtonReport& nr, LinearReport& linear, StageTimes& times) {
  if (prm.globalization == Globalization::trust_region) {
    if (problem.bounded())
      return failure(nr, "newton", Status::invalid_input,
                     "the trust region cannot keep a barrier's iterates admissible: use globalization = line_search");
    return minimize_trust_region(problem, d, absolute_tolerance, prm, nr, linear);
  }
  LineSearchParams search = prm.search;  // a bounded problem: no extrapolation past its bound
  if (problem.bounded()) search.max_step = 1.0;
  nr.method = fmt::format("minimise E_inc, line search {}, Hessian {}", enum_name(prm.line_search, line_search_names),
                          enum_name(prm.hessian, hessian_choice_names));
  const Eigen::Index n = d.size();
  Eigen::VectorXd f(n), ft(n), dir(n), trial(n);
  auto fail = [&](std::string stage, Status st, std::string msg) { return failure(nr, std::move(stage), st, std::move(msg)); };

  double e = problem.potential(d);
  if (!std::isfinite(e)) return fail("energy", Status::numerical_issue, "the initial guess is not admissible (non-finite energy)");
  const double e0 = e;
  problem.gradient(d, f);
  double r = problem.norm(f);
  nr.initial_residual = r;
  nr.tolerance = prm.relative_tolerance * r + absolute_tolerance;
  if (!std::isfinite(r)) return fail("energy", Status::numerical_issue, "non-finite gradient at the start of the step");

  // Inexact Newton: the solver's tolerance is restored on every way out.
  struct RestoreTolerance {
    NewtonProblem& p;
    ~RestoreTolerance() { p.set_linear_tolerance(0); }
  } restore{problem};
  bool confirm = false;  // a small step met with a loose solve: the next solve is exact
  for (int it = 0;; ++it) {
    if (NewtonFailure stop; should_stop(nr, r, it, prm.max_iterations, "Newton", stop)) {
      if (stop.status != Status::success) return stop;
      break;
    }
    NewtonIteration rec;
    rec.merit = e;
    rec.residual = r;

    const double forcing =
        prm.forcing > 0 && !confirm && nr.initial_residual > 0 ? std::min(prm.forcing, std::sqrt(r / nr.initial_residual)) : 0.0;
    problem.set_linear_tolerance(forcing);
    double slope = 0;
    if (const NewtonFailure df = descent_direction(problem, d, f, prm, shift_hint, rec, linear, dir, slope);
        df.status != Status::success) {
      nr.status = df.status;
      nr.message = df.message;
      return df;
    }
    // A bounded problem (a barrier): only the admissible part of the direction is searched.
    // The convergence and round-off tests keep reading the uncut direction (a direction the
    // CCD cut short is not a small Newton step).
    const double newton_step = dir.cwiseAbs().maxCoeff(), newton_slope = slope;
    if (problem.bounded()) {
      const double bound = problem.step_bound(d, dir);
      if (!(bound > 0))
        return fail("line_search", Status::numerical_issue,
                    "no admissible step along the Newton direction (the iterate is at its domain's boundary)");
      if (bound < 1) {
        dir *= bound;
        slope *= bound;
      }
      rec.step_bound = bound;
    }
    rec.directional_derivative = slope;

    // Line search on E.
    LineSearchResult ls;
    {
      ScopedTimer t(times, Stage::line_search);
      // Trials are made feasible before they are judged: the line search follows the arc
      // the projection bends the straight step into. Judged on the straight step, a vertex
      // held on a curved obstacle (a rounded box edge) by a force that K does not see (the
      // constraint's curvature times its reaction) is moved across the edge and projected
      // back to where it came from: the iteration cycles between two iterates.
      auto phi = [&](double step) {
        trial = d + step * dir;
        problem.make_feasible(trial);
        return problem.potential(trial);
      };
      // phi and phi' = f(d + s p)^T p: one energy and one gradient per trial.
      auto phi_slope = [&](double step) {
        const double value = phi(step);
        if (!std::isfinite(value)) return std::pair<double, double>(value, value);
        problem.gradient(trial, ft);
        return std::pair<double, double>(value, ft.dot(dir));
      };
      // Below round-off (methods/integration-and-contact §6.6, mitigation 2): when the full step's predicted decrease
      // is too small for E_inc to resolve, value comparisons are noise; accept the full step
      // on the derivative test of approximate Wolfe instead (the slope along the direction
      // must shrink in magnitude and stay a descent-side slope).
      const double noise = 1e-12 * (std::abs(e) + problem.merit_scale());
      bool decided = false;
      if (prm.line_search != LineSearchKind::full_step && std::abs(slope) <= noise) {
        const auto [value, slope1] = phi_slope(1.0);
        if (std::isfinite(value) && std::abs(slope1) <= 0.9 * std::abs(slope)) {
          ls = {true, 1.0, value, 1};
          decided = true;
          ++nr.round_off_steps;
        }
      }
      if (!decided) switch (prm.line_search) {
        case LineSearchKind::full_step: ls = {true, 1.0, phi(1.0), 1}; break;
        case LineSearchKind::backtracking: ls = backtracking(phi, e, slope, search); break;
        case LineSearchKind::more_thuente: ls = more_thuente(phi_slope, e, slope, search); break;
        case LineSearchKind::hager_zhang: ls = hager_zhang(phi_slope, e, slope, search); break;
      }
      // At a bound the Wolfe searches cannot extrapolate, so their curvature test can fail
      // on a step that decreases E (still descending at the bound): backtrack instead.
      if (!decided && !ls.accepted && rec.step_bound < 1 &&
          (prm.line_search == LineSearchKind::more_thuente || prm.line_search == LineSearchKind::hager_zhang)) {
        const int used = ls.evaluations;
        ls = backtracking(phi, e, slope, search);
        ls.evaluations += used;
      }
    }
    rec.line_search_evaluations = ls.evaluations;
    nr.iterations = it + 1;
    if (!ls.accepted) {
      nr.history.push_back(rec);
      // Below round-off the decrease of E cannot be resolved: converged to precision.
      if (std::abs(newton_slope) < 1e-12 * (std::abs(e) + problem.merit_scale()) + 1e-300) {
        nr.stop_reason = "precision";
        break;
      }
      return fail("line_search", Status::numerical_issue,
                  fmt::format("line search found no decrease of E_inc in {} trials (slope {:.3e}, ||f|| {:.3e})",
                              ls.evaluations, slope, r));
    }
    rec.step_length = ls.step;
    const double full_step = newton_step;
    rec.step_norm = ls.step * dir.cwiseAbs().maxCoeff();
    d += ls.step * dir;
    problem.make_feasible(d);  // the point the line search judged: ls.value is E there
    const double decrease = e - ls.value;
    e = ls.value;
    // New constraints where this iterate crossed an obstacle: a different problem from here
    // on (its vertices restart), so no convergence test on this update.
    const bool updated = problem.update_constraints(d) > 0;
    if (updated) {
      problem.make_feasible(d);
      e = problem.potential(d);
      rec.constraints_updated = true;
    }
    problem.gradient(d, f);
    r = problem.norm(f);
    nr.history.push_back(rec);
    if (!std::isfinite(r)) return fail("energy", Status::numerical_issue, "non-finite gradient after the Newton update");
    if (!updated && small_step(nr, prm, full_step, decrease, e0 - e)) {
      if (forcing > 0) {  // the loose solve's step may be small for being loose: confirm
        confirm = true;
        nr.stop_reason.clear();
        continue;
      }
      nr.final_residual = r;
      break;
    }
    confirm = false;
  }
  nr.status = Status::success;
  return {};
}

NewtonFailure find_root(NewtonProblem& problem, Eigen::VectorXd& d, double absolute_tolerance, const NewtonParams& prm,
                        NewtonReport& nr, LinearReport& linear, StageTimes& times) {
  const Eigen::Index n = d.size();
  Eigen::VectorXd f(n), ft(n), dir(n), rhs(n), trial(n), Kp(n);
  auto fail = [&](std::string stage, Status st, std::string msg) { return failure(nr, std::move(stage), st, std::move(msg)); };
  nr.method = fmt::format("root finding on 1/2 |f|^2, line search {}", enum_name(prm.line_search, line_search_names));
  problem.gradient(d, f);
  double r = problem.norm(f);
  double merit = 0.5 * f.squaredNorm();
  const double merit0 = merit;
  nr.initial_residual = r;
  nr.tolerance = prm.relative_tolerance * r + absolute_tolerance;
  if (!std::isfinite(r)) return fail("energy", Status::numerical_issue, "non-finite residual at the start of the step");

  for (int it = 0;; ++it) {
    if (NewtonFailure stop; should_stop(nr, r, it, prm.max_iterations, "root finding", stop)) {
      if (stop.status != Status::success) return stop;
      break;
    }
    NewtonIteration rec;
    rec.merit = merit;
    rec.residual = r;
    // The Newton direction descends 1/2 ||f||^2 whenever K is nonsingular (slope -||f||^2),
    // so no definiteness is needed: shift only when the factorisation fails.
    const HessianMode mode = prm.hessian == HessianChoice::projected ? HessianMode::projected : HessianMode::exact;
    double shift = 0, slope = 0;
    for (;;) {
      const Status st = problem.prepare(d, mode, shift);
      LinearReport lr;
      if (st == Status::success) {
        rhs = -f;
        dir.setZero();
        lr = problem.solve(rhs, dir);
        linear.accumulate(lr);
        rec.linear_iterations += lr.iterations;
        problem.multiply(dir, Kp);
        slope = f.dot(Kp);
      } else {
        lr.status = st;
        lr.message = "the linear solver could not set up the Jacobian";
      }
      if (lr.status == Status::success && slope < 0) break;
      shift = shift == 0 ? prm.min_shift : 10 * shift;
      if (shift > prm.max_shift)
        return fail(st != Status::success ? "linear_setup" : "linear_solve", Status::numerical_issue,
                    lr.status != Status::success ? lr.message : "no descent direction for the residual norm");
    }
    rec.shift = shift;
    rec.projected = mode == HessianMode::projected;
    rec.directional_derivative = slope;
    LineSearchResult ls;
    {
      ScopedTimer t(times, Stage::line_search);
      auto phi = [&](double step) {
        trial = d + step * dir;
        problem.make_feasible(trial);
        problem.gradient(trial, ft);
        const double m = 0.5 * ft.squaredNorm();
        return std::isfinite(m) ? m : std::numeric_limits<double>::infinity();
      };
      if (prm.line_search == LineSearchKind::full_step) ls = {true, 1.0, phi(1.0), 1};
      else ls = backtracking(phi, merit, slope, prm.search);
    }
    rec.line_search_evaluations = ls.evaluations;
    nr.iterations = it + 1;
    nr.history.push_back(rec);
    if (!ls.accepted)
      return fail("line_search", Status::numerical_issue,
                  fmt::format("line search found no decrease of ||f|| in {} trials (||f|| {:.3e})", ls.evaluations, r));
    nr.history.back().step_length = ls.step;
    const double full_step = dir.cwiseAbs().maxCoeff();
    nr.history.back().step_norm = ls.step * full_step;
    d += ls.step * dir;
    problem.make_feasible(d);  // the point the line search judged
    // New constraints where this iterate crossed an obstacle (as in `minimize`).
    const bool updated = problem.update_constraints(d) > 0;
    if (updated) {
      problem.make_feasible(d);
      nr.history.back().constraints_updated = true;
    }
    problem.gradient(d, f);
    const double decrease = merit - 0.5 * f.squaredNorm();
    merit = 0.5 * f.squaredNorm();
    r = problem.norm(f);
    if (!std::isfinite(r)) return fail("energy", Status::numerical_issue, "non-finite residual after the Newton update");
    if (!updated && small_step(nr, prm, full_step, decrease, merit0 - merit)) {
      nr.final_residual = r;
      break;
    }
  }
  nr.status = Status::success;
  return {};
}

}  // namespace weft::integrators
