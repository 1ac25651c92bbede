#pragma once
/// \file obstacle_penalty.hpp
/// `ObstaclePenalty`: frictionless contact with the scene's obstacles (sphere, box, plane,
/// triangle mesh, all with scripted motion) as a penalty potential inside the implicit solve.
///
/// For vertex i with signed distance phi_i to an obstacle (posed at the end of the step),
///   E_i = 1/2 kappa m_i (delta - phi_i)^2   if phi_i < delta, else 0,
/// with delta the contact thickness and kappa a stiffness per unit mass [1/s^2] (so the
/// contact pressure does not depend on the mesh resolution). Exact gradient and Hessian:
///   grad E_i = -kappa m_i (delta - phi) grad phi,
///   Hess E_i = kappa m_i (grad phi grad phi^T - (delta - phi) Hess phi);
/// the second term is negative semi-definite for convex obstacles (and near the convex
/// edges and vertices of a mesh) and is dropped in
/// HessianMode::projected. A stand-in until the contact strategies of the cloth-contact
/// issue land: no friction (a scene with friction > 0 is rejected), no self contact.
#include <Eigen/Core>

#include <optional>
#include <string_view>
#include <vector>

#include "framework/concepts.hpp"
#include "framework/params.hpp"
#include "framework/scene.hpp"

namespace weft::contact {

/// Signed distance of x to an obstacle at a given pose, with its derivatives.
struct Distance {
  double phi = 0;                                  ///< > 0 outside
  Eigen::Vector3d grad = Eigen::Vector3d::Zero();  ///< unit outward normal where defined
  Eigen::Matrix3d hess = Eigen::Matrix3d::Zero();
};

class MeshDistance;

/// Pose of an obstacle at time t: centre c(t) and rotation R(t) from its scripted motion.
/// Body coordinates are y = R^T (x - c); a mesh obstacle's OBJ origin sits at c.
struct ObstaclePose {
  ObstacleShape shape;
  Eigen::Vector3d center;
  Eigen::Matrix3d rotation;
  double radius;
  Eigen::Vector3d half_extents, normal;
  const MeshDistance* mesh = nullptr;  ///< mesh: the closest-point index of the spec's `mesh` (owned by it)
  /// \throws ConfigError for a mesh obstacle without its geometry (`ObstacleSpec::mesh`).
  static ObstaclePose at(const ObstacleSpec& o, double t);
  /// Signed distance (sphere, box, plane: analytic; mesh: contact/mesh_distance.hpp).
  Distance distance(const Eigen::Vector3d& x) const;
};

class ObstaclePenalty {
 public:
  static constexpr std::string_view name = "obstacle_penalty";
  static constexpr bool stateless = true;  ///< checkpoints: the poses are taken at each begin_step
  static constexpr bool provides_potential = true;
  struct Params {
    std::optional<double> stiffness;  ///< kappa [1/s^2]; required: no safe default exists
    double thickness = 2e-3;          ///< delta [m]: contact starts at this distance
    template <class V>
    void visit(V& v) {
      v.field("stiffness", stiffness,
              {Unit::frequency, Range::gt(0), "kappa, penalty stiffness per unit vertex mass [1/s^2] (required)", true});
      v.field("thickness", thickness, {Unit::length, Range::ge(0), "contact thickness delta: the distance kept to obstacles"});
    }
    static Checker validate(const Params& p) {
      Checker c("contact");
      c.require(p.stiffness.has_value(), "stiffness", "unset", "a value in 1/s^2 (e.g. 1e6): there is no safe default");
      return c;
    }
  };

  ObstaclePenalty(const Scene& scene, const Params& prm);
  void declare(AssemblyPlan& plan);
  ContactReport begin_step(const State& s, double dt);
  double energy(const State& s) const;
  void add_gradient(const State& s, Eigen::VectorXd& g) const;
  void add_hessian(const State& s, ElementBuffer& buf, HessianMode mode) const;
  ContactReport end_step(State& s, double dt);
  /// Largest penetration below the thickness over all vertices and obstacles [m] (0: none).
  double max_penetration(const State& s) const;

 private:
  std::vector<ObstacleSpec> obstacles_;
  std::vector<ObstaclePose> poses_;  // at the end of the current step
  Eigen::VectorXd mass_;
  std::vector<unsigned char> free_;
  double kappa_, delta_;
  int group_ = -1;
};

static_assert(ContactStrategy<ObstaclePenalty>);

}  // namespace weft::contact
