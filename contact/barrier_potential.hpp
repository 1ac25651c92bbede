#pragma once
/// \file barrier_potential.hpp
/// The local potentials of barrier contact (Li et al. 2020, "Incremental Potential
/// Contact", §4-5; Li et al. 2021, "Codimensional Incremental Potential Contact"): a log
/// barrier on the distance of a contact pair, its parallel-edge mollifier, and smoothed
/// lagged Coulomb friction, each with exact gradient and Hessian.
///
/// **Pairs.** A pair has a stencil of four positions (unused ones ignored):
///  - point_triangle (p; t0, t1, t2) and edge_edge (a0, a1; b0, b1): the distance of the
///    two primitives, d^2 = s(x);
///  - sphere_triangle (c; t0, t1, t2): a sphere of radius R centred at c against a
///    triangle: gap g = dist(c, triangle) - R, s = g^2 (g > 0: the triangle outside);
///  - point_plane (p; q): gap g = n . (p - q) for the unit normal n, s = g^2.
/// Any stencil position may be a constant (an obstacle's): the derivatives are taken with
/// respect to all twelve coordinates and the caller keeps the cloth's.
///
/// **Distance types** (IPC §4.3). The closest points of a point-triangle or edge-edge pair
/// lie in the interiors of the two primitives or on their boundaries; the type of the
/// pair (point-point, point-edge, point-plane, line-line) is read off the closest points
/// at double precision (framework/distance.hpp), and s is then the squared distance of
/// that type, a rational function of the coordinates, smooth inside each type's region
/// and continuous (C^1 in s) across them:
///   PP: |a - b|^2,  PE: |(p - e0) x (e1 - e0)|^2 / |e1 - e0|^2,
///   PT: ((p - t0) . n)^2 / |n|^2 with n = (t1 - t0) x (t2 - t0),
///   EE: ((b0 - a0) . (ea x eb))^2 / |ea x eb|^2.
/// Its derivatives are exact: forward-mode second-order dual numbers over the twelve
/// coordinates (no finite differences, no truncated chain rule).
///
/// **Barrier** (IPC eq. 6, on squared distances):
///   b(s) = -(s - s_hat)^2 ln(s / s_hat) for 0 < s < s_hat,  0 for s >= s_hat,
/// s_hat = d_hat^2 with d_hat the contact thickness: C^2 at s_hat, +infinity as s -> 0.
/// The energy of a pair is kappa m(x) b(s(x)).
///
/// **Parallel-edge mollifier** (IPC §4.3, eq. 13): for edge-edge pairs, with
/// c = |ea x eb|^2 and eps_x = 1e-3 |ea_rest|^2 |eb_rest|^2,
///   m = (2 - c / eps_x) c / eps_x for c < eps_x, 1 beyond,
/// so that the energy stays C^1 when the edges become parallel (where the line-line type
/// hands over to a point-edge type); 1 for every other kind.
///
/// **Friction** (IPC §5, eqs. 14-16): lagged from the start of the step, a pair has its
/// normal force lambda = -d(kappa m b)/d(d) at the start, a tangent basis T (3 x 2,
/// orthonormal, normal to the closest-point direction there) and the closest-point weights
/// gamma (sum_j gamma_j x_j = p^a - p^b). Its relative tangential displacement over the step
/// is u = T^T (sum_j gamma_j (x_j - x0_j)) + u_obstacle (an obstacle's own motion), and
///   D(u) = mu lambda f0(|u|),  f0(y) = -y^3 / (3 eps^2) + y^2 / eps + eps / 3 (y < eps), y beyond,
/// eps = eps_v dt: Coulomb's law with a smooth stick-slip transition below the slip
/// velocity eps_v. Its Hessian mu lambda [f1/y I + (f1' - f1/y) u u^T / y^2] is positive
/// semidefinite everywhere (f1 = f0', both eigenvalues f1/y and f1' are >= 0).
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>

