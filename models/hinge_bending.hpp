#pragma once
/// \file hinge_bending.hpp
/// Discrete-shells hinge bending (methods/shells §6; Grinspun et al. 2003, Tamstorf & Grinspun
/// 2013): one scalar energy psi_e(theta_e) per interior edge of the signed dihedral angle,
/// with the exact gradient psi' grad(theta) and Hessian psi' Hess(theta) + psi'' grad grad^T.
///
/// Two assembly paths share every kernel below: the refactored per-triangle assembly of
/// methods/shells §6.7-§6.9 (Algorithms 1 and 2; the default) and the closed form per hinge
/// (§6.6; the alternative path, the test oracle, and what the projected mode needs). A
/// third path, forward-mode automatic differentiation, lives in bending_autodiff.hpp
/// (benchmark and test oracle only).
#include <Eigen/Core>

#include <array>
#include <span>
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

/// Geometry of one triangle (v0, v1, v2), counter-clockwise about n (methods/shells §1, §6.5).
/// Edge i is opposite v_i and cyclic: e0 = v2 - v1, e1 = v0 - v2, e2 = v1 - v0.
struct TriangleFrame {
  Eigen::Vector3d n;                     ///< unit normal, (v1 - v0) x (v2 - v0) normalised
  double area;                           ///< A
  std::array<Eigen::Vector3d, 3> e;      ///< edge vectors
  std::array<Eigen::Vector3d, 3> e_hat;  ///< unit edge vectors
  std::array<Eigen::Vector3d, 3> m;      ///< m_i = e_hat_i x n: unit, in-plane, outward
  std::array<double, 3> l;               ///< edge lengths l_i
  std::array<double, 3> h;               ///< altitudes from v_i onto edge i, h_i = 2A / l_i
  std::array<double, 3> inv_h;           ///< 1 / h_i = l_i / 2A (stored: the kernels multiply, never divide)
  std::array<double, 3> cos_alpha;       ///< cos of the interior angle at v_i = -e_hat_{i+1} . e_hat_{i+2}
};
/// Not finite (NaN) for a zero-area triangle: check the altitudes before using it.
TriangleFrame triangle_frame(const Eigen::Vector3d& v0, const Eigen::Vector3d& v1, const Eigen::Vector3d& v2);

/// The two triangles of a hinge x0..x3: T = (x0, x1, x2), T~ = (x3, x2, x1) (methods/shells §6.1).
struct HingeFrames {
  TriangleFrame T, Tt;
};
HingeFrames hinge_frames(const Eigen::Vector3d& x0, const Eigen::Vector3d& x1, const Eigen::Vector3d& x2,
                         const Eigen::Vector3d& x3);

/// Signed dihedral angle and half-angle quantities (methods/shells §6.1, Eq. 5.12).
struct HingeAngle {
  double theta;       ///< atan2((n x n~) . e0_hat, n . n~) in [-pi, pi], positive when the normals point apart
  double tan_half;    ///< tan(theta / 2) = sgn((n x n~) . e0) ||n - n~|| / ||n + n~||
  double normal_sum;  ///< ||n + n~|| = 2 cos(theta / 2): 0 when the hinge folds flat onto itself
};
HingeAngle hinge_angle(const HingeFrames& f);
/// The same from the two unit normals and the unit hinge edge as traversed by T.
HingeAngle hinge_angle(const Eigen::Vector3d& n, const Eigen::Vector3d& nt, const Eigen::Vector3d& e_hat);

/// grad(theta), 12-vector over (x0, x1, x2, x3) (methods/shells Eq. 5.4):
///   d/dx0 = -n / h_T(x0),  d/dx3 = -n~ / h_T~(x3),
///   d/dx1 = cos a_T(x2) / h_T(x1) n + cos a_T~(x2) / h_T~(x1) n~,
///   d/dx2 = cos a_T(x1) / h_T(x2) n + cos a_T~(x1) / h_T~(x2) n~.
Vec12 grad_theta(const HingeFrames& f);
/// The same for a hinge whose triangles are labelled by their own (rotated) CCW order: the
/// hinge is edge j of T and edge k of T~, so (x0, x1, x2) = (T.v_j, T.v_{j+1}, T.v_{j+2})
/// and x3 = T~.v_k. `grad_theta(f)` is `grad_theta(f.T, 0, f.Tt, 0)`.
Vec12 grad_theta(const TriangleFrame& T, int j, const TriangleFrame& Tt, int k);

