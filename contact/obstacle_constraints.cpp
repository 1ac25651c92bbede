#include "contact/obstacle_constraints.hpp"

#include <Eigen/QR>

#include <algorithm>
#include <array>
#include <cmath>

#include "framework/error.hpp"
#include "framework/timers.hpp"

namespace weft::contact {

ObstacleConstraints::ObstacleConstraints(const Scene& scene, const Params& prm)
    : obstacles_(scene.spec.obstacles), mass_(scene.lumped_masses()), prm_(prm) {
  Params::validate(prm).throw_if_failed(fmt::format("{}: invalid contact configuration:", scene.path));
  free_.resize(scene.dof.size());
  for (size_t i = 0; i < scene.dof.size(); ++i) free_[i] = scene.dof[i] == Dof::free;
  for (const auto& o : obstacles_) {
    start_.push_back(ObstaclePose::at(o, 0.0));
    end_.push_back(start_.back());
  }
}

namespace {
constexpr int contact_record = 13;  // vertex, obstacle, mode, normal force, slip, friction, anchor
}

void ObstacleConstraints::save(Checkpoint& c, std::string_view prefix) const {
  std::vector<double> rec, rel;
  rec.reserve(contact_record * contacts_.size());
  for (const Contact& k : contacts_) {
    rec.insert(rec.end(), {double(k.vertex), double(k.obstacle), double(static_cast<int>(k.mode)), k.normal_force});
    for (const Eigen::Vector3d* v : {&k.slip, &k.friction, &k.anchor}) rec.insert(rec.end(), v->data(), v->data() + 3);
  }
  const long long no = static_cast<long long>(obstacles_.size());
  for (long long k : released_) rel.insert(rel.end(), {double(k / no), double(k % no)});
  c.put(std::string(prefix) + "contacts", std::move(rec));
  c.put(std::string(prefix) + "released", std::move(rel));
}

void ObstacleConstraints::restore(const Checkpoint& c, std::string_view prefix) {
  const std::string cname = std::string(prefix) + "contacts", rname = std::string(prefix) + "released";
  if (!c.has(cname) && !c.has(rname)) {
    contacts_.clear();
    released_.clear();
    return;
  }
  const int nv = static_cast<int>(free_.size()), no = static_cast<int>(obstacles_.size());
  const auto pair = [&](const std::string& name, double v, double o) {
    if (!(v >= 0 && v < nv && o >= 0 && o < no && v == std::floor(v) && o == std::floor(o)))
      throw ConfigError(fmt::format("checkpoint array '{}': vertex {} with obstacle {} is not a pair of this scene ({} vertices, {} obstacles)",
                                    name, v, o, nv, no));
  };
  const std::vector<double>& rec = c.get(cname);
  const std::vector<double>& rel = c.get(rname);
  if (rec.size() % contact_record != 0)
    throw ConfigError(fmt::format("checkpoint array '{}' has {} values, not a multiple of {}", cname, rec.size(), contact_record));
  if (rel.size() % 2 != 0) throw ConfigError(fmt::format("checkpoint array '{}' has {} values, not pairs", rname, rel.size()));
  std::vector<Contact> contacts(rec.size() / contact_record);
  for (size_t k = 0; k < contacts.size(); ++k) {
    const double* r = rec.data() + contact_record * k;
    pair(cname, r[0], r[1]);
    if (!(r[2] == 0 || r[2] == 1 || r[2] == 2)) throw ConfigError(fmt::format("checkpoint array '{}': contact {} has mode {} (valid: 0, 1, 2)", cname, k, r[2]));
    Contact& q = contacts[k];
    q.vertex = static_cast<int>(r[0]);
    q.obstacle = static_cast<int>(r[1]);
    q.mode = static_cast<Mode>(static_cast<int>(r[2]));
    q.normal_force = r[3];
    q.slip = Eigen::Vector3d(r[4], r[5], r[6]);
    q.friction = Eigen::Vector3d(r[7], r[8], r[9]);
    q.anchor = Eigen::Vector3d(r[10], r[11], r[12]);
  }
  std::vector<long long> released;
  for (size_t k = 0; k < rel.size(); k += 2) {
    pair(rname, rel[k], rel[k + 1]);
    released.push_back(key(static_cast<int>(rel[k]), static_cast<int>(rel[k + 1]), no));
  }
  std::sort(released.begin(), released.end());
  const auto by_key = [no](const Contact& a, const Contact& b) { return key(a.vertex, a.obstacle, no) < key(b.vertex, b.obstacle, no); };
  if (!std::is_sorted(contacts.begin(), contacts.end(), by_key))
    throw ConfigError(fmt::format("checkpoint array '{}': contacts not sorted by vertex and obstacle", cname));
  contacts_ = std::move(contacts);
  released_ = std::move(released);
}

Eigen::Vector3d ObstacleConstraints::carry(int o, const Eigen::Vector3d& x) const {
  if (obstacles_[o].motion.is_static()) return x;  // exactly, so a vertex at rest has no relative slip
  const ObstaclePose &a = start_[o], &b = end_[o];
  return b.rotation * (a.rotation.transpose() * (x - a.center)) + b.center;
}

Eigen::Vector3d ObstacleConstraints::obstacle_velocity(int o, const Eigen::Vector3d& x, double dt) const {
  // The material point of the obstacle at x at the end of the step was at T^-1(x) at its start.
  if (obstacles_[o].motion.is_static()) return Eigen::Vector3d::Zero();
  const ObstaclePose &a = start_[o], &b = end_[o];
  const Eigen::Vector3d back = a.rotation * (b.rotation.transpose() * (x - b.center)) + a.center;
  return (x - back) / dt;
}

ObstacleConstraints::Contact ObstacleConstraints::make_contact(int i, int o, const State& s, double dt, const Contact* kept) const {
  const Eigen::Vector3d x = s.position(i), v = s.velocity(i);
  const Distance d = end_[o].distance(x);
  // Relative velocity at the start of the step (the obstacle's over the step).
  const Eigen::Vector3d vrel = v - (carry(o, x) - x) / dt;
  const double vn = d.grad.dot(vrel);
  Contact c;
  if (kept) c = *kept;
  c.vertex = i;
  c.obstacle = o;
  const double mu = obstacles_[o].friction;
  if (mu == 0) {
    c.mode = Mode::frictionless;
  } else if (!kept || c.mode == Mode::frictionless) {
    // New contact: the impact cone on the relative velocity at the start of the step.
    const Eigen::Vector3d vt = vrel - vn * d.grad;
    const double approach = std::max(0.0, -vn);
    // (A slip below the projection tolerance over the step counts as none.)
    if (vt.norm() * dt <= mu * approach * dt + prm_.projection_tolerance) {
      c.mode = Mode::stick;
    } else {
      c.mode = Mode::slide;
      c.slip = vt.normalized();
      c.normal_force = mass_[i] * approach / dt;
    }
  }
  return c;
}

int ObstacleConstraints::prepare_contacts(const State& s) {
  // Several obstacles at one vertex: normal constraints only (no stick).
  for (size_t a = 0; a < contacts_.size();) {
    size_t b = a + 1;
    while (b < contacts_.size() && contacts_[b].vertex == contacts_[a].vertex) ++b;
    if (b - a > 1)
      for (size_t c = a; c < b; ++c)
        if (contacts_[c].mode == Mode::stick) {
          contacts_[c].mode = Mode::slide;
          contacts_[c].slip.setZero();  // unknown until the end of the step: no kinetic force this step
        }
    a = b;
  }
  // The step's anchors (stick) and kinetic forces (slide).
  int sticking = 0;
  for (Contact& c : contacts_) {
    c.friction.setZero();
    const Eigen::Vector3d x = s.position(c.vertex);
    if (c.mode == Mode::stick) {
      const Eigen::Vector3d a = carry(c.obstacle, x);
      const Distance da = end_[c.obstacle].distance(a);
      c.anchor = a + (prm_.thickness - da.phi) * da.grad;
      ++sticking;
    } else if (c.mode == Mode::slide) {
      const Eigen::Vector3d n = end_[c.obstacle].distance(x).grad;
      const Eigen::Vector3d tangent = c.slip - c.slip.dot(n) * n;
      if (tangent.norm() > 1e-12) c.friction = -obstacles_[c.obstacle].friction * c.normal_force * tangent.normalized();
    }
  }
  return sticking;
}

ContactReport ObstacleConstraints::begin_step(const State& s, double dt) {
  ContactReport r;
  ScopedTimer t(r.detection_seconds);
  have_reactions_ = false;
  redetections_ = 0;
  redetected_ = 0;
  const int no = static_cast<int>(obstacles_.size());
  for (int o = 0; o < no; ++o) {
    start_[o] = ObstaclePose::at(obstacles_[o], s.t);
    end_[o] = ObstaclePose::at(obstacles_[o], s.t + dt);
  }
  const double reach = prm_.thickness + prm_.margin;
  std::vector<Contact> next;
  size_t old = 0;
  int receded = 0;
  for (int i = 0; i < s.num_vertices() && no > 0; ++i) {
    if (!free_[i]) continue;
    const Eigen::Vector3d x = s.position(i), v = s.velocity(i), xp = x + dt * v;
    for (int o = 0; o < no; ++o) {
      const long long k = key(i, o, no);
      while (old < contacts_.size() && key(contacts_[old].vertex, contacts_[old].obstacle, no) < k) ++old;
      const bool kept = old < contacts_.size() && key(contacts_[old].vertex, contacts_[old].obstacle, no) == k;
      if (std::binary_search(released_.begin(), released_.end(), k)) continue;  // released at the last step
      const Distance d = end_[o].distance(x);
      const double vn = d.grad.dot(v - (carry(o, x) - x) / dt);
      // In contact: the predicted position within reach of the obstacle where it will be,
      // or the position within reach and not separating by more than the re-detection depth
      // over the step (the tolerance the step accepts the other way). A vertex sliding over a
      // curved obstacle leaves end_step with the outward normal velocity of the chord,
      // dt |v_t|^2 / (2 R): `respond` puts it on the surface with a tangential velocity, but
      // the failsafe's obstacle pass (ImplicitContact, contact/impulse.hpp) works with
      // x1 = x0 + dt v, finds that point below the thickness and pushes v out by that much
      // (7e-4 m/s at 0.3 m/s on the drape's sphere). With the margin alone (1e-8 m) as the
      // slack, hundreds of resting contacts were dropped every step and re-detected after
      // the solve had carried their vertices into the sphere. (Letting the failsafe skip the
      // vertices the constraints hold would remove the velocity at its source; not done.)
      const double slack = std::max(prm_.margin, prm_.redetection_depth);
      if (end_[o].distance(xp).phi > reach && !(d.phi <= reach && vn * dt <= slack)) {
        receded += kept;
        continue;
      }
      next.push_back(make_contact(i, o, s, dt, kept ? &contacts_[old] : nullptr));
    }
  }
  r.released = receded;  // those of released_ were counted when end_step released them
  released_.clear();
  contacts_ = std::move(next);
  r.sticking = prepare_contacts(s);
  r.contacts = r.obstacle_contacts = static_cast<int>(contacts_.size());
  return r;
}

int ObstacleConstraints::redetect(const State& start, const State& trial, double dt, std::vector<int>& vertices, bool converged) {
  if (redetections_ >= prm_.max_redetections || obstacles_.empty() || !(converged || prm_.redetect_iterates)) return 0;
  const int no = static_cast<int>(obstacles_.size());
  std::vector<Contact> added;
  size_t at = 0;
  for (int i = 0; i < trial.num_vertices(); ++i) {
    if (!free_[i]) continue;
    while (at < contacts_.size() && contacts_[at].vertex < i) ++at;
    const Eigen::Vector3d x = trial.position(i);
    for (int o = 0; o < no; ++o) {
      bool known = false;
      for (size_t c = at; c < contacts_.size() && contacts_[c].vertex == i; ++c) known |= contacts_[c].obstacle == o;
      if (known || prm_.thickness - end_[o].distance(x).phi <= prm_.redetection_depth) continue;
      added.push_back(make_contact(i, o, start, dt, nullptr));
    }
  }
  if (added.empty()) return 0;
  for (const Contact& c : added)
    if (vertices.empty() || vertices.back() != c.vertex) vertices.push_back(c.vertex);
  ++redetections_;
  redetected_ += static_cast<int>(added.size());
  contacts_.insert(contacts_.end(), added.begin(), added.end());
  std::sort(contacts_.begin(), contacts_.end(), [no](const Contact& a, const Contact& b) {
    return key(a.vertex, a.obstacle, no) < key(b.vertex, b.obstacle, no);
  });
  prepare_contacts(start);
  return static_cast<int>(added.size());
}

double ObstacleConstraints::energy(const State& s) const {
  double e = 0;
  for (const Contact& c : contacts_)
    if (c.mode == Mode::slide) e -= c.friction.dot(s.position(c.vertex));
  return e;
}

void ObstacleConstraints::add_gradient(const State&, Eigen::VectorXd& g) const {
  for (const Contact& c : contacts_)
    if (c.mode == Mode::slide) g.segment<3>(3 * c.vertex) -= c.friction;
}

unsigned ObstacleConstraints::effective(size_t a, size_t b, const Eigen::Vector3d& x) const {
  const size_t n = b - a;
  if (n == 1) return 1u;
  if (n > 32) return ~0u;  // (more obstacles at one vertex than the mask holds: all of them)
  // Closest obstacle first (ties by obstacle index: contacts_ is sorted by it).
  std::array<std::pair<double, int>, 32> order;
  std::array<Distance, 32> dist;
  for (size_t c = 0; c < n; ++c) {
    dist[c] = end_[contacts_[a + c].obstacle].distance(x);
    order[c] = {dist[c].phi, static_cast<int>(c)};
  }
  std::sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(n));
  const double tol = std::max(1e-9, 1e-6 * prm_.thickness);
  unsigned kept = 0;
  for (size_t r = 0; r < n; ++r) {
    const int c = order[r].second;
    const Eigen::Vector3d closest = x - dist[c].phi * dist[c].grad;  // on obstacle c's surface
    bool inner = false;
    for (size_t q = 0; q < n && !inner; ++q)
      if (kept >> q & 1u) inner = end_[contacts_[a + q].obstacle].distance(closest).phi <= tol;
    if (!inner) kept |= 1u << c;
  }
  return kept;
}

