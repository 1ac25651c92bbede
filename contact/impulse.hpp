#pragma once
/// \file impulse.hpp
/// `Impulse`: decoupled, zeroth-order contact response on cloth after the implicit solve
/// (methods/rod-contact §8 (a), compliance D = M^-1; Bridson, Fedkiw & Anderson 2002, "Robust treatment
/// of collisions, contact and friction for cloth animation"), with Provot / Bridson rigid
/// impact zones as the failsafe. No potential terms: the integrator advances the elastic
/// dynamics alone, then `end_step` corrects the velocities.
///
/// Conventions. x0 are the start-of-step positions (kept by `begin_step`), v the step
/// velocities and x1 = x0 + dt v the end positions; every correction changes v and moves
/// x1 consistently (backward Euler's v_{k+1} = d / dt, methods/integration-and-contact §13: the response is fully
/// inelastic, no bounce). Pinned and scripted vertices have infinite mass: impulses never
/// change them. h is the contact thickness, kept to obstacles and between cloth layers.
///
/// Algorithm of `end_step` (one time step):
///  1. Obstacles (analytic sphere, box, plane with scripted motion; `ObstaclePose`), per
///     free vertex, independent of the others:
///     - end-of-step contact: phi1 = phi(x1, t1) < h. The normal velocity changes by
///       dun = (h - phi1) / dt along the end-of-step normal n1 (methods/integration-and-contact §11.2: the normal
///       of a cloth-object contact is taken at the end of the step), which puts the vertex
///       at distance h exactly for planes and spheres (the distance grows at unit rate
///       along its gradient). The relative velocity over the step, (h - phi0) / dt, no
///       longer approaches when the vertex started at the thickness: resting contact is
///       inelastic, and a vertex that started farther lands on the thickness in the step
///       instead of stopping short (the gap-aware variant of methods/integration-and-contact §11.4).
///     - Coulomb friction (methods/integration-and-contact §14.1, Bridson 2002 §7.2): the tangential velocity
///       relative to the obstacle, u_t = (v - w) - ((v - w).n) n, becomes
///       max(0, 1 - mu dun / |u_t|) u_t (static when it would stop, kinetic otherwise),
///       mu = the obstacle's `friction`, w = the obstacle's velocity at the contact point,
///       (p(t1) - p(t0)) / dt for the material point p of the obstacle under the contact.
///       On a plane inclined by alpha a vertex resting at the thickness sticks iff
///       tan(alpha) <= mu and otherwise slides with acceleration g (sin alpha - mu cos alpha)
///       (methods/integration-and-contact E7, exact in this discretisation).
///     - crossing during the step (a fast vertex or obstacle): the relative path
///       (x0 + s (x1 - x0), pose(t0 + s dt)), s in [0, 1], is checked by conservative
///       advancement on phi with a bound L on its rate (vertex displacement plus the
///       obstacle's linear and angular speed over the region: phi is 1-Lipschitz in the
///       body frame), after the cheap rejection (phi0 + phi1 - L) / 2 > 0. When the path
///       touches the surface at s* and the end-of-step normal does not point to the side
///       it came from (it went through), the vertex is stopped at the contact point
///       (inelastic, with friction) and carried by the obstacle for the rest of the step,
///       then the end-of-step test above runs again.
///     The vertex is swept over the obstacles up to 4 times (vertices squeezed between
///     obstacles); `max_penetration` reports what remains.
///  2. Cloth-cloth repulsion (`self_contact`): proximity pairs (vertex-triangle and
///     interior edge-edge, contact/detection/proximity.hpp) within h at the end positions
///     x1, with their weights gamma and normal n (methods/integration-and-contact §11.1). A pair whose material
///     points were on the other side of n at the start (n . g(x0) <= 0: it crossed during
///     the step) is left to step 3, and a pair whose material points are closer than h in
///     the rest state (|sum_j gamma_j X_j| < h: a fine or irregular mesh) is no contact.
///     For the rest, Gauss-Seidel sweeps in detection order
///     over C = n . sum_j gamma_j x1_j - h: when C < 0, dun = -C / dt with the mass-weighted
///     impulse of Bridson 2002 Eq. (7.1) (impulse_kernels.hpp) and friction `cloth_friction`.
///     Obstacles are re-checked afterwards (step 1).
///  3. Iterated CCD impulses (Bridson 2002 §7.4): up to `ccd_sweeps` sweeps of continuous
///     collision detection on x0 -> x1 (contact/detection/ccd.hpp, tolerance `eta`), each
///     followed by impulses in detection order on the hits, with the weights and normal at
///     the time of impact (methods/integration-and-contact §11.2): the separation along n, s(x) = n . sum gamma_j x_j,
///     is made to end at min(h, s(x0)) or more, dun = max(0, min(h, s(x0)) - s(x1)) / dt
///     (the pair stops at the thickness, or does not approach further if it started
///     closer), plus friction; then step 1 again. Detection is repeated after every sweep;
///     a sweep that finds nothing ends the step.
///     Pairs already within eta at the start (toi = 0; e.g. a previous step that ended
///     between eta/2 and eta) cannot be resolved by any velocity; they count as resolved
///     when their separation along n does not decrease over the step.
///  4. Failsafe, rigid impact zones (Provot 1997; Bridson 2002 §7.4; Harmon et al. 2008):
///     the stencil vertices of the remaining hits are merged into zones (union-find over
///     free vertices; pinned and scripted vertices, and vertices held by a moving obstacle,
///     join as anchors that keep their velocities). Each zone then moves rigidly:
///     - a zone with a vertex held by a static obstacle stops, x1 = x0 (rigid, and feasible
///       for static obstacles; the obstacle takes the momentum: a fully inelastic landing);
///     - a zone with anchors follows their least-squares rigid motion;
///     - any other zone keeps its linear and angular momentum (`rigidify_zone`).
///     Obstacles are re-checked (the vertices they move are "held" from then on), and CCD
///     runs again, ignoring pairs inside one zone that nothing moved after its rigid motion
///     (a rigid zone cannot intersect itself). This repeats with the accumulated hits until
///     no hit remains. After `max_zone_iterations` iterations the step fails with
///     Status::no_convergence and a message naming the step, the remaining hits and the
///     largest zone (never an endless loop); hits among anchors alone fail at once
///     (Status::numerical_issue: no velocity can resolve them).
///
/// Guarantees when `end_step` succeeds: no free vertex closer to an obstacle than
/// h (1 - 1e-9) at the end of the step (obstacles squeezing a vertex between them
/// excepted: `max_penetration` reports it); with self_contact, no cloth-cloth pair came
/// within eta / 2 along x0 -> x1 (ccd.hpp) apart from pairs inside one rigid zone and the
/// separating toi = 0 pairs above, so no intersection given an intersection-free start;
/// with ccd_sweeps = 0 the zones alone enforce it. The result does not depend on the number of
/// OpenMP threads: detection is deterministic, the obstacle pass is per vertex, the
/// impulse sweeps and zones run serially in detection order.
///
/// Timing: `detection_seconds` is the time in the collision detector (BVH refits,
/// proximity and CCD); `response_seconds` everything else of `end_step` (obstacle checks
/// and impulses, repulsion and CCD impulses, zones).
#include <Eigen/Core>

