#include "contact/barrier.hpp"

#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "contact/box_mesh.hpp"
#include "contact/detection/ccd.hpp"
#include "contact/detection/collision_detector.hpp"
#include "contact/obstacle_penalty.hpp"
#include "framework/distance.hpp"
#include "framework/obstacle_mesh.hpp"
#include "framework/timers.hpp"

namespace weft::contact {

using barrier::PairKind;
using barrier::Stencil;
using Eigen::Vector3d;

struct Barrier::Obstacle {
  int spec = -1;
  ObstacleShape shape = ObstacleShape::sphere;
  int body = -1;           // detector body (mesh, box)
  Eigen::MatrixX3d local;  // body-coordinate vertices (mesh, box)
  Eigen::MatrixX3i faces;
  Eigen::VectorXd x1;      // world positions at the end of the step, stacked
  ObstaclePose p0, p1;     // poses at the start and the end of the step
};

namespace {

constexpr double inf = std::numeric_limits<double>::infinity();
enum GroupKind { vertex_kind = 0, edge_kind = 1, triangle_kind = 2, self_kind = 3 };

std::uint64_t pair_key(int code, int a, int b) {
  return (static_cast<std::uint64_t>(code) << 48) ^ (static_cast<std::uint64_t>(a) << 24) ^ static_cast<std::uint64_t>(b);
}
std::uint64_t edge_key(int i, int j) { return (static_cast<std::uint64_t>(std::min(i, j)) << 32) | static_cast<std::uint64_t>(std::max(i, j)); }

Vector3d at(const Eigen::VectorXd& x, int i) { return x.segment<3>(3 * i); }

// The element's stencil position of vertex id among `ids`, or -1.
std::int8_t position_of(int id, const int* ids, int k) {
  for (int a = 0; a < k; ++a)
    if (ids[a] == id) return static_cast<std::int8_t>(a);
  return -1;
}

// Earliest fraction of the straight motion x0 -> x1 at which the sphere (centre x[0], radius
// R, at rest) comes within `eta` of the triangle (x[1..3]), by conservative advancement on
// the gap; the gap stays above eta / 2 before the returned time, 1 when it never comes that
// close. Each step is the longer of two safe ones: the gap is L-Lipschitz in t (L the largest
// vertex displacement), and along the fixed unit axis n from the closest point to the centre
// it is at least min_j n . (c - x_j(t)) - R, a minimum of linear functions of t (exact for a
// triangle sliding past at a constant gap, where the Lipschitz steps would crawl).
double sphere_triangle_toi(const Stencil& x0, const Stencil& x1, double R, double eta) {
  double L = 0;
  for (int j = 1; j < 4; ++j) L = std::max(L, (x1[j] - x0[j]).norm());
  if (L == 0) return 1.0;
  const Vector3d c = x0[0];
  double t = 0;
  for (int it = 0; it < 10000; ++it) {
    Stencil xt;
    xt[0] = c;
    for (int j = 1; j < 4; ++j) xt[j] = x0[j] + t * (x1[j] - x0[j]);
    const PointTriangle pt = point_triangle_distance(c, xt[1], xt[2], xt[3]);
    const double dist = std::sqrt(pt.distance_squared), g = dist - R;
    if (g <= eta) return t;
    double step = (g - 0.5 * eta) / L;
    if (dist > 0) {
      const Vector3d n = (c - pt.closest) / dist;
      double axis = std::numeric_limits<double>::infinity();  // n . (c - x_j(t + s)) - R >= eta / 2 for s <= axis
      for (int j = 1; j < 4; ++j) {
        const double a = n.dot(c - xt[j]) - R - 0.5 * eta, rate = -n.dot(x1[j] - x0[j]);
        if (a <= 0) {
          axis = 0;
          break;
        }
        if (rate < 0) axis = std::min(axis, a / -rate);
      }
      step = std::max(step, axis);
    }
    t += step;
    if (t >= 1) return 1.0;
  }
  return t;  // the iteration cap: a conservative time
}

}  // namespace

Barrier::Barrier(const Scene& scene, const Params& prm) : prm_(prm) {
  Params::validate(prm).throw_if_failed(fmt::format("{}: invalid contact configuration:", scene.path));
  const TriangleMesh& mesh = scene.mesh;
  num_vertices_ = mesh.num_vertices();
  faces_ = mesh.faces();
  edges_ = mesh.edges();
  rest_.resize(3 * num_vertices_);
  for (int i = 0; i < num_vertices_; ++i) rest_.segment<3>(3 * i) = mesh.rest().row(i).transpose();
  edge_rest_sq_.resize(edges_.size());
  for (size_t e = 0; e < edges_.size(); ++e) {
    edge_rest_sq_[e] = (at(rest_, edges_[e][1]) - at(rest_, edges_[e][0])).squaredNorm();
    edge_of_.emplace(edge_key(edges_[e][0], edges_[e][1]), static_cast<int>(e));
  }
  cloth_of_.assign(num_vertices_, 0);
  for (size_t c = 1; c < scene.cloth_vertex_offset.size(); ++c)
    for (int i = scene.cloth_vertex_offset[c]; i < num_vertices_; ++i) cloth_of_[i] = static_cast<int>(c);
  specs_ = scene.spec.obstacles;
  const bool self = prm_.self_contact && mesh.num_faces() > 0;
  bool meshes = false;
  for (const ObstacleSpec& o : specs_) meshes |= o.shape == ObstacleShape::mesh || o.shape == ObstacleShape::box;
  if (self || meshes) {
    detection::CollisionDetectorParams d;
    d.margin = prm_.thickness;  // CCD with eta = 2 d_hat finds every pair within d_hat
    d.self_contact = self;
    detector_ = std::make_unique<detection::CollisionDetector>(mesh, d);
  }
  for (size_t k = 0; k < specs_.size(); ++k) {
    const ObstacleSpec& o = specs_[k];
    Obstacle ob;
    ob.spec = static_cast<int>(k);
    ob.shape = o.shape;
    if (o.shape == ObstacleShape::mesh) {
      if (!o.mesh)
        throw ConfigError(fmt::format("{}: obstacle '{}' (shape = mesh, file \"{}\") has no geometry", scene.path, o.name, o.file));
      ob.local = o.mesh->V;
      ob.faces = o.mesh->F;
    } else if (o.shape == ObstacleShape::box) {
      box_mesh(o.half_extents, ob.local, ob.faces);
    }
    if (ob.local.rows() > 0) ob.body = detector_->add_obstacle(ob.faces, static_cast<int>(ob.local.rows()));
    obstacles_.push_back(std::move(ob));
  }
}

Barrier::~Barrier() = default;
Barrier::Barrier(Barrier&&) noexcept = default;
Barrier& Barrier::operator=(Barrier&&) noexcept = default;

void Barrier::declare(AssemblyPlan& plan) {
  if (!detector_ && obstacles_.empty()) return;
  std::vector<int> ids(num_vertices_);
  for (int i = 0; i < num_vertices_; ++i) ids[i] = i;
  vertex_group_ = plan.add_group(1, ids);
  if (!obstacles_.empty()) {
    ids.clear();
    for (const auto& e : edges_) ids.insert(ids.end(), e.begin(), e.end());
    edge_group_ = plan.add_group(2, ids);
    ids.clear();
    for (int f = 0; f < faces_.rows(); ++f)
      for (int k = 0; k < 3; ++k) ids.push_back(faces_(f, k));
    triangle_group_ = plan.add_group(3, ids);
  }
  if (detector_ && detector_->params().self_contact) self_group_ = plan.add_group(4, {});
}

barrier::PairConstants Barrier::constants(const Pair& p) const {
  barrier::PairConstants c;
  c.kind = p.kind;
  c.s_hat = prm_.thickness * prm_.thickness;
  c.kappa = kappa_;
  c.eps_x = p.eps_x;
  if (p.obstacle >= 0) {
    const Obstacle& o = obstacles_[p.obstacle];
    c.radius = o.p1.radius;
    c.normal = o.p1.normal;
  }
  return c;
}

Stencil Barrier::stencil(const Pair& p, const Eigen::VectorXd& x) const {
  Stencil s;
  for (int j = 0; j < 4; ++j) s[j] = p.v[j] >= 0 ? Vector3d(at(x, p.v[j])) : p.fixed[j];
  return s;
}

bool Barrier::excluded_at_rest(const Pair& p) const {
  for (int j = 1; j < 4; ++j)
    if (cloth_of_[p.v[j]] != cloth_of_[p.v[0]]) return false;  // different cloths: always a contact
  const Stencil r = stencil(p, rest_);
  const double s = p.kind == PairKind::point_triangle ? barrier::point_triangle_type(r).s : barrier::edge_edge_type(r).s;
  return s < prm_.thickness * prm_.thickness;
}

void Barrier::collect(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1, std::vector<Pair>& out) {
  out.clear();
  const double dh = prm_.thickness;
  if (detector_) {
    detector_->update(x0, x1);
    std::vector<int> obstacle_of(detector_->num_bodies(), -1);
    for (size_t k = 0; k < obstacles_.size(); ++k)
      if (obstacles_[k].body >= 0) obstacle_of[obstacles_[k].body] = static_cast<int>(k);
    for (const detection::CcdPair& h : detector_->ccd(x0, x1, 2 * dh)) {
      Pair p;
      p.kind = h.kind == detection::PairKind::vertex_triangle ? PairKind::point_triangle : PairKind::edge_edge;
      const bool vf = p.kind == PairKind::point_triangle;
      if (h.body_a == 0 && h.body_b == 0) {
        p.v = h.v;
        p.key = pair_key(vf ? 1 : 2, h.a, h.b);
        if (!vf) {
          const double ea = (at(rest_, h.v[1]) - at(rest_, h.v[0])).squaredNorm();
          const double eb = (at(rest_, h.v[3]) - at(rest_, h.v[2])).squaredNorm();
          p.eps_x = 1e-3 * ea * eb;
        }
        if (excluded_at_rest(p)) continue;
      } else {
        const bool cloth_first = h.body_a == 0;
        const int k = obstacle_of[cloth_first ? h.body_b : h.body_a];
        const Obstacle& o = obstacles_[k];
        p.obstacle = k;
        p.obstacle_first = !cloth_first;
        const int na = vf ? 1 : 2;  // stencil entries of side A
        for (int j = 0; j < 4; ++j) {
          const bool cloth = (j < na) == cloth_first;
          if (cloth) p.v[j] = h.v[j];
          else p.fixed[j] = at(o.x1, h.v[j]);
        }
        p.key = pair_key(3 + 4 * k + (vf ? (cloth_first ? 0 : 1) : 2), h.a, h.b);
        if (vf && !cloth_first) p.element = h.b;  // the cloth triangle
        if (!vf) {
          const auto e = edge_of_.find(edge_key(h.v[0], h.v[1]));
          const double ea = e != edge_of_.end() ? edge_rest_sq_[e->second] : (at(rest_, h.v[1]) - at(rest_, h.v[0])).squaredNorm();
          p.eps_x = 1e-3 * ea * (p.fixed[3] - p.fixed[2]).squaredNorm();
        }
      }
      out.push_back(p);
    }
  }
  // Analytic obstacles: spheres against cloth triangles, planes against cloth vertices.
  for (size_t k = 0; k < obstacles_.size(); ++k) {
    const Obstacle& o = obstacles_[k];
    if (o.shape == ObstacleShape::sphere) {
      const Vector3d c = o.p1.center;
      for (int f = 0; f < faces_.rows(); ++f) {
        Eigen::AlignedBox3d box;
        for (int j = 0; j < 3; ++j) {
          box.extend(at(x0, faces_(f, j)));
          box.extend(at(x1, faces_(f, j)));
        }
        if (std::sqrt(box.squaredExteriorDistance(c)) - o.p1.radius >= dh) continue;
        Pair p;
        p.kind = PairKind::sphere_triangle;
        p.v = {-1, faces_(f, 0), faces_(f, 1), faces_(f, 2)};
        p.fixed[0] = c;
        p.element = f;
        p.obstacle = static_cast<int>(k);
        p.obstacle_first = true;
        p.key = pair_key(3 + 4 * static_cast<int>(k) + 3, 0, f);
        out.push_back(p);
      }
    } else if (o.shape == ObstacleShape::plane) {
      const Vector3d n = o.p1.normal, q = o.p1.center;
      for (int i = 0; i < num_vertices_; ++i) {
        const double g = std::min(n.dot(at(x0, i) - q), n.dot(at(x1, i) - q));
        if (g >= dh) continue;
        Pair p;
        p.kind = PairKind::point_plane;
        p.v = {i, -1, -1, -1};
        p.fixed[1] = q;
        p.obstacle = static_cast<int>(k);
        p.key = pair_key(3 + 4 * static_cast<int>(k) + 3, 0, i);
        out.push_back(p);
      }
    }
  }
}

double Barrier::bound(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1) const {
  const double dh = prm_.thickness;
  double alpha = 1.0;
  const int n = static_cast<int>(pairs_.size());
#pragma omp parallel for reduction(min : alpha) schedule(dynamic, 64) if (n > 512)
  for (int q = 0; q < n; ++q) {
    const Pair& p = pairs_[q];
    const barrier::PairConstants c = constants(p);
    const Stencil s0 = stencil(p, x0), s1 = stencil(p, x1);
    const double g0 = barrier::pair_gap(s0, c);
    const double eta = 0.2 * std::min(g0, dh);  // the distance stays above half of it
    double toi = 1.0;
    switch (p.kind) {
      case PairKind::point_triangle:
      case PairKind::edge_edge: {
        const detection::Impact imp = p.kind == PairKind::point_triangle ? detection::vertex_triangle_ccd(s0, s1, eta)
                                                                         : detection::edge_edge_ccd(s0, s1, eta);
        if (imp.hit) toi = imp.toi;
        break;
      }
      case PairKind::sphere_triangle: toi = sphere_triangle_toi(s0, s1, c.radius, eta); break;
      case PairKind::point_plane: {
        const double g1 = barrier::pair_gap(s1, c);
        if (g1 < 0.5 * eta) toi = (g0 - 0.5 * eta) / (g0 - g1);
        break;
      }
    }
    alpha = std::min(alpha, toi);
  }
  return alpha;
}

void Barrier::index_contributions() {
  const int P = static_cast<int>(pairs_.size());
  const int Q = P + static_cast<int>(friction_pairs_.size());
  const std::array<int, 4> sizes = {num_vertices_, static_cast<int>(edges_.size()), static_cast<int>(faces_.rows()),
                                    static_cast<int>(self_ids_.size() / 4)};
  struct Item {
    int kind, element;
    Contribution c;
  };
  std::vector<Item> all;
  all.reserve(Q);
  for (int q = 0; q < Q; ++q) {
    const Pair& p = q < P ? pairs_[q] : friction_pairs_[q - P];
    int cloth[4], nc = 0;
    for (int j = 0; j < 4; ++j)
      if (p.v[j] >= 0) cloth[nc++] = j;
    if (p.obstacle < 0) {
      // A pair the pattern lacks (just collected by step_bound) is indexed again by
      // refresh_pattern, which runs before the next assembly and adds it.
      const auto it = self_element_.find(p.key);
      if (it != self_element_.end()) all.push_back({self_kind, it->second, {q, {0, 1, 2, 3}}});
      continue;
    }
    Contribution c{q, {-1, -1, -1, -1}};
    if (nc == 1) {
      c.local[cloth[0]] = 0;
      all.push_back({vertex_kind, p.v[cloth[0]], c});
    } else if (nc == 2) {
      const int e = edge_of_.at(edge_key(p.v[cloth[0]], p.v[cloth[1]]));
      for (int m = 0; m < 2; ++m) c.local[cloth[m]] = position_of(p.v[cloth[m]], edges_[e].data(), 2);
      all.push_back({edge_kind, e, c});
    } else {
      const int f = p.element;  // the cloth triangle (sphere and obstacle-vertex pairs)
      const int ids[3] = {faces_(f, 0), faces_(f, 1), faces_(f, 2)};
      for (int m = 0; m < 3; ++m) c.local[cloth[m]] = position_of(p.v[cloth[m]], ids, 3);
      all.push_back({triangle_kind, f, c});
    }
  }
  for (int g = 0; g < 4; ++g) {
    first_[g].assign(sizes[g] + 1, 0);
    items_[g].clear();
  }
  for (const Item& it : all) ++first_[it.kind][it.element + 1];
  for (int g = 0; g < 4; ++g) {
    for (int e = 0; e < sizes[g]; ++e) first_[g][e + 1] += first_[g][e];
    items_[g].resize(first_[g][sizes[g]]);
  }
  std::array<std::vector<int>, 4> next;
  for (int g = 0; g < 4; ++g) next[g].assign(first_[g].begin(), first_[g].end() - 1);
  for (const Item& it : all) items_[it.kind][next[it.kind][it.element]++] = it.c;
}

ContactReport Barrier::begin_step(const State& s, double dt) {
  ContactReport rep;
  const double t_end = s.t + dt;
  x0_ = s.x;
  bounded_steps_ = 0;
  pattern_refreshes_ = 0;
  pattern_stale_ = false;
  double free_mass = 0;
  int free = 0;
  for (int i = 0; i < s.num_vertices(); ++i)
    if (s.is_free(i)) {
      free_mass += s.mass[i];
      ++free;
    }
  kappa_ = free > 0 ? prm_.stiffness * (free_mass / free) / (dt * dt * prm_.thickness * prm_.thickness) : 0.0;
  for (Obstacle& o : obstacles_) {
    const ObstacleSpec& spec = specs_[o.spec];
    o.p0 = ObstaclePose::at(spec, s.t);
    o.p1 = ObstaclePose::at(spec, t_end);
    if (o.body >= 0) {
      o.x1.resize(3 * o.local.rows());
      for (int i = 0; i < o.local.rows(); ++i)
        o.x1.segment<3>(3 * i) = o.p1.rotation * o.local.row(i).transpose() + o.p1.center;
      detector_->set_obstacle_positions(o.body, o.x1, o.x1);
    }
  }

  // The pairs of the predicted motion: this step's pattern, and those active at x0.
  {
    ScopedTimer t(rep.detection_seconds);
    const Eigen::VectorXd xp = s.x + dt * s.v;
    collect(s.x, xp, pairs_);
  }
  self_ids_.clear();
  self_element_.clear();
  for (const Pair& p : pairs_)
    if (p.obstacle < 0 && self_element_.emplace(p.key, static_cast<int>(self_ids_.size() / 4)).second)
      self_ids_.insert(self_ids_.end(), p.v.begin(), p.v.end());

  // Admissible start; friction lagged from it.
  friction_pairs_.clear();
  friction_.clear();
  const double dh = prm_.thickness;
  for (const Pair& p : pairs_) {
    const barrier::PairConstants c = constants(p);
    const Stencil x = stencil(p, s.x);
    const double g = barrier::pair_gap(x, c);
    if (!(g > 0)) {
      rep.status = Status::numerical_issue;
      rep.message = p.obstacle >= 0
                        ? fmt::format("the cloth touches or crosses obstacle '{}' at the start of the step (gap {:.3e} m; the "
                                      "barrier needs an intersection-free start against the obstacle's end-of-step pose: a "
                                      "smaller dt when a scripted obstacle moves into the cloth)",
                                      specs_[obstacles_[p.obstacle].spec].name, g)
                        : fmt::format("the cloth touches or crosses itself at the start of the step (vertices {} {} {} {})",
                                      p.v[0], p.v[1], p.v[2], p.v[3]);
      return rep;
    }
    if (g >= dh) continue;
    ++rep.contacts;
    const double mu = p.obstacle >= 0 ? specs_[obstacles_[p.obstacle].spec].friction : prm_.cloth_friction;
    if (mu <= 0) continue;
    // Closest-point weights and normal at the start.
    barrier::FrictionPair f;
    Vector3d gap;
    switch (p.kind) {
      case PairKind::point_triangle:
      case PairKind::sphere_triangle: {
        const barrier::TypedDistance td = barrier::point_triangle_type(x);
        f.gamma = td.gamma;
        break;
      }
      case PairKind::edge_edge: f.gamma = barrier::edge_edge_type(x).gamma; break;
      case PairKind::point_plane: f.gamma = {1, -1, 0, 0}; break;
    }
    gap.setZero();
    for (int j = 0; j < 4; ++j) gap += f.gamma[j] * x[j];
    const Vector3d n = p.kind == PairKind::point_plane ? c.normal : Vector3d(gap.normalized());
    if (!n.allFinite()) continue;
    f.basis = barrier::tangent_basis(n);
    f.mu_lambda = mu * barrier::pair_normal_force(x, c);
    f.eps = prm_.friction_velocity * dt;
    if (p.obstacle >= 0) {
      // The obstacle's own displacement at its contact point over the step, on its side.
      const Obstacle& o = obstacles_[p.obstacle];
      Vector3d q = Vector3d::Zero();  // the obstacle side's closest point
      if (p.kind == PairKind::sphere_triangle) {
        q = x[0] - c.radius * n;  // on the sphere's surface (n points from the triangle to the centre)
      } else if (p.kind == PairKind::point_plane) {
        q = x[0] - n.dot(x[0] - x[1]) * n;  // the vertex's projection onto the plane
      } else {
        double w = 0;
        for (int j = 0; j < 4; ++j)
          if (p.v[j] < 0) {
            q += std::abs(f.gamma[j]) * x[j];
            w += std::abs(f.gamma[j]);
          }
        if (w > 0) q /= w;
      }
      const Vector3d y = o.p1.rotation.transpose() * (q - o.p1.center);
      const Vector3d moved = q - (o.p0.rotation * y + o.p0.center);  // displacement of that material point
      f.offset = f.basis.transpose() * ((p.obstacle_first ? 1.0 : -1.0) * moved);
      for (int j = 0; j < 4; ++j)
        if (p.v[j] < 0) f.gamma[j] = 0;  // obstacle positions: their motion is in the offset
    }
    friction_pairs_.push_back(p);
    friction_.push_back(f);
  }
  index_contributions();
  return rep;
}

bool Barrier::update_pattern(AssemblyPlan& plan) {
  if (self_group_ < 0 || self_ids_ == declared_self_) return false;
  plan.replace_group(self_group_, self_ids_);
  declared_self_ = self_ids_;
  return true;
}

bool Barrier::refresh_pattern(AssemblyPlan& plan) {
  if (!pattern_stale_ || self_group_ < 0) return false;
  pattern_stale_ = false;
  for (const Pair& p : pairs_)
    if (p.obstacle < 0 && self_element_.emplace(p.key, static_cast<int>(self_ids_.size() / 4)).second)
      self_ids_.insert(self_ids_.end(), p.v.begin(), p.v.end());
  if (self_ids_ == declared_self_) return false;
  plan.replace_group(self_group_, self_ids_);
  declared_self_ = self_ids_;
  ++pattern_refreshes_;
  index_contributions();
  return true;
}

double Barrier::step_bound(const State& at_state, const Eigen::VectorXd& dx) {
  const Eigen::VectorXd x1 = at_state.x + dx;
  collect(at_state.x, x1, pairs_);
  if (self_group_ >= 0)
    for (const Pair& p : pairs_)
      if (p.obstacle < 0 && !self_element_.count(p.key)) {
        pattern_stale_ = true;
        break;
      }
  index_contributions();
  const double alpha = bound(at_state.x, x1);
  if (alpha < 1) ++bounded_steps_;
  return alpha;
}

namespace {
// The stencil of friction displacements: cloth entries x - x0, obstacle entries zero.
Stencil displacement(const Barrier::Pair& p, const Eigen::VectorXd& x, const Eigen::VectorXd& x0) {
  Stencil d;
  for (int j = 0; j < 4; ++j) d[j] = p.v[j] >= 0 ? Vector3d(at(x, p.v[j]) - at(x0, p.v[j])) : Vector3d::Zero();
  return d;
}
}  // namespace

double Barrier::energy(const State& s) const {
  double e = 0;
  for (const Pair& p : pairs_) {
    e += barrier::pair_energy(stencil(p, s.x), constants(p));
    if (!std::isfinite(e)) return inf;
  }
  for (size_t k = 0; k < friction_.size(); ++k) e += barrier::friction_energy(friction_[k], displacement(friction_pairs_[k], s.x, x0_));
  return e;
}

void Barrier::add_gradient(const State& s, Eigen::VectorXd& g) const {
  barrier::Vec12 grad;
  double value;
  for (const Pair& p : pairs_) {
    if (!barrier::pair_derivatives(stencil(p, s.x), constants(p), value, grad, nullptr)) continue;
    for (int j = 0; j < 4; ++j)
      if (p.v[j] >= 0) g.segment<3>(3 * p.v[j]) += grad.segment<3>(3 * j);
  }
  for (size_t k = 0; k < friction_.size(); ++k) {
    const Pair& p = friction_pairs_[k];
    barrier::friction_derivatives(friction_[k], displacement(p, s.x, x0_), grad, nullptr);
    for (int j = 0; j < 4; ++j)
      if (p.v[j] >= 0) g.segment<3>(3 * p.v[j]) += grad.segment<3>(3 * j);
  }
}

void Barrier::add_hessian(const State& s, ElementBuffer& buf, HessianMode mode) const {
  if (vertex_group_ < 0) return;
  const int P = static_cast<int>(pairs_.size());
  const int Q = P + static_cast<int>(friction_.size());
  hess_.resize(Q);
  auto local = [&](int q) {
    barrier::Mat12& H = hess_[q];
    barrier::Vec12 grad;
    if (q < P) {
      const Pair& p = pairs_[q];
      double value;
      if (!barrier::pair_derivatives(stencil(p, s.x), constants(p), value, grad, &H)) return;  // H zeroed
      for (int j = 0; j < 4; ++j)
        if (p.v[j] < 0) {  // obstacle positions are constants
          H.middleRows<3>(3 * j).setZero();
          H.middleCols<3>(3 * j).setZero();
        }
      if (mode == HessianMode::projected) {
        Eigen::SelfAdjointEigenSolver<barrier::Mat12> es(H);
        const auto lam = es.eigenvalues().cwiseMax(0.0);
        H = es.eigenvectors() * lam.asDiagonal() * es.eigenvectors().transpose();
      }
    } else {
      const Pair& p = friction_pairs_[q - P];
      barrier::friction_derivatives(friction_[q - P], displacement(p, s.x, x0_), grad, &H);  // PSD
    }
  };
#pragma omp parallel for schedule(dynamic, 32) if (Q > 256)
  for (int q = 0; q < Q; ++q) local(q);
  const std::array<int, 4> groups = {vertex_group_, edge_group_, triangle_group_, self_group_};
  for (int g = 0; g < 4; ++g) {
    const int gid = groups[g];
    if (gid < 0) continue;
    if (buf.mode() == AssemblyMode::stored) buf.zero_group(gid);
    const std::vector<int>& first = first_[g];
    const std::vector<Contribution>& items = items_[g];
    if (items.empty()) continue;
    buf.for_each(gid, [&](int e) {
      if (e + 1 >= static_cast<int>(first.size()) || first[e] == first[e + 1]) return;
      ElementBuffer::Slot slot = buf.slot(gid, e);
      const int k = slot.stencil_size();
      std::fill_n(slot.data(), 9 * k * k, 0.0);
      for (int it = first[e]; it < first[e + 1]; ++it) {
        const Contribution& c = items[it];
        const barrier::Mat12& H = hess_[c.pair];
        for (int a = 0; a < 4; ++a) {
          if (c.local[a] < 0) continue;
          for (int b = 0; b < 4; ++b)
            if (c.local[b] >= 0) slot.block(c.local[a], c.local[b]) += H.block<3, 3>(3 * a, 3 * b);
        }
      }
    });
  }
}

ContactReport Barrier::end_step(State& s, double dt) {
  (void)dt;
  ContactReport rep;
  rep.bounded_steps = bounded_steps_;
  rep.pattern_updates = pattern_refreshes_;  // within the step (begin_step's update counts in the simulator)
  double min_gap = inf;
  for (const Pair& p : pairs_) {
    const double g = barrier::pair_gap(stencil(p, s.x), constants(p));
    if (!(g > 0)) {
      rep.status = Status::numerical_issue;
      rep.message = fmt::format("a contact pair touches or crosses after the solve (gap {:.3e} m)", g);
      return rep;
    }
    if (g < prm_.thickness) {
      ++rep.barrier_pairs;
      min_gap = std::min(min_gap, g);
    }
  }
  rep.min_gap = rep.barrier_pairs > 0 ? min_gap : 0.0;
  return rep;
}

}  // namespace weft::contact
