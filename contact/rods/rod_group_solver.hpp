#pragma once
/// \file rod_group_solver.hpp
/// The contact problem of one rod contact group and its two solvers (methods/rod-contact §9, §10.3):
/// Gauss-Seidel over the contacts with the exact single-contact solver (the thesis), and a
/// convergent alternative, a semismooth Newton method on the group's Fischer-Burmeister
/// system (the fix the thesis proposes in §14.4).
///
/// Problem. Contact k of the group has the local displacement u_k = G_k^T x + b_k, x the
/// displacements of the group's rods, and x = d_u + sum_l P_l lambda_l (P_l = D G_l, on
/// the rows of the contact's one or two rods). So u = W lambda + c with the Delassus
/// blocks W_kl = G_k^T P_l, nonzero only when contacts k and l share a rod. Coulomb's law
/// on the smooth cone for every contact is Phi(lambda) = 0, Phi_k = phi_FB(lambda_k, u_k)
/// (contact/coulomb.hpp: De Saxce's change of variable, then the Fischer-Burmeister
/// function of the second-order cone, in the units of u; |Phi_k| is the contact's residual).
///
/// Newton (`solve_contacts_newton`): contact/contact_newton.hpp's semismooth Newton on this
/// group, with W assembled once per solve (blocks only where contacts share a rod), u read
/// from x (x kept equal to d_u + sum_k P_k lambda_k) and Gauss-Seidel sweeps of this file
/// as the last fallback.
/// Known limit: two near-duplicate contacts on a sliding rod (the same crossing found from
/// two edges) stall it near 1e-9 m; the detection merges them (rod_detection.hpp,
/// `merge_fraction`, `merge_angle`), with which the V-06/V-07, V-13 and V-14 tests pass.
/// With merging off (merge_fraction = 0) the stall comes back.
#include <Eigen/Core>

#include <array>
#include <utility>
#include <vector>

#include "contact/contact_newton.hpp"
#include "contact/rods/rod_detection.hpp"

namespace weft::contact::rods {

/// One contact of a step: where it acts, its basis and its compliance columns.
struct RodContactRows {
  RodContact geometry;
  std::array<int, 2> rods{-1, -1};           ///< distinct rods touched (second -1 for self and obstacle contacts)
  std::array<int, 2> slot{-1, -1};          ///< their positions in the group's rod list (set by the group solve)
  std::array<Eigen::MatrixXd, 2> G, P;       ///< per touched rod: n_r x 3 columns of G_k and of D G_k
  /// Per touched rod, the vertices whose three position rows of G_k may be nonzero (the
  /// contact's stencil: at most 4), so that G_k^T x reads 3-12 rows instead of n_r;
  /// blocks[side] < 0: G_k is read whole (a G_k built by hand, as in the tests).
  std::array<std::array<int, 4>, 2> stencil{};
  std::array<int, 2> blocks{-1, -1};
  Eigen::Vector3d b = Eigen::Vector3d::Zero();  ///< scripted part of u_k
  Eigen::Matrix3d W = Eigen::Matrix3d::Zero();  ///< G_k^T D G_k
  Eigen::Vector3d lambda = Eigen::Vector3d::Zero();
  Eigen::Vector3d lambda_first = Eigen::Vector3d::Zero();  ///< lambda after the first constrained Newton iteration of the last round
  double mu = 0;
  double scale = 1;                          ///< coulomb_scale(W)
  bool follows = false;                      ///< an end-overlap contact that moves with its edge pair (contact.overlap_follow)
  int moves = 0;                             ///< follows: how often the pair's follower moved in this step (contact.overlap_keep)
};

/// The rods' displacements of a group, by slot.
using GroupDisplacements = std::vector<Eigen::VectorXd>;

/// u_k = G_k^T x + b_k.
Eigen::Vector3d local_displacement(const RodContactRows& k, const GroupDisplacements& x);
/// x += P_k r.
void add_response(const RodContactRows& k, const Eigen::Vector3d& r, GroupDisplacements& x);
using contact::fischer_burmeister_jacobian;
using contact::NewtonContactOptions;
using contact::NewtonContactResult;

/// max over the contacts `ids` of |phi_FB(lambda_k, G_k^T x + b_k)|, in the units of u.
double contact_error(const std::vector<RodContactRows>& cs, const std::vector<int>& ids, const GroupDisplacements& x);

/// Which problem a Gauss-Seidel sweep solves per contact.
enum class SweepMode {
  coulomb,   ///< the full single-contact Coulomb problem (contact/coulomb.hpp)
  normal,    ///< the normal multiplier, the tangential ones fixed (staggered projections)
  friction,  ///< the tangential multipliers on their disk, the normal one fixed (staggered projections)
};

/// One Gauss-Seidel sweep over the contacts `ids` in that order (methods/rod-contact §10.3, incremental
/// form: x is kept equal to d_u + sum_k P_k lambda_k). Returns the largest change and the
/// largest size of a multiplier in the sweep, both in the units of u (times `scale`).
std::pair<double, double> gauss_seidel_sweep(std::vector<RodContactRows>& cs, const std::vector<int>& ids, GroupDisplacements& x,
                                             SweepMode mode);

/// Semismooth Newton on the group's Fischer-Burmeister system (contact_newton.hpp), from the
/// multipliers in `cs` and the consistent displacements x; both are updated.
NewtonContactResult solve_contacts_newton(std::vector<RodContactRows>& cs, const std::vector<int>& ids, GroupDisplacements& x,
                                          const NewtonContactOptions& opt);

}  // namespace weft::contact::rods
