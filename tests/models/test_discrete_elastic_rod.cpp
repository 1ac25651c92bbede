#include <doctest/doctest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "framework/band_matrix.hpp"
#include "models/discrete_elastic_rod.hpp"
#include "tests/support/fd.hpp"
#include "tests/support/model_fixtures.hpp"

namespace {

using namespace weft;
using namespace weft::models;
using support::Rng;

constexpr double kPi = std::numbers::pi;

/// A material with moduli of order one (the derivative checks are scale-free; the tests use
/// edges of length ~1 so one finite-difference step suits positions and angles alike).
RodMaterial unit_material(double viscosity = 0) {
  RodMaterial m;
  m.radius = 0.3;
  m.youngs = 10.0;
  m.shear = 4.0;
  m.density = 2.0;
  m.viscosity = viscosity;
  return m;
}

int vertices_of(const Eigen::VectorXd& q) { return static_cast<int>((q.size() + 1) / 4); }
Eigen::Vector3d edge(const Eigen::VectorXd& q, int j) { return q.segment<3>(4 * (j + 1)) - q.segment<3>(4 * j); }

/// A random curved polyline: each edge turns by up to `max_turn` [rad] about a random axis,
/// lengths in [0.7, 1.3], twists uniform in [-twist, twist].
Eigen::VectorXd random_rod(int V, double max_turn, double twist, std::uint32_t seed) {
  Rng rng(seed);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(4 * V - 1);
  Eigen::Vector3d x = rng.vec3(), d = rng.vec3().normalized();
  for (int i = 0; i < V; ++i) {
    q.segment<3>(4 * i) = x;
    if (i + 1 == V) break;
    q[4 * i + 3] = rng.uniform(-twist, twist);
    Eigen::Vector3d axis = d.cross(rng.vec3()).normalized();
    d = Eigen::AngleAxisd(rng.uniform(0, max_turn), axis) * d;
    x += rng.uniform(0.7, 1.3) * d;
  }
  return q;
}

/// Positions moved by up to `dx`, twists by up to `dtheta`.
Eigen::VectorXd perturb(Eigen::VectorXd q, double dx, double dtheta, std::uint32_t seed) {
  Rng rng(seed);
  const int V = vertices_of(q);
  for (int i = 0; i < V; ++i) {
    q.segment<3>(4 * i) += dx * rng.vec3();
    if (i + 1 < V) q[4 * i + 3] += rng.uniform(-dtheta, dtheta);
  }
  return q;
}

/// A helix of radius a and pitch p (per turn), V vertices spaced by angle dphi, twists theta_j = w j.
Eigen::VectorXd helix(int V, double a, double p, double dphi, double w) {
  Eigen::VectorXd q = Eigen::VectorXd::Zero(4 * V - 1);
  for (int i = 0; i < V; ++i) {
    const double phi = dphi * i;
    q.segment<3>(4 * i) = Eigen::Vector3d(a * std::cos(phi), a * std::sin(phi), p * phi / (2 * kPi));
    if (i + 1 < V) q[4 * i + 3] = w * i;
  }
  return q;
}

/// Frames far from those of q: every tangent rotated away from q's by an angle in
/// [0.3, max_angle] about a random axis, random directors orthogonal to it, random reference
/// twists (some off the principal branch).
RodFrames far_frames(const Eigen::VectorXd& q, double max_angle, std::uint32_t seed) {
  Rng rng(seed);
  const int V = vertices_of(q);
  RodFrames f;
  for (int j = 0; j + 1 < V; ++j) {
    const Eigen::Vector3d t = edge(q, j).normalized();
    const Eigen::Vector3d axis = t.cross(rng.vec3()).normalized();
    const Eigen::Vector3d t0 = Eigen::AngleAxisd(rng.uniform(0.3, max_angle), axis) * t;
    f.tangent.push_back(t0);
    f.director.push_back(t0.cross(rng.vec3()).normalized());
  }
  for (int i = 1; i + 1 < V; ++i) f.reference_twist.push_back(rng.uniform(-kPi, kPi) + (i % 3 == 0 ? 2 * kPi : 0.0));
  return f;
}

double min_edge(const Eigen::VectorXd& q) {
  double m = std::numeric_limits<double>::infinity();
  for (int j = 0; j + 1 < vertices_of(q); ++j) m = std::min(m, edge(q, j).norm());
  return m;
}

Eigen::VectorXd gradient(const DiscreteElasticRod& rod, const Eigen::VectorXd& q, const RodFrames& from) {
  Eigen::VectorXd g = Eigen::VectorXd::Zero(q.size());
  rod.add_gradient(q, from, g);
  return g;
}

Eigen::MatrixXd hessian(const DiscreteElasticRod& rod, const Eigen::VectorXd& q, const RodFrames& from,
                        HessianMode mode = HessianMode::exact) {
  BandMatrix H(static_cast<int>(q.size()), DiscreteElasticRod::bandwidth);
  rod.add_hessian(q, from, H, mode);
  return H.dense();
}

/// A derivative check: rod, configuration, frames at the start of the step.
struct Case {
  std::string name;
  DiscreteElasticRod rod;
  Eigen::VectorXd q;
  RodFrames from;
  bool far = false;  ///< from is far from the frames of q (the holonomy term must matter)
};

/// Gradient and Hessian against fourth-order central differences (energy -> gradient,
/// gradient -> Hessian), step 1e-5 of the shortest edge. Guards against a vacuous pass:
/// nonzero derivatives, a finite-difference error far below the derivative itself, and, for
/// frames far from q's, derivatives that differ clearly from those with the frames of q
/// (which is what the textbook formulas compute): the test would catch a missing holonomy term.
void check_derivatives(const Case& c) {
  CAPTURE(c.name);
  REQUIRE(c.rod.admissible(c.q, c.from));
  const double h = 1e-5 * min_edge(c.q);
  const Eigen::VectorXd g = gradient(c.rod, c.q, c.from);
  const Eigen::VectorXd g_fd =
      support::fd_gradient([&](const Eigen::VectorXd& y) { return c.rod.energy(y, c.from); }, c.q, h);
  REQUIRE(g.norm() > 0);
  const double g_err = (g - g_fd).norm() / g.norm();
  CAPTURE(g_err);
  CHECK(g_err <= 1e-7);
  const Eigen::MatrixXd H = hessian(c.rod, c.q, c.from);
  const Eigen::MatrixXd H_fd = support::fd_jacobian([&](const Eigen::VectorXd& y) { return gradient(c.rod, y, c.from); }, c.q, h);
  REQUIRE(H.norm() > 0);
  const double H_err = (H - H_fd).norm() / H.norm();
  CAPTURE(H_err);
  CHECK(H_err <= 1e-7);
  // Banded and symmetric; the finite-difference Hessian agrees that nothing lies outside the band.
  CHECK((H - H.transpose()).norm() <= 1e-13 * H.norm());
  double outside = 0;
  for (int i = 0; i < H.rows(); ++i)
    for (int j = 0; j < H.cols(); ++j)
      if (std::abs(i - j) > DiscreteElasticRod::bandwidth) outside = std::max(outside, std::abs(H_fd(i, j)));
  CHECK(outside <= 1e-9 * H.norm());
  if (c.far) {
    const RodFrames here = c.rod.transport(c.from, c.q);
    CHECK(std::abs(c.rod.energy(c.q, here) - c.rod.energy(c.q, c.from)) <= 1e-12 * std::abs(c.rod.energy(c.q, c.from)));
    const double g_hol = (gradient(c.rod, c.q, here) - g).norm() / g.norm();
    const double H_hol = (hessian(c.rod, c.q, here) - H).norm() / H.norm();
    CAPTURE(g_hol);
    CAPTURE(H_hol);
    CHECK(g_hol >= 1e3 * std::max(g_err, 1e-10));
    CHECK(H_hol >= 1e3 * std::max(H_err, 1e-10));
  }
}

std::vector<Case> derivative_cases() {
  std::vector<Case> cases;
  const RodMaterial m = unit_material();
  // Random curved rods with random twists, frames of the rest state (far from q: large perturbation).
  for (std::uint32_t seed : {1u, 2u}) {
    const Eigen::VectorXd rest = random_rod(8, 0.8, 1.0, seed);
    DiscreteElasticRod rod(rest, m);
    const Eigen::VectorXd q = perturb(rest, 0.15, 0.8, seed + 10);
    cases.push_back({"random curved rod seed " + std::to_string(seed), rod, q, rod.rest_frames(), true});
  }
  // Frames far from q's: tangents rotated by up to 60 degrees.
  for (std::uint32_t seed : {3u, 4u}) {
    const Eigen::VectorXd rest = random_rod(7, 0.7, 0.5, seed);
    DiscreteElasticRod rod(rest, m);
    const Eigen::VectorXd q = perturb(random_rod(7, 1.0, 2.0, seed + 20), 0.0, 0.0, 0);
    cases.push_back({"from frames up to 60 degrees away seed " + std::to_string(seed), rod, q,
                     far_frames(q, kPi / 3, seed + 30), true});
  }
  {  // Near-straight: turning angles ~1e-6 (kb -> 0), straight rest with twists.
    const Eigen::VectorXd rest = random_rod(6, 0.0, 0.5, 5);
    DiscreteElasticRod rod(rest, m);
    Eigen::VectorXd q = perturb(rest, 0.0, 0.7, 6);
    q = perturb(q, 1e-6, 0.0, 7);
    cases.push_back({"near-straight rod", rod, q, far_frames(q, 0.8, 8), true});
    cases.push_back({"near-straight rod with its own frames", rod, q, rod.transport(rod.rest_frames(), q), false});
  }
  {  // Nearly folded: a 170 degree turn at vertex 2 (e_1 . e_2 = cos 170 deg).
    const Eigen::VectorXd rest = random_rod(5, 0.5, 0.3, 9);
    DiscreteElasticRod rod(rest, m);
    Eigen::VectorXd q = rest;
    const Eigen::Vector3d e1 = edge(q, 1);
    const Eigen::Vector3d axis = e1.unitOrthogonal();
    const Eigen::Vector3d e2 = Eigen::AngleAxisd(170.0 * kPi / 180.0, axis) * e1;
    q.segment<3>(12) = q.segment<3>(8) + e2;
    q.segment<3>(16) = q.segment<3>(12) + Eigen::AngleAxisd(0.4, e2.unitOrthogonal()) * e2;
    cases.push_back({"nearly folded stencil 170 degrees", rod, q, far_frames(q, 0.6, 10), true});
  }
  {  // A very short edge (1e-4 of the others).
    Eigen::VectorXd rest = random_rod(6, 0.6, 0.5, 11);
    const Eigen::Vector3d e2 = edge(rest, 2);
    const Eigen::Vector3d shift = e2 - 1e-4 * e2.normalized();
    for (int i = 3; i < 6; ++i) rest.segment<3>(4 * i) -= shift;
    DiscreteElasticRod rod(rest, m);
    Eigen::VectorXd q = perturb(rest, 0.0, 0.5, 12);
    // Move the far end of the short edge sideways by a fraction of its length (keeps it short).
    q.segment<3>(12) += 3e-5 * e2.unitOrthogonal();
    for (int i = 4; i < 6; ++i) q.segment<3>(4 * i) += Eigen::Vector3d(0.05, -0.1, 0.07) * (i - 3);
    cases.push_back({"very short edge", rod, q, far_frames(q, 0.5, 13), true});
  }
  {  // Helix rest shape: natural curvature and rest twist.
    const Eigen::VectorXd rest = helix(9, 1.0, 0.8, 0.7, 0.3);
    DiscreteElasticRod rod(rest, m);
    const Eigen::VectorXd q = perturb(rest, 0.2, 0.6, 14);
    cases.push_back({"helix rest shape", rod, q, rod.rest_frames(), true});
    cases.push_back({"helix rest shape with far frames", rod, q, far_frames(q, kPi / 3, 15), true});
  }
  {  // Viscosity on: rest = start of the step.
    const Eigen::VectorXd rest = random_rod(7, 0.6, 0.5, 16);
    DiscreteElasticRod rod(rest, unit_material(/*viscosity=*/3.0));
    const Eigen::VectorXd q_start = perturb(rest, 0.1, 0.3, 17);
    const RodFrames f_start = rod.transport(rod.rest_frames(), q_start);
    rod.set_viscous_rest(q_start, f_start, 0.1);
    REQUIRE(rod.viscous());
    const Eigen::VectorXd q = perturb(q_start, 0.15, 0.5, 18);
    cases.push_back({"viscous rod", rod, q, f_start, true});
  }
  return cases;
}

BandMatrix band(int n) { return BandMatrix(n, DiscreteElasticRod::bandwidth); }

}  // namespace