#include <memory>
#include <string_view>
#include <vector>

#include "contact/obstacle_penalty.hpp"
#include "framework/concepts.hpp"
#include "framework/params.hpp"
#include "framework/scene.hpp"

namespace weft::contact {

namespace detection {
class CollisionDetector;
}

class Impulse {
 public:
  static constexpr std::string_view name = "impulse";
  static constexpr bool stateless = true;  ///< checkpoints: x0 and the poses are taken at each begin_step; the BVH output does not depend on its history
  /// No potential terms: energy 0, no gradient, no Hessian (a zero potential, as for
  /// `NoContact`), so a minimising integrator may use it; all the work is in `end_step`.
  static constexpr bool provides_potential = true;

  struct Params {
    double thickness = 1e-3;       ///< h [m], > 0: distance kept to obstacles and between cloth layers
    double cloth_friction = 0.0;   ///< Coulomb coefficient of cloth-cloth contacts, >= 0 (cloth-obstacle: each obstacle's `friction`)
    int repulsion_sweeps = 2;      ///< Gauss-Seidel sweeps over the proximity pairs, >= 0
    int ccd_sweeps = 2;            ///< CCD impulse sweeps before the impact zones, >= 0
    int max_zone_iterations = 100; ///< impact-zone iterations before the step fails, >= 1
    double eta = 1e-6;             ///< CCD tolerance [m], in (0, thickness)
    bool self_contact = true;      ///< cloth-cloth contact (repulsion, CCD, zones)
    template <class V>
    void visit(V& v) {
      v.field("thickness", thickness,
              {Unit::length, Range::gt(0), "contact thickness h: the distance kept to obstacles and between cloth layers"});
      v.field("cloth_friction", cloth_friction,
              {Unit::none, Range::ge(0), "Coulomb coefficient of cloth-cloth contacts (cloth-obstacle: obstacles.N.friction)"});
      v.field("repulsion_sweeps", repulsion_sweeps,
              {Unit::none, Range::closed(0, 1000), "Gauss-Seidel sweeps of repulsion impulses over the proximity pairs"});
      v.field("ccd_sweeps", ccd_sweeps,
              {Unit::none, Range::closed(0, 1000), "sweeps of CCD impulses before the impact-zone failsafe"});
      v.field("max_zone_iterations", max_zone_iterations,
              {Unit::none, Range::closed(1, 1e6), "impact-zone iterations before the step fails"});
      v.field("eta", eta, {Unit::length, Range::gt(0), "CCD tolerance: pairs closer than eta count as colliding (< thickness)"});
      v.field("self_contact", self_contact, {Unit::none, Range::any(), "cloth-cloth contact (off: obstacles only)"});
    }
    static Checker validate(const Params& p) {
      Checker c("contact");
      c.require(p.thickness > 0, "thickness", p.thickness, "> 0")
          .require(p.cloth_friction >= 0, "cloth_friction", p.cloth_friction, ">= 0")
          .require(p.repulsion_sweeps >= 0, "repulsion_sweeps", p.repulsion_sweeps, ">= 0")
          .require(p.ccd_sweeps >= 0, "ccd_sweeps", p.ccd_sweeps, ">= 0")
          .require(p.max_zone_iterations >= 1, "max_zone_iterations", p.max_zone_iterations, ">= 1")
          .require(p.eta > 0 && p.eta < p.thickness, "eta", p.eta, "in (0, thickness)");
      return c;
    }
  };

  /// \throws ConfigError for invalid parameters.
  Impulse(const Scene& scene, const Params& prm);
  ~Impulse();
  Impulse(Impulse&&) noexcept;
  Impulse& operator=(Impulse&&) noexcept;

  void declare(AssemblyPlan&) {}
  /// Keeps x0, the time and the obstacle poses at the start and end of the step.
  ContactReport begin_step(const State& s, double dt);
  double energy(const State&) const { return 0.0; }
  void add_gradient(const State&, Eigen::VectorXd&) const {}
  void add_hessian(const State&, ElementBuffer&, HessianMode) const {}
  /// The response on the integrator's end-of-step state (see the file comment).
  ContactReport end_step(State& out, double dt);

  const Params& params() const { return prm_; }

 private:
  struct Obstacle;
  struct Step;
  Params prm_;
  std::vector<ObstacleSpec> obstacles_;
  Eigen::VectorXd rest_;  // #V*3 rest positions
  std::unique_ptr<detection::CollisionDetector> detector_;
  Eigen::VectorXd x0_;
  double t0_ = 0;
  bool started_ = false;
};

static_assert(ContactStrategy<Impulse>);

}  // namespace weft::contact
