#pragma once
/// \file obstacle_constraints.hpp
/// `ObstacleConstraints`: contact with the scene's analytic obstacles (sphere, box, plane,
/// all with scripted motion) as equality constraints inside the implicit solve, released
/// when their force pulls (Baraff & Witkin 1998 §5; methods/integration-and-contact §10, methods/multigrid §7). The linear
/// solver enforces them: ModifiedPcg filters, Ppcg and Direct prefilter (linear/).
///
/// **Active set.** A contact is a (free vertex i, obstacle o) pair. `begin_step` makes one
/// when the prediction x_i + dt v_i lies within delta + margin of o posed at the end of the
/// step (signed distance phi_o, delta the thickness), or x_i does and its velocity relative
/// to o does not separate from it by more than the margin over the step. Contacts kept
/// from the last step carry their friction state. Contacts released at the end of the last
/// step (their reaction pulled) are dropped and not re-made for this step; contacts whose
/// vertex and obstacle separate (a receding obstacle, a vertex thrown off) fail the test
/// and are dropped before they can pull.
///
/// **Re-detection inside the step** (`redetect`, the `HasRedetection` hook). The set above
/// is fixed from the start and the prediction x_i + dt v_i, which ignores the forces of
/// the step: a vertex can cross an obstacle during the solve (gravity, a fold pushed
/// through the box edge) with no constraint to stop it. After a converged solve (and, with
/// `redetect_iterates`, at every accepted Newton iterate of the line-search Newton and of
/// root finding), every free vertex deeper than `redetection_depth` below the thickness surface of an obstacle it
/// has no contact with gets that contact (a new contact, friction mode from the impact cone
/// at the start of the step), its vertex goes back to the integrator's initial guess, and
/// the Newton iterations (IncrementalPotential, BackwardEulerRoot) continue from there made
/// feasible, up to `max_redetections` rounds per step; what is left is projected at the end
/// of the step as before. Caught at the iterate that crosses, a contact does not cost the
/// iterations of converging a solution that is then discarded for its vertices (the drape
/// on the sphere at 41 x 41: 75 iterations before the converged-only re-detection of 146
/// contacts at step 64, docs/contact.md); but a crossing of a transient iterate then adds
/// a contact the solution would not have needed, so the step depends on the path of the
/// iterates (root finding and minimisation no longer agree): off by default. The
/// linearly implicit integrator keeps BW98's single solve (no re-detection). Without it a
/// 41 x 41 dropVertical projected 11-16 vertices by up to 8 mm per step before it failed
/// (docs/contact.md).
///
/// **Constraints of a Newton iterate** (`constraints`, called by the integrator with the
/// trial positions x = x_k + d): on the increment dx of the Newton direction,
///   normal:  n^T dx_i = delta - phi_o(x_i),     n = grad phi_o(x_i)  (o at t + dt)
/// i.e. the increment brings x_i to the thickness surface of the obstacle *where it is at
/// the end of the step* (a moving obstacle carries the target along). For the analytic
/// shapes the move x_i + n (delta - phi) lands exactly on phi = delta, so the integrator
/// first makes its iterate feasible with the targets of the set (step_system.hpp); the
/// values left at later iterates are what a partial line-search step or the curvature of
/// the obstacle left (the gap is asked for again at the next iterate).
///
/// **Friction** (Coulomb, mu = the obstacle's `friction`; methods/integration-and-contact §14), per contact mode:
///  - *stick* (static friction): a full 3D constraint, dx_i = x*_i - x_i with the anchor
///    x*_i = T(x_k,i) moved along the normal onto phi = delta, T the obstacle's rigid motion
///    over the step: the vertex moves with the obstacle. Kept while the reaction R_i (3D)
///    satisfies ||R_t|| <= mu R_n (R_n = n^T R_i, R_t = R_i - R_n n); otherwise the
///    contact slides from the next step, in the direction -R_t (the step in which the cone
///    was exceeded stays stuck: the slide starts one step late).
///  - *slide* (kinetic friction): the normal constraint plus an explicit force
///      F_i = -mu lambda_n t,   t = the slip direction (unit, tangent at x_k)
///    constant over the step, with lambda_n the normal reaction of the *previous* step and t
///    the relative tangential velocity at its end (or -R_t at the switch from stick). It
///    lags one step: the normal force and the slip direction are those of the step before.
///    It enters the solve as the linear potential -F^T x (`energy`, `add_gradient`), so
///    E_inc stays a potential and the line searches work. When the relative tangential
///    velocity at the end of a step has turned against t (the explicit force stopped or
///    reversed the slip), that velocity is set to zero and the contact sticks from the next
///    step: kinetic friction never reverses a slip.
///  - a *new* contact sticks when its relative tangential velocity at the start of the step
///    satisfies the impact cone ||v_t|| <= mu v_n (v_n the approach speed), else it slides
///    with the impact estimate lambda_n = m_i v_n / dt (the force that stops the approach
///    over one step) for its first step.
///  - mu = 0: normal constraints only. A vertex touching several obstacles: normal
///    constraints only, with the kinetic force of each contact (never stick).
///
/// **Reactions and release** (`accept_reactions`, called by the integrator at the accepted
/// solution d): R = (I - S) f(d) / dt^2, the part of the backward Euler residual
/// f(d) = M~ d - dt M v_k + dt^2 grad(V - F^T x) along the constrained directions. At the
/// constrained solution S f = 0, and f = dt^2 R is exactly the force the constraints add to
/// the equations of motion M (v_{k+1} - v_k) / dt = -grad V + F + R. (A linearly implicit
/// step reports the R of the linear system it solved; step_system.hpp.) `end_step`
///  1. splits R_i among the contacts of vertex i (least squares on their normals);
///  2. releases the contacts whose normal reaction lambda_n = n^T R_i <= 0 pulls (adhesion,
///     BW98), unless the vertex still approaches the obstacle (faster than the margin per
///     step: it reached the surface at the end of the step and needed no force yet; it
///     stays in contact and keeps its friction mode);
///  3. updates the friction modes (above);
///  4. holds every contact that stays on its constraint and its hidden constraint
///     (methods/integration-and-contact §10.1: C = 0 and grad C qdot = 0): it moves the vertex onto phi = delta
///     (a single linearised step leaves it off a curved obstacle by O(step^2 / R)) and
///     zeroes its relative normal velocity (v = d / dt keeps the chord's O(dt) normal part
///     on a curved obstacle, or the approach of a contact made during the step: an
///     inelastic contact keeps neither);
///  5. projects every free vertex still deeper than `projection_tolerance` below the
///     thickness surface onto it (vertices that were not in contact), zeroing its
///     approaching relative normal velocity.
///
/// **Several obstacles at a vertex.** Obstacles that touch (the box with a hole of
/// dropHorizontal / dropVertical is four boxes sharing faces) make a vertex near a seam a
/// contact of both, although their union is flat there: the second box's rounded edge,
/// tangent to the first box's thickness surface along the seam, pins the vertex onto the
/// seam line (two nearly parallel constraints, an ill-conditioned projection that stalled
/// Newton on a 41 x 41 dropVertical). Per iterate the contacts of a vertex are taken
/// closest obstacle first, and one whose closest point on its obstacle lies in (or on) the
/// solid of an obstacle taken before it is an inner surface of the union and skipped
/// (`effective`); at the end of the step such a contact is released. Concave corners (the
/// hole's walls) keep both constraints: each wall's closest point lies outside the other.
///
/// Rigid motion of an obstacle between t_k and t_{k+1}: T(x) = R_{k+1} R_k^T (x - c_k) +
/// c_{k+1}; its velocity at x at the end of the step: v_o(x) = (x - T^-1(x)) / dt.
#include <Eigen/Core>

