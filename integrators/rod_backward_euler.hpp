#pragma once
/// \file rod_backward_euler.hpp
/// `RodBackwardEuler`: the unconstrained time step of one elastic rod (spec 03 §3), backward
/// Euler in displacement form solved as the minimisation of the incremental potential
///     E_inc(d) = 1/2 d^T M d - h d^T M v + h^2 (V(q + d) - f_ext^T d),
/// whose gradient is the DEL residual f(d) = M d - h M v + h^2 (grad V(q + d) - f_ext)
/// and whose Hessian is K(d) = M + h^2 H(q + d). Newton with a backtracking (Armijo) line
/// search on E_inc over the rod's free DoFs; the held DoFs (a scripted root) are set to
/// their targets first and their rows decoupled. Rods are independent systems: the rod
/// simulator runs one solve per rod, in parallel.
///
/// The exact Hessian is tried first; when it does not give a descent direction (or its
/// factorisation fails) the step is recomputed with the per-stencil PSD projection. The
/// iteration stops when the largest position change of a Newton step is below
/// `tolerance` times the rod's mean rest edge length (a scale-free geometric test; the
/// residual is reported as well), or after `max_iterations` (a failure).
///
/// A `Body` provides: `model` (energy(q, frames), add_gradient, add_hessian, admissible),
/// `q`, `v`, `mass`, `fext` (n-vectors), `fixed` (n flags), `target` (n: end-of-step values
/// of the held DoFs), `frames` (the frames at q), `d` (the displacement: initial guess in,
/// solution out), `K` (a BandMatrix scratch), `lu` (a linear solver with
/// factorize(BandMatrix) -> Status and solve(Eigen::Ref<MatrixXd>)), `mean_edge`.
#include <Eigen/Core>

#include <cmath>
#include <string_view>

#include <fmt/format.h>

#include <limits>

#include "framework/band_matrix.hpp"
#include "framework/concepts.hpp"
#include "framework/params.hpp"
#include "framework/status.hpp"

namespace weft::integrators {

class RodBackwardEuler {
 public:
  static constexpr std::string_view name = "rod_backward_euler";
  struct Params {
    double tolerance = 1e-9;   ///< largest Newton position step, relative to the mean rest edge length
    int max_iterations = 50;
    double armijo = 1e-4;      ///< sufficient decrease constant of the backtracking line search
    int max_halvings = 40;
    template <class V>
    void visit(V& v) {
      v.field("tolerance", tolerance, {Unit::none, Range::open(0, 1), "Newton stops when its step moves no vertex by more than this times the mean rest edge length"});
      v.field("max_iterations", max_iterations, {Unit::none, Range::closed(1, 10000), "Newton iterations before the step fails"});
      v.field("armijo", armijo, {Unit::none, Range::open(0, 0.5), "sufficient-decrease constant of the backtracking line search"});
      v.field("max_halvings", max_halvings, {Unit::none, Range::closed(1, 200), "line-search halvings before the step fails"});
    }
  };

  explicit RodBackwardEuler(const Params& p) : prm_(p) {}
  const Params& params() const { return prm_; }

  /// f(d) = M d - h M v + h^2 (grad V(q + d) - f_ext), held rows zeroed.
  template <class Body>
  static void residual(const Body& b, const Eigen::VectorXd& d, double h, Eigen::VectorXd& f) {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(d.size());
    b.model.add_gradient(b.q + d, b.frames, g);
    f = b.mass.cwiseProduct(d - h * b.v) + h * h * (g - b.fext);
    for (Eigen::Index i = 0; i < f.size(); ++i)
      if (b.fixed[i]) f[i] = 0;
  }

  /// E_inc(d) (constants dropped); +inf outside the model's domain.
  template <class Body>
  static double potential(const Body& b, const Eigen::VectorXd& d, double h) {
    const Eigen::VectorXd q = b.q + d;
    if (!b.model.admissible(q, b.frames)) return std::numeric_limits<double>::infinity();
    const double e = 0.5 * d.dot(b.mass.cwiseProduct(d)) - h * d.dot(b.mass.cwiseProduct(b.v)) +
                     h * h * (b.model.energy(q, b.frames) - b.fext.dot(d));
    return std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
  }

  /// K = M + h^2 H(q + d) with the held rows and columns decoupled (diagonal M), factorised
  /// into b.lu.
  template <class Body>
  static Status relinearize(Body& b, double h, HessianMode mode) {
    const int n = static_cast<int>(b.q.size());
    if (b.K.rows() != n) b.K = BandMatrix(n, 10);
    b.K.setZero();
    b.model.add_hessian(b.q + b.d, b.frames, b.K, mode);
    const int k = b.K.bandwidth();
    for (int i = 0; i < n; ++i)
      for (int j = std::max(0, i - k); j <= std::min(n - 1, i + k); ++j) b.K(i, j) *= h * h;
    for (int i = 0; i < n; ++i) b.K(i, i) += b.mass[i];
    for (int i = 0; i < n; ++i) {
      if (!b.fixed[i]) continue;
      for (int j = std::max(0, i - k); j <= std::min(n - 1, i + k); ++j) b.K(i, j) = b.K(j, i) = 0;
      b.K(i, i) = b.mass[i] > 0 ? b.mass[i] : 1.0;
    }
    return b.lu.factorize(b.K);
  }

