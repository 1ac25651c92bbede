#pragma once
/// \file rod_group_solver.hpp
/// The contact problem of one rod contact group and its two solvers (spec 03 §9, §10.3):
/// Gauss-Seidel over the contacts with the exact single-contact solver (the thesis), and a
/// convergent alternative, a semismooth Newton method on the group's Fischer-Burmeister
/// system (issue 7, the fix the thesis proposes in §14.4).
///
/// Problem. Contact k of the group has the local displacement u_k = G_k^T x + b_k, x the
/// displacements of the group's rods, and x = d_u + sum_l P_l lambda_l (P_l = D G_l, on
/// the rows of the contact's one or two rods). So u = W lambda + c with the Delassus
/// blocks W_kl = G_k^T P_l, nonzero only when contacts k and l share a rod. Coulomb's law
/// on the smooth cone for every contact is Phi(lambda) = 0, Phi_k = phi_FB(lambda_k, u_k)
/// (contact/coulomb.hpp: De Saxce's change of variable, then the Fischer-Burmeister
/// function of the second-order cone, in the units of u; |Phi_k| is the contact's residual).
///
/// Newton (`solve_contacts_newton`). From the current multipliers (Gauss-Seidel's):
///  1. the local derivatives A_k = dPhi_k/dlambda_k and B_k = dPhi_k/du_k, exact
///     (`fischer_burmeister_jacobian`, nudged off the kinks of the cone where it is not
///     defined); contacts with lambda_k = 0 and u_{k,n} > 0 (take-off) keep lambda_k = 0 and
///     leave the system;
///  2. the Newton step on the others with the regularised Jacobian A + B (W + rho S), S the
///     contacts' scales and rho = clamp(residual / |u|, 1e-10, 1e-3) shrinking with the
///     residual (dense LU up to `dense_limit` unknowns, sparse LU beyond; W assembled once per
///     solve);
///  3. Armijo backtracking on the merit 1/2 |Phi|^2 of the unregularised problem; the step is
///     applied to x through the P_k, and u recomputed from x;
///  4. when that step does not divide the merit by 4 (redundant contacts make J singular and
///     the load split between them non-unique), two steps compete and the lowest merit wins:
///     the stick step (every pressed contact sticks: one linear system u_k + (W delta)_k = 0
///     with a 1e-10 s diagonal, which keeps the split of exact duplicates) and a lightly
///     regularised Levenberg-Marquardt step (J^T J + nu I) delta = -J^T Phi; when none
///     decreases the merit, nu is raised, then `fallback_sweeps` Gauss-Seidel sweeps.
/// Known limit: two near-duplicate contacts on a sliding rod (the same crossing found from
/// two edges) stall it near 1e-9 m; the detection merges them (rod_detection.hpp,
/// `merge_fraction`, `merge_angle`), with which the V-06/V-07, V-13 and V-14 tests pass.
/// With merging off (merge_fraction = 0) the stall comes back.
/// It stops when max_k |Phi_k| <= tolerance, after `max_iterations` steps, or when the
/// fallbacks stop making progress; it returns the best iterate (smallest max_k |Phi_k|),
/// so it is never worse than the Gauss-Seidel iterate it starts from. Semismooth Newton on
/// the SOC Fischer-Burmeister function: Fukushima, Luo & Tseng 2002; on the frictional
/// contact of rods with a merit line search: Bertails-Descoubes et al. 2011 (for the
/// Alart-Curnier function).
#include <Eigen/Core>

#include <array>
#include <utility>
#include <vector>

#include "contact/rods/rod_detection.hpp"

namespace weft::contact::rods {

/// One contact of a step: where it acts, its basis and its compliance columns.
struct RodContactRows {
  RodContact geometry;
  std::array<int, 2> rods{-1, -1};           ///< distinct rods touched (second -1 for self and obstacle contacts)
  std::array<int, 2> slot{-1, -1};          ///< their positions in the group's rod list (set by the group solve)
  std::array<Eigen::MatrixXd, 2> G, P;       ///< per touched rod: n_r x 3 columns of G_k and of D G_k
  Eigen::Vector3d b = Eigen::Vector3d::Zero();  ///< scripted part of u_k
  Eigen::Matrix3d W = Eigen::Matrix3d::Zero();  ///< G_k^T D G_k
  Eigen::Vector3d lambda = Eigen::Vector3d::Zero();
  double mu = 0;
  double scale = 1;                          ///< coulomb_scale(W)
};

/// The rods' displacements of a group, by slot.
using GroupDisplacements = std::vector<Eigen::VectorXd>;

/// u_k = G_k^T x + b_k.
Eigen::Vector3d local_displacement(const RodContactRows& k, const GroupDisplacements& x);
/// x += P_k r.
void add_response(const RodContactRows& k, const Eigen::Vector3d& r, GroupDisplacements& x);
/// An element of the generalised Jacobian of phi_FB(r, u) (contact::fischer_burmeister_vector):
/// A = dphi/dr and B = dphi/du, exact where phi is differentiable (file comment).
void fischer_burmeister_jacobian(const Eigen::Vector3d& r, const Eigen::Vector3d& u, double mu, double scale, Eigen::Matrix3d& A,
                                 Eigen::Matrix3d& B);
/// max over the contacts `ids` of |phi_FB(lambda_k, G_k^T x + b_k)|, in the units of u.
double contact_error(const std::vector<RodContactRows>& cs, const std::vector<int>& ids, const GroupDisplacements& x);

/// Which problem a Gauss-Seidel sweep solves per contact.
enum class SweepMode {
  coulomb,   ///< the full single-contact Coulomb problem (contact/coulomb.hpp)
  normal,    ///< the normal multiplier, the tangential ones fixed (staggered projections)
  friction,  ///< the tangential multipliers on their disk, the normal one fixed (staggered projections)
};

/// One Gauss-Seidel sweep over the contacts `ids` in that order (spec 03 §10.3, incremental
/// form: x is kept equal to d_u + sum_k P_k lambda_k). Returns the largest change and the
/// largest size of a multiplier in the sweep, both in the units of u (times `scale`).
std::pair<double, double> gauss_seidel_sweep(std::vector<RodContactRows>& cs, const std::vector<int>& ids, GroupDisplacements& x,
                                             SweepMode mode);

/// Options of the Newton contact solver (the rod strategies fill them from their params).
struct NewtonContactOptions {
  double tolerance = 1e-8;   ///< [units of u] max_k |Phi_k| to reach
  int max_iterations = 50;   ///< Newton and fallback steps
  int fallback_sweeps = 10;  ///< Gauss-Seidel sweeps of the last fallback
  int dense_limit = 1500;    ///< dense LU up to this many unknowns (3 per contact left in the system), sparse LU beyond
};

/// What a Newton contact solve did.
struct NewtonContactResult {
  int iterations = 0;  ///< steps taken (Newton and fallbacks)
  int fallbacks = 0;   ///< of which Levenberg-Marquardt or Gauss-Seidel
  int stick_steps = 0; ///< of which stick steps (the pressed contacts' linear stick system)
  int sweeps = 0;      ///< Gauss-Seidel sweeps of the fallbacks
  double residual = 0; ///< max_k |Phi_k| at exit (the best iterate)
};

/// Semismooth Newton on the group's Fischer-Burmeister system (file comment), from the
/// multipliers in `cs` and the consistent displacements x; both are updated.
NewtonContactResult solve_contacts_newton(std::vector<RodContactRows>& cs, const std::vector<int>& ids, GroupDisplacements& x,
                                          const NewtonContactOptions& opt);

}  // namespace weft::contact::rods