#include <string_view>
#include <vector>

#include "contact/obstacle_penalty.hpp"
#include "framework/checkpoint.hpp"
#include "framework/concepts.hpp"
#include "framework/constraints.hpp"
#include "framework/params.hpp"
#include "framework/scene.hpp"

namespace weft::contact {

class ObstacleConstraints {
 public:
  static constexpr std::string_view name = "obstacle_constraints";
  static constexpr bool provides_potential = false;  ///< constraints, not potential terms

  struct Params {
    double thickness = 2e-3;               ///< delta [m] >= 0: the distance kept to obstacles
    double margin = 1e-8;                  ///< [m] >= 0: detection slack above delta (vertices resting at delta, to round-off)
    double projection_tolerance = 1e-9;    ///< [m] >= 0: depth below delta left alone by the end-of-step projection
    double redetection_depth = 1e-4;       ///< [m] >= 0: a solution deeper than this below delta, where no contact was, is solved again
    int max_redetections = 4;              ///< re-detections per step (0: off, the contact set of the start of the step only)
    bool redetect_iterates = false;        ///< also re-detect at every accepted Newton iterate (else at converged solutions only)
    template <class V>
    void visit(V& v) {
      v.field("thickness", thickness, {Unit::length, Range::ge(0), "contact thickness delta: the distance kept to obstacles"});
      v.field("margin", margin,
              {Unit::length, Range::ge(0), "a contact starts when the start or predicted position is within thickness + margin"});
      v.field("projection_tolerance", projection_tolerance,
              {Unit::length, Range::ge(0), "after the solve, vertices deeper than this below the thickness surface are projected onto it"});
      visit_redetection(v, redetection_depth, max_redetections, redetect_iterates);
    }
    template <class V>
    static void visit_redetection(V& v, double& depth, int& rounds, bool& iterates) {
      v.field("redetection_depth", depth,
              {Unit::length, Range::ge(0),
               "a converged solve that leaves a vertex deeper than this below an obstacle's thickness surface, where the step had no contact, gets that contact and is solved again"});
      v.field("max_redetections", rounds,
              {Unit::none, Range::closed(0, 100), "re-detections (contacts added, solve continued) per step; 0: the contacts of the start of the step only"});
      v.field("redetect_iterates", iterates,
              {Unit::none, Range::any(),
               "also re-detect at every accepted Newton iterate (a crossing is caught where it happens, but the contact set then depends on the iterates' path); else at converged solutions only"});
    }
    static Checker validate(const Params& p) {
      Checker c("contact");
      c.require(p.thickness >= 0, "thickness", p.thickness, ">= 0")
          .require(p.margin >= 0, "margin", p.margin, ">= 0")
          .require(p.projection_tolerance >= 0, "projection_tolerance", p.projection_tolerance, ">= 0");
      validate_redetection(c, p.redetection_depth, p.max_redetections);
      return c;
    }
    static void validate_redetection(Checker& c, double depth, int rounds) {
      c.require(depth >= 0, "redetection_depth", depth, ">= 0")
          .require(rounds >= 0 && rounds <= 100, "max_redetections", rounds, "in [0, 100]");
    }
  };

