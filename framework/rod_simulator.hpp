#pragma once
/// \file rod_simulator.hpp
/// `RodSimulator<Model, Integrator, Contact, Linear>`: elastic rods (hair) with frictional
/// contact, composed at compile time (methods/rod-contact §10.8, §16). Each rod is an independent
/// system in the interleaved DoF layout of framework/rod_set.hpp with a banded Hessian:
///
///   1. per rod, in parallel: the unconstrained backward Euler step d_DEL (the integrator);
///   2. the contact strategy owns the constrained Newton loop: it detects contacts on the
///      trajectory q -> q + d_DEL, groups the rods they link, and corrects d per group with
///      the compliance it uses (M^-1 for impulses, K^-1 frozen for linear compliance, K^-1
///      refreshed per over-stretched rod for ADONIS). It reaches the rods through this
///      class: `body(r)`, `relinearize(r)`, `solve(r, B)`, `residual(r, d, f)`;
///   3. q <- q + d, v <- d / h, frames transported in time.
///
/// The rods' centrelines are exposed as a `State` (positions, velocities, vertex masses,
/// held vertices as scripted), so writers and reports treat rods like cloth vertices.
#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <memory>
#include <type_traits>
#include <new>
#include <vector>

#include "framework/band_matrix.hpp"
#include "framework/checkpoint.hpp"
#include "framework/concepts.hpp"
#include "framework/params_json.hpp"
#include "framework/scene.hpp"
#include "framework/status.hpp"

namespace weft {

/// One rod during a step: the data the integrator and the contact strategies work on.
template <class Model, class Linear>
struct RodBody {
  using Frames = std::decay_t<decltype(std::declval<const Model&>().rest_frames())>;
  Model model;
  Eigen::VectorXd q, v;           ///< DoFs and their rates at the start of the step
  Eigen::VectorXd mass;           ///< per DoF: vertex masses (x entries), twist inertias (theta entries)
  Eigen::VectorXd fext;           ///< external force per DoF (gravity on the x entries)
  Eigen::VectorXd target;         ///< end-of-step values of the held DoFs (other entries unused)
  Eigen::VectorXd d;              ///< displacement of the step (DEL, then corrected by contact)
  std::vector<unsigned char> fixed;  ///< per DoF: 1 when held by the scripted root
  Frames frames;                  ///< reference frames at q (the DEL may move them to its iterate within a step)
  BandMatrix K;                   ///< M + h^2 H at the last linearisation
  Linear lu;                      ///< its factorisation
  double mean_edge = 0;           ///< [m] mean rest edge length
  double radius = 0;              ///< [m] cross-section radius
  int first_vertex = 0;           ///< global index of the rod's first centreline vertex
  int num_vertices() const { return static_cast<int>((q.size() + 1) / 4); }

  RodBody(Model m, Linear l) : model(std::move(m)), lu(std::move(l)) {}
};

template <class Model, class Integ, class Contact, class Linear>
class RodSimulator {
 public:
  using ModelType = Model;
  using IntegratorType = Integ;
  using ContactType = Contact;
  using LinearType = Linear;
  using Body = RodBody<Model, Linear>;

  /// The params tree: the scene file's "integrator" and "contact" sections (a rod's
  /// material is part of the scene's rod family; the banded solver has no parameters).
  struct Params {
    typename Integ::Params integrator{};
    typename Contact::Params contact{};
    template <class V>
    void visit(V& v) {
      v.section("integrator", integrator);
      v.section("contact", contact);
    }
    static Checker validate(const Params& p) {
      Checker c;
      if constexpr (requires { Contact::Params::validate(p.contact); }) c.merge(Contact::Params::validate(p.contact));
      return c;
    }
  };

