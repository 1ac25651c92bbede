#pragma once
/// \file simulator.hpp
/// `Simulator<Energy, Integrator, Contact, Linear>`: a concrete simulator composed from
/// four policies at compile time. It owns the state, the assembly plan (pattern built once
/// per topology) and the policies, and advances the scene one time step per `step()`.
#include <Eigen/Core>

#include <cmath>
#include <memory>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "framework/block_csr.hpp"
#include "framework/checkpoint.hpp"
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
  AssemblyPlan& plan;                    ///< element -> matrix map (a barrier strategy may extend it within the step)
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
  /// Every policy is stateless between steps or saves its state (framework/checkpoint.hpp):
  /// the simulator then writes and reads checkpoints, and a step that fails leaves it where
  /// the step started.
  static constexpr bool checkpointable =
      CheckpointPolicy<Energy> && CheckpointPolicy<Integ> && CheckpointPolicy<Contact> && CheckpointPolicy<Linear>;

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
  ///
  /// A step that fails leaves the state (and, when `checkpointable`, the policies' state:
  /// contact sets, friction modes, warm starts) as they were at its start, so that the
  /// failure replays from a checkpoint taken then; only the step counter moves.
  StepReport step() {
    const double dt = scene_.spec.time.dt;
    ++steps_;
    const Snapshot start = snapshot();
    StepReport rep;
    try {
      rep = advance(dt, scene_.spec.time.max_subdivisions, &start);
    } catch (const std::exception& e) {
      // A broken invariant or an allocation that failed: a bug or a machine limit, not a
      // numerical outcome. It is reported as a failed step (stage "internal") whose start
      // state is restored, so that it replays from a checkpoint like any other.
      rep = StepReport{};
      rep.dt = dt;
      rep.fail("internal", Status::numerical_issue,
               fmt::format("internal error: {}", dynamic_cast<const std::bad_alloc*>(&e) ? "out of memory (std::bad_alloc)" : e.what()),
               state_.t);
    }
    if (!rep.ok()) rollback(start);
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

  /// The state between two steps, to the bit: time, step count, positions, velocities and
  /// the policies' state (framework/checkpoint.hpp). Header: "kind" = "cloth", "step",
  /// "time", "vertices", and "resume_caveats" (why a resumed run would not repeat this one
  /// to the bit; empty when it will).
  void save(Checkpoint& c) const
    requires checkpointable
  {
    c.header["kind"] = "cloth";
    c.header["step"] = steps_;
    c.header["time"] = state_.t;
    c.header["vertices"] = state_.num_vertices();
    c.header["faces"] = scene_.mesh.num_faces();
    c.header["topology"] = Digest().add_matrix(scene_.mesh.faces()).hex();
    c.header["rest_shape"] = Digest().add_matrix(scene_.mesh.rest()).hex();
    Json caveats = Json::array();
    const auto caveat = [&](const auto& policy) {
      if constexpr (requires { { policy.resume_caveat() } -> std::convertible_to<std::string>; })
        if (std::string why = policy.resume_caveat(); !why.empty()) caveats.push_back(why);
    };
    caveat(energy_), caveat(integrator_), caveat(contact_), caveat(linear_);
    c.header["resume_caveats"] = caveats;
    c.put("x", state_.x);
    c.put("v", state_.v);
    save_policies(c);
  }
  /// Continue from a state `save` wrote, with this scene's mesh, motions and parameters
  /// (they may differ from the run that wrote it, e.g. to replay a failing step with other
  /// parameters; the vertex count must match). Throws ConfigError naming what does not
  /// match; the simulator is unchanged then.
  void restore(const Checkpoint& c)
    requires checkpointable
  {
    const Json& h = c.header;
    if (h.value("kind", "") != "cloth")
      throw ConfigError(fmt::format("checkpoint holds a '{}' state; this combination simulates cloth", h.value("kind", "?")));
    if (!h.contains("step") || !h["step"].is_number_integer() || !h.contains("time") || !h["time"].is_number() ||
        !h.contains("vertices") || !h["vertices"].is_number_integer())
      throw ConfigError("checkpoint header lacks 'step', 'time' or 'vertices'");
    if (h["vertices"].get<long long>() != state_.num_vertices())
      throw ConfigError(fmt::format("checkpoint holds {} vertices; this scene's mesh has {}", h["vertices"].dump(), state_.num_vertices()));
    // The mesh must be this scene's, not only as large (checkpoints of older builds carry no digests).
    if (h.contains("topology") && h["topology"] != Digest().add_matrix(scene_.mesh.faces()).hex())
      throw ConfigError(fmt::format("checkpoint was written for another mesh: its {} faces are not this scene's {} faces (same vertex count, "
                                    "other triangles); resume it with the scene that wrote it",
                                    h.value("faces", Json("?")).dump(), scene_.mesh.num_faces()));
    if (h.contains("rest_shape") && h["rest_shape"] != Digest().add_matrix(scene_.mesh.rest()).hex())
      throw ConfigError("checkpoint was written for another rest shape: the faces match but the rest positions differ (another mesh file, "
                        "size, resolution, scale, translate or seed); resume it with the scene that wrote it");
    const long long n = 3LL * state_.num_vertices();
    const auto& x = c.get("x", n);
    const auto& v = c.get("v", n);
    require_finite(c, {"x", "v"});
    const Snapshot before = snapshot();
    try {
      restore_policies(c);
    } catch (...) {
      rollback(before);  // a policy's array was missing or of the wrong size
      throw;
    }
    state_.x = Eigen::Map<const Eigen::VectorXd>(x.data(), n);
    state_.v = Eigen::Map<const Eigen::VectorXd>(v.data(), n);
    state_.t = h["time"].get<double>();
    steps_ = h["step"].get<int>();
    if constexpr (HasBeginStep<Energy>) energy_.begin_step(state_, state_.t);  // animated rest shapes at t
  }

 private:
  // The state at a step's start: the policies' too when they take part in checkpoints.
  struct Snapshot {
    State state;
    Checkpoint policies;
  };
  Snapshot snapshot() const {
    Snapshot s{state_, {}};
    if constexpr (checkpointable) save_policies(s.policies);
    return s;
  }
  void rollback(const Snapshot& s) {
    state_ = s.state;
    if constexpr (checkpointable) restore_policies(s.policies);
    if constexpr (HasBeginStep<Energy>) energy_.begin_step(state_, state_.t);  // animated rest shapes back at t
  }
  // The policies' arrays, prefixed by their section of the params tree.
  void save_policies(Checkpoint& c) const {
    if constexpr (SavesState<Energy>) energy_.save(c, "energy.");
    if constexpr (SavesState<Integ>) integrator_.save(c, "integrator.");
    if constexpr (SavesState<Contact>) contact_.save(c, "contact.");
    if constexpr (SavesState<Linear>) linear_.save(c, "linear.");
  }
  void restore_policies(const Checkpoint& c) {
    if constexpr (SavesState<Energy>) energy_.restore(c, "energy.");
    if constexpr (SavesState<Integ>) integrator_.restore(c, "integrator.");
    if constexpr (SavesState<Contact>) contact_.restore(c, "contact.");
    if constexpr (SavesState<Linear>) linear_.restore(c, "linear.");
  }

  // Advances by dt, as 2^k substeps when an attempt fails and `depth` allows it. `start`:
  // a snapshot of the current state when the caller has one (else one is taken if needed).
  StepReport advance(double dt, int depth, const Snapshot* start = nullptr) {
    if (depth == 0) return attempt(dt);
    std::optional<Snapshot> own;
    if (!start) start = &own.emplace(snapshot());  // the retry starts where the failed attempt did
    StepReport first = attempt(dt);
    if (first.ok() || first.status == Status::invalid_input || first.status == Status::interrupted) return first;
    rollback(*start);
    StepReport rep = advance(0.5 * dt, depth - 1, start);  // the first half starts from the same state
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
    if (!std::isfinite(r.newton.final_residual))
      return rep.fail("integrator", Status::numerical_issue, "the step's solve ended with a non-finite residual", state_.t);
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
