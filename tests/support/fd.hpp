#pragma once
/// \file fd.hpp
/// Central finite differences for derivative checks (methods/shells §9): energy -> gradient and
/// gradient -> Hessian, with step h = 1e-6 times the mean rest edge length; plus helpers that
/// evaluate a model's analytic gradient and assembled Hessian.
///
/// The stencil is the fourth-order central one, f'(x) ~ (8 (f(x+h) - f(x-h)) - (f(x+2h) - f(x-2h))) / 12h.
/// With the second-order stencil the truncation error is about (h / a)^2 relative, where a is
/// the smallest length the function varies on; for the near-degenerate configurations the
/// spec asks for (an altitude 1e-3 of its edge) that is already ~1e-6, the tolerance itself.
/// The fourth-order stencil leaves rounding (~1e-10 relative) as the only error.
#include <Eigen/Core>

#include <algorithm>
#include <cmath>

#include "framework/block_csr.hpp"
#include "framework/concepts.hpp"
#include "framework/error.hpp"
#include "framework/state.hpp"
#include "framework/triangle_mesh.hpp"

namespace weft::support {

/// Mean rest edge length of a mesh [m].
inline double mean_edge_length(const TriangleMesh& mesh) {
  double sum = 0;
  for (const auto& e : mesh.edges()) sum += (mesh.rest().row(e[0]) - mesh.rest().row(e[1])).norm();
  return mesh.num_edges() > 0 ? sum / mesh.num_edges() : 1.0;
}

/// The finite-difference step of methods/shells §9: 1e-6 times the mean rest edge length.
inline double fd_step(const TriangleMesh& mesh) { return 1e-6 * mean_edge_length(mesh); }

/// Fourth-order central difference of f along coordinate j of x, step h.
template <class F>
auto central_difference(F& f, Eigen::VectorXd& y, Eigen::Index j, double h) {
  const double xj = y[j];
  y[j] = xj + h;
  const auto p1 = f(y);
  y[j] = xj - h;
  const auto m1 = f(y);
  y[j] = xj + 2 * h;
  const auto p2 = f(y);
  y[j] = xj - 2 * h;
  const auto m2 = f(y);
  y[j] = xj;
  return decltype(p1)((8.0 * (p1 - m1) - (p2 - m2)) / (12.0 * h));
}

/// Central differences of a scalar function f(x).
template <class F>
Eigen::VectorXd fd_gradient(F&& f, const Eigen::VectorXd& x, double h) {
  Eigen::VectorXd g(x.size());
  Eigen::VectorXd y = x;
  for (Eigen::Index j = 0; j < x.size(); ++j) g[j] = central_difference(f, y, j, h);
  return g;
}

/// Central differences of a vector function g(x), column by column.
template <class G>
Eigen::MatrixXd fd_jacobian(G&& g, const Eigen::VectorXd& x, double h) {
  Eigen::VectorXd y = x;
  const Eigen::VectorXd g0 = g(x);
  Eigen::MatrixXd J(g0.size(), x.size());
  for (Eigen::Index j = 0; j < x.size(); ++j) J.col(j) = central_difference(g, y, j, h);
  return J;
}

/// The model's analytic gradient at s.
template <class Model>
Eigen::VectorXd gradient(const Model& m, const State& s) {
  Eigen::VectorXd g = Eigen::VectorXd::Zero(s.x.size());
  m.add_gradient(s, g);
  return g;
}

/// Central differences of the model's energy.
template <class Model>
Eigen::VectorXd fd_gradient(const Model& m, const State& s, double h) {
  State t = s;
  return fd_gradient(
      [&](const Eigen::VectorXd& x) {
        t.x = x;
        return m.energy(t);
      },
      s.x, h);
}

/// Central differences of the model's analytic gradient.
template <class Model>
Eigen::MatrixXd fd_hessian(const Model& m, const State& s, double h) {
  State t = s;
  return fd_jacobian(
      [&](const Eigen::VectorXd& x) {
        t.x = x;
        return gradient(m, t);
      },
      s.x, h);
}

/// The model's Hessian assembled through an `AssemblyPlan` (declare, finalize, add_hessian
/// into a copy of the plan's pattern), as a block-sparse matrix. Assembled both ways (direct
/// and stored); the two must agree to round-off, and the direct one is returned.
template <class Model>
BlockCsr assembled_hessian(Model& m, const State& s, HessianMode mode) {
  AssemblyPlan plan;
  m.declare(plan);
  plan.finalize(s.num_vertices());
  BlockCsr H = plan.pattern(), Hs = plan.pattern();
  for (AssemblyMode am : {AssemblyMode::direct, AssemblyMode::stored}) {
    ElementBuffer buf = plan.make_buffer(am);
    BlockCsr& out = am == AssemblyMode::direct ? H : Hs;
    buf.start(out);
    m.add_hessian(s, buf, mode);
    buf.finish();
  }
  double diff = 0, scale = 0;
  bool same_finiteness = true;
  for (size_t k = 0; k < H.values().size(); ++k) {
    const double a = H.values()[k], b = Hs.values()[k];
    same_finiteness &= std::isfinite(a) == std::isfinite(b);
    if (std::isfinite(a) && std::isfinite(b)) {
      diff = std::max(diff, std::abs(a - b));
      scale = std::max(scale, std::abs(b));
    }
  }
  WEFT_ASSERT(same_finiteness && diff <= 1e-13 * scale, "direct and stored assembly differ by {:.3e} (scale {:.3e})", diff, scale);
  return H;
}

/// Dense version of `assembled_hessian`.
template <class Model>
Eigen::MatrixXd dense_hessian(Model& m, const State& s, HessianMode mode) {
  return assembled_hessian(m, s, mode).to_dense();
}

/// ||a - b|| / max(1, ||a||): the methods/shells §9 measure.
inline double spec_error(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).norm() / std::max(1.0, a.norm());
}
/// ||a - b|| / ||a||: the relative error (stricter than `spec_error` when ||a|| < 1).
inline double relative_error(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).norm() / a.norm();
}

}  // namespace weft::support
