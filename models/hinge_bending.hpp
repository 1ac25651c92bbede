#pragma once
/// \file hinge_bending.hpp
/// Discrete-shells hinge bending (spec 01 §6; Grinspun et al. 2003, Tamstorf & Grinspun
/// 2013): one scalar energy psi_e(theta_e) per interior edge of the signed dihedral angle,
/// with the exact gradient psi' grad(theta) and Hessian psi' Hess(theta) + psi'' grad grad^T.
///
/// The kernels below are per triangle (`TriangleFrame`, `half_hinge_hessian`) so that the
/// refactored per-triangle assembly of spec 01 §6.7 can reuse them; this version assembles
/// per hinge (§6.6), which is also what the projected mode needs.
#include <Eigen/Core>

#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/concepts.hpp"
#include "framework/params.hpp"
#include "framework/scene.hpp"
#include "framework/state.hpp"

namespace weft::models {

namespace bending {

using Vec12 = Eigen::Matrix<double, 12, 1>;
using Mat9 = Eigen::Matrix<double, 9, 9>;
using Mat12 = Eigen::Matrix<double, 12, 12>;

/// A curvature proxy phi(theta) and its first two derivatives with respect to theta.
struct Phi {
  double value, d1, d2;
};

/// Energy of one hinge and its derivatives with respect to theta.
struct Psi {
  double value, d1, d2;
};

/// Geometry of one triangle (v0, v1, v2), counter-clockwise about n (spec 01 §1, §6.5).
/// Edge i is opposite v_i and cyclic: e0 = v2 - v1, e1 = v0 - v2, e2 = v1 - v0.
struct TriangleFrame {
  Eigen::Vector3d n;                     ///< unit normal, (v1 - v0) x (v2 - v0) normalised
  double area;                           ///< A
  std::array<Eigen::Vector3d, 3> e;      ///< edge vectors
  std::array<Eigen::Vector3d, 3> e_hat;  ///< unit edge vectors
  std::array<Eigen::Vector3d, 3> m;      ///< m_i = e_hat_i x n: unit, in-plane, outward
  std::array<double, 3> l;               ///< edge lengths l_i
  std::array<double, 3> h;               ///< altitudes from v_i onto edge i, h_i = 2A / l_i
  std::array<double, 3> cos_alpha;       ///< cos of the interior angle at v_i = -e_hat_{i+1} . e_hat_{i+2}
};
/// Not finite (NaN) for a zero-area triangle: check the altitudes before using it.
TriangleFrame triangle_frame(const Eigen::Vector3d& v0, const Eigen::Vector3d& v1, const Eigen::Vector3d& v2);

/// The two triangles of a hinge x0..x3: T = (x0, x1, x2), T~ = (x3, x2, x1) (spec 01 §6.1).
struct HingeFrames {
  TriangleFrame T, Tt;
};
HingeFrames hinge_frames(const Eigen::Vector3d& x0, const Eigen::Vector3d& x1, const Eigen::Vector3d& x2,
                         const Eigen::Vector3d& x3);

/// Signed dihedral angle and half-angle quantities (spec 01 §6.1, Eq. 5.12).
struct HingeAngle {
  double theta;       ///< atan2((n x n~) . e0_hat, n . n~) in [-pi, pi], positive when the normals point apart
  double tan_half;    ///< tan(theta / 2) = sgn((n x n~) . e0) ||n - n~|| / ||n + n~||
  double normal_sum;  ///< ||n + n~|| = 2 cos(theta / 2): 0 when the hinge folds flat onto itself
};
HingeAngle hinge_angle(const HingeFrames& f);

/// grad(theta), 12-vector over (x0, x1, x2, x3) (spec 01 Eq. 5.4):
///   d/dx0 = -n / h_T(x0),  d/dx3 = -n~ / h_T~(x3),
///   d/dx1 = cos a_T(x2) / h_T(x1) n + cos a_T~(x2) / h_T~(x1) n~,
///   d/dx2 = cos a_T(x1) / h_T(x2) n + cos a_T~(x1) / h_T~(x2) n~.
Vec12 grad_theta(const HingeFrames& f);

/// Half-hinge contribution of one triangle to Hess(theta), local labels: wing 0, hinge 1, 2
/// (spec 01 §6.6, Eq. 5.6 with the corrections of traps 1 and 2). With M_i = n m_i^T,
/// N_0 = M_0 / l_0^2, w_ij = 1 / (h_i h_j), S(A) = A + A^T:
///   B00 = -w00 S(M0)
///   B11 = w11 cos a2 S(M1) - N0,        B22 = w22 cos a1 S(M2) - N0
///   B10 = w10 (cos a2 M0^T - M1),       B20 = w20 (cos a1 M0^T - M2)
///   B12 = w12 (cos a2 M2^T + cos a1 M1) + N0^dagger,   B_ji = B_ij^T,
/// dagger = transpose, for exactly one of the two triangles of a hinge (`transpose_n0`).
Mat9 half_hinge_hessian(const TriangleFrame& t, bool transpose_n0);

/// Hess(theta), 12x12 over (x0, x1, x2, x3): half hinge of T on (x0, x1, x2) (T transposes
/// N0) plus half hinge of T~ on (x3, x2, x1). Exactly symmetric.
Mat12 hess_theta(const HingeFrames& f);

/// Clamp the negative eigenvalues of a symmetric matrix to zero.
Mat12 project_psd(const Mat12& H);

}  // namespace bending

/// psi = kappa (theta - thetabar)^2 (discrete shells, spec 01 §6.2). theta wraps at +-pi, where
/// this energy is discontinuous; use TanEnergy to keep hinges from folding through.
struct ThetaEnergy {
  static constexpr std::string_view name = "theta";
  static constexpr bool requires_open_interval = false;  ///< theta may approach +-pi
  static bending::Phi phi(const bending::HingeAngle& a) { return {a.theta, 1.0, 0.0}; }
};

/// psi = kappa (phi(theta) - phi(thetabar))^2 with phi = 2 tan(theta / 2) (spec 01 Eq. 5.8):
/// the energy grows without bound as |theta| -> pi, so adjacent triangles cannot fold through.
struct TanEnergy {
  static constexpr std::string_view name = "tan";
  static constexpr bool requires_open_interval = true;  ///< |theta| < pi, ||n + n~|| >= tolerance
  /// phi = 2t, phi' = 1 + t^2, phi'' = t (1 + t^2) with t = tan(theta / 2) (spec 01 §6.3).
  static bending::Phi phi(const bending::HingeAngle& a) {
    const double t = a.tan_half;
    return {2.0 * t, 1.0 + t * t, t * (1.0 + t * t)};
  }
};

namespace bending {
/// psi = kappa (phi - phibar)^2, psi' = 2 kappa (phi - phibar) phi',
/// psi'' = 2 kappa (phi'^2 + (phi - phibar) phi'') (spec 01 §6.3).
template <class AngleFunction>
Psi psi(const HingeAngle& a, double phi_bar, double kappa) {
  const Phi p = AngleFunction::phi(a);
  const double d = p.value - phi_bar;
  return {kappa * d * d, 2.0 * kappa * d * p.d1, 2.0 * kappa * (p.d1 * p.d1 + d * p.d2)};
}

/// Rest data of one hinge.
struct HingeRest {
  std::array<int, 4> v{};                ///< x0, x1, x2, x3
  int edge = -1;                         ///< mesh edge id
  double theta_bar = 0;                  ///< rest angle [rad]
  double phi_bar = 0;                    ///< phi(theta_bar)
  double kappa = 0;                      ///< k a_e [J], a_e = 3 lbar_e^2 / (Abar_T + Abar_T~)
  std::array<double, 3> rest_length{};   ///< rest lengths of the edges of T (local labels; [0] is the hinge edge)
  std::array<double, 3> rest_length_t{}; ///< rest lengths of the edges of T~ (local labels)
};
}  // namespace bending

/// Hinge bending energy W = sum over interior edges of kappa_e (phi(theta_e) - phi(thetabar_e))^2,
/// kappa_e = k a_e, k = mean of the two faces' `ShellMaterial::bending_k()` (spec 01 §6.2).
///
/// Domain: a hinge is degenerate when an altitude of one of its triangles drops below
/// `altitude_tolerance` times the rest length of the edge it falls onto, when the hinge edge
/// shrinks below `edge_tolerance` times its rest length, or (TanEnergy) when ||n + n~|| <
/// `normal_tolerance`. Then `admissible()` is false and `energy()` is +infinity, so a line
/// search rejects the state; `add_gradient` / `add_hessian` throw `InvariantError` (callers
/// never evaluate derivatives at inadmissible states).
template <class AngleFunction>
class HingeBending {
 public:
  struct Params {
    double altitude_tolerance = 1e-9;  ///< [-] a hinge is degenerate below h < tol * (rest edge length)
    double edge_tolerance = 1e-9;      ///< [-] a hinge is degenerate below l_e < tol * lbar_e
    double normal_tolerance = 1e-8;    ///< [-] TanEnergy only: degenerate below ||n + n~|| < tol (|theta| -> pi)
    template <class V>
    void visit(V& v) {
      v.field("altitude_tolerance", altitude_tolerance,
              {Unit::none, Range::closed_open(0, 1), "degenerate hinge: triangle altitude below this times the rest edge length"});
      v.field("edge_tolerance", edge_tolerance,
              {Unit::none, Range::closed_open(0, 1), "degenerate hinge: hinge edge below this times its rest length"});
      v.field("normal_tolerance", normal_tolerance,
              {Unit::none, Range::closed_open(0, 2), "tan energy: degenerate hinge when ||n + n~|| falls below this"});
    }
  };
  static constexpr std::string_view name = "hinge_bending";

