#pragma once
/// \file motion.hpp
/// Scripted rigid motion of pins, obstacles and rod roots: one phase, or a sequence of
/// phases (rotations about three axes alternating with rest, thesis §9.2).
#include <Eigen/Core>

#include <limits>
#include <string>
#include <vector>

#include "framework/params.hpp"

namespace weft {

/// One phase of a multi-phase motion: constant linear and angular velocity over [start, end].
struct MotionPhase {
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();          ///< [m/s] of the motion's centre
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  ///< [rad/s] about the centre where it is at `start`
  double start = 0;                                            ///< [s]
  double end = std::numeric_limits<double>::infinity();       ///< [s]; only the last phase may be open
  template <class V>
  void visit(V& v) {
    v.field("velocity", velocity, {Unit::velocity, Range::any(), "linear velocity of the centre during the phase"});
    v.field("angular_velocity", angular_velocity,
            {Unit::angular_velocity, Range::any(), "angular velocity (axis * rate, world axes) about the moving centre"});
    v.field("start", start, {Unit::time, Range::ge(0), "start of the phase (>= the previous phase's end)", true});
    v.field("end", end, {Unit::time, Range::ge(0), "end of the phase (> start; the body rests until the next phase)"});
  }
};

/// Scripted rigid motion.
///
/// Single phase (the keys `velocity`, `angular_velocity`, `center`, `start`, `end`), active
/// over [start, end]:
///   x(t) = center + v (t' - start) + R(omega (t' - start)) (x0 - center),  t' = clamp(t, start, end).
///
/// Multi-phase (`phases`, ordered and non-overlapping; `center` as above): the body rests
/// before the first phase, between phases and after the last; during phase k its rigid
/// transform is composed with
///   P_k(y) = c_k + v_k tau + R(omega_k tau) (y - c_k),  tau = t - start_k,
/// where c_k is where the body-fixed point `center` is at start_k (the centre moves with the
/// body: c_{k+1} = c_k + v_k (end_k - start_k)). So x(t) = P_k(t) o P_{k-1}(end_{k-1}) o ...
/// o P_0(end_0) (x0): continuous in t, and one phase gives the single-phase formula.
///
/// Envelope: once `set_envelope` has run (build_scene runs it), a multi-phase motion's
/// single-phase fields hold bounds for code that reads them directly over a step (obstacle
/// CCD): `start`/`end` span the phases, `velocity` and `angular_velocity` are those of the
/// fastest phases (largest norms). With no translating phase the centre stays put, and
/// these bound the motion over any step; obstacles therefore reject translating phases
/// (framework/scene.cpp) until their readers take per-step bounds.
struct Motion {
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();          ///< [m/s]
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  ///< [rad/s] about `center`
  Eigen::Vector3d center = Eigen::Vector3d::Zero();            ///< [m] rotation centre at `start` (the first phase's start)
  double start = 0;                                            ///< [s]
  double end = std::numeric_limits<double>::infinity();       ///< [s]
  std::vector<MotionPhase> phases;                             ///< multi-phase motion; empty: the fields above

  bool multi_phase() const { return !phases.empty(); }
  bool is_static() const;
  /// Position at time t of the point that was at x0 before the motion started.
  Eigen::Vector3d apply(const Eigen::Vector3d& x0, double t) const;
  /// The rigid transform at time t: apply(x0, t) = rotation * x0 + translation.
  struct Transform {
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
    Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  };
  Transform transform(double t) const;
  /// Multi-phase: fills the single-phase fields with the envelope of the phases (see above);
  /// a no-op for a single-phase motion.
  void set_envelope();
  /// A multi-phase motion about `center`, its envelope set.
  static Motion phased(const Eigen::Vector3d& center, std::vector<MotionPhase> phases);
  /// Every violation at once, keys prefixed by `path` (e.g. "obstacles.0.motion"): end >=
  /// start; with phases: start < end per phase, each phase starting at or after the previous
  /// one's end, and the single-phase keys velocity, angular_velocity, start, end left unset
  /// (or equal to the envelope).
  Checker validate(const std::string& path) const;

  template <class V>
  void visit(V& v) {
    v.field("velocity", velocity, {Unit::velocity, Range::any(), "linear velocity (single phase; not with `phases`)"});
    v.field("angular_velocity", angular_velocity,
            {Unit::angular_velocity, Range::any(), "angular velocity (axis * rate) about `center` (single phase; not with `phases`)"});
    v.field("center", center, {Unit::length, Range::any(), "centre of rotation at `start` (or at the first phase's start); moves with the body"});
    v.field("start", start, {Unit::time, Range::ge(0), "start of the motion (single phase; not with `phases`)"});
    v.field("end", end, {Unit::time, Range::ge(0), "end of the motion, the body stops there (single phase; not with `phases`)"});
    v.list("phases", phases,
           "multi-phase motion: phases in time order, not overlapping, composed (rest before, between and after them); "
           "replaces velocity, angular_velocity, start and end");
  }

 private:
  Motion envelope() const;
};

}  // namespace weft
