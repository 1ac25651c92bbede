#pragma once
/// \file implicit_contact.hpp
/// `ImplicitContact`: contact handled inside the implicit solve, as Baraff & Witkin (1998)
/// do it, with a collision failsafe after it.
///  - Obstacles: equality constraints of the solve, released when they pull, with Coulomb
///    friction, re-detected when the solution crosses an obstacle where the step had no
///    contact (`ObstacleConstraints`, obstacle_constraints.hpp). The linear solver takes
///    them through its context (modified PCG filters, PPCG and Direct prefilter).
///  - Cloth against cloth: repulsion springs, potential terms of the solve (below).
///  - After the solve, the `Impulse` pipeline (impulse.hpp) as the failsafe: repulsion and
///    CCD impulses, then rigid impact zones. It only has work where the springs were too
///    soft or a pair met during the step without being near at its start or in the
///    prediction; it guarantees no cloth-cloth intersection as `Impulse` does.
///
/// **Repulsion springs** (methods/integration-and-contact §11.1; BW98 §6 "cloth/cloth collisions"). In `begin_step`
/// the pairs (vertex-triangle, edge-edge; contact/detection/proximity.hpp) within the
/// thickness h at the start positions x0 or at the prediction x0 + dt v0 become springs
/// for the step, each with its stencil (4 vertices), weights gamma and unit normal n from
/// the start positions (B to A; for a pair found only in the prediction the weights and
/// normal of its closest points at x0). Pairs whose material points are closer than h in
/// the rest state (fine meshes) are not contacts, as in `Impulse`. A spring's energy is
///     E = 1/2 k min(C, 0)^2,    C(x) = n . sum_j gamma_j x_j - h,
/// one-sided (it never pulls) and C^1; gradient k min(C,0) gamma_j n for vertex j, Hessian
/// k gamma_i gamma_j n n^T where C < 0 (positive semidefinite), zero elsewhere (exact
/// away from C = 0). The stiffness is k = s m_eff / dt^2 with s = `spring_stiffness` and
/// m_eff = 1 / sum_j gamma_j^2 / m_j (pinned vertices: 1/m = 0): minimising the
/// incremental potential of the pair's relative motion alone, a predicted violation C_p
/// shrinks to C_p / (1 + s). The springs couple vertices that are not neighbours in the
/// mesh, so the matrix pattern follows them (`update_pattern`: a new pattern and symbolic
/// analysis when the set of springs changes).
///
/// Linearly implicit Euler evaluates the springs at x0 only: a spring whose pair is apart
/// at the start (C(x0) > 0) and only predicted to meet has no force and no stiffness in
/// that single Newton step; it acts from the next step, and the failsafe meanwhile.
///
/// Reports: `springs`, and the counters of the two parts (`released`, `sticking`,
/// `projected`, `obstacle_contacts`, `ccd_hits`, `impact_zones`, ...). `contacts` counts
/// obstacle contacts plus springs. Detection time covers the spring detection and the
/// failsafe's detection.
#include <Eigen/Core>

#include <array>
#include <memory>
#include <string_view>
#include <vector>

#include "contact/impulse.hpp"
#include "contact/obstacle_constraints.hpp"
#include "framework/concepts.hpp"
#include "framework/params.hpp"
#include "framework/scene.hpp"

namespace weft::contact {

namespace detection {
class CollisionDetector;
}

class ImplicitContact {
 public:
  static constexpr std::string_view name = "implicit_contact";
  static constexpr bool provides_potential = true;  ///< the springs and the kinetic friction are potential terms

