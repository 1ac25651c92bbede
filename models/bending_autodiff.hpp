#pragma once
/// \file bending_autodiff.hpp
/// Third implementation of the hinge-bending derivatives: forward-mode automatic
/// differentiation of the signed dihedral angle (methods/shells §8 reproduction protocol, path "A";
/// §9 item 5). BENCHMARK AND TEST ORACLE ONLY: no simulator uses it.
///
/// theta(x0..x3) = atan2((n x n~) . e0_hat, n . n~) is evaluated on nested Eigen
/// `AutoDiffScalar`s (forward over forward, fixed-size 12-vector derivatives, so nothing is
/// allocated on the heap): the outer derivatives' values give grad(theta), their inner
/// derivatives Hess(theta). psi', psi'' come from the same `bending::psi` as the other two
/// paths, and H = psi' Hess(theta) + psi'' grad grad^T is written into the model's per-hinge
/// slots exactly like `HingeBending`'s per-hinge path (group 1, if any, is zeroed).
#include <Eigen/Core>

#include "framework/block_csr.hpp"
#include "framework/state.hpp"
#include "models/hinge_bending.hpp"

namespace weft::models::bending {

/// theta of one hinge and its first two derivatives over (x0, x1, x2, x3), by forward-mode AD.
struct ThetaDerivatives {
  HingeAngle angle;  ///< theta, tan(theta/2), ||n + n~|| (values of the AD evaluation, via `hinge_angle`)
  Vec12 grad;        ///< grad(theta)
  Mat12 hess;        ///< Hess(theta), symmetrised
};
ThetaDerivatives theta_derivatives_autodiff(const Eigen::Vector3d& x0, const Eigen::Vector3d& x1, const Eigen::Vector3d& x2,
                                            const Eigen::Vector3d& x3);

/// Gradient and/or exact Hessian of `model` at `s` through the AD path: `g` (if not null)
/// += dW/dx, `buf` (if not null) receives every slot of the model's groups. The state must
/// be admissible (`model.admissible(s)`); degenerate hinges are not guarded here.
template <class AngleFunction>
void autodiff_evaluate(const HingeBending<AngleFunction>& model, const State& s, Eigen::VectorXd* g, ElementBuffer* buf);

extern template void autodiff_evaluate(const HingeBending<ThetaEnergy>&, const State&, Eigen::VectorXd*, ElementBuffer*);
extern template void autodiff_evaluate(const HingeBending<TanEnergy>&, const State&, Eigen::VectorXd*, ElementBuffer*);

}  // namespace weft::models::bending
