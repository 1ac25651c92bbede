#include "contact/obstacle_penalty.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

#include "contact/mesh_distance.hpp"
#include "framework/error.hpp"
#include "framework/timers.hpp"

namespace weft::contact {

ObstaclePose ObstaclePose::at(const ObstacleSpec& o, double t) {
  ObstaclePose p;
  p.shape = o.shape;
  p.center = o.motion.apply(o.center, t);
  // R(t) from the images of the axes: the motion is rigid.
  const Eigen::Vector3d c0 = o.motion.apply(Eigen::Vector3d::Zero(), t);
  for (int k = 0; k < 3; ++k) p.rotation.col(k) = o.motion.apply(Eigen::Vector3d::Unit(k), t) - c0;
  p.radius = o.radius;
  p.half_extents = o.half_extents;
  p.normal = p.rotation * o.normal;
  if (o.shape == ObstacleShape::mesh) {
    if (!o.mesh)
      throw ConfigError(fmt::format("obstacle '{}' (shape = mesh, file \"{}\") has no geometry: load the scene with build_scene, or "
                                    "set ObstacleSpec::mesh with load_obstacle_mesh",
                                    o.name, o.file));
    p.mesh = &MeshDistance::of(*o.mesh);
  }
  return p;
}

Distance ObstaclePose::distance(const Eigen::Vector3d& x) const {
  Distance d;
  switch (shape) {
    case ObstacleShape::plane:
      d.phi = normal.dot(x - center);
      d.grad = normal;
      break;
    case ObstacleShape::sphere: {
      const Eigen::Vector3d r = x - center;
      const double len = r.norm();
      d.phi = len - radius;
      if (len > 0) {
        d.grad = r / len;
        d.hess = (Eigen::Matrix3d::Identity() - d.grad * d.grad.transpose()) / len;
      } else {
        d.grad = Eigen::Vector3d::UnitZ();  // the centre: any direction is as good
      }
      break;
    }
    case ObstacleShape::box: {
      // Local coordinates; q = |y| - h per axis.
      const Eigen::Vector3d y = rotation.transpose() * (x - center);
      const Eigen::Vector3d q = y.cwiseAbs() - half_extents;
      const Eigen::Vector3d s(y[0] < 0 ? -1.0 : 1.0, y[1] < 0 ? -1.0 : 1.0, y[2] < 0 ? -1.0 : 1.0);
      const Eigen::Vector3d qp = q.cwiseMax(0.0);
      int outside = 0;
      for (int k = 0; k < 3; ++k) outside += q[k] > 0;
      Eigen::Vector3d g = Eigen::Vector3d::Zero();
      Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
      if (outside == 0) {  // inside: distance to the nearest face
        int k = 0;
        q.maxCoeff(&k);
        d.phi = q[k];
        g[k] = s[k];
      } else if (outside == 1) {  // facing one face
        int k = 0;
        q.maxCoeff(&k);
        d.phi = q[k];
        g[k] = s[k];
      } else {  // beside an edge or a corner: distance to it
        const double len = qp.norm();
        d.phi = len;
        const Eigen::Vector3d u = qp / len;
        g = s.cwiseProduct(u);
        Eigen::Matrix3d D = Eigen::Matrix3d::Zero();
        for (int k = 0; k < 3; ++k) D(k, k) = q[k] > 0 ? 1.0 : 0.0;
        // d phi / dy = S u and d^2 phi / dy^2 = S (D - u u^T) S / |q+|, S = diag(sign y).
        h = s.asDiagonal() * ((D - u * u.transpose()) / len) * s.asDiagonal();
      }
      d.grad = rotation * g;
      d.hess = rotation * h * rotation.transpose();
      break;
    }
    case ObstacleShape::mesh: {
      const Distance b = mesh->distance(rotation.transpose() * (x - center));
      d.phi = b.phi;
      d.grad = rotation * b.grad;
      d.hess = rotation * b.hess * rotation.transpose();
      break;
    }
  }
  return d;
}

ObstaclePenalty::ObstaclePenalty(const Scene& scene, const Params& prm)
    : obstacles_(scene.spec.obstacles), mass_(scene.lumped_masses()), kappa_(prm.stiffness.value_or(0.0)),
      delta_(prm.thickness) {
  Checker c = Params::validate(prm);
  for (size_t k = 0; k < obstacles_.size(); ++k)
    c.require(obstacles_[k].friction == 0.0, fmt::format("obstacles.{}.friction", k), obstacles_[k].friction,
              "0 with contact = obstacle_penalty (frictionless); friction arrives with the cloth-contact strategies");
  c.throw_if_failed(fmt::format("{}: invalid contact configuration:", scene.path));
  free_.resize(scene.dof.size());
  for (size_t i = 0; i < scene.dof.size(); ++i) free_[i] = scene.dof[i] == Dof::free;
  for (const auto& o : obstacles_) poses_.push_back(ObstaclePose::at(o, 0.0));
}

void ObstaclePenalty::declare(AssemblyPlan& plan) {
  // One single-vertex element per vertex: the sum over obstacles is local to it.
  std::vector<int> ids(mass_.size());
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int>(i);
  group_ = plan.add_group(1, ids);
}

ContactReport ObstaclePenalty::begin_step(const State& s, double dt) {
  ContactReport r;
  ScopedTimer t(r.detection_seconds);
  for (size_t k = 0; k < obstacles_.size(); ++k) poses_[k] = ObstaclePose::at(obstacles_[k], s.t + dt);
  return r;
}

double ObstaclePenalty::energy(const State& s) const {
  double e = 0;
  for (int i = 0; i < s.num_vertices(); ++i) {
    if (!free_[i]) continue;
    for (const auto& p : poses_) {
      const double gap = delta_ - p.distance(s.position(i)).phi;
      if (gap > 0) e += 0.5 * kappa_ * mass_[i] * gap * gap;
    }
  }
  return e;
}

void ObstaclePenalty::add_gradient(const State& s, Eigen::VectorXd& g) const {
  for (int i = 0; i < s.num_vertices(); ++i) {
    if (!free_[i]) continue;
    for (const auto& p : poses_) {
      const Distance d = p.distance(s.position(i));
      const double gap = delta_ - d.phi;
      if (gap > 0) g.segment<3>(3 * i) -= kappa_ * mass_[i] * gap * d.grad;
    }
  }
}

void ObstaclePenalty::add_hessian(const State& s, ElementBuffer& buf, HessianMode mode) const {
  buf.for_each(group_, [&](int i) {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    if (free_[i])
      for (const auto& p : poses_) {
        const Distance d = p.distance(s.position(i));
        const double gap = delta_ - d.phi;
        if (gap <= 0) continue;
        H += kappa_ * mass_[i] * d.grad * d.grad.transpose();
        if (mode == HessianMode::exact) H -= kappa_ * mass_[i] * gap * d.hess;
      }
    buf.set(group_, i, H);
  });
}

ContactReport ObstaclePenalty::end_step(State& s, double) {
  ContactReport r;
  ScopedTimer t(r.response_seconds);
  for (int i = 0; i < s.num_vertices(); ++i)
    if (free_[i])
      for (const auto& p : poses_) r.contacts += p.distance(s.position(i)).phi < delta_;
  return r;
}

double ObstaclePenalty::max_penetration(const State& s) const {
  double m = 0;
  for (int i = 0; i < s.num_vertices(); ++i)
    if (free_[i])
      for (const auto& p : poses_) m = std::max(m, delta_ - p.distance(s.position(i)).phi);
  return m;
}

}  // namespace weft::contact
