#include "framework/motion.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace weft {

namespace {

constexpr double inf = std::numeric_limits<double>::infinity();

std::string vec(const Eigen::Vector3d& v) { return fmt::format("[{}]", fmt::join(v.data(), v.data() + 3, ", ")); }

/// R(omega tau) of a constant angular velocity (identity when it is zero).
Eigen::Matrix3d rotation(const Eigen::Vector3d& omega, double tau) {
  const double angle = omega.norm() * tau;
  if (!(angle > 0)) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, omega.normalized()).toRotationMatrix();
}

}  // namespace

bool Motion::is_static() const {
  if (!velocity.isZero() || !angular_velocity.isZero()) return false;
  return std::all_of(phases.begin(), phases.end(), [](const MotionPhase& p) { return p.velocity.isZero() && p.angular_velocity.isZero(); });
}

Motion::Transform Motion::transform(double t) const {
  Transform T;
  if (!multi_phase()) {
    const double tau = std::clamp(t, start, std::max(start, end)) - start;
    T.rotation = rotation(angular_velocity, tau);
    T.translation = center + velocity * tau - T.rotation * center;
    return T;
  }
  Eigen::Vector3d c = center;  // where the body-fixed centre is at the current phase's start
  for (const MotionPhase& p : phases) {
    if (!(t > p.start)) break;
    const double tau = std::min(t, p.end) - p.start;
    // P(y) = c + v tau + R (y - c) composed after T: R T.rotation, c + v tau + R (T.translation - c).
    const Eigen::Matrix3d R = rotation(p.angular_velocity, tau);
    T.rotation = R * T.rotation;
    T.translation = c + p.velocity * tau + R * (T.translation - c);
    c += p.velocity * tau;
    if (t < p.end) break;
  }
  return T;
}

Eigen::Vector3d Motion::apply(const Eigen::Vector3d& x0, double t) const {
  if (multi_phase()) {
    const Transform T = transform(t);
    return T.rotation * x0 + T.translation;
  }
  // Single phase: the historical formula, kept bit for bit.
  const double tau = std::clamp(t, start, std::max(start, end)) - start;
  Eigen::Vector3d x = x0 + velocity * tau;
  const double angle = angular_velocity.norm() * tau;
  if (angle > 0) {
    const Eigen::AngleAxisd R(angle, angular_velocity.normalized());
    x = center + velocity * tau + R * (x0 - center);
  }
  return x;
}

Motion Motion::envelope() const {
  Motion e = *this;
  e.velocity.setZero();
  e.angular_velocity.setZero();
  e.start = 0;
  e.end = inf;
  if (phases.empty()) return e;
  e.start = phases.front().start;
  e.end = phases.back().end;
  for (const MotionPhase& p : phases) {
    if (p.velocity.norm() > e.velocity.norm()) e.velocity = p.velocity;
    if (p.angular_velocity.norm() > e.angular_velocity.norm()) e.angular_velocity = p.angular_velocity;
  }
  return e;
}

void Motion::set_envelope() {
  if (multi_phase()) *this = envelope();
}

Motion Motion::phased(const Eigen::Vector3d& c, std::vector<MotionPhase> p) {
  Motion m;
  m.center = c;
  m.phases = std::move(p);
  m.set_envelope();
  return m;
}

Checker Motion::validate(const std::string& path) const {
  Checker c(path);
  if (!multi_phase()) {
    c.require(end >= start, "end", end, fmt::format(">= start = {}", start));
    return c;
  }
  // The single-phase keys are not read with phases: unset, or the envelope set_envelope wrote.
  const Motion env = envelope();
  const bool unset = velocity.isZero() && angular_velocity.isZero() && start == 0 && end == inf;
  const bool enveloped = velocity == env.velocity && angular_velocity == env.angular_velocity && start == env.start && end == env.end;
  if (!unset && !enveloped) {
    if (!velocity.isZero() && velocity != env.velocity) c.require(false, "velocity", vec(velocity), "unset when `phases` is given (give each phase its velocity)");
    if (!angular_velocity.isZero() && angular_velocity != env.angular_velocity)
      c.require(false, "angular_velocity", vec(angular_velocity), "unset when `phases` is given (give each phase its angular_velocity)");
    if (start != 0 && start != env.start) c.require(false, "start", start, "unset when `phases` is given (give each phase its start)");
    if (end != inf && end != env.end) c.require(false, "end", end, "unset when `phases` is given (give each phase its end)");
  }
  for (size_t k = 0; k < phases.size(); ++k) {
    const MotionPhase& p = phases[k];
    const std::string key = fmt::format("phases.{}", k);
    c.require(p.start >= 0 && std::isfinite(p.start), key + ".start", p.start, ">= 0 and finite");
    c.require(p.end > p.start, key + ".end", p.end, fmt::format("> phases.{}.start = {}", k, p.start));
    if (k > 0)
      c.require(p.start >= phases[k - 1].end, key + ".start", p.start,
                fmt::format(">= phases.{}.end = {} (phases in time order, not overlapping)", k - 1, phases[k - 1].end));
    c.require(p.velocity.allFinite(), key + ".velocity", vec(p.velocity), "finite");
    c.require(p.angular_velocity.allFinite(), key + ".angular_velocity", vec(p.angular_velocity), "finite");
  }
  return c;
}

}  // namespace weft