  RodSimulator(Scene scene, const Params& prm) : scene_(std::move(scene)), prm_(prm), integrator_(prm_.integrator), contact_(scene_, prm_.contact) {
    Params::validate(prm_).throw_if_failed();
    const RodSet& rods = scene_.rods;
    if (rods.num_rods() == 0) throw ConfigError(scene_.path + ": this combination simulates rods and the scene has none (add a \"rods\" family)");
    if (!scene_.spec.cloths.empty())
      throw ConfigError(scene_.path + ": this combination simulates rods only; the scene's cloths need a cloth combination");
    const Eigen::Vector3d g = scene_.spec.gravity;
    bodies_.reserve(rods.num_rods());
    for (int r = 0; r < rods.num_rods(); ++r) {
      const RodSpec& fam = scene_.spec.rods[rods.family[r]];
      Body b(Model(rods.rest[r], fam.material), Linear{});
      const Eigen::Index n = rods.rest[r].size();
      b.q = rods.rest[r];
      b.v = Eigen::VectorXd::Zero(n);
      b.mass = b.model.mass();
      b.fext = Eigen::VectorXd::Zero(n);
      b.fixed.assign(n, 0);
      const int V = rods.rod_vertices(r);
      for (int i = 0; i < V; ++i) {
        b.v.template segment<3>(4 * i) = fam.initial_velocity;
        b.fext.template segment<3>(4 * i) = b.mass[4 * i] * g;
      }
      const int held = held_vertices(rods.root_held[r]);
      for (int i = 0; i < held; ++i) {
        for (int c = 0; c < 3; ++c) b.fixed[4 * i + c] = 1;
        b.v.template segment<3>(4 * i).setZero();
      }
      if (held > 0) b.fixed[3] = 1, b.v[3] = 0;  // the root edge's twist
      b.target = b.q;
      b.d = Eigen::VectorXd::Zero(n);
      b.frames = b.model.rest_frames();
      double len = 0;
      for (int i = 0; i + 1 < V; ++i) len += (b.q.template segment<3>(4 * i + 4) - b.q.template segment<3>(4 * i)).norm();
      b.mean_edge = len / (V - 1);
      b.radius = fam.material.radius;
      b.first_vertex = rods.first[r];
      bodies_.push_back(std::move(b));
    }
    centre_.mass.resize(rods.num_vertices());
    centre_.dof.assign(rods.num_vertices(), Dof::free);
    for (int r = 0; r < rods.num_rods(); ++r) {
      const Body& b = bodies_[r];
      for (int i = 0; i < b.num_vertices(); ++i) {
        centre_.mass[b.first_vertex + i] = b.mass[4 * i];
        if (b.fixed[4 * i]) centre_.dof[b.first_vertex + i] = rods.motion[r] >= 0 ? Dof::scripted : Dof::pinned;
      }
    }
    sync_centrelines();
  }
  RodSimulator(const RodSimulator&) = delete;
  RodSimulator& operator=(const RodSimulator&) = delete;

  /// Advance by one time step of `scene().spec.time.dt`. A step that fails leaves q, v, the
  /// frames and t as they were at its start, an internal error (a broken invariant, an
  /// allocation that failed: stage "internal") included.
  StepReport step() {
    const int before = steps_;
    try {
      return advance();
    } catch (const std::exception& e) {
      if (frames_saved_)
        for (size_t r = 0; r < bodies_.size(); ++r) bodies_[r].frames = start_frames_[r];
      StepReport rep;
      rep.step = steps_ = before + 1;
      rep.dt = scene_.spec.time.dt;
      return rep.fail("internal", Status::numerical_issue,
                      fmt::format("internal error: {}", dynamic_cast<const std::bad_alloc*>(&e) ? "out of memory (std::bad_alloc)" : e.what()),
                      centre_.t);
    }
  }

 private:
  std::string rest_digest() const {
    Digest d;
    for (const Eigen::VectorXd& r : scene_.rods.rest) d.add_matrix(r);
    return d.hex();
  }