  /// Solves the rod's DEL; b.d holds the initial guess on entry (held entries are reset to
  /// target - q) and the solution on exit. On failure b.d is the last iterate.
  template <class Body>
  NewtonReport solve(Body& b, double h) const {
    NewtonReport rep;
    rep.method = "rod DEL: Newton on E_inc, exact Hessian (PSD-projected fallback), Armijo backtracking";
    const Eigen::Index n = b.q.size();
    for (Eigen::Index i = 0; i < n; ++i)
      if (b.fixed[i]) b.d[i] = b.target[i] - b.q[i];
    const double step_tol = prm_.tolerance * b.mean_edge;
    rep.tolerance = step_tol;
    Eigen::VectorXd f(n), dir(n), trial(n);
    double E = potential(b, b.d, h);
    if (!std::isfinite(E)) {
      rep.status = Status::numerical_issue;
      rep.message = "the initial guess is outside the rod model's domain (zero-length or reversed edge)";
      return rep;
    }
    for (int it = 0; it < prm_.max_iterations; ++it) {
      residual(b, b.d, h, f);
      if (it == 0) rep.initial_residual = f.norm();
      rep.final_residual = f.norm();
      if (!f.allFinite()) {
        rep.status = Status::numerical_issue;
        rep.message = fmt::format("non-finite residual at Newton iteration {}", it);
        return rep;
      }
      if (f.squaredNorm() == 0) {
        rep.stop_reason = "zero residual";
        return rep;
      }
      double slope = 0;
      bool descent = false;
      for (HessianMode mode : {HessianMode::exact, HessianMode::projected}) {
        if (relinearize(b, h, mode) != Status::success) continue;
        dir = -f;
        b.lu.solve(dir);
        for (Eigen::Index i = 0; i < n; ++i)
          if (b.fixed[i]) dir[i] = 0;
        slope = f.dot(dir);
        if (dir.allFinite() && slope < 0) {
          descent = true;
          break;
        }
      }
      if (!descent) {
        rep.status = Status::numerical_issue;
        rep.message = fmt::format("no descent direction at Newton iteration {} (|f| = {:.3e})", it, f.norm());
        return rep;
      }
      if (largest_move(dir) <= step_tol) {  // converged: the full (tiny) Newton step, below what E_inc can resolve
        b.d += dir;
        rep.iterations = it + 1;
        residual(b, b.d, h, f);
        rep.final_residual = f.norm();
        rep.stop_reason = "Newton step below tolerance";
        return rep;
      }
      double s = 1;
      double Et = 0;
      int halvings = 0;
      for (;; ++halvings) {
        trial = b.d + s * dir;
        Et = potential(b, trial, h);
        if (Et <= E + prm_.armijo * s * slope) break;
        // Below round-off of E_inc the decrease cannot be resolved: accept the full step if
        // the slope at the trial point is no longer steeply negative (approximate Wolfe).
        if (s == 1 && std::isfinite(Et) && std::abs(Et - E) <= 1e-12 * (std::abs(E) + 1e-300)) break;
        if (halvings >= prm_.max_halvings) {
          rep.status = Status::numerical_issue;
          rep.message = fmt::format("line search failed at Newton iteration {} after {} halvings (|f| = {:.3e})", it,
                                    halvings, f.norm());
          return rep;
        }
        s *= 0.5;
      }
      b.d = trial;
      E = Et;
      rep.iterations = it + 1;
      if (s * largest_move(dir) <= step_tol) {
        residual(b, b.d, h, f);
        rep.final_residual = f.norm();
        rep.stop_reason = "position step below tolerance";
        return rep;
      }
    }
    rep.status = Status::no_convergence;
    rep.message = fmt::format("rod DEL did not converge in {} Newton iterations (|f| = {:.3e})", prm_.max_iterations,
                              rep.final_residual);
    return rep;
  }

 private:
  /// Largest vertex displacement [m] of a DoF vector (the x entries 4i..4i+2).
  static double largest_move(const Eigen::VectorXd& dq) {
    double m = 0;
    for (Eigen::Index i = 0; i + 2 < dq.size(); i += 4) m = std::max(m, dq.segment<3>(i).norm());
    return m;
  }
  Params prm_;
};

}  // namespace weft::integrators