  struct Params {
    /// Thickness, self contact, cloth friction and the failsafe: the `impulse` fields, in
    /// the same section (the failsafe is an `Impulse` with these parameters).
    Impulse::Params impulse{.thickness = 2e-3};
    double margin = 1e-8;               ///< [m] >= 0: obstacle contacts start within thickness + margin
    double projection_tolerance = 1e-9; ///< [m] >= 0: depth below h left alone by the obstacle projection
    double spring_stiffness = 100;      ///< s > 0: spring stiffness k = s m_eff / dt^2
    double redetection_depth = 1e-4;    ///< [m] >= 0: obstacle re-detection inside the step (obstacle_constraints.hpp)
    int max_redetections = 4;           ///< re-detection rounds per step (0: off)
    bool redetect_iterates = false;     ///< also re-detect at every accepted Newton iterate (else at converged solutions only)
    template <class V>
    void visit(V& v) {
      impulse.visit(v);
      v.field("margin", margin,
              {Unit::length, Range::ge(0), "an obstacle contact starts when the start or predicted position is within thickness + margin"});
      v.field("projection_tolerance", projection_tolerance,
              {Unit::length, Range::ge(0), "after the solve, vertices deeper than this below an obstacle's thickness surface are projected onto it"});
      v.field("spring_stiffness", spring_stiffness,
              {Unit::none, Range::gt(0), "cloth-cloth repulsion springs: k = s m_eff / dt^2 (a predicted violation shrinks to 1 / (1 + s))"});
      ObstacleConstraints::Params::visit_redetection(v, redetection_depth, max_redetections, redetect_iterates);
    }
    static Checker validate(const Params& p) {
      Checker c = Impulse::Params::validate(p.impulse);
      c.require(p.margin >= 0, "margin", p.margin, ">= 0")
          .require(p.projection_tolerance >= 0, "projection_tolerance", p.projection_tolerance, ">= 0")
          .require(p.spring_stiffness > 0, "spring_stiffness", p.spring_stiffness, "> 0");
      ObstacleConstraints::Params::validate_redetection(c, p.redetection_depth, p.max_redetections);
      return c;
    }
  };

  /// One repulsion spring of the step.
  struct Spring {
    std::array<int, 4> v{};         ///< stencil vertex ids
    std::array<double, 4> gamma{};  ///< weights: sum_j gamma_j x_j = p^a - p^b
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit, B to A, at the start of the step
    double stiffness = 0;           ///< k [N/m]
    double gap(const Eigen::VectorXd& x, double h) const;  ///< C(x)
  };

  /// \throws ConfigError for invalid parameters.
  ImplicitContact(const Scene& scene, const Params& prm);
  ~ImplicitContact();
  ImplicitContact(ImplicitContact&&) noexcept;
  ImplicitContact& operator=(ImplicitContact&&) noexcept;

  void declare(AssemblyPlan& plan);
  ContactReport begin_step(const State& s, double dt);
  bool update_pattern(AssemblyPlan& plan);
  double energy(const State& s) const;
  void add_gradient(const State& s, Eigen::VectorXd& g) const;
  void add_hessian(const State& s, ElementBuffer& buf, HessianMode mode) const;
  void constraints(const State& trial, ConstraintSet& out) const { obstacles_.constraints(trial, out); }
  void accept_reactions(const Eigen::VectorXd& force) { obstacles_.accept_reactions(force); }
  /// Obstacle re-detection inside the step (ObstacleConstraints::redetect).
  int redetect(const State& start, const State& trial, double dt, std::vector<int>& vertices, bool converged) {
    return obstacles_.redetect(start, trial, dt, vertices, converged);
  }
  ContactReport end_step(State& s, double dt);
  /// Checkpoints: the obstacle contacts' state (ObstacleConstraints::save); the springs
  /// are made afresh at every step, and the detectors' output does not depend on their history.
  void save(Checkpoint& c, std::string_view prefix) const { obstacles_.save(c, prefix); }
  void restore(const Checkpoint& c, std::string_view prefix) { obstacles_.restore(c, prefix); }

  const Params& params() const { return prm_; }
  const std::vector<Spring>& springs() const { return springs_; }
  const ObstacleConstraints& obstacle_constraints() const { return obstacles_; }

 private:
  Params prm_;
  ObstacleConstraints obstacles_;
  std::unique_ptr<Impulse> failsafe_;  // with self contact
  std::unique_ptr<detection::CollisionDetector> detector_;
  Eigen::VectorXd rest_;
  std::vector<Spring> springs_;
  std::vector<int> declared_;  // stencil ids of the springs in the plan's group
  int group_ = -1;
  bool has_obstacles_ = false;
};

static_assert(ContactStrategy<ImplicitContact>);
static_assert(HasConstraints<ImplicitContact>);
static_assert(HasRedetection<ImplicitContact>);
static_assert(HasDynamicPattern<ImplicitContact>);

}  // namespace weft::contact