void ObstacleConstraints::constraints(const State& trial, ConstraintSet& out) const {
  out.reset(trial.num_vertices());
  for (size_t a = 0; a < contacts_.size();) {
    size_t b = a + 1;
    while (b < contacts_.size() && contacts_[b].vertex == contacts_[a].vertex) ++b;
    const Eigen::Vector3d x = trial.position(contacts_[a].vertex);
    const unsigned keep = effective(a, b, x);
    for (size_t k = a; k < b; ++k) {
      const Contact& c = contacts_[k];
      if (!(keep >> (k - a) & 1u)) continue;
      if (c.mode == Mode::stick) {
        out.fix(c.vertex, c.anchor - x);
      } else {
        const Distance d = end_[c.obstacle].distance(x);
        out.add_direction(c.vertex, d.grad, prm_.thickness - d.phi);
      }
    }
    a = b;
  }
}

void ObstacleConstraints::accept_reactions(const Eigen::VectorXd& force) {
  reactions_ = force;
  have_reactions_ = true;
}

ContactReport ObstacleConstraints::end_step(State& s, double dt) {
  ContactReport r;
  {
    ScopedTimer t(r.response_seconds);
    respond(s, dt, r);
  }
  have_reactions_ = false;
  last_response_ = r;
  return r;
}

