#pragma once
/// \file discrete_elastic_rod.hpp
/// One discrete elastic rod (Bergou et al. 2008, "Discrete elastic rods"; Bergou et al. 2010,
/// "Discrete viscous threads"; methods/rod-contact §13): stretching, bending and twisting energies of a
/// polyline with one twist angle per edge, with the exact gradient and the exact (or
/// per-stencil PSD-projected) banded Hessian.
///
/// DoFs, interleaved (n = 4V - 1): q = (x0, theta0, x1, theta1, ..., theta_{V-2}, x_{V-1}),
/// x_i = q.segment<3>(4i), theta_j (material angle of edge j) = q[4j + 3]. Edge e_j =
/// x_{j+1} - x_j, tangent t_j = e_j / |e_j|. Every bending/twisting stencil (x_{i-1},
/// theta_{i-1}, x_i, theta_i, x_{i+1}) is the 11 consecutive DoFs starting at 4(i - 1), so the
/// Hessian has half-bandwidth 10 (`BandMatrix` with k = 10).
///
/// Frames (Bergou 2010 §4): every edge carries a reference director d1_j, time-parallel
/// transported from the frames of the start of the step (`RodFrames from`):
///   d1_j(q) = P_{from.t_j -> t_j(q)} from.d1_j,
///   P_{a -> b} v = (a.b) v + (a x b) x v + ((a x b).v) / (1 + a.b) (a x b)   (minimal rotation),
/// material frame m1_j = cos(theta_j) d1_j + sin(theta_j) (t_j x d1_j), m2_j = t_j x m1_j,
/// reference twist at interior vertex i: the signed angle about t_i from P_{t_{i-1} -> t_i} d1_{i-1}
/// to d1_i, on the 2 pi branch nearest from.reference_twist.
///
/// Energies (methods/rod-contact §13, circular cross-section of radius r):
///   stretch  E_s = sum_j 1/2 k_s (|e_j| / |ebar_j| - 1)^2 |ebar_j|,   k_s = Y pi r^2
///   bend     E_b = sum_i sum_{j in {i-1, i}} b / (4 lbar_i) |kappa_i^j - kappabar_i^j|^2,   b = Y pi r^4 / 4
///            kappa_i^j = ((kb)_i . m2_j, -(kb)_i . m1_j)   (Bergou 2008 averages the two edges' frames)
///            (kb)_i = 2 e_{i-1} x e_i / (|e_{i-1}| |e_i| + e_{i-1} . e_i)
///                   = 2 t_{i-1} x t_i / (1 + t_{i-1} . t_i)  -- CURRENT lengths (Bergou 2008), not rest lengths
///            lbar_i = (|ebar_{i-1}| + |ebar_i|) / 2
///   twist    E_t = sum_i k_t / (2 lbar_i) (m_i - mbar_i)^2,   m_i = theta_i - theta_{i-1} + reference twist_i,   k_t = G pi r^4 / 2
/// Rest values (ebar, kappabar, mbar) are those of the rest configuration with the rest frames.
///
/// Exactness. With `from` fixed, the energy is a function of q alone; the directors depend on
/// the tangents through the transport from from.t, which differs from the infinitesimal
/// transport of the textbook formulas by a holonomy rotation about t whenever t != from.t.
/// The derivatives here are those of that function, exact for every admissible q, in closed
/// form: the five frame-dependent scalars of a stencil, (kb . d1_j, kb . (t_j x d1_j)) for both
/// edges and the reference twist, are differentiated with respect to (e_{i-1}, e_i) including
/// the holonomy 1-form of the transport (`rod::stencil_scalars`); the rest of the chain (theta,
/// the quadratic energies, the map from edges to DoFs) is a plain chain rule. An automatic
/// differentiation of the transport itself (`rod::stencil_scalars_autodiff`) is the test oracle.
#include <Eigen/Core>

#include <array>
#include <string_view>
#include <vector>

#include "framework/band_matrix.hpp"
#include "framework/concepts.hpp"
#include "framework/rod_set.hpp"

