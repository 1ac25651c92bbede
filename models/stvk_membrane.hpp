#pragma once
/// \file stvk_membrane.hpp
/// St. Venant–Kirchhoff membrane on constant-strain triangles, in the edge-based form of
/// methods/shells §4 (thesis §4.5): per triangle the edge elongations s_i = 1/2 (l_i^2 - lbar_i^2),
/// a precomputed symmetric 3x3 matrix T, and W = s^T T s. Isotropic and orthotropic
/// materials differ only in how T is precomputed; the runtime kernel is the same.
#include <Eigen/Core>

#include <array>
#include <string_view>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/concepts.hpp"
#include "framework/scene.hpp"
#include "framework/state.hpp"

namespace weft::models {

/// Isotropic membrane: accepts `model = isotropic` materials only (a = b = 0 in T).
struct Isotropic {
  static constexpr std::string_view name = "isotropic";
  static constexpr bool accepts_orthotropic = false;
};

/// Orthotropic membrane (methods/shells §3.2, §4.3): T gains the terms 2b T3 + a T4 of a direction
/// per face (`Scene::face_warp`). Accepts isotropic materials too, as the special case
/// eta = 1, G = Y / (1 + nu) (then a = b = 0). Same per-element cost as `Isotropic`.
struct Orthotropic {
  static constexpr std::string_view name = "orthotropic";
  static constexpr bool accepts_orthotropic = true;
};

namespace membrane {

using Mat9 = Eigen::Matrix<double, 9, 9>;
using Vec9 = Eigen::Matrix<double, 9, 1>;

/// Material constants of the quadratic StVK density (methods/shells §3.2, Eq. 4.4):
///   psi = lambda/2 J1^2 + mu J2 + a J1 J3 + b J3^2,  J3 = ahat^T E ahat.
struct LameConstants {
  double lambda = 0;  ///< [Pa]
  double mu = 0;      ///< [Pa]
  double a = 0;       ///< [Pa] orthotropic coupling J1 J3
  double b = 0;       ///< [Pa] orthotropic J3^2
  bool orthotropic() const { return a != 0 || b != 0; }
};

/// Plane-stress Lamé constants of an isotropic sheet (methods/shells Eq. 4.2):
///   lambda = Y nu / (1 - nu^2), mu = Y / (2 (1 + nu)), a = b = 0.
LameConstants isotropic_lame(double youngs_modulus, double poisson_ratio);

/// Orthotropic constants (methods/shells Eq. 4.4) in the symbols of methods/shells §3.2, x = ahat_perp, y = ahat:
///   lambda = Y / (1 - eta nu^2) - G,           mu = G / 2,
///   a = (eta nu - 1) / (1 - eta nu^2) Y + G,   b = (1 + eta - 2 eta nu) / (2 (1 - eta nu^2)) Y - G,
/// \param Y Young's modulus along x [Pa]  \param eta Y_y / Y_x  \param nu nu_xy
/// \param G the thesis' shear constant, the Voigt entry of *tensor* shear strain: G = 2 G12
///        (engineering shear modulus G12; methods/shells §0 trap 4). Isotropy: eta = 1, G = Y/(1+nu).
LameConstants orthotropic_lame(double Y, double eta, double nu, double G);

/// Constants of a scene material in the project's warp/weft convention (see `ShellMaterial`:
/// x = warp, y = weft): Y = youngs_modulus_warp, eta = Y_weft / Y_warp, nu = poisson_ratio,
/// G = 2 shear_modulus; isotropic materials through `isotropic_lame`.
LameConstants material_lame(const ShellMaterial& m);

/// Twice the area of the triangle (v0, v1, v2).
double double_area(const Eigen::Vector3d& v0, const Eigen::Vector3d& v1, const Eigen::Vector3d& v2);

/// The intrinsic rest shape of one element: everything T depends on besides the material
/// (methods/shells §5). Static rest states and animated ones (blended edge lengths) go through the
/// same `element_matrix`.
struct RestShape {
  Eigen::Vector3d length2 = Eigen::Vector3d::Zero();  ///< lbar_i^2 of the cyclic edges [m^2]
  /// (w0, w1): the warp direction ahat_perp = w0 ebar_0 + w1 ebar_1 in the rest plane (methods/shells
  /// §5: the 2x2 Gram solve in the true rest configuration). Any nonzero length (normalised
  /// in `element_matrix`); zero when the element has no direction (isotropic).
  Eigen::Vector2d warp = Eigen::Vector2d::Zero();
};

/// Rest shape from rest vertices (rows v0, v1, v2) and a warp direction (any length; the
/// component normal to the rest plane drops out of the Gram solve; zero for none).
RestShape rest_shape(const Eigen::Matrix3d& rest, const Eigen::Vector3d& warp = Eigen::Vector3d::Zero());

/// The element matrix T of methods/shells Eq. 4.8 from edge lengths only (§4.3–4.4, §5):
///   T = h / (32 Abar^3) (lambda T1 + mu T2 + 2 b T3 + a T4),
///   T1_il = d_{i+1,i+2} d_{l+1,l+2},
///   T2_il = d_{i+2,l+1} d_{i+1,l+2} + d_{i+2,l+2} d_{i+1,l+1},
///   T3_il = beta_{i+1} beta_{i+2} beta_{l+1} beta_{l+2},
///   T4_il = d_{i+1,i+2} beta_{l+1} beta_{l+2} + d_{l+1,l+2} beta_{i+1} beta_{i+2},
/// indices mod 3, with
///   Abar by Heron's formula (Kahan's stable form, `triangle_area`),
///   d_ii = lbar_i^2, d_jk = ebar_j . ebar_k = 1/2 (lbar_i^2 - lbar_j^2 - lbar_k^2)   (Eq. 4.10, {i,j,k} = {0,1,2}),
///   beta_i = ahat_perp . ebar_i / ||ahat_perp|| = (w0 d_0i + w1 d_1i) / sqrt(w^T [d_00 d_01; d_01 d_11] w)
/// (= -ahat . mbar_i with mbar_i = nbar x ebar_i; the sign is immaterial: only products
/// beta_j beta_k occur). The normalisation by ||ahat_perp|| is methods/shells §5's [L] addition: T3,
/// T4 assume a unit direction.
/// \returns false (T untouched) when the lengths are not a proper triangle (`proper_triangle`).
bool element_matrix(const RestShape& rest, double thickness, const LameConstants& c, Eigen::Matrix3d& T);

/// `element_matrix` of rest vertices (rows v0, v1, v2; non-degenerate) with the structural
/// direction ahat (methods/shells §3.2 y axis, unit, in the rest plane; only read when a or b is
/// nonzero, may be zero otherwise), i.e. warp = nbar x ahat.
Eigen::Matrix3d stvk_T(const Eigen::Matrix3d& rest, double thickness, const LameConstants& c,
                       const Eigen::Vector3d& direction = Eigen::Vector3d::Zero());

/// Rest data of one element, all the runtime kernel reads.
struct Element {
  Eigen::Vector3d rest_length2;  ///< lbar_i^2 of the cyclic edges [m^2]
  Eigen::Matrix3d T;             ///< symmetric, [J/m^4]
};

/// Deformed positions x0, x1, x2 of one element, rows of a 3 by 3 matrix.
using Corners = Eigen::Matrix3d;

/// W = s^T T s (methods/shells Eq. 4.8).
double element_energy(const Corners& x, const Element& el);
/// dW/dx_m = r_{m+1} e_{m+1} - r_{m+2} e_{m+2}, r = 2 T s (methods/shells §4.5: f = -dW/dx).
Vec9 element_gradient(const Corners& x, const Element& el);
/// Factored Hessian (methods/shells §4.6): H = B^T (2T) B + sum_i r_i (eps_i eps_i^T) (x) I3, with
/// B_i = ds_i/dx. `projected` replaces r_i by max(r_i, 0) in the second term (PSD when T is).
Mat9 element_hessian(const Corners& x, const Element& el, bool projected);

}  // namespace membrane

/// St. Venant–Kirchhoff membrane energy of every face (methods/shells §4), material per face from
/// `Scene::face_material`, warp direction per face from `Scene::face_warp` (orthotropic
/// materials only), optionally with an animated rest state (`ClothSpec::rest_state`, methods/shells §5).
///
/// The exact Hessian is indefinite when an edge is compressed (r_i < 0); `HessianMode::projected`
/// clamps those edge tensions to zero in the geometric term, which makes every element PSD.
///
/// Animated rest state: the rest data comes from edge lengths only (`RestShape` ->
/// `element_matrix`), so `begin_step` recomputes lbar_i^2 and T of the affected elements from
/// the blended lengths lbar_e (1 - w + w s(t)) through the same code as the static precompute.
/// Bending rest data (rest angles, hinge weights) is not this model's and stays that of the mesh.
template <class Material>
class StvkMembrane {
 public:
  /// No options: stiffness and thickness are material properties of the scene's cloths.
  struct Params {
    template <class V>
    void visit(V&) {}
  };
  static constexpr std::string_view name = "stvk_membrane";
  /// Checkpoints: an animated rest state is a function of time, applied again by
  /// `begin_step` (the simulator calls it at the restored time).
  static constexpr bool stateless = true;