  /// Rest angles and stiffnesses of every interior edge. \throws ConfigError for degenerate
  /// rest hinges, negative bending stiffness, or (TanEnergy) a rest angle with |thetabar| ~ pi.
  HingeBending(const Scene& scene, const Params& prm);
  static Checker validate(const Params& prm);

  /// Registers one group of stencil 4 (x0, x1, x2, x3 per hinge).
  void declare(AssemblyPlan& plan);
  /// +infinity if a hinge is degenerate.
  double energy(const State& s) const;
  void add_gradient(const State& s, Eigen::VectorXd& g) const;
  /// 12x12 per hinge; projected: eigenvalues clamped to >= 0. Parallel over hinges.
  void add_hessian(const State& s, ElementBuffer& buf, HessianMode mode) const;
  /// Appends ("bending", W).
  void energy_terms(const State& s, EnergyTerms& terms) const;
  /// False if a position is not finite or a hinge is degenerate.
  bool admissible(const State& s) const;

  int num_hinges() const { return static_cast<int>(hinges_.size()); }
  const bending::HingeRest& hinge(int i) const { return hinges_[i]; }
  /// Signed dihedral angle of hinge i in state s [rad].
  double angle(const State& s, int i) const;

 private:
  enum class Defect { none, edge, altitude, normals };
  bending::HingeFrames frames(const State& s, int i) const;
  Defect check(const bending::HingeFrames& f, const bending::HingeAngle& a, int i) const;
  [[noreturn]] void throw_degenerate(int i, Defect d, std::string_view where) const;

  Params prm_;
  std::vector<bending::HingeRest> hinges_;
  std::vector<int> ids_;  // #hinges*4
  int group_ = -1;
};

extern template class HingeBending<ThetaEnergy>;
extern template class HingeBending<TanEnergy>;
static_assert(EnergyModel<HingeBending<ThetaEnergy>>);
static_assert(EnergyModel<HingeBending<TanEnergy>>);

}  // namespace weft::models