/// Half-hinge contribution of one triangle to Hess(theta), local labels: wing 0, hinge 1, 2
/// (methods/shells §6.6, Eq. 5.6 with the corrections of traps 1 and 2). With M_i = n m_i^T,
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

/// Clamp the negative eigenvalues of a symmetric hinge Hessian to zero. H must annihilate the
/// translations (1 (x) t), as every hinge Hessian does: the decomposition runs on their 9-dim
/// complement.
Mat12 project_psd(const Mat12& H);

/// Refactored per-triangle terms (methods/shells §6.7, Eq. 5.7): the sum over the triangle's three
/// edges of psi'_e times that edge's half hinge, and the matching gradient. With
/// gamma_i = chi_i psi'_i (0 on boundary edges), R_i = gamma_i N_i, N_i = M_i / l_i^2,
///   d_i  = gamma_{i+2} cos a_{i+1} + gamma_{i+1} cos a_{i+2} - gamma_i
///   H_ii = w_ii d_i S(M_i) - sym(R_{i+1}) - sym(R_{i+2}),        sym(R_i) = gamma_i S(M_i) / (2 l_i^2)
///   H_{i,i+1} = w_{i,i+1} (d_i M_{i+1}^T + d_{i+1} M_i) + R_{i+2}^dagger,   H_ji = H_ij^T
///   grad_i = (d_i / h_i) n,
/// dagger = transpose iff this triangle transposes edge i+2 (it traverses the edge, from v_i
/// to v_{i+1}, along the edge's global orientation). The thesis writes -R in the diagonal
/// blocks; of the two triangles of an edge only the sum -(N + N~) is symmetric, so using
/// the symmetric parts gives the same assembled matrix while every triangle's blocks, and
/// hence the assembled matrix, are exactly symmetric.
struct TriangleTerms {
  std::array<Eigen::Matrix3d, 3> diag;   ///< H_ii
  std::array<Eigen::Matrix3d, 3> upper;  ///< H_{i,i+1}
  std::array<Eigen::Vector3d, 3> grad;   ///< (d_i / h_i) n
};
/// `hessian = false` fills `grad` only.
void triangle_terms(const TriangleFrame& t, const std::array<double, 3>& gamma, const std::array<bool, 3>& transpose,
                    bool hessian, TriangleTerms& out);
/// The 9x9 matrix of `TriangleTerms` (local vertex order), for tests.
Mat9 triangle_hessian(const TriangleTerms& terms);

}  // namespace bending

/// How `HingeBending` evaluates its exact Hessian (methods/shells §10.3, "assembly strategy").
enum class BendingAssembly {
  refactored,  ///< per triangle, methods/shells §6.7-§6.9 (Algorithms 1 and 2)
  per_hinge,   ///< closed form per hinge, methods/shells §6.6
};
inline constexpr std::array<std::string_view, 2> bending_assembly_names = {"refactored", "per_hinge"};

/// How `HingeBending` makes a hinge's Hessian positive semi-definite (`HessianMode::projected`,
/// methods/shells §6.12). Gauss-Newton is the default: on the eight-sheet stack at 40k
/// vertices it takes the same Newton and PCG iterations as the eigen-projection and cuts the
/// step by 25 % (bench/results/contact/barrier/README.md).
enum class BendingProjection {
  eigen,         ///< the exact 12x12 Hessian with its eigenvalues clamped to >= 0
  gauss_newton,  ///< max(psi'', 0) grad(theta) grad(theta)^T: drops psi' Hess(theta), no eigen-solve
};
inline constexpr std::array<std::string_view, 2> bending_projection_names = {"eigen", "gauss_newton"};

/// psi = kappa (theta - thetabar)^2 (discrete shells, methods/shells §6.2). theta wraps at +-pi, where
/// this energy is discontinuous; use TanEnergy to keep hinges from folding through.
struct ThetaEnergy {
  static constexpr std::string_view name = "theta";
  static constexpr bool requires_open_interval = false;  ///< theta may approach +-pi
  static bending::Phi phi(const bending::HingeAngle& a) { return {a.theta, 1.0, 0.0}; }
};

