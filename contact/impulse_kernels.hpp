#pragma once
/// \file impulse_kernels.hpp
/// The two velocity updates of the `Impulse` strategy (impulse.hpp), as free functions
/// over stacked vectors so that tests can check their conservation laws directly:
///  - `apply_stencil_impulse`: one contact impulse with Coulomb friction on a stencil of
///    vertices with weights gamma (Bridson, Fedkiw & Anderson 2002 §7.1, mass-weighted);
///  - `rigidify_zone`: the rigid velocity field of an impact zone (Provot 1997; Bridson
///    et al. 2002 §7.4).
/// Velocities are the step velocities: end-of-step positions are x1 = x0 + dt v.
#include <Eigen/Core>

#include <array>
#include <span>

namespace weft::contact::impulse {

/// Coulomb friction on a relative tangential velocity u_t, given the change dun >= 0 of the
/// relative normal velocity that the normal impulse made (methods/integration-and-contact §14.1, Bridson 2002 §7.2):
///   |u_t| <= mu dun:  u_t' = 0                              (static: the contact sticks)
///   otherwise:        u_t' = (1 - mu dun / |u_t|) u_t        (kinetic: slides, slower)
/// \returns u_t'.
Eigen::Vector3d coulomb(const Eigen::Vector3d& ut, double mu, double dun);

/// Outcome of one stencil impulse.
struct StencilImpulse {
  bool applied = false;  ///< false when every stencil vertex has infinite mass (nothing can move)
  double normal = 0;     ///< change of the relative normal velocity [m/s]
  double tangential = 0; ///< |change| of the relative tangential velocity [m/s]
  bool sticking = false; ///< friction stopped the relative tangential motion
};

/// Changes the relative velocity u = sum_j gamma_j v_j of a contact stencil (methods/integration-and-contact
/// §11.1: gamma = (1, -w0, -w1, -w2) vertex-triangle, (1 - s, s, -(1 - t), -t) edge-edge,
/// sum gamma = 0) by dun >= 0 along the unit normal n plus Coulomb friction (`coulomb`
/// with the tangential part of u before the impulse). With inverse masses w_j (0 for
/// pinned and scripted vertices: infinite mass) the impulse is distributed as
///   v_j += gamma_j w_j (I_n n + I_t),   I = du / sum_j gamma_j^2 w_j,
/// the mass-weighted form of Bridson et al. 2002 Eq. (7.1) ("I~ = 2 I / (1 + sum w^2)" for
/// equal masses). Then sum_j gamma_j dv_j = du exactly, and when every stencil vertex is
/// free the momentum change sum_j m_j dv_j = I sum_j gamma_j = 0: linear momentum is
/// conserved.
/// \param ids stencil vertex ids  \param inv_mass #V inverse masses  \param v #V*3 velocities (updated)
StencilImpulse apply_stencil_impulse(const std::array<int, 4>& ids, const std::array<double, 4>& gamma,
                                     const Eigen::Vector3d& n, double dun, double mu,
                                     const Eigen::Ref<const Eigen::VectorXd>& inv_mass, Eigen::Ref<Eigen::VectorXd> v);

/// The rigid velocity field of an impact zone (Provot 1997; Bridson et al. 2002 §7.4).
/// Zone vertices are `members` (their velocities are replaced) and `anchors` (velocities
/// kept: pinned, scripted, or held by an obstacle; infinite mass).
///  - Without anchors, the field preserves the zone's linear and angular momentum,
///    measured at the start-of-step positions x0:
///      x_c = sum m x0 / M,  v_c = sum m v / M,  L = sum m r x (v - v_c),  r = x0 - x_c,
///      I = sum m (|r|^2 Id - r r^T),  omega = I^+ L,   v_i <- v_c + omega x r_i.
///    (I^+ is the pseudo-inverse: a collinear zone has no inertia about its line and no
///    angular momentum about it either.)
///  - With anchors, the field is the least-squares rigid fit v_c + omega x (x0 - a_c) to
///    the anchors' velocities (a_c their centroid; a single anchor gives a translation);
///    momentum then changes by the anchors' reaction.
/// The velocity field is linear in x0, so the end positions x1 = x0 + dt v are the image of
/// x0 by the affine map x -> x + dt (v_c + omega x (x - c)), and every intermediate
/// configuration x0 + t dt v by x -> x + t dt (...). Its linear part Id + t dt [omega]_x
/// has determinant 1 + (t dt |omega|)^2 > 0, so the zone moves without any intersection
/// among its own members (an invertible affine map keeps disjoint triangles disjoint).
/// This is the linearised rotation: lengths grow by at most sqrt(1 + (dt |omega|)^2), which
/// the elastic forces undo over the next steps; Bridson et al. rotate exactly, which keeps
/// lengths but not the angular momentum of the step velocities.
/// \param x0 #V*3 start positions  \param mass #V masses  \param v #V*3 velocities (members updated)
void rigidify_zone(std::span<const int> members, std::span<const int> anchors,
                   const Eigen::Ref<const Eigen::VectorXd>& x0, const Eigen::Ref<const Eigen::VectorXd>& mass,
                   Eigen::Ref<Eigen::VectorXd> v);

}  // namespace weft::contact::impulse
