#include "integrators/newton.hpp"

#include <cmath>
#include <limits>

namespace weft::integrators {

namespace {

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
  problem.gradient(d, f);
  nr.final_residual = problem.norm(f);
  nr.iterations = 1;
  nr.history.push_back(rec);
  nr.stop_reason = "single_step";
  nr.status = Status::success;
  return {};
}

NewtonFailure minimize(NewtonProblem& problem, Eigen::VectorXd& d, double absolute_tolerance, const NewtonParams& prm,
                       double& shift_hint, NewtonReport& nr, LinearReport& linear, StageTimes& times) {
  const Eigen::Index n = d.size();
  Eigen::VectorXd f(n), ft(n), dir(n), trial(n);
  auto fail = [&](std::string stage, Status st, std::string msg) {
    nr.status = st;
    nr.message = msg;
    return NewtonFailure{st, std::move(stage), std::move(msg)};
  };

  double e = problem.potential(d);
  if (!std::isfinite(e)) return fail("energy", Status::numerical_issue, "the initial guess is not admissible (non-finite energy)");
  problem.gradient(d, f);
  double r = problem.norm(f);
  nr.initial_residual = r;
  nr.tolerance = prm.relative_tolerance * r + absolute_tolerance;
  if (!std::isfinite(r)) return fail("energy", Status::numerical_issue, "non-finite gradient at the start of the step");

  for (int it = 0;; ++it) {
    nr.final_residual = r;
    if (r <= nr.tolerance) {
      nr.stop_reason = "residual";
      break;
    }
    if (it == prm.max_iterations) {
      nr.stop_reason = "max_iterations";
      return fail("newton", Status::no_convergence,
                  fmt::format("Newton did not reach ||f|| <= {:.3e} in {} iterations (||f|| = {:.3e}, initial {:.3e})",
                              nr.tolerance, it, r, nr.initial_residual));
    }
    NewtonIteration rec;
    rec.merit = e;
    rec.residual = r;

    double slope = 0;
    if (const NewtonFailure df = descent_direction(problem, d, f, prm, shift_hint, rec, linear, dir, slope);
        df.status != Status::success) {
      nr.status = df.status;
      nr.message = df.message;
      return df;
    }
    rec.directional_derivative = slope;

    // Line search on E.
    LineSearchResult ls;
    {
      ScopedTimer t(times, Stage::line_search);
      auto phi = [&](double step) {
        trial = d + step * dir;
        return problem.potential(trial);
      };
      // phi and phi' = f(d + s p)^T p: one energy and one gradient per trial.
      auto phi_slope = [&](double step) {
        const double value = phi(step);
        if (!std::isfinite(value)) return std::pair<double, double>(value, value);
        problem.gradient(trial, ft);
        return std::pair<double, double>(value, ft.dot(dir));
      };
      switch (prm.line_search) {
        case LineSearchKind::full_step: ls = {true, 1.0, phi(1.0), 1}; break;
        case LineSearchKind::backtracking: ls = backtracking(phi, e, slope, prm.search); break;
        case LineSearchKind::more_thuente: ls = more_thuente(phi_slope, e, slope, prm.search); break;
        case LineSearchKind::hager_zhang: ls = hager_zhang(phi_slope, e, slope, prm.search); break;
      }
    }
    rec.line_search_evaluations = ls.evaluations;
    nr.iterations = it + 1;
    if (!ls.accepted) {
      nr.history.push_back(rec);
      // Below round-off the decrease of E cannot be resolved: converged to precision.
      if (std::abs(slope) < 1e-12 * (std::abs(e) + problem.merit_scale()) + 1e-300) {
        nr.stop_reason = "precision";
        break;
      }
      return fail("line_search", Status::numerical_issue,
                  fmt::format("line search found no decrease of E_inc in {} trials (slope {:.3e}, ||f|| {:.3e})",
                              ls.evaluations, slope, r));
    }
    rec.step_length = ls.step;
    rec.step_norm = ls.step * dir.cwiseAbs().maxCoeff();
    d += ls.step * dir;
    e = ls.value;
    problem.gradient(d, f);
    r = problem.norm(f);
    nr.history.push_back(rec);
    if (!std::isfinite(r)) return fail("energy", Status::numerical_issue, "non-finite gradient after the Newton update");
  }
  nr.status = Status::success;
  return {};
}

NewtonFailure find_root(NewtonProblem& problem, Eigen::VectorXd& d, double absolute_tolerance, const NewtonParams& prm,
                        NewtonReport& nr, LinearReport& linear, StageTimes& times) {
  const Eigen::Index n = d.size();
  Eigen::VectorXd f(n), ft(n), dir(n), rhs(n), trial(n), Kp(n);
  auto fail = [&](std::string stage, Status st, std::string msg) {
    nr.status = st;
    nr.message = msg;
    return NewtonFailure{st, std::move(stage), std::move(msg)};
  };
  problem.gradient(d, f);
  double r = problem.norm(f);
  double merit = 0.5 * f.squaredNorm();
  nr.initial_residual = r;
  nr.tolerance = prm.relative_tolerance * r + absolute_tolerance;
  if (!std::isfinite(r)) return fail("energy", Status::numerical_issue, "non-finite residual at the start of the step");

  for (int it = 0;; ++it) {
    nr.final_residual = r;
    if (r <= nr.tolerance) {
      nr.stop_reason = "residual";
      break;
    }
    if (it == prm.max_iterations) {
      nr.stop_reason = "max_iterations";
      return fail("newton", Status::no_convergence,
                  fmt::format("root finding did not reach ||f|| <= {:.3e} in {} iterations (||f|| = {:.3e}, initial {:.3e})",
                              nr.tolerance, it, r, nr.initial_residual));
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
    nr.history.back().step_norm = ls.step * dir.cwiseAbs().maxCoeff();
    d += ls.step * dir;
    problem.gradient(d, f);
    merit = 0.5 * f.squaredNorm();
    r = problem.norm(f);
    if (!std::isfinite(r)) return fail("energy", Status::numerical_issue, "non-finite residual after the Newton update");
  }
  nr.status = Status::success;
  return {};
}

}  // namespace weft::integrators
