#pragma once
/// \file coulomb.hpp
/// The single-contact Coulomb problem and its solver (methods/rod-contact §9), shared by every
/// strategy that runs Gauss-Seidel over contacts (contact_gauss_seidel.hpp): impulses
/// (D = M^-1), linear compliance (D = A^-1) and ADONIS, on cloth and on rods.
///
/// Problem. In the local frame of a contact (normal first, then two tangents), with W
/// the 3x3 Delassus block (SPD in general; only needs a positive normal response) and
/// b the free relative velocity (the contact's velocity with its own response removed):
///     u = W r + b,   r in K_mu = {|r_t| <= mu r_n},
///     0 <= r_n  _|_  u_n >= 0,   r_t = argmin { r_t . u_t : |r_t| <= mu r_n }.
/// Units are the caller's; in this project r is an impulse [N s] and u a velocity [m/s]
/// (`linear_compliance.hpp`); the rods may use displacements and multipliers instead.
/// The solution is one of (methods/rod-contact §9.1):
///  - take-off: r = 0, b_n >= 0;
///  - stick:    u = 0, r = -W^-1 b inside the cone;
///  - slide:    u_n = 0, |r_t| = mu r_n > 0, r_t = -mu r_n u_t / |u_t|.
///
/// Residual (methods/rod-contact §9.2): the Fischer-Burmeister function on the second-order cone after
/// De Saxcé's change of variable u~ = u + mu |u_t| e_n, with x = s (mu r_n, r_t) and
/// y = (u~_n / mu, u~_t) mapped to the unit cone, phi = x + y - (x o x + y o y)^1/2 (Jordan
/// product, spectral square root); |phi|_2 is the residual. s = tr(W) / 3 scales the
/// response into the units of u, so the residual and its tolerance are velocities. For
/// mu = 0 the scalar FB function on the normal components, together with s |r_t|.
///
/// Solver (methods/rod-contact §9.3, the "hybrid" strategy of Daviet, Bertails-Descoubes & Boissieux
/// 2011 / So-bogus): 1. take-off if b_n >= 0; 2. stick if -W^-1 b lies in the cone
/// (W solved with full pivoting; a singular W is accepted when the least-squares r meets
/// W r + b = 0); 3. slide: a damped semismooth Newton iteration on phi_FB(r) (central
/// finite-difference Jacobian, backtracking on |phi|^2) from the warm start or the
/// projection of the stick solution; 4. failsafe when Newton stalls above the tolerance:
/// the enumerative method in the sliding angle theta: r = r_n (1, mu cos theta,
/// mu sin theta), u_n = 0 gives r_n(theta) = -b_n / (W_nn + mu W_nt . e(theta)), and the
/// remaining scalar equation e(theta) x u_t(theta) = 0 with u_t . e < 0 (u_t anti-parallel
/// to the friction direction) is bracketed on a uniform grid of theta and bisected (the
/// equivalent of So-bogus' quartic in tan(theta / 2), without its polynomial root
/// finding). Among the roots, the one with the smallest residual wins. mu = 0 is solved in
/// closed form (frictionless: r_n = max(0, -b_n / W_nn)).
#include <Eigen/Core>

#include <array>
#include <string_view>

namespace weft::contact {

enum class CoulombRegime {
  take_off,  ///< r = 0
  stick,     ///< u = 0, r inside the cone
  slide,     ///< u_n = 0, r on the cone's boundary, r_t against u_t
  failed,    ///< no admissible solution found (e.g. W_nn <= 0 with b_n < 0); r is the best found
};
inline constexpr std::array<std::string_view, 4> coulomb_regime_names = {"take_off", "stick", "slide", "failed"};

struct CoulombOptions {
  double tolerance = 1e-12;  ///< FB residual to reach, relative to |b| + s |r_guess| (then absolute)
  int max_newton = 50;       ///< Newton iterations before the enumerative failsafe
  int angle_samples = 128;   ///< theta grid of the enumerative failsafe
};

struct CoulombResult {
  Eigen::Vector3d r = Eigen::Vector3d::Zero();  ///< the response (local frame, normal first)
  Eigen::Vector3d u = Eigen::Vector3d::Zero();  ///< W r + b
  double residual = 0;                          ///< |phi_FB(r, u)|, in the units of u
  CoulombRegime regime = CoulombRegime::take_off;
  int newton_iterations = 0;
  bool enumerative = false;  ///< the failsafe produced the result
};

/// The scale s = tr(W) / 3 of the residual (1 when W has no positive trace).
double coulomb_scale(const Eigen::Matrix3d& W);

/// phi_FB(r, u) as a vector (file comment); `scale` as `coulomb_scale`. Its norm is the residual.
Eigen::Vector3d fischer_burmeister_vector(const Eigen::Vector3d& r, const Eigen::Vector3d& u, double mu, double scale);

/// |phi_FB| of a response r and the local velocity u = W r + b (file comment); `scale` as
/// `coulomb_scale`.
double fischer_burmeister(const Eigen::Vector3d& r, const Eigen::Vector3d& u, double mu, double scale);

/// Solves the single-contact problem; `guess` warm-starts the Newton iteration of the
/// slide case (Gauss-Seidel passes the previous response).
CoulombResult solve_coulomb(const Eigen::Matrix3d& W, const Eigen::Vector3d& b, double mu,
                            const Eigen::Vector3d& guess = Eigen::Vector3d::Zero(), const CoulombOptions& opt = {});

}  // namespace weft::contact
