#include "contact/impulse.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <bit>
#include <numeric>
#include <utility>

#include "contact/detection/collision_detector.hpp"
#include "contact/impulse_kernels.hpp"
#include "framework/error.hpp"
#include "framework/timers.hpp"
#include "framework/union_find.hpp"

namespace weft::contact {

namespace {

using Eigen::Vector3d;

/// A cloth-cloth contact: stencil, weights, normal, and the separation along n that the
/// end positions must reach: n . sum_j gamma_j x1_j >= target.
struct StencilContact {
  std::array<int, 4> v{};
  std::array<double, 4> gamma{};
  Vector3d n = Vector3d::UnitZ();
  double target = 0;
};

double separation(const StencilContact& c, const Eigen::VectorXd& x) {
  Vector3d g = Vector3d::Zero();
  for (int j = 0; j < 4; ++j) g += c.gamma[j] * x.segment<3>(3 * c.v[j]);
  return c.n.dot(g);
}

}  // namespace

/// An obstacle over the current step: poses at its start and end, and the speed bounds of
/// its material points used by the conservative advancement.
struct Impulse::Obstacle {
  const ObstacleSpec* spec = nullptr;
  ObstaclePose p0, p1;
  bool moving = false;
  double centre_speed = 0;   // bound on |d/dt pose centre| [m/s]
  double angular_speed = 0;  // |omega| [rad/s]

  /// Velocity of the obstacle's material point that is at p at the end of the step.
  Vector3d velocity_at(const Vector3d& p, double dt) const {
    if (!moving) return Vector3d::Zero();
    const Vector3d y = p1.rotation.transpose() * (p - p1.center);
    return (p - (p0.center + p0.rotation * y)) / dt;
  }
};

/// Working data of one `end_step`.
struct Impulse::Step {
  const Params& prm;
  double dt = 0, t0 = 0, h = 0;
  const Eigen::VectorXd& x0;
  Eigen::VectorXd x1, v, mass, inv_mass;
  std::vector<unsigned char> free, touched;
  // Impact-zone phase: held[i] = 1 (2) once an obstacle pass moved vertex i during the zones
  // and every obstacle involved was static (some was moving); moved[i] = 1 if the pass after
  // the current iteration's rigidification moved it.
  std::vector<unsigned char> held, moved;
  std::vector<Obstacle> obstacles;
  long long changes = 0;  // velocity updates so far (the detector is refitted only after some)

  Step(const Params& p, const Eigen::VectorXd& start) : prm(p), x0(start) {}
  /// Keeps its velocity in a zone: pinned, scripted, or held by a moving obstacle.
  bool anchor(int i) const { return !free[i] || held[i] == 2; }
  /// x1 = x0 + dt v for a free vertex whose velocity changed.
  void sync(int i) {
    if (!free[i]) return;
    x1.segment<3>(3 * i) = x0.segment<3>(3 * i) + dt * v.segment<3>(3 * i);
    touched[i] = 1;
    ++changes;
  }

  /// First fraction s in [0, 1) of the step at which the relative path of a vertex
  /// touches the obstacle's surface (phi <= 0), or -1. Conservative advancement with L a
  /// bound on |d phi / ds|: phi is 1-Lipschitz in the obstacle's frame, where the vertex
  /// moves at most |x1 - x0| + dt (|c'| + |omega| max |x - c|) per step.
  double first_touch(const Obstacle& o, const Vector3d& a, const Vector3d& b, double phi0, double phi1) const {
    if (phi0 <= 0) return -1;  // already inside at the start: the end-of-step push handles it
    const double move = (b - a).norm();
    double L = move;
    if (o.moving) {
      const double reach = (a - o.p0.center).norm() + move + o.centre_speed * dt;
      L += dt * (o.centre_speed + o.angular_speed * reach);
    }
    if (!(L > 0) || 0.5 * (phi0 + phi1 - L) > 0) return -1;  // cannot reach the surface
    const double tol = 1e-6 * h;
    double s = 0, phi = phi0;
    for (int it = 0; it < 256; ++it) {
      s += phi / L;
      if (s >= 1) return -1;
      const ObstaclePose pose = o.moving ? ObstaclePose::at(*o.spec, t0 + s * dt) : o.p1;
      phi = pose.distance(a + s * (b - a)).phi;
      if (phi <= tol) return s;
    }
    return -1;  // creeping along the surface without reaching it
  }

