// The unconstrained rod step (integrators/rod_backward_euler.hpp) at large time steps
// a clamped hair whose root turns fast converges, and did not with the straight
// line search from the constant-velocity guess; the converged step is a minimiser of E_inc
// with a small DEL residual; one huge step reaches the static equilibrium whatever its size;
// the arc path of the line search is tangent to the Newton direction and keeps edge lengths
// under rotations; follow the leader keeps the start-of-step edge lengths.
#include <doctest/doctest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <random>

#include "framework/rod_simulator.hpp"
#include "integrators/rod_backward_euler.hpp"
#include "linear/banded_lu.hpp"
#include "models/discrete_elastic_rod.hpp"

using namespace weft;
using integrators::RodBackwardEuler;
using Body = RodBody<models::DiscreteElasticRod, linear::BandedLu>;

namespace {

/// The whip of scenes/whip.json without its wall: V vertices over 20 cm from (5 cm, 0, 0)
/// along x, r = 60 um, Y = 1e9 Pa, G = 3.4e8 Pa, rho = 1300 kg/m^3, the root edge clamped,
/// gravity along -z, at rest.
Body whip(int V = 30) {
  Eigen::VectorXd rest = Eigen::VectorXd::Zero(models::rod_dofs(V));
  for (int i = 0; i < V; ++i) rest.segment<3>(4 * i) = Eigen::Vector3d(0.05 + 0.2 * i / (V - 1), 0, 0);
  Body b(models::DiscreteElasticRod(rest, models::RodMaterial{60e-6, 1e9, 3.4e8, 1300, 0}), linear::BandedLu{});
  const Eigen::Index n = rest.size();
  b.q = rest;
  b.v = Eigen::VectorXd::Zero(n);
  b.mass = b.model.mass();
  b.fext = Eigen::VectorXd::Zero(n);
  for (int i = 0; i < V; ++i) b.fext[4 * i + 2] = -9.81 * b.mass[4 * i];
  b.fixed.assign(n, 0);
  for (int i = 0; i < 2; ++i)
    for (int c = 0; c < 3; ++c) b.fixed[4 * i + c] = 1;
  b.fixed[3] = 1;
  b.target = b.q;
  b.d = Eigen::VectorXd::Zero(n);
  b.frames = b.model.rest_frames();
  b.mean_edge = 0.2 / (V - 1);
  return b;
}

/// The root edge turned about z by angle (as the handle of scenes/whip.json turns).
void turn_root(Body& b, const Eigen::VectorXd& rest, double angle) {
  const Eigen::AngleAxisd R(angle, Eigen::Vector3d::UnitZ());
  for (int i = 0; i < 2; ++i) b.target.segment<3>(4 * i) = R * rest.segment<3>(4 * i);
}

/// One step from the constant-velocity guess, as RodSimulator::step does; commits it on success.
NewtonReport step(Body& b, const RodBackwardEuler& integ, double h) {
  b.d = h * b.v;
  const NewtonReport r = integ.solve(b, h);
  if (r.status == Status::success) {
    b.v = b.d / h;
    b.q += b.d;
    b.frames = b.model.transport(b.frames, b.q);
  }
  return r;
}

/// The integrator as it was before the large-step safeguards: straight line search from the guess d = h v.
RodBackwardEuler legacy(int max_iterations = 50) {
  return RodBackwardEuler({.max_iterations = max_iterations, .arc_step = false, .follow_the_leader = false});
}

double edge_length(const Eigen::VectorXd& q, int j) { return (q.segment<3>(4 * j + 4) - q.segment<3>(4 * j)).norm(); }

}  // namespace