  StepReport advance() {
    StepReport rep;
    dt_ = scene_.spec.time.dt;
    rep.step = ++steps_;
    rep.dt = dt_;
    const double t1 = centre_.t + dt_;
    const int R = num_rods();
    std::vector<NewtonReport> del(R);
    frames_saved_ = false;
    start_frames_.resize(R);
    // A failed step leaves q, v, frames and t at the step's start (the runner's failed_step
    // checkpoint is the state then); the DEL may move a rod's frames within the step
    // (integrator.follow_twist, follow_frames), so they are put back on every failure below.
    const auto fail = [&](const char* stage, Status status, std::string message) -> StepReport& {
      for (int r = 0; r < R; ++r) bodies_[r].frames = start_frames_[r];
      return rep.fail(stage, status, std::move(message), centre_.t);
    };
    {
      ScopedTimer timer(rep.times, Stage::energy);  // the unconstrained solves (energy, Hessian and banded solves)
#pragma omp parallel for schedule(dynamic, 4) if (R > 1)
      for (int r = 0; r < R; ++r) {
        Body& b = bodies_[r];
        start_frames_[r] = b.frames;
        held_targets(r, t1);
        if constexpr (requires { b.model.set_viscous_rest(b.q, b.frames, dt_); }) b.model.set_viscous_rest(b.q, b.frames, dt_);
        b.d = dt_ * b.v;  // initial guess: constant velocity
        del[r] = integrator_.solve(b, dt_);
      }
    }
    frames_saved_ = true;
    for (int r = 0; r < R; ++r) {
      rep.newton.iterations = std::max(rep.newton.iterations, del[r].iterations);
      rep.newton.final_residual = std::max(rep.newton.final_residual, del[r].final_residual);
      if (del[r].status != Status::success)
        return fail("integrator", del[r].status, fmt::format("rod {}: {}", r, del[r].message));
      if (!std::isfinite(del[r].final_residual))  // e.g. a density of 1e300: a "converged" solve of overflowing forces
        return fail("integrator", Status::numerical_issue, fmt::format("rod {}: the DEL solve ended with a non-finite residual", r));
    }
    rep.newton.method = del.empty() ? "" : del[0].method;
    rep.newton.stop_reason = "every rod converged (iterations: the largest over the rods)";
    if constexpr (!InertContact<Contact>) {
      ScopedTimer timer(rep.times, Stage::contact);
      rep.contact = contact_.resolve(*this);
    }
    if (rep.contact.status != Status::success) return fail("contact response", rep.contact.status, rep.contact.message);
    double stretch = 0;
    for (int r = 0; r < R; ++r) {
      Body& b = bodies_[r];
      if (!b.d.allFinite()) return fail("contact response", Status::numerical_issue, fmt::format("rod {}: non-finite displacement", r));
      if (!b.model.admissible(b.q + b.d, b.frames))
        return fail("contact response", Status::numerical_issue,
                    fmt::format("rod {}: the step leaves the model's domain (a zero-length, reversed or folded edge)", r));
    }
#pragma omp parallel for schedule(dynamic, 4) reduction(max : stretch) if (R > 1)
    for (int r = 0; r < R; ++r) {
      Body& b = bodies_[r];
      b.v = b.d / dt_;
      b.q += b.d;
      b.frames = b.model.transport(b.frames, b.q);
      stretch = std::max(stretch, b.model.stretch(b.q));
    }
    rep.contact.max_stretch = stretch;
    centre_.t = t1;
    sync_centrelines();
    rep.time = centre_.t;
    rep.energy = energies();
    return rep;
  }

 public:
  const State& state() const { return centre_; }
  const Scene& scene() const { return scene_; }
  const Params& params() const { return prm_; }
  const Contact& contact() const { return contact_; }