  /// How a contact treats the tangential directions during a step.
  enum class Mode : unsigned char {
    frictionless,  ///< normal constraint only (mu = 0, or a vertex touching several obstacles)
    stick,         ///< full 3D constraint: the vertex moves with the obstacle
    slide,         ///< normal constraint + explicit kinetic friction force
  };

  /// One vertex-obstacle contact.
  struct Contact {
    int vertex = -1;
    int obstacle = -1;
    Mode mode = Mode::frictionless;
    double normal_force = 0;                                ///< lambda_n [N] of the last solve (or the impact estimate)
    Eigen::Vector3d slip = Eigen::Vector3d::Zero();         ///< unit slip direction (slide)
    Eigen::Vector3d friction = Eigen::Vector3d::Zero();     ///< kinetic friction force of this step [N] (slide)
    Eigen::Vector3d anchor = Eigen::Vector3d::Zero();       ///< stick: target position at the end of the step [m]
  };

  ObstacleConstraints(const Scene& scene, const Params& prm);
  void declare(AssemblyPlan&) {}
  /// Detection and the friction state of the step (see the file comment). Reports the
  /// contacts, the sticking ones, and in `released` the contacts of the last step dropped
  /// now because vertex and obstacle separate (those whose reaction pulled were counted by
  /// the end of the last step, which released them).
  ContactReport begin_step(const State& s, double dt);
  /// -F^T x summed over the sliding contacts (the explicit kinetic friction) [J].
  double energy(const State& s) const;
  /// g_i -= F_c for every sliding contact c of vertex i.
  void add_gradient(const State& s, Eigen::VectorXd& g) const;
  void add_hessian(const State&, ElementBuffer&, HessianMode) const {}

