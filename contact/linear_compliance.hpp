#pragma once
/// \file linear_compliance.hpp
/// `LinearCompliance`: contact response after the implicit solve through the compliance
/// of the step's linear system, D = A^-1 with A = M~ + dt^2 K the last Newton matrix
/// (methods/rod-contact §8 (b), "linear compliance": Otaduy et al. 2009 / the thesis' chapter 9
/// baseline), frictional contacts solved exactly on the smooth cone by Gauss-Seidel over
/// single-contact Coulomb problems (contact_gauss_seidel.hpp, coulomb.hpp), with the
/// `Impulse` pipeline (CCD impulses and rigid impact zones) as the failsafe. No potential
/// terms (energy 0, like `Impulse`): the integrator advances the elastic dynamics alone.
///
/// Conventions (those of `Impulse`, impulse.hpp): x0 the start-of-step positions, v the
/// step velocities, x1 = x0 + dt v; every correction changes v and moves x1 with it (fully
/// inelastic, methods/integration-and-contact §13). Pinned and scripted vertices have infinite mass: their columns
/// of the contact Jacobian are zero, their motion enters the free velocity u_f.
///
/// Units. The backward Euler residual with a contact force F added is
///     f(d) = M~ d - dt M v_k + dt^2 (grad V(q_k + d) - F),
/// so, linearised at the accepted d (f = 0 there), a force F held over the step changes
/// the displacement by Delta d = dt^2 A^-1 F, i.e. an impulse p = dt F changes the
/// velocity v = d / dt by Delta v = A^-1 p. The compliance is thus D = A^-1 [1/kg]; with
/// K = 0 and no damping it is M^-1, the compliance of `Impulse`. Responses r are impulses
/// [N s] in each contact's local frame (normal first), u = H v relative velocities [m/s],
/// W = H A^-1 H^T [1/kg], and the GS tolerance is a velocity (the FB residual with the
/// impulse scaled by tr(W_kk) / 3).
///
/// Algorithm of `end_step`:
///  1. Contacts at the end positions x1 (the integrator's result), in a fixed order:
///     - obstacles: per free vertex i and obstacle, phi1 = phi(x1_i, t1) < h; frame from
///       the end-of-step normal n1 (methods/integration-and-contact §11.2); u_f = (-(h - phi1) / dt,
///       t1 . (v_i - w), t2 . (v_i - w)), w the obstacle's velocity at the contact point;
///       mu = the obstacle's `friction`. u_n >= 0 then means n1 . Delta v_i >=
///       (h - phi1) / dt: the vertex ends at the thickness or beyond (to first order; exact
///       on planes), as Impulse's obstacle impulse; the tangential velocity is relative.
///     - cloth-cloth (`self_contact`): the proximity pairs within h at x1, filtered as in
///       Impulse's repulsion stage (crossed during the step: left to CCD; material points
///       closer than h at rest: no contact); weights gamma and normal n (B to A);
///       u_f = ((s1 - h) / dt, T^T sum_j gamma_j v_j), s1 = n . sum_j gamma_j x1_j;
///       mu = `cloth_friction`.
///  2. H: three rows per contact, F_k^T sum_j gamma_j (e_j^T (x) I_3) over free stencil
///     vertices (obstacle contacts: gamma = 1 on the vertex). W = H A^-1 H^T, formed
///     column by column: 3m solves with A (rows of fixed vertices ignored).
///  3. Gauss-Seidel over the contacts (DenseDelassus) to `tolerance` or `max_sweeps`; with
///     `solver = newton`, when the sweeps stop above the tolerance, semismooth Newton on the
///     contacts' Fischer-Burmeister system (contact_newton.hpp) from there, up to
///     `solver_max` steps. Plain Gauss-Seidel stalls when hundreds of contacts are coupled
///     through the dense A^-1 (a sheet resting on another); Newton converges there.
///  4. v += A^-1 H^T r (one more solve), x1 = x0 + dt v.
///  5. The failsafe: `Impulse::end_step` on the result (obstacle crossings during the step,
///     repulsion where the linearisation left a pair closer than h, CCD impulses, impact
///     zones). It keeps Impulse's guarantees: no free vertex deeper than the thickness at
///     an obstacle, no cloth-cloth intersection given an intersection-free start.
/// A contact set with no accepted system (an integrator that does not call
/// `accept_system`) falls back to D = M^-1: the impulse response on the same contacts.
///
/// Solves with A: `own_factorization` (default) factorises A again with a sparse LDL^T
/// (exact, symmetric W whatever the step's solver); otherwise the step's own solver is
/// used (`SystemSolve::solve`; an iterative solver makes W inexact and unsymmetric).
/// Cost: one factorisation and 3m + 1 solves per step with contacts, plus W (9 m^2
/// doubles): meant for small contact counts; the rods apply the compliance without
/// forming W (contact_gauss_seidel.hpp, `ComplianceDelassus`).
///
/// Reports: `contacts` (obstacle + cloth contacts of the GS, plus the failsafe's CCD hits),
/// `obstacle_contacts`, `proximity_contacts`, the failsafe's counters; the Gauss-Seidel
/// statistics in `last_report()` (and in `message` when it did not converge).
#include <Eigen/Core>