namespace weft::contact::barrier {

using Vec12 = Eigen::Matrix<double, 12, 1>;
using Mat12 = Eigen::Matrix<double, 12, 12>;
using Stencil = std::array<Eigen::Vector3d, 4>;

/// A function of one variable and its first two derivatives.
struct Value2 {
  double f = 0, df = 0, d2f = 0;
};

/// b(s) with s_hat = d_hat^2: +infinity for s <= 0, 0 for s >= s_hat.
Value2 log_barrier(double s, double s_hat);
/// f0, f1 = f0', f1' of the smoothed friction at y >= 0 (eps > 0).
Value2 friction_f0(double y, double eps);
/// The mollifier m(c) with threshold eps_x > 0.
Value2 edge_mollifier(double c, double eps_x);

enum class PairKind : std::uint8_t { point_triangle, edge_edge, sphere_triangle, point_plane };

/// Which distance formula applies and to which stencil positions.
enum class DistanceType : std::uint8_t { point_point, point_edge, point_plane, line_line };
struct TypedDistance {
  DistanceType type = DistanceType::point_plane;
  std::array<std::uint8_t, 4> idx{0, 1, 2, 3};  ///< stencil positions of the formula's arguments
  double s = 0;                                  ///< squared distance of the primitives [m^2]
  std::array<double, 4> gamma{};                 ///< closest-point weights: sum gamma_j x_j = p^a - p^b
};
/// Type, squared distance and weights of a point-triangle (p; t0, t1, t2) or edge-edge
/// (a0, a1; b0, b1) stencil.
TypedDistance point_triangle_type(const Stencil& x);
TypedDistance edge_edge_type(const Stencil& x);

/// The constants of one pair.
struct PairConstants {
  PairKind kind = PairKind::point_triangle;
  double s_hat = 0;    ///< d_hat^2 [m^2]
  double kappa = 0;    ///< barrier stiffness [J / m^4]
  double eps_x = 0;    ///< edge_edge: mollifier threshold (0: no mollifier)
  double radius = 0;   ///< sphere_triangle: R [m]
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< point_plane: unit n
};

/// The gap of a pair (distance, minus R for a sphere; signed for a plane) and its squared
/// value s; s <= 0 or a negative gap means contact or penetration.
double pair_gap(const Stencil& x, const PairConstants& c);
/// kappa m b(s): +infinity at or through contact, 0 beyond d_hat.
double pair_energy(const Stencil& x, const PairConstants& c);
/// kappa m b(s) with its gradient and (when `hessian`) Hessian over the twelve
/// coordinates; returns false (outputs zero) when the pair is beyond d_hat, and the value
/// +infinity at or through contact.
bool pair_derivatives(const Stencil& x, const PairConstants& c, double& value, Vec12& grad, Mat12* hessian);
/// -d(energy)/d(gap) at x: the normal force of the pair [N] (>= 0; 0 beyond d_hat).
double pair_normal_force(const Stencil& x, const PairConstants& c);

/// Lagged friction of one pair (file comment).
struct FrictionPair {
  std::array<double, 4> gamma{};        ///< closest-point weights at the start
  Eigen::Matrix<double, 3, 2> basis;    ///< T, orthonormal, normal to the contact normal
  Eigen::Vector2d offset = Eigen::Vector2d::Zero();  ///< u of the obstacle's own motion
  double mu_lambda = 0;                 ///< mu times the lagged normal force [N]
  double eps = 0;                       ///< eps_v dt [m]
};
/// u = T^T sum_j gamma_j dx_j + offset, for the displacements dx of the four stencil positions.
Eigen::Vector2d tangential_displacement(const FrictionPair& f, const Stencil& dx);
double friction_energy(const FrictionPair& f, const Stencil& dx);
/// Gradient (twelve coordinates of dx) and, when `hessian`, the Hessian (PSD).
void friction_derivatives(const FrictionPair& f, const Stencil& dx, Vec12& grad, Mat12* hessian);
/// An orthonormal basis of the plane normal to the unit vector n.
Eigen::Matrix<double, 3, 2> tangent_basis(const Eigen::Vector3d& n);

}  // namespace weft::contact::barrier