namespace weft::models {

/// Number of DoFs of a rod with V vertices (V positions and V - 1 twist angles).
inline int rod_dofs(int V) { return 4 * V - 1; }

/// Material of a rod, SI.
struct RodMaterial {
  double radius = 5e-5;   ///< [m] circular cross-section, > 0
  double youngs = 1e9;    ///< [Pa] Young's modulus Y, > 0
  double shear = 3.4e8;   ///< [Pa] shear modulus G, > 0
  double density = 1300;  ///< [kg/m^3] > 0
  double viscosity = 0;   ///< [Pa s] internal viscosity eta (0: none), >= 0
};

/// Reference frame of every edge: unit tangent and reference director d1 (orthogonal to it),
/// and the reference twist at each interior vertex (V - 2 values), all taken at one configuration.
struct RodFrames {
  std::vector<Eigen::Vector3d> tangent, director;  ///< V - 1 each
  std::vector<double> reference_twist;             ///< V - 2 [rad], unwrapped (not reduced to (-pi, pi])
};

/// Rest data of the three energies (elastic rest shape, or the viscous "rest" = start of step).
struct RodRest {
  std::vector<double> length;             ///< |ebar_j|, V - 1
  std::vector<double> voronoi;            ///< lbar_i, V - 2 (index i - 1 for interior vertex i)
  std::vector<Eigen::Vector4d> kappa;     ///< (kappabar_i^{i-1}, kappabar_i^i), V - 2
  std::vector<double> twist;              ///< mbar_i, V - 2
  double ks = 0, kb = 0, kt = 0;          ///< stretch [N], bend [N m^2], twist [N m^2] moduli
};

namespace rod {

/// `from` data of one bending/twisting stencil (interior vertex i): tangent and director of
/// edges i-1 (a) and i (b) at the start of the step, and the reference twist there.
struct StencilFrom {
  Eigen::Vector3d ta, da, tb, db;
  double reference_twist = 0;
};

/// The five frame-dependent scalars of a stencil as functions of (e0, e1) = (e_{i-1}, e_i):
///   s = (kb . d1_{i-1}, kb . d2_{i-1}, kb . d1_i, kb . d2_i, reference twist),  d2 = t x d1,
/// and their gradients (rows of G) and Hessians over the 6-vector (e0, e1).
struct StencilScalars {
  Eigen::Matrix<double, 5, 1> s;
  Eigen::Matrix<double, 5, 6> G;
  std::array<Eigen::Matrix<double, 6, 6>, 5> H;
};
enum class Order { value, gradient, hessian };

/// Closed form (what the model uses). With the holonomy 1-form of the transport from T0,
///   alpha_j = (t_j x T0_j) . dt_j / (1 + T0_j . t_j)   (the extra rotation of d1_j about t_j
///   beyond the infinitesimal transport; T0_j = from.tangent[j]), and dt = (I - t t^T) de / |e|:
///   d(kb . d1) = dkb . d1 + alpha (kb . d2),   d(kb . d2) = dkb . d2 - alpha (kb . d1),
///   d(reference twist) = kb . de_{i-1} / (2 |e_{i-1}|) + kb . de_i / (2 |e_i|) + alpha_i - alpha_{i-1};
/// the Hessians are the exact derivatives of these expressions (alpha is not closed, its
/// derivative is not symmetric; the sums are).
void stencil_scalars(const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, const StencilFrom& from, Order order,
                     StencilScalars& out);
/// The same by forward-over-forward automatic differentiation of the transport itself
/// (test oracle and benchmark only).
void stencil_scalars_autodiff(const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, const StencilFrom& from, Order order,
                              StencilScalars& out);

}  // namespace rod

/// One discrete elastic rod; see the file comment for DoFs, frames, energies and exactness.
class DiscreteElasticRod {
 public:
  static constexpr std::string_view name = "discrete_elastic_rod";
  /// Half-bandwidth of the Hessian.
  static constexpr int bandwidth = 10;

  /// Rest shape from rest_q (rest edge lengths, rest material curvatures, rest twists: a
  /// curly rest shape gives natural curvature). The rest reference frames: the first edge's
  /// director is the unit vector t0 x a_k / |t0 x a_k| with a_k the coordinate axis least
  /// aligned with t0, then space-parallel transport along the rod (rest reference twists 0).
  /// \throws ConfigError for V < 3, a size that is not 4V - 1, a non-positive modulus,
  /// radius or density, a negative viscosity, a zero-length rest edge or a rest fold.
  DiscreteElasticRod(const Eigen::VectorXd& rest_q, const RodMaterial& m);
  /// The same from a scene's rod material (framework/rod_set.hpp).
  DiscreteElasticRod(const Eigen::VectorXd& rest_q, const RodMaterialSpec& m)
      : DiscreteElasticRod(rest_q, RodMaterial{m.radius, m.youngs_modulus, m.shear_modulus, m.density, m.viscosity}) {}

