#pragma once
/// \file contact_newton.hpp
/// A convergent solver of the multi-contact Coulomb problem: semismooth Newton on the
/// contacts' Fischer-Burmeister system (the fix the thesis proposes in §14.4 for
/// the Gauss-Seidel that does not converge). Shared by the rods (rod_group_solver.hpp, a
/// block-sparse W per contact group) and the cloth's linear compliance
/// (linear_compliance.hpp, W dense).
///
/// Problem. m contacts with multipliers lambda_k and local velocities or displacements
/// u = W lambda + c (W the Delassus operator, symmetric positive semidefinite); Coulomb's
/// law on the smooth cone for every contact is Phi(lambda) = 0, Phi_k = phi_FB(lambda_k,
/// u_k) (contact/coulomb.hpp: De Saxce's change of variable, then the Fischer-Burmeister
/// function of the second-order cone, in the units of u; |Phi_k| is the contact's residual).
/// The state (lambda and whatever u is computed from) stays with the caller, which reads
/// and updates it through `NewtonContactProblem`.
///
/// Newton. From the current multipliers (typically Gauss-Seidel's):
///  1. the local derivatives A_k = dPhi_k/dlambda_k and B_k = dPhi_k/du_k, exact
///     (`fischer_burmeister_jacobian`, nudged off the kinks of the cone where it is not
///     defined); contacts with lambda_k = 0 and u_{k,n} > 0 (take-off) keep lambda_k = 0 and
///     leave the system;
///  2. the Newton step on the others with the regularised Jacobian A + B (W + rho S), S the
///     contacts' scales and rho = clamp(residual / |u|, 1e-10, 1e-3) shrinking with the
///     residual (dense LU up to `dense_limit` unknowns, sparse LU beyond);
///  3. Armijo backtracking on the merit 1/2 |Phi|^2 of the unregularised problem; the step is
///     handed to the caller (`apply`), which updates its state, and u is read back from it;
///  4. when that step does not divide the merit by 4 (redundant contacts make J singular and
///     the load split between them non-unique), two steps compete and the lowest merit wins:
///     the stick step (every pressed contact sticks: one linear system u_k + (W delta)_k = 0
///     with a 1e-10 s diagonal, which keeps the split of exact duplicates) and a lightly
///     regularised Levenberg-Marquardt step (J^T J + nu I) delta = -J^T Phi (in the sparse
///     path only when neither the Newton nor the stick step decreases the merit:
///     `sparse_lm_only_when_stuck`); when none decreases the merit, nu is raised, then
///     `fallback_sweeps` Gauss-Seidel sweeps (the caller's `sweep`).
/// It stops when max_k |Phi_k| <= tolerance, after `max_iterations` steps, or when the
/// fallbacks stop making progress; it returns to the best iterate (smallest max_k |Phi_k|),
/// so it is never worse than the iterate it starts from. Semismooth Newton on the SOC
/// Fischer-Burmeister function: Fukushima, Luo & Tseng 2002; on frictional contact with a
/// merit line search: Bertails-Descoubes et al. 2011 (for the Alart-Curnier function).
#include <Eigen/Core>

#include <array>
#include <functional>
#include <span>
#include <string_view>
#include <vector>

#include "contact/contact_gauss_seidel.hpp"

namespace weft::contact {

/// The multi-contact solve of a contact strategy (rods and cloth's linear compliance): the
/// scene key `contact.solver`.
enum class ContactSolver {
  gauss_seidel,  ///< Gauss-Seidel sweeps up to the sweep limit (the thesis): may stop above the tolerance
  newton,        ///< Gauss-Seidel, then semismooth Newton to the tolerance (this file)
};
inline constexpr std::array<std::string_view, 2> contact_solver_names = {"gauss_seidel", "newton"};

/// A nonzero 3x3 block W_ij of block row i (j: `col`).
struct DelassusBlock {
  int col;
  Eigen::Matrix3d w;
};
/// W by block rows, each sorted by column; only nonzero blocks need be present.
using DelassusRows = std::vector<std::vector<DelassusBlock>>;

/// An element of the generalised Jacobian of phi_FB(r, u) (contact::fischer_burmeister_vector):
/// A = dphi/dr and B = dphi/du, exact where phi is differentiable (file comment).
void fischer_burmeister_jacobian(const Eigen::Vector3d& r, const Eigen::Vector3d& u, double mu, double scale, Eigen::Matrix3d& A,
                                 Eigen::Matrix3d& B);

/// Options of the Newton contact solver.
struct NewtonContactOptions {
  double tolerance = 1e-8;   ///< [units of u] max_k |Phi_k| to reach
  int max_iterations = 50;   ///< Newton and fallback steps
  int fallback_sweeps = 10;  ///< Gauss-Seidel sweeps of the last fallback
  int dense_limit = 1500;    ///< dense LU up to this many unknowns (3 per contact left in the system), sparse LU beyond
  /// Sparse systems (beyond dense_limit): the Levenberg-Marquardt step competes with the
  /// Newton and stick steps only when neither decreases the merit (false: whenever they
  /// fall short of a quarter of it, as in the dense path)
  bool sparse_lm_only_when_stuck = true;
};

/// What a Newton contact solve did.
struct NewtonContactResult {
  int iterations = 0;  ///< steps taken (Newton and fallbacks)
  int fallbacks = 0;   ///< of which Levenberg-Marquardt or Gauss-Seidel
  int stick_steps = 0; ///< of which stick steps (the pressed contacts' linear stick system)
  int sweeps = 0;      ///< Gauss-Seidel sweeps of the fallbacks
  double residual = 0; ///< max_k |Phi_k| at exit (the best iterate)
};

/// The problem as the solver sees it; the state lives with the caller.
struct NewtonContactProblem {
  const DelassusRows* W = nullptr;  ///< m block rows
  std::span<const double> mu;       ///< friction coefficient per contact
  std::span<const double> scale;    ///< coulomb_scale(W_kk) per contact
  /// The current multipliers and u = W lambda + c (3m each; sized by the solver).
  std::function<void(Eigen::VectorXd& lambda, Eigen::VectorXd& u)> read;
  /// lambda += step (3m, zero blocks for untouched contacts); u follows.
  std::function<void(const Eigen::VectorXd& step)> apply;
  /// `sweeps` Gauss-Seidel sweeps from the current state (the last fallback).
  std::function<void(int sweeps)> sweep;
};

/// Semismooth Newton on the Fischer-Burmeister system (file comment).
NewtonContactResult solve_contacts_newton(const NewtonContactProblem& p, const NewtonContactOptions& opt);

/// The same on an explicit W (`DenseDelassus`, u kept by `op`), from the responses `r`
/// (resized to m zeros when its size differs; else `op` must already reflect them); the
/// fallback sweeps are `gauss_seidel` with `local`. Blocks of W that are exactly zero are
/// left out of the Jacobian.
NewtonContactResult solve_contacts_newton(DenseDelassus& op, std::span<const double> mu, std::vector<Eigen::Vector3d>& r,
                                          const NewtonContactOptions& opt, const CoulombOptions& local = {});

}  // namespace weft::contact
