#pragma once
/// \file concepts.hpp
/// The four policy kinds. Each is documented as associated types, valid expressions and
/// semantics (Boost.Odeint style). Conformance is checked with `static_assert` right after
/// each implementation.
#include <Eigen/Core>

#include <concepts>
#include <functional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/constraints.hpp"
#include "framework/state.hpp"
#include "framework/status.hpp"

namespace weft {

struct Scene;  // framework/scene.hpp
struct StepProblem;

/// Which Hessian an energy returns.
enum class HessianMode {
  exact,      ///< the true Hessian (indefinite in general: compressed membrane edges, bent hinges)
  projected,  ///< every element's Hessian projected to positive semi-definite
};
inline constexpr std::array<std::string_view, 2> hessian_mode_names = {"exact", "projected"};

/// Named terms of an energy, for statistics: (name, value in J).
using EnergyTerms = std::vector<std::pair<std::string, double>>;

/// Every policy: a `Params` aggregate with defaults and a `name`.
template <class P>
concept Component = requires {
  typename P::Params;
  { P::name } -> std::convertible_to<std::string_view>;
} && std::default_initializable<typename P::Params>;

/// Potential energy V(x) summed over elements, with exact gradient and Hessian.
///   construction: `M(const Scene&, const M::Params&)`; throws ConfigError on bad input.
template <class M>
concept EnergyModel = Component<M> && std::constructible_from<M, const Scene&, const typename M::Params&> &&
    requires(M& m, const M& cm, const State& s, Eigen::VectorXd& g, ElementBuffer& buf, AssemblyPlan& plan,
             HessianMode mode, EnergyTerms& terms) {
      m.declare(plan);                         // register element stencils, once per topology
      { cm.energy(s) } -> std::same_as<double>;  // V(x) [J]
      cm.add_gradient(s, g);                   // g += dV/dx; never resizes
      cm.add_hessian(s, buf, mode);            // writes (overwrites) the model's element blocks
      cm.energy_terms(s, terms);               // appends one (name, value) per term
      { cm.admissible(s) } -> std::same_as<bool>;  // false: the state is outside the model's domain
    };

/// Optional hook of an energy model: called once before each step with the state at its
/// start and the time at its end, e.g. to update an animated rest state (methods/shells §5).
template <class M>
concept HasBeginStep = requires(M& m, const State& s, double t_end) { m.begin_step(s, t_end); };

/// Contact handling within and after the implicit solve.
///   construction: `C(const Scene&, const C::Params&)`.
///   `provides_potential`: contact acts through potential terms inside the solve (so an
///   integrator that minimises a potential may use it).
template <class C>
concept ContactStrategy = Component<C> && std::constructible_from<C, const Scene&, const typename C::Params&> &&
    requires(C& c, const C& cc, const State& s, State& out, Eigen::VectorXd& g, ElementBuffer& buf,
             AssemblyPlan& plan, double dt, HessianMode mode) {
      { C::provides_potential } -> std::convertible_to<bool>;
      c.declare(plan);                                       // stencils of potential terms (may be none)
      { c.begin_step(s, dt) } -> std::same_as<ContactReport>;  // detection; caches the active set
      { cc.energy(s) } -> std::same_as<double>;              // potential terms of the active set
      cc.add_gradient(s, g);
      cc.add_hessian(s, buf, mode);                          // writes its element blocks (exact or PSD)
      { c.end_step(out, dt) } -> std::same_as<ContactReport>;  // post-solve response (impulses, ...)
    };

/// Optional marker of a contact strategy that does nothing (`static constexpr bool inert =
/// true`, e.g. NoContact): the simulators skip the contact stage altogether, so a scene
/// without contact does not even run the stage's timer.
template <class C>
concept InertContact = requires { requires C::inert; };

/// Solves A x = b for the Newton systems. Eigen-like life cycle.
template <class L>
concept LinearSolver = Component<L> && std::constructible_from<L, const typename L::Params&> &&
    requires(L& l, const BlockCsr& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
      { l.analyze_pattern(A) } -> std::same_as<Status>;  // once per pattern
      { l.factorize(A) } -> std::same_as<Status>;        // new values, same pattern
      { l.solve(b, x) } -> std::same_as<LinearReport>;   // x holds the initial guess on entry
    };

/// Optional hook of a linear solver: the constraint set and positions of the next
/// `factorize` (framework/constraints.hpp). Solvers without it require an unconstrained
/// system (the integrators then filter fixed rows themselves).
template <class L>
concept HasSolveContext = requires(L& l, const SolveContext& ctx) { l.set_context(ctx); };

/// Optional hook of a linear solver: a new time step begins (the integrator calls
/// `l.begin_step()` before the step's first factorize). Solvers that keep a preconditioner
/// per step (SaAmg with reuse = step) refresh it at the next factorize.
template <class L>
concept HasStepHook = requires(L& l) { l.begin_step(); };

/// Optional hook of a contact strategy: equality constraints inside the implicit solve
/// (Baraff & Witkin 1998; methods/integration-and-contact §10, methods/multigrid §7). The integrators hand them to the
/// linear solver, which must then model `HasSolveContext` (a static_assert says so).
///   `cc.constraints(trial, set)`: resets `set` to trial's vertex count and fills it with
///     the constraints n^T dx_i = value on the increment dx of the Newton direction at the
///     iterate `trial` (positions x_k + d); values are measured from trial's positions,
///     so `x_k + d + set.target()` satisfies them to first order.
///   `c.accept_reactions(force)`: at the accepted solution d, the #V*3 forces [N] the
///     constraints exert, (I - S) f(d) / dt^2 with f the backward Euler residual (a
///     linearly implicit step: that of the linear system it solved; see
///     integrators/step_system.hpp); called once per successful step, before `end_step`.
/// Semantics: the integrator's iterates satisfy the constraints (it projects its initial
/// guess with the targets), its gradient is filtered (S f), and it stops on ||S f||.
template <class C>
concept HasConstraints = requires(C& c, const C& cc, const State& trial, ConstraintSet& set, const Eigen::VectorXd& force) {
  cc.constraints(trial, set);  // constraints of the Newton direction at `trial`
  c.accept_reactions(force);   // constraint forces at the solution [N]
};

/// Optional hook of a constraint strategy: re-detection inside the step. The constraints
/// are fixed at the start of the step from the positions and the prediction, so a vertex
/// can cross an obstacle during the solve without any constraint seeing it (the end-of-step
/// projection then moves it without a consistent velocity). After every accepted Newton
/// update (`converged` false) and after a converged solve (`converged` true) the integrator
/// calls `c.redetect(start, trial, dt, vertices, converged)` with the start-of-step state and
/// the positions; the strategy adds contacts for what they put inside, appends
/// their vertices to `vertices` and returns how many contacts it added. When > 0 the
/// integrator moves those vertices back to where its initial guess had them (outside: they
/// were not in contact there), makes the iterate feasible and continues the Newton
/// iteration from it; the strategy bounds the number of rounds (it returns 0 once its
/// budget for the step is spent).
template <class C>
concept HasRedetection = HasConstraints<C> && requires(C& c, const State& start, const State& trial, double dt,
                                                       std::vector<int>& vertices, bool converged) {
  { c.redetect(start, trial, dt, vertices, converged) } -> std::same_as<int>;
};

/// Optional hook of a contact strategy whose Hessian couples vertices that change from step
/// to step (e.g. cloth-cloth repulsion springs): after `begin_step`, `c.update_pattern(plan)`
/// replaces the elements of its own groups (`AssemblyPlan::replace_group`) and returns true
/// when they changed; the simulator then finalises the plan again and remakes its buffer,
/// matrix and the linear solver's symbolic analysis. Called only between steps.
template <class C>
concept HasDynamicPattern = requires(C& c, AssemblyPlan& plan) {
  { c.update_pattern(plan) } -> std::same_as<bool>;
};

/// Optional hook of a contact strategy whose potential is a barrier, infinite where the
/// cloth touches or intersects (contact/barrier.hpp): every iterate of the solve must stay
/// intersection-free. `c.step_bound(at, dx)` returns the largest s in (0, 1] such that the
/// straight motion from `at`'s positions by s dx stays at a positive distance (continuous
/// collision detection with a safety margin), and makes the strategy's potential exact on
/// that whole segment (it caches the pairs within its range there). The integrators that
/// minimise the incremental potential call it for every Newton direction and for the
/// step's initial guess, and search the line only up to the bound; the others must refuse
/// such a strategy (a static_assert).
template <class C>
concept HasStepBound = requires(C& c, const State& at, const Eigen::VectorXd& dx) {
  { c.step_bound(at, dx) } -> std::same_as<double>;
};

/// Optional hook of a strategy with a step bound whose pairs couple vertices the step's
/// pattern does not (pairs met during the step, off the predicted motion the pattern was
/// made for): before each Newton matrix is assembled, `c.refresh_pattern(plan)` adds them to
/// its group (`AssemblyPlan::replace_group`) and returns true when it did; the integrator
/// then finalises the plan again and remakes its buffer, matrix and symbolic analysis.
template <class C>
concept HasPatternRefresh = HasStepBound<C> && requires(C& c, AssemblyPlan& plan) {
  { c.refresh_pattern(plan) } -> std::same_as<bool>;
};

/// What a compliance-based contact response needs from the implicit step it follows: solves
/// with the step's last Newton matrix A = M~ + dt^2 K (the matrix of the last factorisation;
/// rows of pinned and scripted vertices decoupled, so their components of a solution must
/// be ignored), and dt. Valid until the strategy's next `end_step` returns.
struct SystemSolve {
  std::function<LinearReport(const Eigen::VectorXd& rhs, Eigen::VectorXd& x)> solve;  ///< x = A^-1 rhs (x: initial guess)
  const BlockCsr* matrix = nullptr;  ///< A
  double dt = 0;
};

/// Optional hook of a contact strategy that applies the implicit system's compliance
/// D = A^-1 in its response (methods/rod-contact §8 (b), "linear compliance"): after a successful
/// step and before `end_step`, the integrators call `c.accept_system(solve)`.
template <class C>
concept HasSystemCompliance = requires(C& c, const SystemSolve& s) { c.accept_system(s); };

/// Advances a `StepProblem` by one time step.
///   construction: `I(const I::Params&)`.
template <class I, class E, class C, class L>
concept Integrator = Component<I> && std::constructible_from<I, const typename I::Params&> &&
    requires(I& i, const E& e, C& c, L& l, StepProblem& p) {
      { i.step(e, c, l, p) } -> std::same_as<StepReport>;
    };

}  // namespace weft
