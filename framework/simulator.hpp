#pragma once
/// \file simulator.hpp
/// `Simulator<Energy, Integrator, Contact, Linear>`: a concrete simulator composed from
/// four policies at compile time. It owns the state, the assembly plan (pattern built once
/// per topology) and the policies, and advances the scene one time step per `step()`.
#include <Eigen/Core>

#include <cmath>
#include <memory>
#include <vector>

#include <fmt/format.h>

#include "framework/block_csr.hpp"
#include "framework/concepts.hpp"
#include "framework/params_json.hpp"
#include "framework/scene.hpp"
#include "framework/status.hpp"

namespace weft {

/// What an integrator needs for one step. The integrator updates `state` (positions,
/// velocities; not the time) only when it succeeds.
struct StepProblem {
  State& state;                          ///< q_k, v_k on entry
  double dt;                             ///< [s]
  const Eigen::VectorXd& target;         ///< #V*3: positions at t + dt of non-free vertices
  double mass_damping;                   ///< [1/s] c in the drag force -c M v
  const AssemblyPlan& plan;              ///< element -> matrix map
  ElementBuffer& buffer;                 ///< scratch for element Hessians
  BlockCsr& matrix;                      ///< scratch with the plan's pattern
  const std::vector<unsigned char>& fixed;  ///< #V: 1 for pinned or scripted vertices
  bool& pattern_analyzed;                ///< set once the linear solver analysed the pattern
};

namespace detail {
template <class P>
void validate_into(const P& p, Checker& c) {
  if constexpr (requires { P::validate(p); }) c.merge(P::validate(p));
}
}  // namespace detail

template <EnergyModel Energy, class Integ, ContactStrategy Contact, LinearSolver Linear>
  requires Integrator<Integ, Energy, Contact, Linear>
class Simulator {
 public:
  using EnergyType = Energy;
  using IntegratorType = Integ;
  using ContactType = Contact;
  using LinearType = Linear;

  /// The params tree; its sections are the scene file's "energy", "integrator",
  /// "contact" and "linear" objects.
  struct Params {
    typename Energy::Params energy{};
    typename Integ::Params integrator{};
    typename Contact::Params contact{};
    typename Linear::Params linear{};
    template <class V>
    void visit(V& v) {
      v.section("energy", energy);
      v.section("integrator", integrator);
      v.section("contact", contact);
      v.section("linear", linear);
    }
    /// Cross-field checks of every policy, all at once.
    static Checker validate(const Params& p) {
      Checker c;
      detail::validate_into(p.energy, c);
      detail::validate_into(p.integrator, c);
      detail::validate_into(p.contact, c);
      detail::validate_into(p.linear, c);
      return c;
    }
  };

  Simulator(Scene scene, const Params& prm)
      : scene_(std::move(scene)),
        prm_(prm),
        energy_(scene_, prm_.energy),
        integrator_(prm_.integrator),
        contact_(scene_, prm_.contact),
        linear_(prm_.linear) {
    Params::validate(prm_).throw_if_failed();
    static_assert(!Integ::minimizes_potential || Contact::provides_potential || HasConstraints<Contact>,
                  "this integrator minimises a potential: the contact strategy must act through potential terms "
                  "or equality constraints of the solve");
    state_ = scene_.initial_state();
    energy_.declare(plan_);
    contact_.declare(plan_);
    plan_.finalize(state_.num_vertices());
    buffer_ = plan_.make_buffer();
    matrix_ = plan_.pattern();
    fixed_.resize(state_.num_vertices());
    for (int i = 0; i < state_.num_vertices(); ++i) fixed_[i] = state_.is_free(i) ? 0 : 1;
  }
  Simulator(const Simulator&) = delete;
  Simulator& operator=(const Simulator&) = delete;

  /// Advance by one time step of `scene().spec.time.dt`. With `time.max_subdivisions` > 0, a
  /// step that fails is retried from its start as two steps of dt/2 (recursively): the report
  /// then counts the substeps, keeps the first failure in `retry_reason` and includes the time
  /// spent on the failed attempts.
  StepReport step() {
    const double dt = scene_.spec.time.dt;
    ++steps_;
    StepReport rep = advance(dt, scene_.spec.time.max_subdivisions);
    rep.step = steps_;
    rep.dt = dt;
    if (rep.ok())
      rep.energy = energies();
    else if (rep.subdivisions > 0)
      rep.message += fmt::format(" (in a substep of dt/{}; the step was first retried because {})", 1 << rep.subdivisions, rep.retry_reason);
    return rep;
  }

