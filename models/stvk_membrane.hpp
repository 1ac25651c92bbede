#pragma once
/// \file stvk_membrane.hpp
/// St. Venant–Kirchhoff membrane on constant-strain triangles, in the edge-based form of
/// spec 01 §4 (thesis §4.5): per triangle the edge elongations s_i = 1/2 (l_i^2 - lbar_i^2),
/// a precomputed symmetric 3x3 matrix T, and W = s^T T s.
#include <Eigen/Core>

#include <array>
#include <string_view>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/concepts.hpp"
#include "framework/scene.hpp"
#include "framework/state.hpp"

namespace weft::models {

/// Isotropic StVK material: (lambda, mu) from Young's modulus and Poisson ratio, a = b = 0.
/// (The Orthotropic tag arrives with the next issue; it only changes how T is precomputed.)
struct Isotropic {
  static constexpr std::string_view name = "isotropic";
};

namespace membrane {

using Mat9 = Eigen::Matrix<double, 9, 9>;
using Vec9 = Eigen::Matrix<double, 9, 1>;

/// Material constants of the quadratic StVK density (spec 01 §3.2, Eq. 4.4):
///   psi = lambda/2 J1^2 + mu J2 + a J1 J3 + b J3^2.
/// Isotropic: lambda = Y nu / (1 - nu^2), mu = Y / (2 (1 + nu)) (plane stress, Eq. 4.2), a = b = 0.
struct LameConstants {
  double lambda = 0;  ///< [Pa]
  double mu = 0;      ///< [Pa]
  double a = 0;       ///< [Pa] orthotropic coupling J1 J3
  double b = 0;       ///< [Pa] orthotropic J3^2
};

/// Plane-stress Lamé constants of an isotropic sheet (spec 01 Eq. 4.2).
LameConstants isotropic_lame(double youngs_modulus, double poisson_ratio);

/// Twice the area of the triangle (v0, v1, v2).
double double_area(const Eigen::Vector3d& v0, const Eigen::Vector3d& v1, const Eigen::Vector3d& v2);

/// The element matrix T of spec 01 Eq. 4.8 (§4.3–4.4):
///   T = h / (32 Abar^3) (lambda T1 + mu T2 + 2 b T3 + a T4),
///   T1_il = d_{i+1,i+2} d_{l+1,l+2},
///   T2_il = d_{i+2,l+1} d_{i+1,l+2} + d_{i+2,l+2} d_{i+1,l+1},
///   T3_il = beta_{i+1} beta_{i+2} beta_{l+1} beta_{l+2},
///   T4_il = d_{i+1,i+2} beta_{l+1} beta_{l+2} + d_{l+1,l+2} beta_{i+1} beta_{i+2},
/// with d_il = ebar_i . ebar_l (rest edges, cyclic: e0 = v2 - v1, e1 = v0 - v2, e2 = v1 - v0),
/// beta_i = ahat . (nbar x ebar_i) and indices mod 3.
/// \param rest 3 by 3, rows are the rest vertices v0, v1, v2 (non-degenerate)
/// \param thickness h [m]
/// \param direction unit material direction ahat in the rest plane; only read when a or b
///        is nonzero (orthotropic), may be zero otherwise
Eigen::Matrix3d stvk_T(const Eigen::Matrix3d& rest, double thickness, const LameConstants& c,
                       const Eigen::Vector3d& direction = Eigen::Vector3d::Zero());

/// Rest data of one element.
struct Element {
  Eigen::Vector3d rest_length2;  ///< lbar_i^2 of the cyclic edges [m^2]
  Eigen::Matrix3d T;             ///< symmetric, [J/m^4]
};

/// Deformed positions x0, x1, x2 of one element, rows of a 3 by 3 matrix.
using Corners = Eigen::Matrix3d;

/// W = s^T T s (spec 01 Eq. 4.8).
double element_energy(const Corners& x, const Element& el);
/// dW/dx_m = r_{m+1} e_{m+1} - r_{m+2} e_{m+2}, r = 2 T s (spec 01 §4.5: f = -dW/dx).
Vec9 element_gradient(const Corners& x, const Element& el);
/// Factored Hessian (spec 01 §4.6): H = B^T (2T) B + sum_i r_i (eps_i eps_i^T) (x) I3, with
/// B_i = ds_i/dx. `projected` replaces r_i by max(r_i, 0) in the second term (PSD when T is).
Mat9 element_hessian(const Corners& x, const Element& el, bool projected);

}  // namespace membrane

/// St. Venant–Kirchhoff membrane energy of every face (spec 01 §4), material per face from
/// `Scene::face_material` (youngs_modulus, poisson_ratio, thickness).
///
/// The exact Hessian is indefinite when an edge is compressed (r_i < 0); `HessianMode::projected`
/// clamps those edge tensions to zero in the geometric term, which makes every element PSD.
template <class Material>
class StvkMembrane {
 public:
  /// No options: stiffness and thickness are material properties of the scene's cloths.
  struct Params {
    template <class V>
    void visit(V&) {}
  };
  static constexpr std::string_view name = "stvk_membrane";

  /// Precomputes T per face. \throws ConfigError for invalid materials or zero-area rest faces.
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

  int num_elements() const { return static_cast<int>(elements_.size()); }
  const membrane::Element& element(int f) const { return elements_[f]; }

 private:
  membrane::Corners corners(const State& s, int f) const;

  std::vector<int> ids_;  // #F*3 face vertex ids
  std::vector<membrane::Element> elements_;
  int group_ = -1;
};

extern template class StvkMembrane<Isotropic>;
static_assert(EnergyModel<StvkMembrane<Isotropic>>);

}  // namespace weft::models