/// psi = kappa (phi(theta) - phi(thetabar))^2 with phi = 2 tan(theta / 2) (methods/shells Eq. 5.8):
/// the energy grows without bound as |theta| -> pi, so adjacent triangles cannot fold through.
struct TanEnergy {
  static constexpr std::string_view name = "tan";
  static constexpr bool requires_open_interval = true;  ///< |theta| < pi, ||n + n~|| >= tolerance
  /// phi = 2t, phi' = 1 + t^2, phi'' = t (1 + t^2) with t = tan(theta / 2) (methods/shells §6.3).
  static bending::Phi phi(const bending::HingeAngle& a) {
    const double t = a.tan_half;
    return {2.0 * t, 1.0 + t * t, t * (1.0 + t * t)};
  }
};

namespace bending {
/// psi = kappa (phi - phibar)^2, psi' = 2 kappa (phi - phibar) phi',
/// psi'' = 2 kappa (phi'^2 + (phi - phibar) phi'') (methods/shells §6.3).
template <class AngleFunction>
Psi psi(const HingeAngle& a, double phi_bar, double kappa) {
  const Phi p = AngleFunction::phi(a);
  const double d = p.value - phi_bar;
  return {kappa * d * d, 2.0 * kappa * d * p.d1, 2.0 * kappa * (p.d1 * p.d1 + d * p.d2)};
}

/// Rest data of one hinge. T = (x0, x1, x2) is the owner triangle: the one whose traversal
/// x1 -> x2 follows the edge's global orientation, i.e. the one that transposes N0 (§6.7).
struct HingeRest {
  std::array<int, 4> v{};                ///< x0, x1, x2, x3 (also the order of its element slot)
  std::array<int, 2> face{-1, -1};       ///< mesh faces of T (owner) and T~
  std::array<int, 2> local{-1, -1};      ///< the hinge's local edge index in T and in T~
  int edge = -1;                         ///< mesh edge id
  double theta_bar = 0;                  ///< rest angle [rad]
  double phi_bar = 0;                    ///< phi(theta_bar)
  double kappa = 0;                      ///< k a_e [J], a_e = 3 lbar_e^2 / (Abar_T + Abar_T~)
  std::array<double, 3> rest_length{};   ///< rest lengths of the edges of T (local labels; [0] is the hinge edge)
  std::array<double, 3> rest_length_t{}; ///< rest lengths of the edges of T~ (local labels)
};
}  // namespace bending

