#pragma once
/// \file contact_gauss_seidel.hpp
/// Projected Gauss-Seidel over contacts with the exact single-contact Coulomb solve
/// (methods/rod-contact §10.1, §10.3; `solve_coulomb`, coulomb.hpp), on a Delassus operator that is
/// either an explicit matrix or a compliance that is only applied. Shared by the cloth
/// strategies (linear_compliance.hpp) and the rods (impulse, linear compliance, ADONIS).
///
/// The problem (methods/rod-contact Eq. 7.4): responses r_k (local frame of contact k, normal first),
/// u = W r + u_f with W = H D H^T, H the contact Jacobian (3 rows per contact: normal and
/// two tangents, stencil weights), D the compliance (M^-1 for impulses, A^-1 for linear
/// compliance); every (r_k, u_k) satisfies Signorini-Coulomb.
///
/// The operator (`DelassusOperator`) hides how u is kept: the incremental form of methods/rod-contact
/// §10.3 keeps a running state (x = v_free + D H^T r on the DoFs, or u = W r + u_f) and
/// each update costs one block column. A sweep, per contact k in order:
///     u_k = op.velocity(k);  b_k = u_k - W_kk r_k;  r = solve_coulomb(W_kk, b_k, mu_k, r_k);
///     op.add_response(k, r - r_k);  r_k = r.
/// After the sweep the residual is recomputed with the final state, max_k |phi_FB(r_k, u_k)|
/// (scale tr(W_kk) / 3: velocity units when r is an impulse), and the loop stops below
/// `tolerance` or after `max_sweeps` sweeps. The order is the caller's (deterministic).
///
/// Implementations provided:
///  - `DenseDelassus`: W explicit (3m x 3m, from 3m solves with the compliance; cloth with
///    moderate contact counts), u kept as a vector;
///  - `ComplianceDelassus`: the compliance applied without forming W (the rods: x += P_k dr
///    on the two rods of contact k, u_k = G_k^T x + b^s_k), through two callbacks and the
///    diagonal blocks W_kk.
/// Any other type modelling the concept works (e.g. a rod assembly's own storage of P_k).
#include <Eigen/Core>

#include <algorithm>
#include <concepts>
#include <functional>
#include <span>
#include <vector>

#include "contact/coulomb.hpp"

namespace weft::contact {

/// A Delassus operator W = H D H^T with the state of a Gauss-Seidel solve.
///   `cop.num_contacts()`: m.
///   `cop.block(k)`: W_kk (3x3).
///   `cop.velocity(k)`: u_k = (W r + u_f)_k at the current responses.
///   `op.add_response(k, dr)`: the response of contact k grew by dr; afterwards velocity()
///     reflects it for every contact.
template <class Op>
concept DelassusOperator = requires(Op& op, const Op& cop, int k, const Eigen::Vector3d& dr) {
  { cop.num_contacts() } -> std::convertible_to<int>;
  { cop.block(k) } -> std::convertible_to<Eigen::Matrix3d>;
  { cop.velocity(k) } -> std::convertible_to<Eigen::Vector3d>;
  op.add_response(k, dr);
};

/// Explicit W, u kept as a 3m vector (u = W r + u_f, with the responses given on entry).
class DenseDelassus {
 public:
  /// `W` 3m x 3m, `free_velocity` u_f (3m); responses start at zero.
  DenseDelassus(Eigen::MatrixXd W, const Eigen::VectorXd& free_velocity) : W_(std::move(W)), u_(free_velocity) {}
  int num_contacts() const { return static_cast<int>(u_.size() / 3); }
  Eigen::Matrix3d block(int k) const { return W_.block<3, 3>(3 * k, 3 * k); }
  Eigen::Vector3d velocity(int k) const { return u_.segment<3>(3 * k); }
  void add_response(int k, const Eigen::Vector3d& dr) { u_.noalias() += W_.middleCols<3>(3 * k) * dr; }
  const Eigen::MatrixXd& matrix() const { return W_; }
  const Eigen::VectorXd& velocities() const { return u_; }

