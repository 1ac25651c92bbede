#include "contact/implicit_contact.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <map>
#include <tuple>

#include "contact/detection/collision_detector.hpp"
#include "contact/detection/proximity.hpp"
#include "framework/timers.hpp"

namespace weft::contact {

using Eigen::Vector3d;

namespace {

ObstacleConstraints::Params obstacle_params(const ImplicitContact::Params& p) {
  ObstacleConstraints::Params o;
  o.thickness = p.impulse.thickness;
  o.margin = p.margin;
  o.projection_tolerance = p.projection_tolerance;
  o.redetection_depth = p.redetection_depth;
  o.max_redetections = p.max_redetections;
  o.redetect_iterates = p.redetect_iterates;
  return o;
}

Vector3d at(const Eigen::VectorXd& x, int i) { return x.segment<3>(3 * i); }

}  // namespace

double ImplicitContact::Spring::gap(const Eigen::VectorXd& x, double h) const {
  Vector3d g = Vector3d::Zero();
  for (int j = 0; j < 4; ++j) g += gamma[j] * at(x, v[j]);
  return normal.dot(g) - h;
}

ImplicitContact::ImplicitContact(const Scene& scene, const Params& prm)
    : prm_(prm), obstacles_(scene, (Params::validate(prm).throw_if_failed(fmt::format("{}: invalid contact configuration:", scene.path)),
                                    obstacle_params(prm))) {
  has_obstacles_ = !scene.spec.obstacles.empty();
  if (prm_.impulse.self_contact && scene.mesh.num_faces() > 0) {
    failsafe_ = std::make_unique<Impulse>(scene, prm_.impulse);
    detection::CollisionDetectorParams d;
    d.margin = 0.5 * prm_.impulse.thickness;
    d.self_contact = true;
    d.proximity.edge_edge_interior_only = true;  // endpoint pairs are found as vertex-triangle pairs
    detector_ = std::make_unique<detection::CollisionDetector>(scene.mesh, d);
    rest_.resize(3 * scene.mesh.num_vertices());
    for (int i = 0; i < scene.mesh.num_vertices(); ++i) rest_.segment<3>(3 * i) = scene.mesh.rest().row(i).transpose();
  }
}

ImplicitContact::~ImplicitContact() = default;
ImplicitContact::ImplicitContact(ImplicitContact&&) noexcept = default;
ImplicitContact& ImplicitContact::operator=(ImplicitContact&&) noexcept = default;

void ImplicitContact::declare(AssemblyPlan& plan) {
  obstacles_.declare(plan);
  if (detector_) group_ = plan.add_group(4, {});
}

ContactReport ImplicitContact::begin_step(const State& s, double dt) {
  ContactReport rep = obstacles_.begin_step(s, dt);
  springs_.clear();
  if (!detector_ || rep.status != Status::success) return rep;
  failsafe_->begin_step(s, dt);

  // Pairs within h at the start or at the prediction, keyed by kind and primitives.
  const double h = prm_.impulse.thickness;
  Eigen::VectorXd xp = s.x + dt * s.v;
  std::map<std::tuple<int, int, int>, detection::ProximityPair> found;
  {
    ScopedTimer t(rep.detection_seconds);
    detector_->update(s.x, xp);
    for (const auto& p : detector_->proximity(s.x, h)) found.emplace(std::tuple(static_cast<int>(p.kind), p.a, p.b), p);
    for (const auto& p : detector_->proximity(xp, h)) {
      const auto key = std::tuple(static_cast<int>(p.kind), p.a, p.b);
      if (found.count(key)) continue;
      // Found only in the prediction: the weights and normal of its closest points at x0.
      const double far = std::numeric_limits<double>::infinity();
      std::optional<detection::Proximity> g =
          p.kind == detection::PairKind::vertex_triangle
              ? detection::vertex_triangle_proximity(at(s.x, p.v[0]), at(s.x, p.v[1]), at(s.x, p.v[2]), at(s.x, p.v[3]), far)
              : detection::edge_edge_proximity(at(s.x, p.v[0]), at(s.x, p.v[1]), at(s.x, p.v[2]), at(s.x, p.v[3]), far);
      if (!g) continue;
      detection::ProximityPair q = p;
      q.geometry = *g;
      found.emplace(key, q);
    }
  }
  for (const auto& [key, p] : found) {
    Spring sp{p.v, p.geometry.gamma, p.geometry.normal, 0.0};
    Vector3d g_rest = Vector3d::Zero();  // material points this close at rest: no contact
    for (int j = 0; j < 4; ++j) g_rest += sp.gamma[j] * at(rest_, sp.v[j]);
    if (g_rest.norm() < h) continue;
    double inv_m = 0;
    for (int j = 0; j < 4; ++j)
      if (s.is_free(sp.v[j]) && s.mass[sp.v[j]] > 0) inv_m += sp.gamma[j] * sp.gamma[j] / s.mass[sp.v[j]];
    if (inv_m == 0) continue;  // all four vertices prescribed: nothing can move
    sp.stiffness = prm_.spring_stiffness / (inv_m * dt * dt);
    springs_.push_back(sp);
  }
  rep.springs = static_cast<int>(springs_.size());
  rep.contacts += rep.springs;
  return rep;
}

bool ImplicitContact::update_pattern(AssemblyPlan& plan) {
  if (group_ < 0) return false;
  std::vector<int> ids;
  ids.reserve(4 * springs_.size());
  for (const Spring& sp : springs_) ids.insert(ids.end(), sp.v.begin(), sp.v.end());
  if (ids == declared_) return false;
  plan.replace_group(group_, ids);
  declared_ = std::move(ids);
  return true;
}

double ImplicitContact::energy(const State& s) const {
  double e = obstacles_.energy(s);
  for (const Spring& sp : springs_) {
    const double c = std::min(sp.gap(s.x, prm_.impulse.thickness), 0.0);
    e += 0.5 * sp.stiffness * c * c;
  }
  return e;
}

void ImplicitContact::add_gradient(const State& s, Eigen::VectorXd& g) const {
  obstacles_.add_gradient(s, g);
  for (const Spring& sp : springs_) {
    const double c = sp.gap(s.x, prm_.impulse.thickness);
    if (c >= 0) continue;
    for (int j = 0; j < 4; ++j) g.segment<3>(3 * sp.v[j]) += sp.stiffness * c * sp.gamma[j] * sp.normal;
  }
}

void ImplicitContact::add_hessian(const State& s, ElementBuffer& buf, HessianMode mode) const {
  obstacles_.add_hessian(s, buf, mode);
  if (group_ < 0 || springs_.empty()) return;
  // The spring Hessians are positive semidefinite: the same in every mode.
  buf.for_each(group_, [&](int e) {
    const Spring& sp = springs_[e];
    const bool active = sp.gap(s.x, prm_.impulse.thickness) < 0;
    if (!active && buf.mode() == AssemblyMode::direct) return;  // contributes nothing
    const Eigen::Matrix3d nn = active ? Eigen::Matrix3d(sp.stiffness * sp.normal * sp.normal.transpose())
                                      : Eigen::Matrix3d::Zero();  // stored mode keeps old values otherwise
    ElementBuffer::Slot slot = buf.slot(group_, e);
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) slot.block(a, b) = (sp.gamma[a] * sp.gamma[b]) * nn;
  });
}

ContactReport ImplicitContact::end_step(State& s, double dt) {
  ContactReport rep = obstacles_.end_step(s, dt);
  if (rep.status != Status::success || !failsafe_) return rep;
  ContactReport f = failsafe_->end_step(s, dt);
  // The failsafe's obstacle counts would double those of the constraints: keep its own
  // counters of cloth-cloth work and its depth check (it runs last).
  f.contacts = 0;
  f.obstacle_contacts = 0;
  f.released = 0;
  rep.merge_end(f);
  return rep;
}

}  // namespace weft::contact