/// Hinge bending energy W = sum over interior edges of kappa_e (phi(theta_e) - phi(thetabar_e))^2,
/// kappa_e = k a_e, k = mean of the two faces' `ShellMaterial::bending_k(cos_warp)` for bending
/// across the edge (methods/shells §6.2; docs/materials.md for k from D).
///
/// Domain: a hinge is degenerate when an altitude of one of its triangles drops below
/// `altitude_tolerance` times the rest length of the edge it falls onto, when the hinge edge
/// shrinks below `edge_tolerance` times its rest length, or (TanEnergy) when ||n + n~|| <
/// `normal_tolerance`. Then `admissible()` is false and `energy()` is +infinity, so a line
/// search rejects the state; `add_gradient` / `add_hessian` throw `InvariantError` (callers
/// never evaluate derivatives at inadmissible states).
///
/// Element layout (`declare`). The refactored assembly produces one 3x3-vertex matrix per
/// triangle (H^tri) plus one 4x4-vertex outer product psi'' grad grad^T per interior edge,
/// and the element buffer needs fixed square stencils with one writer per slot. Group 0
/// has one stencil-4 slot per hinge (x0, x1, x2, x3), written only by the hinge's owner
/// triangle T = (x0, x1, x2): it holds the hinge's outer product and, for the first edge
/// the triangle owns, also H^tri(T), whose vertices are the slot's first three. Triangles
/// that own no interior edge (only near the boundary; with the low -> high orientation
/// every triangle transposes one or two of its edges) get a stencil-3 slot in group 1.
/// So the refactored path writes 16 E + 9 F_lone blocks, the per-hinge path (which writes
/// the hinge's 12x12 into the same slot and zeros in group 1) the same, and the matrix
/// pattern is exactly the hinges' pattern. Rejected alternatives: a per-triangle group of
/// stencil 3 plus a stencil-4 group for the outer products gathers 9 F + 16 E blocks
/// (a third more than per hinge); a per-triangle stencil of 6 (triangle + its three wings)
/// couples the wings of different edges, which adds ~6 F spurious blocks to the pattern
/// (fill-in for the linear solver) and gathers 36 blocks per triangle.
///
/// The evaluation uses scratch storage held by the model (pass A/B results), so one model
/// must not be evaluated from two threads at once; each evaluation is parallel inside.
template <class AngleFunction>
class HingeBending {
 public:
  struct Params {
    double altitude_tolerance = 1e-9;  ///< [-] a hinge is degenerate below h < tol * (rest edge length)
    double edge_tolerance = 1e-9;      ///< [-] a hinge is degenerate below l_e < tol * lbar_e
    double normal_tolerance = 1e-8;    ///< [-] TanEnergy only: degenerate below ||n + n~|| < tol (|theta| -> pi)
    /// Exact-Hessian and gradient evaluation: per triangle (default) or per hinge. The
    /// projected Hessian is always per hinge (the refactoring mixes hinges, methods/shells §6.12).
    BendingAssembly assembly = BendingAssembly::refactored;
    BendingProjection projection = BendingProjection::gauss_newton;
    template <class V>
    void visit(V& v) {
      v.field("altitude_tolerance", altitude_tolerance,
              {Unit::none, Range::closed_open(0, 1), "degenerate hinge: triangle altitude below this times the rest edge length"});
      v.field("edge_tolerance", edge_tolerance,
              {Unit::none, Range::closed_open(0, 1), "degenerate hinge: hinge edge below this times its rest length"});
      v.field("normal_tolerance", normal_tolerance,
              {Unit::none, Range::closed_open(0, 2), "tan energy: degenerate hinge when ||n + n~|| falls below this"});
      v.choice("assembly", assembly, bending_assembly_names,
               "exact Hessian and forces per triangle (refactored, thesis Eq. 5.7) or per hinge (closed form); "
               "the projected Hessian is always per hinge");
      v.choice("projection", projection, bending_projection_names,
               "projected Hessian per hinge: eigenvalues of the exact one clamped (eigen), or the Gauss-Newton "
               "term psi'' grad(theta) grad(theta)^T alone, PSD by construction and without an eigen-solve");
    }
  };
  static constexpr std::string_view name = "hinge_bending";
  static constexpr bool stateless = true;  ///< checkpoints: rest angles fixed, the rest is per-call scratch

  /// Rest angles and stiffnesses of every interior edge. \throws ConfigError for degenerate
  /// rest hinges, negative bending stiffness, or (TanEnergy) a rest angle with |thetabar| ~ pi.
  HingeBending(const Scene& scene, const Params& prm);
  /// The same with the global orientation of the edges marked in `flip_edges` (#edges, by
  /// mesh edge id) reversed to high -> low id; it decides which triangle of a hinge
  /// transposes N0 and owns the hinge (methods/shells §9 item 13: the result must not depend on it).
  HingeBending(const Scene& scene, const Params& prm, std::span<const unsigned char> flip_edges);
  static Checker validate(const Params& prm);

  /// Registers group 0 (stencil 4, one slot per hinge) and, if some triangle owns no
  /// interior edge, group 1 (stencil 3, one slot per such triangle).
  void declare(AssemblyPlan& plan);
  /// +infinity if a hinge is degenerate.
  double energy(const State& s) const;
  /// g += dW/dx, by `Params::assembly`.
  void add_gradient(const State& s, Eigen::VectorXd& g) const;
  /// Writes every slot of the model's groups. Exact: by `Params::assembly`; projected:
  /// 12x12 per hinge with its eigenvalues clamped to >= 0. Parallel over elements.
  void add_hessian(const State& s, ElementBuffer& buf, HessianMode mode) const;
  /// Forces and Hessian in one pass (thesis Algorithm 1) along an explicit path:
  /// `g` (if not null) += dW/dx, `buf` (if not null) receives the Hessian as `add_hessian`.
  /// `mode == projected` forces the per-hinge path for the Hessian.
  void evaluate(const State& s, Eigen::VectorXd* g, ElementBuffer* buf, HessianMode mode, BendingAssembly path) const;
  /// Appends ("bending", W).
  void energy_terms(const State& s, EnergyTerms& terms) const;
  /// False if a position is not finite or a hinge is degenerate.
  bool admissible(const State& s) const;