 private:
  Eigen::MatrixXd W_;
  Eigen::VectorXd u_;
};

/// The compliance applied, W never formed: the caller keeps its own running state and
/// supplies u_k from it and the update x += D H_k^T dr (e.g. P_k dr with P_k = D H_k^T
/// cached on the bodies of contact k).
class ComplianceDelassus {
 public:
  ComplianceDelassus(std::vector<Eigen::Matrix3d> blocks, std::function<Eigen::Vector3d(int)> velocity,
                     std::function<void(int, const Eigen::Vector3d&)> apply)
      : blocks_(std::move(blocks)), velocity_(std::move(velocity)), apply_(std::move(apply)) {}
  int num_contacts() const { return static_cast<int>(blocks_.size()); }
  Eigen::Matrix3d block(int k) const { return blocks_[k]; }
  Eigen::Vector3d velocity(int k) const { return velocity_(k); }
  void add_response(int k, const Eigen::Vector3d& dr) { apply_(k, dr); }

 private:
  std::vector<Eigen::Matrix3d> blocks_;
  std::function<Eigen::Vector3d(int)> velocity_;
  std::function<void(int, const Eigen::Vector3d&)> apply_;
};

static_assert(DelassusOperator<DenseDelassus>);
static_assert(DelassusOperator<ComplianceDelassus>);

struct GaussSeidelParams {
  double tolerance = 1e-6;  ///< max FB residual over the contacts (units of u)
  int max_sweeps = 200;     ///< >= 1
  CoulombOptions local{};   ///< the single-contact solver
};

struct GaussSeidelReport {
  int contacts = 0;
  int sweeps = 0;
  double residual = 0;     ///< max_k |phi_FB| after the last sweep
  bool converged = false;  ///< residual <= tolerance
  int stick = 0, slide = 0, take_off = 0, failed = 0;  ///< regimes at the last sweep
  int enumerative = 0;     ///< local solves settled by the enumerative failsafe (all sweeps)
};

/// Runs the sweeps. `mu[k]` the friction coefficient of contact k; `r` the responses:
/// resized to m (zeros) when its size differs, else a warm start that `op` must already
/// reflect in its velocities.
template <DelassusOperator Op>
GaussSeidelReport gauss_seidel(Op& op, std::span<const double> mu, std::vector<Eigen::Vector3d>& r,
                               const GaussSeidelParams& prm) {
  GaussSeidelReport rep;
  const int m = op.num_contacts();
  rep.contacts = m;
  if (static_cast<int>(r.size()) != m) r.assign(m, Eigen::Vector3d::Zero());
  if (m == 0) {
    rep.converged = true;
    return rep;
  }
  std::vector<Eigen::Matrix3d> W(m);
  std::vector<double> scale(m);
  for (int k = 0; k < m; ++k) {
    W[k] = op.block(k);
    scale[k] = coulomb_scale(W[k]);
  }
  auto residual = [&] {
    double e = 0;
    for (int k = 0; k < m; ++k) e = std::max(e, fischer_burmeister(r[k], op.velocity(k), mu[k], scale[k]));
    return e;
  };
  rep.residual = residual();
  if (rep.residual <= prm.tolerance) {
    rep.converged = true;
    return rep;
  }
  for (rep.sweeps = 1; rep.sweeps <= prm.max_sweeps; ++rep.sweeps) {
    rep.stick = rep.slide = rep.take_off = rep.failed = 0;
    for (int k = 0; k < m; ++k) {
      const Eigen::Vector3d b = op.velocity(k) - W[k] * r[k];
      const CoulombResult c = solve_coulomb(W[k], b, mu[k], r[k], prm.local);
      switch (c.regime) {
        case CoulombRegime::stick: ++rep.stick; break;
        case CoulombRegime::slide: ++rep.slide; break;
        case CoulombRegime::take_off: ++rep.take_off; break;
        case CoulombRegime::failed: ++rep.failed; break;
      }
      rep.enumerative += c.enumerative ? 1 : 0;
      const Eigen::Vector3d dr = c.r - r[k];
      if (dr.squaredNorm() > 0) op.add_response(k, dr);
      r[k] = c.r;
    }
    rep.residual = residual();
    if (rep.residual <= prm.tolerance) {
      rep.converged = true;
      return rep;
    }
  }
  rep.sweeps = prm.max_sweeps;
  return rep;
}

extern template GaussSeidelReport gauss_seidel<DenseDelassus>(DenseDelassus&, std::span<const double>,
                                                              std::vector<Eigen::Vector3d>&, const GaussSeidelParams&);
extern template GaussSeidelReport gauss_seidel<ComplianceDelassus>(ComplianceDelassus&, std::span<const double>,
                                                                   std::vector<Eigen::Vector3d>&, const GaussSeidelParams&);

}  // namespace weft::contact