  /// The state between two steps, to the bit: time, step count and, per rod, its DoFs,
  /// their rates and the reference frames (everything a step reads from the last one: the
  /// contact strategies and the rod integrator start every step afresh, and the viscous rest
  /// shape is taken from q and the frames at the step's start).
  void save(Checkpoint& c) const {
    std::vector<double> q, v, tangent, director, twist;
    Json dofs = Json::array();
    for (const Body& b : bodies_) {
      q.insert(q.end(), b.q.data(), b.q.data() + b.q.size());
      v.insert(v.end(), b.v.data(), b.v.data() + b.v.size());
      for (size_t j = 0; j < b.frames.tangent.size(); ++j)
        for (int k = 0; k < 3; ++k) tangent.push_back(b.frames.tangent[j][k]), director.push_back(b.frames.director[j][k]);
      twist.insert(twist.end(), b.frames.reference_twist.begin(), b.frames.reference_twist.end());
      dofs.push_back(b.q.size());
    }
    c.header["kind"] = "rods";
    c.header["step"] = steps_;
    c.header["time"] = centre_.t;
    c.header["rod_dofs"] = dofs;
    c.header["rest_shape"] = rest_digest();
    c.put("q", std::move(q));
    c.put("v", std::move(v));
    c.put("tangent", std::move(tangent));
    c.put("director", std::move(director));
    c.put("reference_twist", std::move(twist));
  }
  /// Continue from a state `save` wrote, with this scene's rods, motions and parameters
  /// (they may differ from the run that wrote it, e.g. to replay a failing step with
  /// another strategy; the rods' DoF counts must match). Throws ConfigError naming what
  /// does not match; the state is unchanged then.
  void restore(const Checkpoint& c) {
    const Json& h = c.header;
    if (h.value("kind", "") != "rods")
      throw ConfigError(fmt::format("checkpoint holds a '{}' state; this combination simulates rods", h.value("kind", "?")));
    if (!h.contains("step") || !h["step"].is_number_integer() || !h.contains("time") || !h["time"].is_number() || !h.contains("rod_dofs") ||
        !h["rod_dofs"].is_array())
      throw ConfigError("checkpoint header lacks 'step', 'time' or 'rod_dofs'");
    const Json& dofs = h["rod_dofs"];
    if (dofs.size() != bodies_.size())
      throw ConfigError(fmt::format("checkpoint holds {} rod(s); this scene has {}", dofs.size(), bodies_.size()));
    long long n = 0, edges = 0, interior = 0;
    for (size_t r = 0; r < bodies_.size(); ++r) {
      const auto nr = bodies_[r].q.size();
      if (!dofs[r].is_number_integer() || dofs[r].get<long long>() != nr)
        throw ConfigError(fmt::format("checkpoint rod {} has {} DoFs; this scene's rod {} has {} ({} vertices)", r, dofs[r].dump(), r, nr,
                                      bodies_[r].num_vertices()));
      n += nr, edges += bodies_[r].num_vertices() - 1, interior += bodies_[r].num_vertices() - 2;
    }
    if (h.contains("rest_shape") && h["rest_shape"] != rest_digest())
      throw ConfigError("checkpoint was written for other rods: the DoF counts match but the rest shapes differ (another shape, length, "
                        "root, spacing, curl or seed); resume it with the scene that wrote it");
    const auto& q = c.get("q", n);
    const auto& v = c.get("v", n);
    const auto& tangent = c.get("tangent", 3 * edges);
    require_finite(c, {"q", "v", "tangent", "director", "reference_twist"});
    const auto& director = c.get("director", 3 * edges);
    const auto& twist = c.get("reference_twist", interior);
    size_t iq = 0, ie = 0, it = 0;
    for (Body& b : bodies_) {
      const auto nr = b.q.size();
      b.q = Eigen::Map<const Eigen::VectorXd>(q.data() + iq, nr);
      b.v = Eigen::Map<const Eigen::VectorXd>(v.data() + iq, nr);
      iq += nr;
      for (size_t j = 0; j < b.frames.tangent.size(); ++j, ie += 3) {
        b.frames.tangent[j] = Eigen::Vector3d(tangent[ie], tangent[ie + 1], tangent[ie + 2]);
        b.frames.director[j] = Eigen::Vector3d(director[ie], director[ie + 1], director[ie + 2]);
      }
      for (double& w : b.frames.reference_twist) w = twist[it++];
      b.d.setZero();
    }
    steps_ = h["step"].get<int>();
    centre_.t = h["time"].get<double>();
    sync_centrelines();
  }