  /// The constraints on the increment dx of a Newton direction at the iterate `trial`
  /// (positions x_k + d): `out` is reset to trial's vertex count and receives one normal
  /// constraint per contact, or the full 3D constraint of a sticking one (file comment).
  void constraints(const State& trial, ConstraintSet& out) const;
  /// Re-detection (`HasRedetection`, framework/concepts.hpp): every free vertex that the
  /// solution positions (or a Newton iterate's) `trial` put deeper than `redetection_depth` below the thickness
  /// surface of an obstacle it has no contact with gets that contact, made as a new
  /// contact of the step from the start-of-step state `start` (impact cone, anchor), and
  /// the step's constraints are updated. Returns the number added; 0 when none, or once
  /// `max_redetections` rounds of this step found some; their vertices are appended to
  /// `vertices`. The integrator then moves them back to its initial guess (outside the
  /// obstacle: no contact was made there) and continues the solve with the new
  /// constraints: a vertex that crossed during the solve is brought back by the solve, with
  /// the velocity and the reaction that go with it, onto the surface it approached, instead
  /// of the end-of-step projection moving it alone (from deep inside, the nearest surface of
  /// a box can be a side face, or a face shared with another box).
  /// `converged`: trial is a converged solution (else an intermediate Newton iterate, where
  /// re-detection runs only with `redetect_iterates`).
  int redetect(const State& start, const State& trial, double dt, std::vector<int>& vertices, bool converged);

  /// #V*3 forces the constraints exert at the accepted solution [N] (zero off the
  /// constrained directions); read by the next `end_step`.
  void accept_reactions(const Eigen::VectorXd& force);

  /// Release, friction modes and the projection (file comment). `s` holds q_{k+1}, v_{k+1}.
  ContactReport end_step(State& s, double dt);

  /// Checkpoints: what a step hands the next, the contacts (`contacts`: vertex, obstacle,
  /// mode, normal force, slip, friction force and anchor, 13 values each) and the pairs
  /// released at the end of the step (`released`: vertex, obstacle). A checkpoint without
  /// them (another contact strategy) restores no contacts, as at the start of a run.
  void save(Checkpoint& c, std::string_view prefix) const;
  void restore(const Checkpoint& c, std::string_view prefix);

  /// The active contacts of the current step.
  const std::vector<Contact>& contacts() const { return contacts_; }
  /// The report of the last `end_step` (the simulator forwards only part of it).
  const ContactReport& last_response() const { return last_response_; }
  /// Largest depth of a free vertex below the thickness surface of an obstacle posed at
  /// the end of the current step [m] (0: none).
  double max_penetration(const State& s) const;

 private:
  void respond(State& s, double dt, ContactReport& r);
  /// The contact of vertex i with obstacle o for this step from the start state s: a kept
  /// one keeps its friction state, a new one gets its mode from the impact cone.
  Contact make_contact(int i, int o, const State& s, double dt, const Contact* kept) const;
  /// The step's friction set-up of contacts_ (sorted): several obstacles at a vertex give
  /// normal constraints only; anchors of sticking contacts, kinetic forces of sliding ones.
  /// Returns the number sticking.
  int prepare_contacts(const State& s);
  /// Which of the contacts [a, b) of one vertex (sorted, same vertex) constrain it at x, as
  /// a bit mask over c - a (file comment, "Several obstacles at a vertex").
  unsigned effective(size_t a, size_t b, const Eigen::Vector3d& x) const;
  Eigen::Vector3d carry(int o, const Eigen::Vector3d& x) const;      // T(x)
  Eigen::Vector3d obstacle_velocity(int o, const Eigen::Vector3d& x, double dt) const;  // v_o(x) at the end
  static long long key(int vertex, int obstacle, int num_obstacles) {
    return static_cast<long long>(vertex) * num_obstacles + obstacle;
  }

  std::vector<ObstacleSpec> obstacles_;
  std::vector<ObstaclePose> start_, end_;  // poses at t_k and t_{k+1}
  Eigen::VectorXd mass_;
  std::vector<unsigned char> free_;
  Params prm_;
  std::vector<Contact> contacts_;          // sorted by (vertex, obstacle)
  std::vector<long long> released_;        // keys released at the end of the last step (sorted)
  Eigen::VectorXd reactions_;              // from accept_reactions
  bool have_reactions_ = false;
  int redetections_ = 0;                   // re-detection rounds of this step that added contacts
  int redetected_ = 0;                     // contacts they added
  ContactReport last_response_;
};

static_assert(ContactStrategy<ObstacleConstraints>);
static_assert(HasConstraints<ObstacleConstraints>);
static_assert(HasRedetection<ObstacleConstraints>);

}  // namespace weft::contact