  const State& state() const { return state_; }
  /// Writable state, e.g. to set initial conditions before the first step. Topology and
  /// which vertices are free must not change.
  State& state() { return state_; }
  const Scene& scene() const { return scene_; }
  const Params& params() const { return prm_; }
  const Energy& energy_model() const { return energy_; }
  /// Kinetic and potential energies of the current state.
  EnergyReport energies() const {
    EnergyReport e;
    e.kinetic = state_.kinetic_energy();
    energy_.energy_terms(state_, e.terms);
    for (const auto& [name, value] : e.terms) e.potential += value;
    return e;
  }
  /// dV/dx at the current state with non-free entries zeroed: the static force residual.
  Eigen::VectorXd potential_gradient() const {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(state_.x.size());
    energy_.add_gradient(state_, g);
    state_.zero_constrained(g);
    return g;
  }

 private:
  // Advances by dt, as 2^k substeps when an attempt fails and `depth` allows it.
  StepReport advance(double dt, int depth) {
    if (depth == 0) return attempt(dt);
    const State start = state_;  // the policies leave the state alone only when the integrator fails
    StepReport first = attempt(dt);
    if (first.ok() || first.status == Status::invalid_input || first.status == Status::interrupted) return first;
    state_ = start;
    StepReport rep = advance(0.5 * dt, depth - 1);
    if (rep.ok()) rep.merge_substep(advance(0.5 * dt, depth - 1));
    rep.times += first.times;
    rep.discarded_newton_iterations += first.newton.iterations;
    rep.subdivisions += 1;
    rep.retry_reason = fmt::format("at dt = {} s, {}: {}", dt, first.failed_stage, first.message);
    return rep;
  }

  // One attempt at a step of dt from the current state.
  StepReport attempt(double dt) {
    StepReport rep;
    rep.dt = dt;
    scene_.constrained_positions(state_.t + dt, state_, target_);
    if constexpr (HasBeginStep<Energy>) energy_.begin_step(state_, state_.t + dt);
    if constexpr (!InertContact<Contact>) {
      ScopedTimer t(rep.times, Stage::contact);
      rep.contact = contact_.begin_step(state_, dt);
      if constexpr (HasDynamicPattern<Contact>)
        if (rep.contact.status == Status::success && contact_.update_pattern(plan_)) {
          // The contact couplings changed: a new pattern, and a new symbolic analysis.
          plan_.finalize(state_.num_vertices());
          buffer_ = plan_.make_buffer();
          matrix_ = plan_.pattern();
          analyzed_ = false;
          ++rep.contact.pattern_updates;
        }
    }
    if (rep.contact.status != Status::success) return rep.fail("contact detection", rep.contact.status, rep.contact.message, state_.t);

    StepProblem problem{state_, dt, target_, scene_.spec.damping.mass, plan_, buffer_, matrix_, fixed_, analyzed_};
    const StepReport r = integrator_.step(energy_, contact_, linear_, problem);
    rep.newton = r.newton;
    rep.linear = r.linear;
    rep.times += r.times;
    if (r.status != Status::success) return rep.fail(r.failed_stage, r.status, r.message, state_.t);
    if constexpr (!InertContact<Contact>) {
      ScopedTimer t(rep.times, Stage::contact);
      rep.contact.merge_end(contact_.end_step(state_, dt));
      if (rep.contact.status != Status::success)
        return rep.fail("contact response", rep.contact.status, rep.contact.message, state_.t);
    }
    if (!state_.x.allFinite() || !state_.v.allFinite())
      return rep.fail("integrator", Status::numerical_issue, "non-finite positions or velocities after the step", state_.t);
    state_.t += dt;
    rep.time = state_.t;
    return rep;
  }

  Scene scene_;
  Params prm_;
  Energy energy_;
  Integ integrator_;
  Contact contact_;
  Linear linear_;
  State state_;
  AssemblyPlan plan_;
  ElementBuffer buffer_;
  BlockCsr matrix_;
  std::vector<unsigned char> fixed_;
  Eigen::VectorXd target_;
  bool analyzed_ = false;
  int steps_ = 0;
};

}  // namespace weft