  /// Precomputes T per face at the rest state of t = 0.
  /// \throws ConfigError for invalid or unstable materials (`ShellMaterial::validate`), an
  ///   orthotropic material in `StvkMembrane<Isotropic>` (naming `cloths.N.material.model`),
  ///   an orthotropic face without a warp direction, zero-area rest faces, and animated rest
  ///   states that would break a triangle (`check_rest_states`).
  StvkMembrane(const Scene& scene, const Params& prm);

  /// Registers one group of stencil 3 (the face vertex ids).
  void declare(AssemblyPlan& plan);
  double energy(const State& s) const;
  void add_gradient(const State& s, Eigen::VectorXd& g) const;
  /// 9x9 local Hessian of every face into the declared group (parallel over faces).
  void add_hessian(const State& s, ElementBuffer& buf, HessianMode mode) const;
  /// Appends ("membrane", W).
  void energy_terms(const State& s, EnergyTerms& terms) const;
  /// False if a position is not finite (StVK itself accepts inverted elements).
  bool admissible(const State& s) const;

  /// Animated rest state (the `HasBeginStep` hook): sets the rest state of time t_end, the
  /// end of the coming step (backward Euler evaluates the elastic forces there). No-op for
  /// static scenes and when no factor changed since the last call.
  void begin_step(const State& s, double t_end);
  /// Same as `begin_step` without a state: rest lengths lbar_e (1 - w + w s(t)).
  void set_rest_time(double t);
  /// True if some cloth has an animated rest state.
  bool animated() const { return !animated_faces_.empty(); }

