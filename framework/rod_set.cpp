#include "framework/rod_set.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <numbers>
#include <random>

#include "framework/error.hpp"
#include "framework/scene.hpp"

namespace weft {
namespace {

/// A unit vector orthogonal to the unit vector a (deterministic).
Eigen::Vector3d orthogonal(const Eigen::Vector3d& a) {
  const Eigen::Vector3d t = std::abs(a.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  return (t - t.dot(a) * a).normalized();
}

/// Centreline of one rod from `root` along the unit `axis`: straight, or a helix of radius
/// R and pitch p whose first point is the root, its axis offset from the root along the
/// direction at angle `phase` about `axis` from orthogonal(axis). Vertices are equally
/// spaced in arc length.
std::vector<Eigen::Vector3d> centreline(const RodSpec& f, const Eigen::Vector3d& root, const Eigen::Vector3d& axis, double phase = 0) {
  std::vector<Eigen::Vector3d> x(f.vertices);
  const double R = f.curl_radius, p = f.curl_pitch;
  const Eigen::Vector3d a1 = orthogonal(axis), a2 = axis.cross(a1);
  const Eigen::Vector3d e1 = std::cos(phase) * a1 + std::sin(phase) * a2, e2 = axis.cross(e1);
  const double turn = std::sqrt(std::pow(2 * std::numbers::pi * R, 2) + p * p);  // arc length per turn
  for (int i = 0; i < f.vertices; ++i) {
    const double s = f.length * i / (f.vertices - 1);
    if (R == 0) {
      x[i] = root + s * axis;
      continue;
    }
    const double phi = 2 * std::numbers::pi * s / turn;
    x[i] = root + R * (std::cos(phi) - 1) * e1 + R * std::sin(phi) * e2 + (p * phi / (2 * std::numbers::pi)) * axis;
  }
  return x;
}

Eigen::VectorXd interleave(const std::vector<Eigen::Vector3d>& x) {
  const int V = static_cast<int>(x.size());
  Eigen::VectorXd q = Eigen::VectorXd::Zero(4 * V - 1);
  for (int i = 0; i < V; ++i) q.segment<3>(4 * i) = x[i];
  return q;
}

}  // namespace

RodSet build_rods(const SceneSpec& spec) {
  RodSet set;
  set.first = {0};
  std::vector<std::string> errors;
  for (size_t k = 0; k < spec.rods.size(); ++k) {
    const RodSpec& f = spec.rods[k];
    const std::string p = fmt::format("rods.{}", k);
    if (!(f.direction.norm() > 1e-12)) {
      errors.push_back(fmt::format("{}.direction = [{}]: a nonzero vector", p, fmt::join(f.direction.data(), f.direction.data() + 3, ", ")));
      continue;
    }
    const Eigen::Vector3d axis = f.direction.normalized();
    std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> roots;  // (root, growth axis)
    std::vector<double> phases;                                       // helix phase per rod
    if (f.shape == RodShape::sphere_hair) {
      // Area-uniform roots on the cap: cos(polar angle) uniform in [cos(coverage), 1]; curls
      // with a uniformly random phase about their normal.
      std::mt19937_64 rng(static_cast<std::uint64_t>(f.seed));
      std::uniform_real_distribution<double> u01(0.0, 1.0);
      const Eigen::Vector3d e1 = orthogonal(axis), e2 = axis.cross(e1);
      const double c0 = std::cos(f.coverage_angle);
      for (int r = 0; r < f.count; ++r) {
        const double c = c0 + (1 - c0) * u01(rng), sn = std::sqrt(std::max(0.0, 1 - c * c));
        const double az = 2 * std::numbers::pi * u01(rng);
        const Eigen::Vector3d n = c * axis + sn * (std::cos(az) * e1 + std::sin(az) * e2);
        roots.emplace_back(f.sphere_center + (f.sphere_radius + f.material.radius) * n, n);
        phases.push_back(2 * std::numbers::pi * u01(rng));
      }
    } else {
      if (f.count > 1 && !(f.spread.norm() > 1e-12)) {
        errors.push_back(fmt::format("{}.spread = [{}]: a nonzero vector when count > 1", p, fmt::join(f.spread.data(), f.spread.data() + 3, ", ")));
        continue;
      }
      const Eigen::Vector3d step = f.count > 1 ? Eigen::Vector3d(f.spacing * f.spread.normalized()) : Eigen::Vector3d::Zero();
      for (int r = 0; r < f.count; ++r) roots.emplace_back(f.root + r * step, axis);
    }
    if (f.shape == RodShape::helix && f.curl_radius == 0)
      errors.push_back(fmt::format("{}.curl_radius = 0: a helix needs curl_radius > 0", p));
    if (f.shape == RodShape::straight && f.curl_radius > 0)
      errors.push_back(fmt::format("{}.curl_radius = {}: only read for shape = helix or sphere_hair", p, f.curl_radius));
    const bool moving = f.root_held != RodRoot::free && !f.motion.is_static();
    if (moving) set.motions.push_back(f.motion);
    for (size_t r = 0; r < roots.size(); ++r) {
      const auto& [root, dir] = roots[r];
      set.rest.push_back(interleave(centreline(f, root, dir, phases.empty() ? 0.0 : phases[r])));
      set.first.push_back(set.first.back() + f.vertices);
      set.family.push_back(static_cast<int>(k));
      set.root_held.push_back(f.root_held);
      set.motion.push_back(moving ? static_cast<int>(set.motions.size()) - 1 : -1);
    }
  }
  if (!errors.empty()) throw ConfigError("invalid rods", errors);
  return set;
}

}  // namespace weft