  const Params& params() const { return prm_; }
  int num_hinges() const { return static_cast<int>(hinges_.size()); }
  /// Hinge i. Hinges are numbered by owner triangle (mesh face order), then local edge, so
  /// the refactored loop fills the slots in memory order; `edge` gives the mesh edge.
  const bending::HingeRest& hinge(int i) const { return hinges_[i]; }
  /// Signed dihedral angle of hinge i in state s [rad].
  double angle(const State& s, int i) const;
  /// Triangles with at least one interior edge (the refactored path's element loop).
  int num_active_triangles() const { return static_cast<int>(faces_.size()); }
  /// Active triangles that own no interior edge (the slots of group 1).
  int num_lone_triangles() const { return static_cast<int>(lone_.size()); }
  /// Group ids from `declare` (-1 before, or for an empty group 1).
  int hinge_group() const { return group_; }
  int triangle_group() const { return tri_group_; }

 private:
  enum class Defect { none, edge, altitude, normals };
  /// An active triangle: its vertices (CCW), the hinge of each local edge (-1: boundary),
  /// which of those it owns (transposes), the rest length of each edge, and its slot.
  struct Face {
    std::array<int, 3> v{};
    std::array<int, 3> hinge{-1, -1, -1};
    std::array<bool, 3> owns{};
    std::array<double, 3> rest_length{};
    int slot_hinge = -1;  ///< hinge whose group-0 slot also holds H^tri (first owned edge), or -1
    int slot_edge = -1;   ///< its local edge index j (slot vertex p is local vertex (j + p) mod 3)
    int lone = -1;        ///< slot in group 1 when the triangle owns no interior edge
  };

  bending::HingeFrames frames(const State& s, int i) const;
  Defect check(const bending::HingeFrames& f, const bending::HingeAngle& a, int i) const;
  [[noreturn]] void throw_degenerate(int i, Defect d, std::string_view where) const;
  /// Finds the first degenerate hinge and throws (cold path after a failed evaluation).
  [[noreturn]] void throw_first_degenerate(const State& s, std::string_view where) const;
  void evaluate_refactored(const State& s, Eigen::VectorXd* g, ElementBuffer* buf, std::string_view where) const;
  void evaluate_per_hinge(const State& s, Eigen::VectorXd* g, ElementBuffer* buf, HessianMode mode,
                          std::string_view where) const;

  Params prm_;
  std::vector<bending::HingeRest> hinges_;
  std::vector<int> ids_;  // #hinges*4
  std::vector<Face> faces_;
  std::vector<int> lone_;            // active-face index of each group-1 slot
  std::vector<int> lone_ids_;        // #lone*3
  std::vector<int> hinge_face_[2];   // per hinge: active-face index of T and T~
  std::vector<int> corner_ptr_, corner_;  // per vertex: (active face * 3 + local vertex) incidences
  int group_ = -1, tri_group_ = -1;
  int num_vertices_ = 0;
  Colouring tri_writers_;  // pass C of the refactored path, by the vertices each triangle writes
  // Scratch of the refactored passes (sized in the constructor; never reallocated).
  mutable std::vector<bending::TriangleFrame> frame_;  // pass A, per active face
  mutable std::vector<double> dpsi_, ddpsi_;           // pass B, per hinge
  mutable std::vector<Eigen::Vector3d> corner_grad_;   // pass C, per active face corner
  mutable std::vector<bending::Vec12> hinge_grad_;     // per-hinge path: psi' grad(theta) per hinge
};

extern template class HingeBending<ThetaEnergy>;
extern template class HingeBending<TanEnergy>;
static_assert(EnergyModel<HingeBending<ThetaEnergy>>);
static_assert(EnergyModel<HingeBending<TanEnergy>>);

}  // namespace weft::models
