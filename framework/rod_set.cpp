#include "framework/rod_set.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <unordered_map>

#include "framework/distance.hpp"
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

/// The centreline segments of the rods placed so far, hashed by the cell of their midpoint,
/// to check that a new rod keeps `reach` (radii plus clearance) from all of them. Two
/// segments no longer than `longest` whose midpoints are farther apart than longest + reach
/// are farther apart than reach, so with cells of that size the 27 cells around a midpoint
/// hold every segment that can be too close.
class SeedGrid {
 public:
  SeedGrid(double longest, double reach) : cell_(longest + reach), reach_(reach) {}

  /// True when no segment of x comes within `reach` of a segment already added.
  bool clear(const std::vector<Eigen::Vector3d>& x) const {
    for (size_t i = 0; i + 1 < x.size(); ++i) {
      const Eigen::Vector3i c = cell(0.5 * (x[i] + x[i + 1]));
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            const auto it = cells_.find(key(c + Eigen::Vector3i(dx, dy, dz)));
            if (it == cells_.end()) continue;
            for (const int s : it->second)
              if (segment_segment_distance(x[i], x[i + 1], ends_[s].first, ends_[s].second).distance_squared < reach_ * reach_) return false;
          }
    }
    return true;
  }

  void add(const std::vector<Eigen::Vector3d>& x) {
    for (size_t i = 0; i + 1 < x.size(); ++i) {
      cells_[key(cell(0.5 * (x[i] + x[i + 1])))].push_back(static_cast<int>(ends_.size()));
      ends_.emplace_back(x[i], x[i + 1]);
    }
  }

 private:
  Eigen::Vector3i cell(const Eigen::Vector3d& p) const { return (p / cell_).array().floor().cast<int>(); }
  static std::int64_t key(const Eigen::Vector3i& c) {
    // 21 bits per axis: cells of a hair ball are within +-2^20 of the origin by far.
    const auto u = [](int v) { return static_cast<std::int64_t>(v + (1 << 20)) & ((std::int64_t{1} << 21) - 1); };
    return (u(c.x()) << 42) | (u(c.y()) << 21) | u(c.z());
  }
  double cell_, reach_;
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> ends_;
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
};

/// True when every segment of x keeps `reach` from the centre c (x outside the scalp).
bool outside_sphere(const std::vector<Eigen::Vector3d>& x, const Eigen::Vector3d& c, double reach) {
  for (size_t i = 0; i + 1 < x.size(); ++i)
    if (point_segment_distance(c, x[i], x[i + 1]).distance_squared < reach * reach) return false;
  return true;
}

// Draws per rod before a sphere_hair family is declared too dense: the first half redraw the
// phase only, the rest the root as well.
constexpr int max_draws = 400;

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
      // with a uniformly random phase about their normal. A rod closer than the radii plus
      // `clearance` to a rod placed before it, or to the scalp, is drawn again: its phase
      // first, then its root too. A rod placed at its first draw uses the same random numbers
      // as without the check.
      std::mt19937_64 rng(static_cast<std::uint64_t>(f.seed));
      std::uniform_real_distribution<double> u01(0.0, 1.0);
      const Eigen::Vector3d e1 = orthogonal(axis), e2 = axis.cross(e1);
      const double c0 = std::cos(f.coverage_angle), rod_r = f.material.radius;
      const auto draw_root = [&] {
        const double c = c0 + (1 - c0) * u01(rng), sn = std::sqrt(std::max(0.0, 1 - c * c));
        const double az = 2 * std::numbers::pi * u01(rng);
        const Eigen::Vector3d n = c * axis + sn * (std::cos(az) * e1 + std::sin(az) * e2);
        return std::make_pair(Eigen::Vector3d(f.sphere_center + (f.sphere_radius + rod_r) * n), n);
      };
      // The longest chord of a rest shape: the vertices are equally spaced in arc length.
      const std::vector<Eigen::Vector3d> probe = centreline(f, Eigen::Vector3d::Zero(), axis);
      double longest = 0;
      for (size_t i = 0; i + 1 < probe.size(); ++i) longest = std::max(longest, (probe[i + 1] - probe[i]).norm());
      SeedGrid grid(longest, 2 * rod_r + f.clearance);
      // No rod inside the scalp. Its root vertex sits on it (at sphere_radius + r): allow rounding.
      const double scalp_reach = (f.sphere_radius + rod_r) * (1 - 1e-12);
      for (int r = 0; r < f.count; ++r) {
        auto root = draw_root();
        bool placed = false;
        for (int d = 0; d < max_draws && !placed; ++d) {
          if (d >= max_draws / 2) root = draw_root();
          const double phase = 2 * std::numbers::pi * u01(rng);
          const std::vector<Eigen::Vector3d> x = centreline(f, root.first, root.second, phase);
          if (!grid.clear(x) || !outside_sphere(x, f.sphere_center, scalp_reach)) continue;
          grid.add(x);
          roots.push_back(root);
          phases.push_back(phase);
          placed = true;
        }
        if (!placed) {
          errors.push_back(fmt::format("{}.clearance = {} m: after {} draws rod {} of {} still comes closer than the radii plus the clearance to one "
                                       "of the {} rods before it, or enters the scalp; lower `count` or `clearance`, or enlarge `sphere_radius`",
                                       p, f.clearance, max_draws, r, f.count, r));
          break;
        }
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