TEST_SUITE("models") {
  TEST_CASE("discrete_elastic_rod: gradient and Hessian match central differences - frames far from q included") {
    for (const Case& c : derivative_cases()) check_derivatives(c);
  }

  TEST_CASE("discrete_elastic_rod: closed-form stencil derivatives match automatic differentiation of the transport") {
    // The closed form (holonomy 1-form included) against forward-over-forward AD of the
    // transport formula itself, on random stencils with frames up to 90 degrees away,
    // near-straight and nearly folded ones included.
    Rng rng(101);
    double worst_g = 0, worst_h = 0, holonomy = 0;
    int checked = 0;
    for (int trial = 0; trial < 60; ++trial) {
      const Eigen::Vector3d e0 = rng.vec3();
      Eigen::Vector3d e1 = rng.vec3();
      if (trial % 6 == 1) e1 = 0.7 * e0 + 1e-7 * rng.vec3();                           // kb ~ 1e-7
      if (trial % 6 == 2) e1 = Eigen::AngleAxisd(3.0, e0.unitOrthogonal()) * e0;    // 172 degrees
      if (e0.dot(e1) <= -0.999 * e0.norm() * e1.norm()) continue;
      auto away = [&](const Eigen::Vector3d& e) {
        const Eigen::Vector3d t = e.normalized();
        return Eigen::Vector3d(Eigen::AngleAxisd(rng.uniform(0, kPi / 2), t.cross(rng.vec3()).normalized()) * t);
      };
      rod::StencilFrom f;
      f.ta = away(e0);
      f.tb = away(e1);
      f.da = f.ta.cross(rng.vec3()).normalized();
      f.db = f.tb.cross(rng.vec3()).normalized();
      f.reference_twist = rng.uniform(-7, 7);
      rod::StencilScalars a, b, c;
      rod::stencil_scalars(e0, e1, f, rod::Order::hessian, a);
      rod::stencil_scalars_autodiff(e0, e1, f, rod::Order::hessian, b);
      rod::stencil_scalars(e0, e1, f, rod::Order::gradient, c);
      CHECK((a.s - b.s).norm() <= 1e-14 * (1 + b.s.norm()));
      CHECK((a.G - c.G).norm() == 0.0);
      for (int k = 0; k < 5; ++k) {
        CAPTURE(trial);
        CAPTURE(k);
        REQUIRE(b.G.row(k).norm() > 0);
        REQUIRE(b.H[k].norm() > 0);
        worst_g = std::max(worst_g, (a.G.row(k) - b.G.row(k)).norm() / b.G.row(k).norm());
        worst_h = std::max(worst_h, (a.H[k] - b.H[k]).norm() / b.H[k].norm());
      }
      // The same stencil with frames at the current tangents: the holonomy terms vanish there.
      rod::StencilFrom here = f;
      here.ta = e0.normalized();
      here.tb = e1.normalized();
      rod::StencilScalars d;
      rod::stencil_scalars(e0, e1, here, rod::Order::gradient, d);
      holonomy = std::max(holonomy, (d.G.row(4) - a.G.row(4)).norm() / a.G.row(4).norm());
      ++checked;
    }
    CAPTURE(worst_g);
    CAPTURE(worst_h);
    REQUIRE(checked >= 50);
    CHECK(worst_g <= 1e-12);
    CHECK(worst_h <= 1e-12);
    CHECK(holonomy >= 0.1);  // the far frames matter
  }

  TEST_CASE("discrete_elastic_rod: finite-difference error of the gradient shrinks with the step") {
    // A second guard against a vacuous pass: with the second-order stencil the error falls
    // like h^2 until round-off, so the analytic gradient is what the differences converge to.
    const Eigen::VectorXd rest = random_rod(6, 0.7, 0.5, 21);
    const DiscreteElasticRod rod(rest, unit_material());
    const Eigen::VectorXd q = perturb(rest, 0.2, 0.5, 22);
    const RodFrames from = far_frames(q, kPi / 3, 23);
    const Eigen::VectorXd g = gradient(rod, q, from);
    auto fd2 = [&](double h) {
      Eigen::VectorXd y = q, out(q.size());
      for (Eigen::Index j = 0; j < q.size(); ++j) {
        y[j] = q[j] + h;
        const double p = rod.energy(y, from);
        y[j] = q[j] - h;
        out[j] = (p - rod.energy(y, from)) / (2 * h);
        y[j] = q[j];
      }
      return out;
    };
    const double e1 = (fd2(1e-2) - g).norm(), e2 = (fd2(5e-3) - g).norm();
    CAPTURE(e1);
    CAPTURE(e2);
    REQUIRE(e1 > 1e-8 * g.norm());  // truncation-dominated at these steps
    CHECK(e1 / e2 == doctest::Approx(4.0).epsilon(0.1));
  }

  TEST_CASE("discrete_elastic_rod: V-01 stretching is blind to transverse motion of a straight rod") {
    const double L = 0.01;
    Eigen::VectorXd rest = Eigen::VectorXd::Zero(11);
    rest.segment<3>(4) = Eigen::Vector3d(L, 0, 0);
    rest.segment<3>(8) = Eigen::Vector3d(2 * L, 0, 0);
    const RodMaterial m;  // SI defaults: hair
    const DiscreteElasticRod rod(rest, m);
    const double ks = m.youngs * kPi * m.radius * m.radius;
    BandMatrix Hs = band(11);
    rod.add_stretch_hessian(rest, Hs, HessianMode::exact);
    const Eigen::MatrixXd D = Hs.dense();
    REQUIRE(std::abs(D(0, 0)) >= 0.5 * ks / L);  // the axial block is there
    double transverse = 0;
    for (int a : {1, 2, 5, 6, 9, 10})
      for (int b : {1, 2, 5, 6, 9, 10}) transverse = std::max(transverse, std::abs(D(a, b)));
    CHECK(transverse <= 1e-12 * ks / L);
    // The finite-difference transverse stretch force at offset delta scales as delta^3.
    std::vector<double> ld, lf;
    for (double delta : {1e-3 * L, 2e-3 * L, 4e-3 * L, 8e-3 * L, 1.6e-2 * L}) {
      Eigen::VectorXd q = rest;
      q[5] = delta;
      auto E = [&](const Eigen::VectorXd& y) { return rod.stretch_energy(y); };
      const double f = -support::central_difference(E, q, 5, 1e-3 * delta);
      ld.push_back(std::log(delta));
      lf.push_back(std::log(std::abs(f)));
    }
    const double n = static_cast<double>(ld.size());
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (size_t k = 0; k < ld.size(); ++k) sx += ld[k], sy += lf[k], sxx += ld[k] * ld[k], sxy += ld[k] * lf[k];
    const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
    CAPTURE(slope);
    CHECK(std::abs(slope - 3.0) <= 0.05);
  }

  TEST_CASE("discrete_elastic_rod: the rest shape has zero energy and zero gradient") {
    for (int shape = 0; shape < 2; ++shape) {
      CAPTURE(shape);
      const Eigen::VectorXd rest = shape == 0 ? random_rod(10, 0.8, 1.0, 31) : helix(12, 1.0, 0.8, 0.6, 0.4);
      const DiscreteElasticRod rod(rest, unit_material());
      CHECK(rod.energy(rest, rod.rest_frames()) == doctest::Approx(0.0));
      CHECK(rod.energy(rest, rod.rest_frames()) <= 1e-25);
      CHECK(gradient(rod, rest, rod.rest_frames()).norm() <= 1e-12);
      // The helix has natural curvature and twist: the rest values are not trivially zero.
      if (shape == 1) {
        REQUIRE(rod.rest().kappa[3].norm() > 0.1);
        REQUIRE(std::abs(rod.rest().twist[3]) > 0.1);
      }
      for (double r : rod.rest_frames().reference_twist) CHECK(std::abs(r) <= 1e-12);
    }
  }

  TEST_CASE("discrete_elastic_rod: rigid motions with their frames leave the energy unchanged") {
    const Eigen::VectorXd rest = helix(9, 1.0, 0.8, 0.7, 0.3);
    const DiscreteElasticRod rod(rest, unit_material());
    const Eigen::VectorXd q = perturb(rest, 0.2, 0.6, 41);
    const RodFrames from = far_frames(q, 0.8, 42);
    const double E = rod.energy(q, from);
    REQUIRE(E > 1e-3);
    Rng rng(43);
    const Eigen::Matrix3d R = rng.rotation();
    const Eigen::Vector3d c = rng.vec3(-5, 5);
    Eigen::VectorXd qm = q;
    RodFrames fm = from;
    for (int i = 0; i < rod.num_vertices(); ++i) qm.segment<3>(4 * i) = R * q.segment<3>(4 * i) + c;
    for (size_t j = 0; j < fm.tangent.size(); ++j) {
      fm.tangent[j] = R * from.tangent[j];
      fm.director[j] = R * from.director[j];
    }
    CHECK(rod.energy(qm, fm) == doctest::Approx(E).epsilon(1e-12));
    // Translation alone: the frames do not change, and the forces on the vertices sum to zero.
    Eigen::VectorXd qt = q;
    for (int i = 0; i < rod.num_vertices(); ++i) qt.segment<3>(4 * i) += c;
    CHECK(rod.energy(qt, from) == doctest::Approx(E).epsilon(1e-12));
    const Eigen::VectorXd g = gradient(rod, q, from);
    Eigen::Vector3d force = Eigen::Vector3d::Zero();
    for (int i = 0; i < rod.num_vertices(); ++i) force += g.segment<3>(4 * i);
    CHECK(force.norm() <= 1e-12 * g.norm());
    // The rotated configuration's frames are the rotated frames (transport commutes with R).
    const RodFrames a = rod.transport(fm, qm), b = rod.transport(from, q);
    for (size_t j = 0; j < a.director.size(); ++j) CHECK((a.director[j] - R * b.director[j]).norm() <= 1e-12);
  }

  TEST_CASE("discrete_elastic_rod: a uniform twist leaves the energy of a naturally straight rod unchanged") {
    const Eigen::VectorXd rest = random_rod(8, 0.0, 0.0, 51);  // straight, untwisted
    const DiscreteElasticRod rod(rest, unit_material());
    // theta_j = c everywhere on the rest shape: zero energy.
    Eigen::VectorXd twisted = rest;
    for (int j = 0; j + 1 < rod.num_vertices(); ++j) twisted[4 * j + 3] = 0.7;
    CHECK(rod.energy(twisted, rod.rest_frames()) <= 1e-25);
    // A bent and twisted configuration, then all theta_j += c: unchanged.
    const Eigen::VectorXd q = perturb(rest, 0.2, 0.8, 52);
    const RodFrames from = far_frames(q, 0.8, 53);
    Eigen::VectorXd qc = q;
    for (int j = 0; j + 1 < rod.num_vertices(); ++j) qc[4 * j + 3] += 1.3;
    const double E = rod.energy(q, from);
    REQUIRE(E > 1e-3);
    CHECK(rod.energy(qc, from) == doctest::Approx(E).epsilon(1e-12));
  }

  TEST_CASE("discrete_elastic_rod: the projected Hessian is PSD and equals the exact one where every stencil is convex") {
    for (int shape = 0; shape < 2; ++shape) {
      CAPTURE(shape);
      const Eigen::VectorXd rest = shape == 0 ? random_rod(10, 0.8, 1.0, 61) : helix(10, 1.0, 0.8, 0.7, 0.3);
      const DiscreteElasticRod rod(rest, unit_material());
      // Far from rest: the exact Hessian is indefinite, the projected one PSD.
      const Eigen::VectorXd q = perturb(rest, 0.3, 1.0, 62);
      const RodFrames from = far_frames(q, 0.8, 63);
      const Eigen::MatrixXd He = hessian(rod, q, from, HessianMode::exact);
      const Eigen::MatrixXd Hp = hessian(rod, q, from, HessianMode::projected);
      const Eigen::VectorXd le = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(He).eigenvalues();
      const Eigen::VectorXd lp = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Hp).eigenvalues();
      CHECK(le.minCoeff() < -1e-3 * le.cwiseAbs().maxCoeff());  // the projection has work to do
      CHECK(lp.minCoeff() >= -1e-10 * lp.cwiseAbs().maxCoeff());
      CHECK((Hp - Hp.transpose()).norm() <= 1e-13 * Hp.norm());
      // At the rest shape every stencil energy (>= 0, = 0 there) has a PSD Hessian: no change.
      const Eigen::MatrixXd Re = hessian(rod, rest, rod.rest_frames(), HessianMode::exact);
      const Eigen::MatrixXd Rp = hessian(rod, rest, rod.rest_frames(), HessianMode::projected);
      CHECK((Re - Rp).norm() <= 1e-10 * Re.norm());
    }
  }

  TEST_CASE("discrete_elastic_rod: transport to the configuration of the frames returns the frames") {
    const Eigen::VectorXd rest = random_rod(9, 0.8, 1.0, 71);
    const DiscreteElasticRod rod(rest, unit_material());
    const Eigen::VectorXd q = perturb(rest, 0.3, 0.5, 72);
    RodFrames f = rod.transport(rod.rest_frames(), q);
    f.reference_twist[2] += 4 * kPi;  // an unwrapped history: the branch is kept
    const RodFrames g = rod.transport(f, q);
    for (size_t j = 0; j < f.tangent.size(); ++j) {
      CHECK((g.tangent[j] - f.tangent[j]).norm() <= 1e-14);
      CHECK((g.director[j] - f.director[j]).norm() <= 1e-14);
      CHECK(std::abs(f.director[j].dot(f.tangent[j])) <= 1e-14);
    }
    for (size_t i = 0; i < f.reference_twist.size(); ++i) CHECK(std::abs(g.reference_twist[i] - f.reference_twist[i]) <= 1e-13);
    // Frames from rest_frames are those of the rest shape.
    const RodFrames r = rod.transport(rod.rest_frames(), rest);
    for (size_t j = 0; j < r.director.size(); ++j) CHECK((r.director[j] - rod.rest_frames().director[j]).norm() <= 1e-14);
  }

  TEST_CASE("discrete_elastic_rod: the reference twist follows a rotation of the end edge about its tangent") {
    // Twisting the last edge's director by transport along a closed loop of tangents
    // accumulates holonomy; the unwrapped reference twist changes continuously past pi.
    const Eigen::VectorXd rest = random_rod(3, 0.0, 0.0, 81);
    const DiscreteElasticRod rod(rest, unit_material());
    RodFrames f = rod.rest_frames();
    Eigen::VectorXd q = rest;
    const Eigen::Vector3d t1 = edge(rest, 1).normalized(), axis = t1.unitOrthogonal();
    double start = 0, prev = 0;
    const int per_loop = 100, loops = 4;
    for (int s = 0; s <= loops * per_loop; ++s) {
      // The last edge sweeps a cone of half-angle 1 rad around its rest direction.
      const double phi = 2 * kPi * s / per_loop;
      const Eigen::Vector3d e = Eigen::AngleAxisd(phi, t1) * (Eigen::AngleAxisd(1.0, axis) * edge(rest, 1));
      q.segment<3>(8) = q.segment<3>(4) + e;
      f = rod.transport(f, q);
      if (s == 0) start = prev = f.reference_twist[0];
      CHECK(std::abs(f.reference_twist[0] - prev) < 0.5);
      prev = f.reference_twist[0];
    }
    // Each loop adds the enclosed solid angle 2 pi (1 - cos 1) (up to the sign and the
    // inscribed polygon's slightly smaller area): the unwrapped twist goes well past pi.
    const double expected = loops * 2 * kPi * (1 - std::cos(1.0));
    CAPTURE(prev - start);
    CHECK(std::abs(std::abs(prev - start) - expected) <= 0.01 * expected);
  }

  TEST_CASE("discrete_elastic_rod: mass sums to rho pi r^2 times the rest length") {
    const Eigen::VectorXd rest = helix(30, 0.01, 0.005, 0.3, 0.0);
    const RodMaterial m;
    const DiscreteElasticRod rod(rest, m);
    const Eigen::VectorXd M = rod.mass();
    REQUIRE(M.size() == rod_dofs(30));
    double length = 0, xsum = 0, tsum = 0;
    for (int j = 0; j + 1 < 30; ++j) {
      length += edge(rest, j).norm();
      tsum += M[4 * j + 3];
    }
    for (int i = 0; i < 30; ++i) xsum += M.segment<3>(4 * i).sum() / 3.0;
    const double r2 = m.radius * m.radius;
    CHECK(xsum == doctest::Approx(m.density * kPi * r2 * length).epsilon(1e-13));
    CHECK(tsum == doctest::Approx(0.5 * m.density * kPi * r2 * r2 * length).epsilon(1e-13));
    CHECK(M.minCoeff() > 0);
  }

  TEST_CASE("discrete_elastic_rod: admissibility and stretch") {
    const Eigen::VectorXd rest = random_rod(5, 0.5, 0.3, 91);
    const DiscreteElasticRod rod(rest, unit_material());
    const RodFrames& f = rod.rest_frames();
    CHECK(rod.admissible(rest, f));
    CHECK(rod.stretch(rest) == doctest::Approx(0.0));
    Eigen::VectorXd q = rest;
    q.segment<3>(8) = q.segment<3>(4);  // zero-length edge 1
    CHECK_FALSE(rod.admissible(q, f));
    CHECK(std::isinf(rod.energy(q, f)));
    q = rest;  // edge 1 reversed: opposite to its from tangent, and folded onto edge 0
    q.segment<3>(8) = q.segment<3>(4) - edge(rest, 1);
    CHECK_FALSE(rod.admissible(q, f));
    // An exact fold with frames that allow the transport.
    Eigen::VectorXd fold = Eigen::VectorXd::Zero(rod_dofs(5));
    for (int i = 0; i < 5; ++i) fold.segment<3>(4 * i) = Eigen::Vector3d(i == 2 ? 1.0 : (i < 2 ? i : 4 - i), 0, 0);
    RodFrames side = f;
    for (int j = 0; j < 4; ++j) {
      side.tangent[j] = Eigen::Vector3d(0, 1, 0);
      side.director[j] = Eigen::Vector3d(0, 0, 1);
    }
    CHECK_FALSE(rod.admissible(fold, side));
    Eigen::VectorXd stretched = rest;
    for (int i = 0; i < 5; ++i) stretched.segment<3>(4 * i) *= 1.25;
    CHECK(rod.stretch(stretched) == doctest::Approx(0.25));
    CHECK_THROWS_AS(DiscreteElasticRod(Eigen::VectorXd::Zero(7), unit_material()), ConfigError);
    RodMaterial bad = unit_material();
    bad.radius = -1;
    CHECK_THROWS_WITH(DiscreteElasticRod(rest, bad), doctest::Contains("radius"));
  }

  TEST_CASE("discrete_elastic_rod: energy terms name stretch bend twist and viscous") {
    const Eigen::VectorXd rest = random_rod(6, 0.5, 0.3, 95);
    DiscreteElasticRod rod(rest, unit_material(1.0));
    const Eigen::VectorXd q = perturb(rest, 0.1, 0.3, 96);
    EnergyTerms terms;
    rod.energy_terms(q, rod.rest_frames(), terms);
    REQUIRE(terms.size() == 3);  // viscosity set but no viscous rest yet: off
    rod.set_viscous_rest(rest, rod.rest_frames(), 0.01);
    terms.clear();
    rod.energy_terms(q, rod.rest_frames(), terms);
    REQUIRE(terms.size() == 4);
    CHECK(terms[0].first == "stretch");
    CHECK(terms[1].first == "bend");
    CHECK(terms[2].first == "twist");
    CHECK(terms[3].first == "viscous");
    double sum = 0;
    for (const auto& t : terms) {
      CHECK(t.second > 0);
      sum += t.second;
    }
    CHECK(sum == doctest::Approx(rod.energy(q, rod.rest_frames())).epsilon(1e-13));
    CHECK(rod.stretch_energy(q) == doctest::Approx(terms[0].second).epsilon(1e-14));
  }
}