TEST_SUITE("integrators") {
  TEST_CASE("rod backward Euler: a clamped rod whose root turns 2 rad in one 100 ms step converges") {
    const RodBackwardEuler integ({});
    Body b = whip();
    const Eigen::VectorXd rest = b.q;
    turn_root(b, rest, 20 * 0.1);  // 20 rad/s
    const NewtonReport r = step(b, integ, 0.1);
    CAPTURE(r.message);
    REQUIRE(r.status == Status::success);
    MESSAGE("arc + follow the leader: " << r.iterations << " Newton iterations, |f| = " << r.final_residual);
    CHECK(r.iterations <= 15);  // 11 when written
    CHECK(b.model.stretch(b.q) < 1e-4);

    // The old failure: the straight line search from d = h v creeps along the valley of
    // constant edge lengths and stops at the 50-iteration cap (|f| ~ 3e-5).
    Body old = whip();
    turn_root(old, rest, 20 * 0.1);
    const NewtonReport o = step(old, legacy(), 0.1);
    CHECK(o.status == Status::no_convergence);
    // The arc path alone already converges on this first step from rest (follow the leader
    // alone does not: it shortens the creep but the straight steps still creep).
    Body arc = whip();
    turn_root(arc, rest, 20 * 0.1);
    CHECK(step(arc, RodBackwardEuler({.follow_the_leader = false}), 0.1).status == Status::success);
  }

  TEST_CASE("rod backward Euler: the whip at 20 rad/s with 30 ms steps converges every step") {
    const RodBackwardEuler integ({});
    Body b = whip(), old = whip();
    const Eigen::VectorXd rest = b.q;
    int worst = 0, old_failure = 0;
    for (int k = 1; k <= 10; ++k) {
      CAPTURE(k);
      turn_root(b, rest, 20 * 0.03 * k);
      const NewtonReport r = step(b, integ, 0.03);
      REQUIRE_MESSAGE(r.status == Status::success, r.message);
      worst = std::max(worst, r.iterations);
      turn_root(old, rest, 20 * 0.03 * k);
      if (!old_failure && step(old, legacy(), 0.03).status != Status::success) old_failure = k;
    }
    MESSAGE("largest Newton iteration count over 10 steps: " << worst << "; the legacy solver failed at step " << old_failure);
    CHECK(worst <= 12);         // 8 when written
    CHECK(old_failure == 5);    // "fails at step 5", as the straight search did on the whip scene
  }

  TEST_CASE("rod backward Euler: the converged step is a minimiser of E_inc with a small DEL residual") {
    const RodBackwardEuler integ({});
    Body b = whip();
    const Eigen::VectorXd rest = b.q;
    const double h = 0.03;
    for (int k = 1; k <= 3; ++k) {  // a moving rod: v != 0
      turn_root(b, rest, 20 * h * k);
      REQUIRE(step(b, integ, h).status == Status::success);
    }
    turn_root(b, rest, 20 * h * 4);
    b.d = h * b.v;
    const NewtonReport r = integ.solve(b, h);
    REQUIRE(r.status == Status::success);
    for (Eigen::Index i = 0; i < b.d.size(); ++i)
      if (b.fixed[i]) REQUIRE(b.d[i] == doctest::Approx(b.target[i] - b.q[i]).epsilon(1e-15));
    // |f| against the size of its terms M d, h M v and h^2 f_ext.
    Eigen::VectorXd f;
    RodBackwardEuler::residual(b, b.d, h, f);
    const double scale = b.mass.cwiseProduct(b.d).norm() + h * b.mass.cwiseProduct(b.v).norm() + h * h * b.fext.norm();
    CAPTURE(scale);
    CHECK(f.norm() == doctest::Approx(r.final_residual).epsilon(1e-12));
    CHECK(f.norm() <= 1e-6 * scale);
    // The Newton step K^-1 f of the solution moves no vertex by more than the tolerance.
    REQUIRE(RodBackwardEuler::relinearize(b, h, HessianMode::exact) == Status::success);
    Eigen::VectorXd dir = -f;
    b.lu.solve(dir);
    for (Eigen::Index i = 0; i + 2 < dir.size(); i += 4) CHECK(dir.segment<3>(i).norm() <= 1e-9 * b.mean_edge);
    // A minimiser, not a saddle: random perturbations of the free DoFs raise E_inc (by about
    // 1/2 p^T K p, far above E_inc's round-off at a 1 um perturbation).
    const double E = RodBackwardEuler::potential(b, b.d, h);
    std::mt19937 rng(7);
    std::normal_distribution<double> N(0, 1);
    for (int t = 0; t < 20; ++t) {
      Eigen::VectorXd p(b.d.size());
      for (Eigen::Index i = 0; i < p.size(); ++i) p[i] = b.fixed[i] ? 0 : N(rng);
      p *= 1e-6 / p.norm();
      CHECK(RodBackwardEuler::potential(b, b.d + p, h) > E);
    }
  }

  TEST_CASE("rod backward Euler: one huge step reaches the static equilibrium whatever its size") {
    const RodBackwardEuler integ({});
    std::vector<double> tip;
    Body eq = whip();
    for (const double h : {10.0, 100.0, 1000.0}) {
      CAPTURE(h);
      Body b = whip();
      const NewtonReport r = step(b, integ, h);  // from straight and horizontal to hanging: about 90 degrees
      REQUIRE_MESSAGE(r.status == Status::success, r.message);
      CHECK(r.iterations <= 15);  // 9 when written (the legacy solver: about 250)
      tip.push_back(b.q[b.q.size() - 1]);
      eq = std::move(b);
    }
    MESSAGE("tip height after one step of 10, 100, 1000 s: " << tip[0] << " " << tip[1] << " " << tip[2] << " m");
    CHECK(tip[0] < -0.18);  // the 20 cm hair hangs from its clamped root 5 cm off the axis
    CHECK(std::abs(tip[1] - tip[0]) < 1e-5);
    CHECK(std::abs(tip[2] - tip[1]) < 1e-7);
    // Static equilibrium: grad V = f_ext on the free DoFs, relative to the weight.
    Eigen::VectorXd g = Eigen::VectorXd::Zero(eq.q.size());
    eq.model.add_gradient(eq.q, eq.frames, g);
    g -= eq.fext;
    for (Eigen::Index i = 0; i < g.size(); ++i)
      if (eq.fixed[i]) g[i] = 0;
    CHECK(g.norm() <= 1e-6 * eq.fext.norm());
    // ... so every step size leaves it at rest (to within 1e-8 m: the 1000 s step keeps an
    // inertia term M d / h^2 of about 2e-14 N, which the soft modes of the hanging hair,
    // about 1e-4 N/m, turn into a few nm).
    for (const double h : {1e-3, 0.1, 10.0}) {
      CAPTURE(h);
      eq.v.setZero();
      eq.d.setZero();
      REQUIRE(integ.solve(eq, h).status == Status::success);
      CHECK(eq.d.lpNorm<Eigen::Infinity>() < 1e-8);  // 2.2e-9 at h = 10 s when written
    }
    Body old = whip();
    CHECK(step(old, legacy(), 100.0).status == Status::no_convergence);
  }

  TEST_CASE("rod backward Euler: the arc path is tangent to the Newton direction and keeps lengths under rotations") {
    Body b = whip(12);
    const Eigen::Index n = b.q.size();
    std::mt19937 rng(3);
    std::normal_distribution<double> N(0, 1);
    Eigen::VectorXd d(n), dir(n), out;
    for (Eigen::Index i = 0; i < n; ++i) d[i] = b.fixed[i] ? 0 : 1e-3 * N(rng), dir[i] = b.fixed[i] ? 0 : 1e-3 * N(rng);
    // d(s) = d + s dir + O(s^2): the error of the straight line shrinks like s^2.
    double prev = 0;
    for (const double s : {1e-2, 1e-3, 1e-4}) {
      RodBackwardEuler::advance(b, d, dir, s, out);
      const double err = (out - d - s * dir).norm();
      CAPTURE(s);
      CHECK(err > 0);
      if (prev > 0) CHECK(err < 0.02 * prev);
      prev = err;
      for (Eigen::Index i = 3; i < n; i += 4) CHECK(out[i] == doctest::Approx(d[i] + s * dir[i]).epsilon(1e-14));  // twists: linear
    }
    // An infinitesimal rotation of the whole rod about the clamped root's axis z through the origin:
    // dir = omega x x (held root: 0). The arc turns every free edge and keeps its length exactly;
    // the straight line stretches the edges by about (omega l)^2 / 2.
    d.setZero();
    dir.setZero();
    const Eigen::Vector3d omega(0.3, 0.4, 0);  // about an axis through vertex 1 (held: the root edge does not move)
    for (int i = 2; i < b.num_vertices(); ++i)
      dir.segment<3>(4 * i) = omega.cross(b.q.segment<3>(4 * i) - b.q.segment<3>(4));
    RodBackwardEuler::advance(b, d, dir, 1.0, out);
    const Eigen::VectorXd arc = b.q + out, straight = b.q + dir;
    for (int j = 1; j + 1 < b.num_vertices(); ++j) {
      CAPTURE(j);
      CHECK(edge_length(arc, j) == doctest::Approx(edge_length(b.q, j)).epsilon(1e-13));
      CHECK(edge_length(straight, j) > edge_length(b.q, j) * 1.05);
    }
    for (Eigen::Index i = 0; i < n; ++i)
      if (b.fixed[i]) CHECK(out[i] == doctest::Approx(0.0).epsilon(1e-15));
  }

  TEST_CASE("rod backward Euler: follow the leader keeps the start-of-step edge lengths and the held DoFs") {
    Body b = whip(10);
    const Eigen::VectorXd rest = b.q;
    turn_root(b, rest, 1.0);
    Eigen::VectorXd d = Eigen::VectorXd::Zero(b.q.size()), out;
    for (Eigen::Index i = 0; i < d.size(); ++i)
      if (b.fixed[i]) d[i] = b.target[i] - b.q[i];
    RodBackwardEuler::follow_the_leader(b, d, out);
    const Eigen::VectorXd x = b.q + out;
    for (int j = 0; j + 1 < b.num_vertices(); ++j) CHECK(edge_length(x, j) == doctest::Approx(edge_length(b.q, j)).epsilon(1e-12));
    for (Eigen::Index i = 0; i < d.size(); ++i)
      if (b.fixed[i]) CHECK(out[i] == doctest::Approx(d[i]).epsilon(1e-15));
    CHECK((d - out).norm() > 1e-3);  // the guess d did stretch the first free edge
  }
}