  /// Kinetic (translation and twist) and potential energies: the model's terms summed over
  /// the rods (in the model's order), then gravity.
  EnergyReport energies() const {
    EnergyReport e;
    double gravity = 0;
    for (const Body& b : bodies_) {
      e.kinetic += 0.5 * b.v.dot(b.mass.cwiseProduct(b.v));
      EnergyTerms terms;
      b.model.energy_terms(b.q, b.frames, terms);
      for (const auto& [name, value] : terms) {  // by name: rods of different families may differ (viscous or not)
        auto it = std::find_if(e.terms.begin(), e.terms.end(), [&](const auto& t) { return t.first == name; });
        if (it == e.terms.end()) e.terms.emplace_back(name, value);
        else it->second += value;
      }
      gravity -= b.fext.dot(b.q);
    }
    e.terms.emplace_back("gravity", gravity);
    for (const auto& [name, value] : e.terms) e.potential += value;
    return e;
  }
  /// dV/dx on the centreline vertices (gravity included), held vertices zeroed: the static
  /// force residual (twist components are not part of it).
  Eigen::VectorXd potential_gradient() const {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(3 * centre_.num_vertices());
    for (const Body& b : bodies_) {
      Eigen::VectorXd gr = Eigen::VectorXd::Zero(b.q.size());
      b.model.add_gradient(b.q, b.frames, gr);
      gr -= b.fext;
      for (int i = 0; i < b.num_vertices(); ++i)
        if (!b.fixed[4 * i]) g.segment<3>(3 * (b.first_vertex + i)) = gr.segment<3>(4 * i);
    }
    return g;
  }

  // ---- the system view of the contact strategies -------------------------------------
  int num_rods() const { return static_cast<int>(bodies_.size()); }
  Body& body(int r) { return bodies_[r]; }
  const Body& body(int r) const { return bodies_[r]; }
  double time() const { return centre_.t; }  ///< start of the current step
  double dt() const { return dt_; }
  const std::vector<ObstacleSpec>& obstacles() const { return scene_.spec.obstacles; }
  /// K_r = M + h^2 H(q + d_r), factorised: the exact Hessian (the PSD projection if that does
  /// not factorise), or the PSD projection when `mode` says so.
  Status relinearize(int r, HessianMode mode = HessianMode::exact) {
    Body& b = bodies_[r];
    if (mode == HessianMode::exact && Integ::relinearize(b, dt_, HessianMode::exact) == Status::success) return Status::success;
    return Integ::relinearize(b, dt_, HessianMode::projected);
  }
  /// B <- K_r^-1 B (the last linearisation); held rows come out zero.
  void solve(int r, Eigen::Ref<Eigen::MatrixXd> B) const {
    const Body& b = bodies_[r];
    b.lu.solve(B);
    for (Eigen::Index i = 0; i < B.rows(); ++i)
      if (b.fixed[i]) B.row(i).setZero();
  }
  /// The DEL residual f_r(d) (held rows zero).
  void residual(int r, const Eigen::VectorXd& d, Eigen::VectorXd& f) const { Integ::residual(bodies_[r], d, dt_, f); }
  /// max_j |e_j| / |e_rest_j| - 1 of q_r + d.
  double stretch(int r, const Eigen::VectorXd& d) const { return bodies_[r].model.stretch(bodies_[r].q + d); }

 private:
  void held_targets(int r, double t1) {
    Body& b = bodies_[r];
    const int m = scene_.rods.motion[r];
    for (int i = 0; i < b.num_vertices(); ++i) {
      if (!b.fixed[4 * i]) continue;
      const Eigen::Vector3d x0 = scene_.rods.rest[r].template segment<3>(4 * i);  // the rods start at rest
      b.target.template segment<3>(4 * i) = m >= 0 ? scene_.rods.motions[m].apply(x0, t1) : x0;
    }
    // The root edge's twist is held at its initial value relative to the transported frame.
    if (b.fixed[3]) b.target[3] = scene_.rods.rest[r][3];
  }
  void sync_centrelines() {
    const int V = scene_.rods.num_vertices();
    centre_.x.resize(3 * V);
    centre_.v.resize(3 * V);
    for (const Body& b : bodies_)
      for (int i = 0; i < b.num_vertices(); ++i) {
        centre_.x.segment<3>(3 * (b.first_vertex + i)) = b.q.template segment<3>(4 * i);
        centre_.v.segment<3>(3 * (b.first_vertex + i)) = b.v.template segment<3>(4 * i);
      }
  }

  Scene scene_;
  Params prm_;
  Integ integrator_;
  Contact contact_;
  std::vector<Body> bodies_;
  std::vector<typename Body::Frames> start_frames_;  ///< each rod's frames at the start of the current step
  bool frames_saved_ = false;  ///< start_frames_ hold this step's start (an exception may come before)
  State centre_;
  double dt_ = 0;
  int steps_ = 0;
};

}  // namespace weft