  int num_elements() const { return static_cast<int>(elements_.size()); }
  const membrane::Element& element(int f) const { return elements_[f]; }
  /// The true (t = 0 mesh) rest shape of face f, before any rest-state scaling.
  const membrane::RestShape& rest_shape(int f) const { return rest_[f]; }

 private:
  membrane::Corners corners(const State& s, int f) const;
  /// (Re)computes element f from its rest shape with the per-edge factors g_i (lbar_i -> g_i
  /// lbar_i); false (element untouched) if that is not a proper triangle.
  bool update_element(int f, const Eigen::Vector3d& factors);

  std::vector<int> ids_;  // #F*3 face vertex ids
  std::vector<membrane::Element> elements_;
  std::vector<membrane::RestShape> rest_;            // #F, true rest shapes
  std::vector<int> face_cloth_;                      // #F
  std::vector<membrane::LameConstants> lame_;        // per cloth
  std::vector<double> thickness_;                    // per cloth [m]
  // Animated rest state: per cloth its script and the factor last applied (NaN: none yet);
  // per affected face the local edges that follow the script.
  std::vector<RestStateSpec> scripts_;
  std::vector<double> applied_factor_;
  struct AnimatedFace {
    int face;
    std::array<bool, 3> scaled;
  };
  std::vector<AnimatedFace> animated_faces_;
  int group_ = -1;
};

extern template class StvkMembrane<Isotropic>;
extern template class StvkMembrane<Orthotropic>;
static_assert(EnergyModel<StvkMembrane<Isotropic>>);
static_assert(EnergyModel<StvkMembrane<Orthotropic>>);
static_assert(HasBeginStep<StvkMembrane<Isotropic>> && HasBeginStep<StvkMembrane<Orthotropic>>);

}  // namespace weft::models