void ObstacleConstraints::respond(State& s, double dt, ContactReport& r) {
  const int no = static_cast<int>(obstacles_.size());
  const double delta = prm_.thickness;
  r.contacts = r.obstacle_contacts = static_cast<int>(contacts_.size());
  r.redetections = redetections_;
  r.redetected = redetected_;
  if (!contacts_.empty() && (!have_reactions_ || reactions_.size() != s.x.size())) {
    r.status = Status::invalid_input;
    r.message = "obstacle_constraints: no constraint reactions for this step (the integrator must call accept_reactions)";
    return;
  }
  released_.clear();
  for (int i = 0; i < s.num_vertices() && no > 0; ++i)
    if (free_[i])
      for (const auto& p : end_) r.solve_penetration = std::max(r.solve_penetration, delta - p.distance(s.position(i)).phi);
  for (size_t a = 0; a < contacts_.size();) {
    size_t b = a + 1;
    while (b < contacts_.size() && contacts_[b].vertex == contacts_[a].vertex) ++b;
    const int i = contacts_[a].vertex;
    const Eigen::Vector3d R = reactions_.segment<3>(3 * i);
    auto x = s.position(i);
    auto v = s.velocity(i);
    // Normal reactions: R_i = sum_c lambda_c n_c (least squares over the effective contacts
    // of i; an inner surface of the obstacles' union carries none and is released).
    const unsigned keep = effective(a, b, x);
    Eigen::Matrix3Xd N(3, static_cast<Eigen::Index>(b - a));
    for (size_t c = a; c < b; ++c)
      N.col(static_cast<Eigen::Index>(c - a)) = (keep >> (c - a) & 1u) ? end_[contacts_[c].obstacle].distance(x).grad : Eigen::Vector3d::Zero();
    Eigen::VectorXd lambda(N.cols());
    if (N.cols() == 1) lambda[0] = N.col(0).dot(R);
    else lambda = N.completeOrthogonalDecomposition().solve(R);
    for (size_t c = a; c < b; ++c) {
      Contact& k = contacts_[c];
      if (!(keep >> (c - a) & 1u)) {
        released_.push_back(key(k.vertex, k.obstacle, no));
        continue;
      }
      if (k.mode == Mode::stick) ++r.sticking;
      const Eigen::Vector3d n = N.col(static_cast<Eigen::Index>(c - a));
      const double ln = lambda[static_cast<Eigen::Index>(c - a)];
      const double vn_end = n.dot(v - obstacle_velocity(k.obstacle, x, dt));
      if (!(ln > 0) && vn_end * dt >= -prm_.margin) {  // the constraint pulls: release (BW98)
        released_.push_back(key(k.vertex, k.obstacle, no));
        continue;
      }
      // (A vertex still approaching at the end of the step, e.g. one that reached the
      // surface just then and needed no force yet, stays in contact, in its mode.)
      k.normal_force = std::max(ln, 0.0);
      const double mu = obstacles_[k.obstacle].friction;
      if (!(ln > 0)) {
        // no normal force: no friction decision
      } else if (k.mode == Mode::stick) {
        const Eigen::Vector3d Rt = R - R.dot(n) * n;
        if (Rt.norm() > mu * k.normal_force) {  // outside the cone: slide from the next step, against the hold
          k.mode = Mode::slide;
          k.slip = -Rt.normalized();
        }
      } else if (k.mode == Mode::slide) {
        const Eigen::Vector3d vrel = v - obstacle_velocity(k.obstacle, x, dt);
        const Eigen::Vector3d vt = vrel - vrel.dot(n) * n;
        const Eigen::Vector3d used = k.friction.norm() > 0 ? Eigen::Vector3d(-k.friction.normalized()) : k.slip;
        if (b - a == 1 && mu > 0 && (used.norm() > 0 ? vt.dot(used) <= 0 : vt.norm() == 0)) {
          // The explicit force stopped (or reversed) the slip: stop it and stick.
          v -= vt;
          k.mode = Mode::stick;
        } else if (vt.norm() > 0) {
          k.slip = vt.normalized();
        }
      }
      // A contact that stays holds C = 0 and its hidden constraint grad C qdot = 0 (methods/integration-and-contact
      // §10.1) at the end of the step. A single linearised step leaves the vertex off a
      // curved obstacle by O(step^2 / R), and v = d / dt keeps O(dt) of relative normal
      // velocity there (the chord of the step), or the approach of a contact made during
      // the step (moved onto the surface by the first iterate): an inelastic contact keeps
      // neither.
      const Distance on = end_[k.obstacle].distance(x);
      x += (delta - on.phi) * on.grad;
      const Eigen::Vector3d m = end_[k.obstacle].distance(x).grad;
      v -= m.dot(v - obstacle_velocity(k.obstacle, x, dt)) * m;
    }
    a = b;
  }
  std::sort(released_.begin(), released_.end());
  r.released = static_cast<int>(released_.size());
  // Projection of whatever is still below the thickness surface (vertices not in contact,
  // or not quite on their constraint: curved obstacles, several obstacles).
  for (int i = 0; i < s.num_vertices() && no > 0; ++i) {
    if (!free_[i]) continue;
    bool moved = false;
    for (int o = 0; o < no; ++o) {
      auto x = s.position(i);
      const Distance d = end_[o].distance(x);
      const double depth = delta - d.phi;
      if (depth <= prm_.projection_tolerance) continue;
      x += depth * d.grad;
      auto v = s.velocity(i);
      const double vn = d.grad.dot(v - obstacle_velocity(o, x, dt));
      if (vn < 0) v -= vn * d.grad;
      moved = true;
    }
    r.projected += moved;
  }
  r.max_penetration = max_penetration(s);
}

double ObstacleConstraints::max_penetration(const State& s) const {
  double m = 0;
  for (int i = 0; i < s.num_vertices(); ++i)
    if (free_[i])
      for (const auto& p : end_) m = std::max(m, prm_.thickness - p.distance(s.position(i)).phi);
  return m;
}

}  // namespace weft::contact
