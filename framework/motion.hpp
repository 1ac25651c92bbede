#pragma once
/// \file motion.hpp
/// Scripted rigid motion of pins, obstacles and rod roots.
#include <Eigen/Core>

#include <limits>

#include "framework/params.hpp"

namespace weft {

/// Scripted rigid motion, active over [start, end]:
/// x(t) = center + v (t' - start) + R(omega (t' - start)) (x0 - center), t' = clamp(t, start, end).
struct Motion {
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();          ///< [m/s]
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  ///< [rad/s] about `center`
  Eigen::Vector3d center = Eigen::Vector3d::Zero();            ///< [m] rotation centre at `start`
  double start = 0;                                            ///< [s]
  double end = std::numeric_limits<double>::infinity();       ///< [s]

  bool is_static() const { return velocity.isZero() && angular_velocity.isZero(); }
  /// Position at time t of the point that was at x0 at time `start`.
  Eigen::Vector3d apply(const Eigen::Vector3d& x0, double t) const;
  template <class V>
  void visit(V& v) {
    v.field("velocity", velocity, {Unit::velocity, Range::any(), "linear velocity"});
    v.field("angular_velocity", angular_velocity, {Unit::angular_velocity, Range::any(), "angular velocity (axis * rate)"});
    v.field("center", center, {Unit::length, Range::any(), "centre of rotation at `start`"});
    v.field("start", start, {Unit::time, Range::ge(0), "start of the motion"});
    v.field("end", end, {Unit::time, Range::ge(0), "end of the motion (the body stops there)"});
  }
};

}  // namespace weft