  /// Obstacle contacts of free vertex i (file comment, step 1).
  /// \returns (vertex-obstacle contacts, impulses applied); `moving` is set when a moving
  /// obstacle was involved.
  std::pair<int, int> resolve_vertex(int i, bool& moving) {
    const Vector3d a = x0.segment<3>(3 * i);
    Vector3d vi = v.segment<3>(3 * i);
    int impulses = 0;
    unsigned contacted = 0;  // bit k: obstacle k (the first 32 obstacles are counted)
    for (int round = 0; round < 4; ++round) {
      bool any = false;
      // Not for rounding errors (a vertex put at h may come out at h (1 - 1e-16)); later
      // rounds only fix what the other obstacles undid.
      const double limit = round == 0 ? h * (1 - 1e-12) : h * (1 - 1e-9);
      for (size_t k = 0; k < obstacles.size(); ++k) {
        const Obstacle& o = obstacles[k];
        const double mu = o.spec->friction;
        Vector3d b = a + dt * vi;
        Distance d1 = o.p1.distance(b);
        // Crossing during the step: only on the integrator's path (round 0); later rounds
        // correct end positions only.
        const double phi0 = round == 0 ? o.p0.distance(a).phi : 0.0;
        const double s = round == 0 ? first_touch(o, a, b, phi0, d1.phi) : -1.0;
        if (s >= 0) {
          const ObstaclePose pose = o.moving ? ObstaclePose::at(*o.spec, t0 + s * dt) : o.p1;
          const Vector3d xc = a + s * (b - a);
          const Vector3d nc = pose.distance(xc).grad;
          if (d1.phi >= h || nc.dot(d1.grad) <= 0) {
            // Went through (or across a cap of) the obstacle: stop the normal motion at the
            // contact point, keep the tangential one (with friction), ride with the obstacle.
            Vector3d w = Vector3d::Zero(), pc1 = xc;
            if (o.moving) {
              const Vector3d y = pose.rotation.transpose() * (xc - pose.center);
              pc1 = o.p1.center + o.p1.rotation * y;
              w = (pc1 - (o.p0.center + o.p0.rotation * y)) / dt;
            }
            const Vector3d vrel = vi - w;
            const double un = vrel.dot(nc);
            const Vector3d ut = vrel - un * nc;
            const Vector3d vrel_new = impulse::coulomb(ut, mu, std::max(-un, 0.0)) + std::max(un, 0.0) * nc;
            vi = (pc1 + (1 - s) * dt * vrel_new - a) / dt;
            b = a + dt * vi;
            d1 = o.p1.distance(b);
            ++impulses;
            contacted |= 1u << (k % 32);
            moving = moving || o.moving;
            any = true;
          }
        }
        if (d1.phi < limit) {
          const Vector3d n = d1.grad;
          const Vector3d w = o.velocity_at(b - d1.phi * n, dt);
          const double dun = (h - d1.phi) / dt;
          const Vector3d vrel = vi - w;
          const Vector3d ut = vrel - vrel.dot(n) * n;
          vi += dun * n + (impulse::coulomb(ut, mu, dun) - ut);
          ++impulses;
          contacted |= 1u << (k % 32);
          moving = moving || o.moving;
          any = true;
        }
      }
      if (!any) break;
    }
    if (impulses > 0) {  // sync() without its counter: this runs in parallel
      v.segment<3>(3 * i) = vi;
      x1.segment<3>(3 * i) = a + dt * vi;
      touched[i] = 1;
    }
    return {std::popcount(contacted), impulses};
  }

  /// Step 1 over every free vertex. `hold`: record the vertices moved (held, moved).
  /// \returns (vertex-obstacle contacts, impulses applied).
  std::pair<int, int> obstacle_pass(bool hold) {
    if (obstacles.empty()) return {0, 0};
    const int n = static_cast<int>(free.size());
    int contacts = 0, impulses = 0;
#pragma omp parallel for reduction(+ : contacts, impulses) schedule(static) if (n > 2048)
    for (int i = 0; i < n; ++i) {
      if (!free[i]) continue;
      bool moving = false;
      const auto [c, m] = resolve_vertex(i, moving);
      contacts += c;
      impulses += m;
      if (hold && m > 0) {
        held[i] = std::max<unsigned char>(held[i], moving ? 2 : 1);
        moved[i] = 1;
      }
    }
    changes += impulses;
    return {contacts, impulses};
  }