#include <memory>
#include <string_view>
#include <vector>

#include "contact/contact_gauss_seidel.hpp"
#include "contact/contact_newton.hpp"
#include "contact/impulse.hpp"
#include "framework/concepts.hpp"
#include "framework/params.hpp"
#include "framework/scene.hpp"

namespace weft::contact {

namespace detection {
class CollisionDetector;
}

class LinearCompliance {
 public:
  static constexpr std::string_view name = "linear_compliance";
  static constexpr bool stateless = true;  ///< checkpoints: x0, the poses and the system are taken at each step; the BVH output does not depend on its history
  /// No potential terms (a zero potential, as `Impulse`): a minimising integrator may use it.
  static constexpr bool provides_potential = true;

  struct Params {
    /// Thickness, self contact, cloth friction and the failsafe: the `impulse` fields, in
    /// the same section (the failsafe is an `Impulse` with these parameters; with D = M^-1
    /// this strategy reproduces it).
    Impulse::Params impulse;
    double tolerance = 1e-6;       ///< [m/s] > 0: Gauss-Seidel stops when the max FB residual is below
    int max_sweeps = 200;          ///< Gauss-Seidel sweeps, >= 1
    bool own_factorization = true; ///< factorise A with a sparse LDL^T of its own (else the step's solver)
    ContactSolver solver = ContactSolver::gauss_seidel;  ///< the multi-contact solve
    int solver_max = 50;           ///< newton: Newton steps after the sweeps, >= 1
    template <class V>
    void visit(V& v) {
      impulse.visit(v);
      v.field("tolerance", tolerance,
              {Unit::velocity, Range::gt(0), "Gauss-Seidel stops when the largest Fischer-Burmeister residual is below (a velocity)"});
      v.field("max_sweeps", max_sweeps, {Unit::none, Range::closed(1, 1e6), "Gauss-Seidel sweeps at most"});
      v.field("own_factorization", own_factorization,
              {Unit::none, Range::any(), "factorise the step's matrix A again (sparse LDL^T) for the compliance, else solve with the step's linear solver"});
      v.choice("solver", solver, contact_solver_names,
               "multi-contact solve: gauss_seidel (capped at max_sweeps) or newton (Gauss-Seidel, then semismooth Newton to the tolerance)");
      v.field("solver_max", solver_max, {Unit::none, Range::closed(1, 100000), "newton: Newton steps after the Gauss-Seidel sweeps"});
    }
    static Checker validate(const Params& p) {
      Checker c = Impulse::Params::validate(p.impulse);
      c.require(p.tolerance > 0, "tolerance", p.tolerance, "> 0").require(p.max_sweeps >= 1, "max_sweeps", p.max_sweeps, ">= 1");
      c.require(p.solver_max >= 1, "solver_max", p.solver_max, ">= 1");
      return c;
    }
  };

  /// What the last `end_step` did (beyond ContactReport).
  struct Report {
    int obstacle_contacts = 0;  ///< vertex-obstacle contacts in the GS solve
    int cloth_contacts = 0;     ///< cloth-cloth proximity contacts in the GS solve
    GaussSeidelReport gauss_seidel;
    NewtonContactResult newton;  ///< `solver = newton` after unconverged sweeps (else zeros)
    double residual = 0;        ///< [m/s] max FB residual at the end of the contact solve
    bool converged = true;      ///< residual <= tolerance
    int solves = 0;             ///< solves with the compliance (3m + 1)
    bool compliance = false;    ///< D = A^-1 (false: no system accepted, D = M^-1)
    double solve_penetration = 0;  ///< [m] largest h - phi over the obstacle contacts after the GS response, before the failsafe
    std::vector<Eigen::Vector3d> responses;  ///< r_k, local frames (normal first) [N s]
  };

  /// \throws ConfigError for invalid parameters.
  LinearCompliance(const Scene& scene, const Params& prm);
  ~LinearCompliance();
  LinearCompliance(LinearCompliance&&) noexcept;
  LinearCompliance& operator=(LinearCompliance&&) noexcept;

  void declare(AssemblyPlan&) {}
  /// Keeps x0 and the time; starts the failsafe.
  ContactReport begin_step(const State& s, double dt);
  double energy(const State&) const { return 0.0; }
  void add_gradient(const State&, Eigen::VectorXd&) const {}
  void add_hessian(const State&, ElementBuffer&, HessianMode) const {}
  /// The step's system (HasSystemCompliance): kept for `end_step`.
  void accept_system(const SystemSolve& s);
  /// The response on the integrator's end-of-step state (see the file comment).
  ContactReport end_step(State& out, double dt);

  const Params& params() const { return prm_; }
  const Report& last_report() const { return report_; }

 private:
  Params prm_;
  std::vector<ObstacleSpec> obstacles_;
  Eigen::VectorXd rest_;
  std::unique_ptr<detection::CollisionDetector> detector_;
  std::unique_ptr<Impulse> failsafe_;
  Eigen::VectorXd x0_;
  double t0_ = 0;
  bool started_ = false;
  SystemSolve system_;
  bool has_system_ = false;
  Report report_;
};

static_assert(ContactStrategy<LinearCompliance>);
static_assert(HasSystemCompliance<LinearCompliance>);

}  // namespace weft::contact