  int num_vertices() const { return V_; }
  int num_dofs() const { return rod_dofs(V_); }
  const RodMaterial& material() const { return mat_; }
  const RodFrames& rest_frames() const { return rest_frames_; }
  const RodRest& rest() const { return rest_; }

  /// Time-parallel transport (Bergou 2010): the frames of configuration q, each edge's
  /// director transported from `from` by the rotation taking from.tangent[j] to the new
  /// tangent (then re-orthonormalised against round-off drift); reference twist unwrapped to
  /// the 2 pi branch nearest from.reference_twist. Requires admissible(q, from).
  RodFrames transport(const RodFrames& from, const Eigen::VectorXd& q) const;

  /// Elastic (+ viscous when enabled) energy [J] with the frames of q = transport(from, q);
  /// +infinity when !admissible(q, from).
  double energy(const Eigen::VectorXd& q, const RodFrames& from) const;
  /// Appends ("stretch", E_s), ("bend", E_b), ("twist", E_t) and, when enabled, ("viscous", E_v).
  void energy_terms(const Eigen::VectorXd& q, const RodFrames& from, weft::EnergyTerms& terms) const;
  /// g += dE/dq (exact). Requires admissible(q, from).
  void add_gradient(const Eigen::VectorXd& q, const RodFrames& from, Eigen::VectorXd& g) const;
  /// H += d2E/dq2: exact, or (HessianMode::projected) every stencil's Hessian projected to
  /// PSD (per edge for stretching, per interior vertex for bending + twisting, elastic and
  /// viscous together). H must be num_dofs() square with bandwidth >= 10. Requires admissible(q, from).
  void add_hessian(const Eigen::VectorXd& q, const RodFrames& from, BandMatrix& H, weft::HessianMode mode) const;

  /// Stretching energy alone (elastic part) [J]; and its gradient / Hessian (g +=, H +=).
  double stretch_energy(const Eigen::VectorXd& q) const;
  void add_stretch_gradient(const Eigen::VectorXd& q, Eigen::VectorXd& g) const;
  void add_stretch_hessian(const Eigen::VectorXd& q, BandMatrix& H, weft::HessianMode mode) const;

  /// n entries: lumped vertex mass rho pi r^2 (|ebar_{i-1}| + |ebar_i|) / 2 on the 3 x entries,
  /// twist inertia 1/2 rho pi r^4 |ebar_j| on the theta entries [kg, kg m^2].
  Eigen::VectorXd mass() const;
  /// max_j |e_j| / |ebar_j| - 1.
  double stretch(const Eigen::VectorXd& q) const;
  /// False for a wrong size or non-finite entry, an edge shorter than 1e-12 of its rest
  /// length, an edge whose tangent is (nearly, 1 + t.from.t <= 1e-12) opposite to
  /// from.tangent (transport undefined), or a fold e_{i-1}.e_i <= -(1 - 1e-12)|e_{i-1}||e_i|.
  bool admissible(const Eigen::VectorXd& q, const RodFrames& from) const;

  /// Viscous threads (Bergou 2010): the same three energies with rest shape = q_start (its
  /// edge lengths, Voronoi lengths, material curvatures and twists, measured with
  /// frames_start transported to q_start) and moduli replaced by stretch 3 eta pi r^2 / dt,
  /// bending 3 eta (pi r^4 / 4) / dt, twist eta pi r^4 / (2 dt). No-op when viscosity is 0.
  void set_viscous_rest(const Eigen::VectorXd& q_start, const RodFrames& frames_start, double dt);
  /// True once set_viscous_rest has enabled the viscous energy.
  bool viscous() const { return viscous_; }

 private:
  struct Sums {
    double stretch = 0, bend = 0, twist = 0, viscous = 0;
  };
  RodRest make_rest(const Eigen::VectorXd& q, const RodFrames& frames, double ks, double kb, double kt) const;
  Sums energies(const Eigen::VectorXd& q, const RodFrames& from) const;
  void evaluate(const Eigen::VectorXd& q, const RodFrames& from, Eigen::VectorXd* g, BandMatrix* H,
                weft::HessianMode mode) const;

  int V_ = 0;
  RodMaterial mat_;
  RodFrames rest_frames_;
  RodRest rest_;
  RodRest visc_;
  bool viscous_ = false;
};

}  // namespace weft::models