  double max_penetration() const {
    double m = 0;
    const int n = static_cast<int>(free.size());
    if (obstacles.empty()) return 0;
#pragma omp parallel for reduction(max : m) schedule(static) if (n > 2048)
    for (int i = 0; i < n; ++i) {
      if (!free[i]) continue;
      for (const Obstacle& o : obstacles) m = std::max(m, h - o.p1.distance(x1.segment<3>(3 * i)).phi);
    }
    return m;
  }

  /// One Gauss-Seidel sweep over cloth-cloth contacts in order. \returns impulses applied.
  int sweep(const std::vector<StencilContact>& contacts, double mu) {
    int applied = 0;
    for (const StencilContact& c : contacts) {
      const double s1 = separation(c, x1);
      if (s1 >= c.target) continue;
      const auto r = impulse::apply_stencil_impulse(c.v, c.gamma, c.n, (c.target - s1) / dt, mu, inv_mass, v);
      if (!r.applied) continue;
      for (int j = 0; j < 4; ++j) sync(c.v[j]);
      ++applied;
    }
    return applied;
  }

  /// A CCD hit as a contact: end at separation min(h, s(x0)) along n, at least.
  StencilContact from_hit(const detection::CcdPair& p) const {
    StencilContact c{p.v, p.impact.gamma, p.impact.normal, 0};
    c.target = std::min(h, std::max(separation(c, x0), 0.0));
    return c;
  }
  /// A hit already within eta at the start whose separation along n does not decrease.
  bool resolved_at_start(const detection::CcdPair& p) const {
    if (p.impact.toi > 0) return false;
    const StencilContact c{p.v, p.impact.gamma, p.impact.normal, 0};
    const double s0 = separation(c, x0), s1 = separation(c, x1);
    // The separation along the start normal at the start weights is not enough: when the
    // triangle (or an edge) turns while the vertex slides, the pair can cross the moving
    // plane with that separation unchanged (the twisted sheet did, at 1 um). So the four
    // points must also keep their orientation: the signed volume of the stencil, zero
    // exactly when the pair is coplanar, has the same sign at the end as at the start.
    auto volume = [&](const Eigen::VectorXd& x) {
      const Vector3d a = x.segment<3>(3 * p.v[0]);
      return (x.segment<3>(3 * p.v[1]) - a).dot((x.segment<3>(3 * p.v[2]) - a).cross(x.segment<3>(3 * p.v[3]) - a));
    };
    return s1 > 0 && s1 >= s0 - 1e-12 * h && volume(x0) * volume(x1) > 0;
  }
};

Impulse::Impulse(const Scene& scene, const Params& prm)
    : prm_(prm), obstacles_(scene.spec.obstacles) {
  Params::validate(prm_).throw_if_failed(fmt::format("{}: invalid contact configuration:", scene.path));
  rest_.resize(3 * scene.mesh.num_vertices());
  for (int i = 0; i < scene.mesh.num_vertices(); ++i) rest_.segment<3>(3 * i) = scene.mesh.rest().row(i).transpose();
  if (prm_.self_contact && scene.mesh.num_faces() > 0) {
    detection::CollisionDetectorParams d;
    d.margin = 0.5 * std::max(prm_.thickness, prm_.eta);
    d.self_contact = true;
    d.proximity.edge_edge_interior_only = true;  // endpoint pairs are found as vertex-triangle pairs
    detector_ = std::make_unique<detection::CollisionDetector>(scene.mesh, d);
  }
}

Impulse::~Impulse() = default;
Impulse::Impulse(Impulse&&) noexcept = default;
Impulse& Impulse::operator=(Impulse&&) noexcept = default;

ContactReport Impulse::begin_step(const State& s, double) {
  x0_ = s.x;
  t0_ = s.t;
  started_ = true;
  return {};
}

ContactReport Impulse::end_step(State& out, double dt) {
  ContactReport rep;
  const std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  auto finish = [&](ContactReport& r) -> ContactReport& {
    r.response_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() -
                         r.detection_seconds;
    return r;
  };
  const int n = out.num_vertices();
  if (!started_ || x0_.size() != out.x.size()) {
    rep.status = Status::invalid_input;
    rep.message = "impulse contact: end_step() without a matching begin_step() (call begin_step with the start-of-step state)";
    return finish(rep);
  }
  started_ = false;

  Step st(prm_, x0_);
  st.dt = dt;
  st.t0 = t0_;
  st.h = prm_.thickness;
  st.x1 = out.x;
  st.v = out.v;
  st.mass = out.mass;
  st.inv_mass.resize(n);
  st.free.resize(n);
  st.touched.assign(n, 0);
  st.held.assign(n, 0);
  st.moved.assign(n, 0);
  for (int i = 0; i < n; ++i) {
    st.free[i] = out.is_free(i) ? 1 : 0;
    st.inv_mass[i] = st.free[i] && out.mass[i] > 0 ? 1.0 / out.mass[i] : 0.0;
  }
  for (const ObstacleSpec& spec : obstacles_) {
    Obstacle o;
    o.spec = &spec;
    o.p0 = ObstaclePose::at(spec, t0_);
    o.p1 = ObstaclePose::at(spec, t0_ + dt);
    o.moving = !spec.motion.is_static();
    if (o.moving) {
      const Motion& m = spec.motion;
      const double tc = std::clamp(t0_, m.start, m.end);
      const Vector3d centre_of_rotation = m.center + m.velocity * (tc - m.start);
      o.angular_speed = m.angular_velocity.norm();
      o.centre_speed = m.velocity.norm() + o.angular_speed * (o.p0.center - centre_of_rotation).norm();
    }
    st.obstacles.push_back(o);
  }

  // 1. Obstacles.
  std::tie(rep.obstacle_contacts, rep.impulses) = st.obstacle_pass(false);

  if (detector_) {
    auto timed = [&](auto&& fn) {
      ScopedTimer t(rep.detection_seconds);
      return fn();
    };
    // Refit the trees to x0 -> x1 unless nothing moved since the last refit (the queries
    // then share its candidate pairs).
    long long fitted = -1;
    auto update = [&] {
      if (fitted == st.changes) return;
      detector_->update(st.x0, st.x1);
      fitted = st.changes;
    };
    // 2. Repulsion on the proximity pairs at the end of the step.
    if (prm_.repulsion_sweeps > 0) {
      const auto pairs = timed([&] {
        update();
        return detector_->proximity(st.x1, st.h);
      });
      std::vector<StencilContact> contacts;
      contacts.reserve(pairs.size());
      for (const auto& p : pairs) {
        StencilContact c{p.v, p.geometry.gamma, p.geometry.normal, st.h};
        if (separation(c, st.x0) <= 0) continue;  // crossed during the step: CCD's job
        Vector3d g_rest = Vector3d::Zero();       // material points this close at rest: no contact
        for (int j = 0; j < 4; ++j) g_rest += c.gamma[j] * rest_.segment<3>(3 * c.v[j]);
        if (g_rest.norm() < st.h) continue;
        contacts.push_back(c);
      }
      for (int k = 0; k < prm_.repulsion_sweeps; ++k) {
        const int applied = st.sweep(contacts, prm_.cloth_friction);
        if (k == 0) rep.proximity_contacts = applied;
        rep.impulses += applied;
        if (applied == 0) break;
      }
      if (rep.proximity_contacts > 0) rep.impulses += st.obstacle_pass(false).second;
    }

    // 3. Iterated CCD impulses.
    std::vector<detection::CcdPair> hits;
    for (int sweep = 0;; ++sweep) {
      auto found = timed([&] {
        update();
        return detector_->ccd(st.x0, st.x1, prm_.eta);
      });
      rep.ccd_hits += static_cast<int>(found.size());
      if (sweep == 0) rep.contacts += static_cast<int>(found.size());
      hits.clear();
      for (auto& p : found)
        if (!st.resolved_at_start(p)) hits.push_back(p);
      if (hits.empty() || sweep == prm_.ccd_sweeps) break;
      std::vector<StencilContact> contacts;
      contacts.reserve(hits.size());
      for (const auto& p : hits) contacts.push_back(st.from_hit(p));
      rep.impulses += st.sweep(contacts, prm_.cloth_friction);
      ++rep.ccd_sweeps;
      rep.impulses += st.obstacle_pass(false).second;
    }

    // 4. Impact zones.
    std::vector<detection::CcdPair> zone_hits;
    UnionFind uf(n);
    for (int iter = 1; !hits.empty(); ++iter) {
      if (iter > prm_.max_zone_iterations) {
        std::map<int, int> sizes;
        for (int i = 0; i < n; ++i) ++sizes[uf.find(i)];
        int largest = 0;
        for (const auto& [root, size] : sizes) largest = std::max(largest, size);
        const auto& p = hits.front();
        rep.status = Status::no_convergence;
        rep.message = fmt::format(
            "impulse contact: {} cloth-cloth collision(s) remain after {} impact-zone iterations in the step from t = {} s "
            "(dt = {} s); largest zone {} vertices; first: {} pair, vertices {} {} {} {}, time of impact {}; reduce time.dt "
            "or raise contact.max_zone_iterations",
            hits.size(), prm_.max_zone_iterations, t0_, dt, largest,
            p.kind == detection::PairKind::vertex_triangle ? "vertex-triangle" : "edge-edge", p.v[0], p.v[1], p.v[2],
            p.v[3], p.impact.toi);
        break;
      }
      rep.zone_iterations = iter;
      zone_hits.insert(zone_hits.end(), hits.begin(), hits.end());
      // Zones from every hit so far: union over the non-anchor vertices of each stencil.
      uf = UnionFind(n);
      std::vector<int> first(zone_hits.size(), -1);
      bool progress = false;
      for (size_t k = 0; k < zone_hits.size(); ++k) {
        for (int j : zone_hits[k].v)
          if (!st.anchor(j)) {
            if (first[k] < 0) first[k] = j;
            uf.unite(first[k], j);
          }
        if (first[k] >= 0) progress = true;
      }
      if (!progress) {
        rep.status = Status::numerical_issue;
        rep.message = fmt::format(
            "impulse contact: in the step from t = {} s, cloth-cloth collisions involve only pinned, scripted or "
            "vertices held by moving obstacles (first: vertices {} {} {} {}): no velocity can resolve them; check the "
            "pins and scripted motions",
            t0_, hits.front().v[0], hits.front().v[1], hits.front().v[2], hits.front().v[3]);
        break;
      }
      std::map<int, std::pair<std::vector<int>, std::vector<int>>> zones;  // root -> (members, anchors)
      for (size_t k = 0; k < zone_hits.size(); ++k) {
        if (first[k] < 0) continue;
        auto& z = zones[uf.find(first[k])];
        for (int j : zone_hits[k].v) (st.anchor(j) ? z.second : z.first).push_back(j);
      }
      rep.impact_zones = 0;
      rep.zone_vertices = 0;
      for (auto& [root, z] : zones) {
        for (auto* list : {&z.first, &z.second}) {
          std::sort(list->begin(), list->end());
          list->erase(std::unique(list->begin(), list->end()), list->end());
        }
        // A zone resting on a static obstacle stops (x1 = x0: feasible, and rigid); the
        // obstacle takes its momentum. Otherwise it moves rigidly (rigidify_zone).
        const bool grounded = std::any_of(z.first.begin(), z.first.end(), [&](int i) { return st.held[i] == 1; });
        if (grounded)
          for (int i : z.first) st.v.segment<3>(3 * i).setZero();
        else
          impulse::rigidify_zone(z.first, z.second, st.x0, st.mass, st.v);
        for (int i : z.first) st.sync(i);
        ++rep.impact_zones;
        rep.zone_vertices += static_cast<int>(z.first.size());
      }
      std::fill(st.moved.begin(), st.moved.end(), 0);
      rep.impulses += st.obstacle_pass(true).second;
      auto found = timed([&] {
        update();
        return detector_->ccd(st.x0, st.x1, prm_.eta);
      });
      rep.ccd_hits += static_cast<int>(found.size());
      hits.clear();
      for (auto& p : found) {
        if (st.resolved_at_start(p)) continue;
        // Every vertex a member of one zone, untouched since its rigid motion: no collision.
        const int root = st.anchor(p.v[0]) ? -1 : uf.find(p.v[0]);
        bool inside = root >= 0;
        for (int j : p.v) inside = inside && !st.anchor(j) && !st.moved[j] && uf.find(j) == root;
        if (!inside) hits.push_back(p);
      }
    }
  }

  rep.contacts += rep.obstacle_contacts + rep.proximity_contacts;
  rep.max_penetration = st.max_penetration();
  for (int i = 0; i < n; ++i)
    if (st.touched[i]) {
      out.x.segment<3>(3 * i) = st.x1.segment<3>(3 * i);
      out.v.segment<3>(3 * i) = st.v.segment<3>(3 * i);
    }
  return finish(rep);
}

}  // namespace weft::contact
