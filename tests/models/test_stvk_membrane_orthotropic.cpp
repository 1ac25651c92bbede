// StvkMembrane<Orthotropic> (methods/shells §3.2, §4.3-4.4; checklist §9 items 1-3, 7, 17-20, 22, 23).
#include <doctest/doctest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <cmath>
#include <string>
#include <vector>

#include "models/stvk_membrane.hpp"
#include "tests/support/fd.hpp"
#include "tests/support/model_fixtures.hpp"
#include "tests/support/uniaxial.hpp"

namespace {

using namespace weft;
using namespace weft::models;
using Ortho = StvkMembrane<Orthotropic>;
using Iso = StvkMembrane<Isotropic>;
using support::MeshData;

/// A strongly orthotropic material for derivative checks: Y_warp 1, Y_weft 3 (eta = 3),
/// G12 = 0.1, nu = 0.4 (eta nu^2 = 0.48).
ShellMaterial fd_material() { return support::orthotropic_material(1.0, 3.0, 0.1, 0.4); }

struct Config {
  std::string name;
  MeshData mesh;
  Eigen::VectorXd x;
  bool well_shaped;  // rest and deformed elements well shaped (Taylor test scales apply)
};

std::vector<Config> derivative_configs() {
  std::vector<Config> c;
  for (std::uint32_t seed : {1u, 2u, 3u}) {
    MeshData m = support::random_patch(seed, /*curved=*/true);
    c.push_back({"random curved patch seed " + std::to_string(seed), m, support::perturb(support::stack(m.V), 0.2, 200 + seed), true});
  }
  {
    MeshData m = support::triangle({0, 0, 0}, {1, 0, 0}, {0.4, 0.9, 0});
    Eigen::VectorXd x(9);
    x << 0, 0, 0, 1.05, 0.02, 0, 0.5, 1e-3, 0;
    c.push_back({"near-degenerate deformed triangle", m, support::rigid_motion(x, support::Rng(5).rotation(), {0.1, 0.2, 0.3}), false});
  }
  {
    MeshData m = support::triangle({0, 0, 0}, {1, 0, 0}, {0.5, 1e-3, 0});
    Eigen::VectorXd x(9);
    x << 0, 0, 0, 1.0, 0, 0, 0.5, 1.3e-3, 2e-4;
    c.push_back({"near-degenerate rest triangle", m, x, false});
  }
  {
    MeshData m = support::triangle({0, 0, 0}, {1, 0, 0}, {0.4, 0.9, 0});
    Eigen::VectorXd x(9);
    x << 0, 0, 0, 1.1, 0, 0.05, 0.5, -0.4, 0.1;
    c.push_back({"inverted triangle", m, x, true});
  }
  {
    MeshData m = support::random_patch(4, /*curved=*/false);
    Eigen::VectorXd x = support::perturb(support::stack(m.V), 0.05, 204);
    x.segment<3>(3 * 5) += Eigen::Vector3d(1.3, 1.1, 0.2);
    c.push_back({"patch with inverted elements", m, x, true});
  }
  return c;
}

/// Each face's warp rotated by 90 degrees in its plane (warp and weft swapped).
std::vector<Eigen::Vector3d> rotated_warps(const MeshData& m, const std::vector<Eigen::Vector3d>& w) {
  std::vector<Eigen::Vector3d> r(w.size());
  for (size_t f = 0; f < w.size(); ++f) {
    const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
    r[f] = (b - a).cross(c - a).normalized().cross(w[f]);
  }
  return r;
}

/// Orthonormal rest frame (t1, t2) of a triangle and the 2D coordinates of a 3D direction.
struct Frame {
  Eigen::Vector3d t1, t2, n;
  explicit Frame(const Eigen::Matrix3d& rest) {
    const Eigen::Vector3d r1 = rest.row(1) - rest.row(0), r2 = rest.row(2) - rest.row(0);
    n = r1.cross(r2).normalized();
    t1 = r1.normalized();
    t2 = n.cross(t1);
  }
  Eigen::Vector2d coords(const Eigen::Vector3d& v) const { return {t1.dot(v), t2.dot(v)}; }
};

/// Green strain of a CST via its deformation gradient (methods/shells §4.1), in the rest frame.
Eigen::Matrix2d green_strain(const Eigen::Matrix3d& rest, const Eigen::Matrix3d& x) {
  const Frame fr(rest);
  const Eigen::Vector3d r1 = rest.row(1) - rest.row(0), r2 = rest.row(2) - rest.row(0);
  Eigen::Matrix2d Dm;
  Dm << fr.t1.dot(r1), fr.t1.dot(r2), fr.t2.dot(r1), fr.t2.dot(r2);
  Eigen::Matrix<double, 3, 2> Ds;
  Ds.col(0) = x.row(1) - x.row(0);
  Ds.col(1) = x.row(2) - x.row(0);
  const Eigen::Matrix<double, 3, 2> F = Ds * Dm.inverse();
  return 0.5 * (F.transpose() * F - Eigen::Matrix2d::Identity());
}

/// Başar's density (methods/shells §3.3, Eq. 4.5) straight from the engineering constants, in the
/// material frame (warp, weft): L_warp, L_weft normal strains, L3 = E_{warp,weft}^2;
///   psi = 1/2 a_weft L_weft^2 + 1/2 a_warp L_warp^2 + a12 L_warp L_weft + G L3,
///   a_weft = eta Y / q, a_warp = Y / q, a12 = eta nu Y / q, q = 1 - eta nu^2, G = 2 G12.
/// An independent reference for the (lambda, mu, a, b) form and for the warp/weft convention.
double basar_psi(const Eigen::Matrix2d& E, const Eigen::Vector2d& warp, double y_warp, double y_weft, double g12, double nu) {
  const Eigen::Vector2d w = warp.normalized(), f(-w[1], w[0]);
  const double Lwarp = w.dot(E * w), Lweft = f.dot(E * f), Lshear = w.dot(E * f);
  const double Y = y_warp, eta = y_weft / y_warp, q = 1 - eta * nu * nu;
  return 0.5 * eta * Y / q * Lweft * Lweft + 0.5 * Y / q * Lwarp * Lwarp + eta * nu * Y / q * Lwarp * Lweft + 2 * g12 * Lshear * Lshear;
}

/// The (lambda, mu, a, b) density with ahat = the weft (methods/shells §3.2).
double lame_psi(const Eigen::Matrix2d& E, const Eigen::Vector2d& weft, const membrane::LameConstants& c) {
  const Eigen::Vector2d a = weft.normalized();
  const double J1 = E.trace(), J2 = (E * E).trace(), J3 = a.dot(E * a);
  return 0.5 * c.lambda * J1 * J1 + c.mu * J2 + c.a * J1 * J3 + c.b * J3 * J3;
}

double min_eigenvalue(const Eigen::MatrixXd& H) { return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(H).eigenvalues().minCoeff(); }

/// Deformed corners that realise the Green strain E (2x2, in the (warp, weft) frame) exactly:
/// x_i = x0 + R [w f] U xi_i with U = sqrt(I + 2E), xi the rest coordinates in that frame.
Eigen::Matrix3d corners_with_strain(const Eigen::Matrix3d& rest, const Eigen::Vector3d& warp, const Eigen::Matrix2d& E,
                                    const Eigen::Matrix3d& R) {
  const Eigen::Vector3d n = Eigen::Vector3d(rest.row(1) - rest.row(0)).cross(Eigen::Vector3d(rest.row(2) - rest.row(0))).normalized();
  const Eigen::Vector3d w = warp.normalized(), f = n.cross(w);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(Eigen::Matrix2d::Identity() + 2 * E);
  REQUIRE(es.eigenvalues().minCoeff() > 0);
  const Eigen::Matrix2d U = es.eigenvectors() * es.eigenvalues().cwiseSqrt().asDiagonal() * es.eigenvectors().transpose();
  Eigen::Matrix3d x;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d d = rest.row(i) - rest.row(0);
    const Eigen::Vector2d xi = U * Eigen::Vector2d(w.dot(d), f.dot(d));
    x.row(i) = (Eigen::Vector3d(rest.row(0)) + R * (xi[0] * w + xi[1] * f)).transpose();
  }
  return x;
}

}  // namespace

TEST_SUITE("models") {
  TEST_CASE("stvk_membrane orthotropic: gradient matches central differences with random warp directions") {
    std::uint32_t seed = 300;
    for (const auto& c : derivative_configs()) {
      CAPTURE(c.name);
      const auto warps = support::random_warps(c.mesh, ++seed);
      auto p = support::make_patch<Ortho>(c.mesh, c.x, {}, fd_material(), warps);
      const Eigen::VectorXd g = support::gradient(p.model, p.state);
      const Eigen::VectorXd g_fd = support::fd_gradient(p.model, p.state, support::fd_step(p.scene.mesh));
      REQUIRE(g.norm() > 0);  // a zero gradient matches anything
      // ... and the orthotropic terms matter: swapping warp and weft changes the gradient.
      auto q = support::make_patch<Ortho>(c.mesh, c.x, {}, fd_material(), rotated_warps(c.mesh, warps));
      REQUIRE(support::relative_error(g, support::gradient(q.model, q.state)) > 1e-2);
      CHECK(support::relative_error(g, g_fd) <= 1e-6);
    }
  }

  TEST_CASE("stvk_membrane orthotropic: Hessian matches central differences of the gradient") {
    std::uint32_t seed = 400;
    for (const auto& c : derivative_configs()) {
      CAPTURE(c.name);
      auto p = support::make_patch<Ortho>(c.mesh, c.x, {}, fd_material(), support::random_warps(c.mesh, ++seed));
      const Eigen::MatrixXd H = support::dense_hessian(p.model, p.state, HessianMode::exact);
      const Eigen::MatrixXd H_fd = support::fd_hessian(p.model, p.state, support::fd_step(p.scene.mesh));
      REQUIRE(H.norm() > 0);
      CHECK(support::relative_error(H, H_fd) <= 1e-6);
    }
  }

  TEST_CASE_TEMPLATE("stvk_membrane: Taylor remainders shrink 4x and 8x per halving (methods/shells §9 item 3)", Model, Iso, Ortho) {
    std::uint32_t seed = 500;
    for (const auto& c : derivative_configs()) {
      if (!c.well_shaped) continue;
      CAPTURE(c.name);
      const ShellMaterial mat = std::is_same_v<Model, Ortho> ? fd_material() : support::unit_material();
      auto p = support::make_patch<Model>(c.mesh, c.x, {}, mat, support::random_warps(c.mesh, ++seed));
      support::Rng rng(seed);
      Eigen::VectorXd d(p.state.x.size());
      for (Eigen::Index i = 0; i < d.size(); ++i) d[i] = rng.uniform(-1, 1);
      d.normalize();
      const double W0 = p.model.energy(p.state);
      const double gd = support::gradient(p.model, p.state).dot(d);
      const double dHd = d.dot(support::dense_hessian(p.model, p.state, HessianMode::exact) * d);
      REQUIRE(std::abs(gd) > 0);
      REQUIRE(std::abs(dHd) > 0);
      State t = p.state;
      std::vector<double> r1, r2;
      double eps = 1e-2 * support::mean_edge_length(p.scene.mesh);
      for (int k = 0; k < 5; ++k, eps /= 2) {  // 4 halvings
        t.x = p.state.x + eps * d;
        const double rem1 = p.model.energy(t) - W0 - eps * gd;
        r1.push_back(std::abs(rem1));
        r2.push_back(std::abs(rem1 - 0.5 * eps * eps * dHd));
      }
      // Above the round-off floor (~1e-16 W per evaluation) by a wide margin (4 decades).
      REQUIRE(r2.back() > 1e4 * 1e-16 * std::max(1.0, std::abs(W0)));
      for (size_t k = 0; k + 1 < r1.size(); ++k) {
        CAPTURE(k);
        CHECK(r1[k] / r1[k + 1] == doctest::Approx(4.0).epsilon(0.1));
        CHECK(r2[k] / r2[k + 1] == doctest::Approx(8.0).epsilon(0.1));
      }
    }
  }

  TEST_CASE("stvk_membrane orthotropic: golden values of methods/shells §9 item 7 through the full model") {
    // ahat = (0, 1, 0) is the weft in the project convention, so the warp is (1, 0, 0):
    // Y = Y_warp = 1, eta = 0.5 -> Y_weft = 0.5, nu = 0.3, G = 0.4 -> G12 = 0.2, h = 1.
    const ShellMaterial mat = support::orthotropic_material(1.0, 0.5, 0.2, 0.3);
    const membrane::LameConstants c = membrane::material_lame(mat);
    CHECK(c.lambda == doctest::Approx(0.647120418848).epsilon(1e-11));
    CHECK(c.mu == doctest::Approx(0.2).epsilon(1e-15));
    CHECK(c.a == doctest::Approx(-0.490052356021).epsilon(1e-11));
    CHECK(c.b == doctest::Approx(0.228272251309).epsilon(1e-11));
    const MeshData m = support::triangle({0, 0, 0}, {1, 0, 0}, {0, 1, 0});
    for (double sign : {1.0, -1.0}) {
      CAPTURE(sign);
      auto p = support::make_patch<Ortho>(m, Eigen::VectorXd::Zero(9), {}, mat, {Eigen::Vector3d(sign, 0, 0)});
      p.state.x << 0, 0, 0, 1.1, 0, 0, 0.2, 0.9, 0.3;
      const double W = p.model.energy(p.state);
      CHECK(std::abs(W - 0.00517654450261780) <= 1e-13 * 0.00517654450261780);
      const Eigen::VectorXd f = -support::gradient(p.model, p.state);
      CHECK(std::abs(f[0] - 0.086558115183) <= 1e-11);
      CHECK(std::abs(f[1] - 0.020153403141) <= 1e-11);
      CHECK(std::abs(f[2] - 0.006717801047) <= 1e-11);
    }
  }

  TEST_CASE("stvk_membrane orthotropic: edge-based energy equals the F-based Basar reference (methods/shells §9 items 7 and 19)") {
    for (std::uint32_t seed = 1; seed <= 8; ++seed) {
      CAPTURE(seed);
      support::Rng rng(600 + seed);
      const Eigen::Vector3d a = rng.vec3(), b = a + rng.rotation() * Eigen::Vector3d(1, 0, 0),
                            c = a + rng.rotation() * Eigen::Vector3d(0.3, 0.9, 0.2);
      const double yw = rng.uniform(0.5, 2), yf = rng.uniform(0.2, 3), g12 = rng.uniform(0.05, 1);
      const double eta = yf / yw, nu = rng.uniform(-0.95, 0.95) / std::sqrt(eta);  // eta nu^2 < 0.9
      const ShellMaterial mat = support::orthotropic_material(yw, yf, g12, nu, rng.uniform(0.1, 1));
      CAPTURE(eta);
      CAPTURE(nu);
      const MeshData m = support::triangle(a, b, c);
      const auto warps = support::random_warps(m, 700 + seed);
      auto p = support::make_patch<Ortho>(m, support::perturb(support::stack(m.V), 0.3, 800 + seed), {}, mat, warps);
      Eigen::Matrix3d x;
      for (int k = 0; k < 3; ++k) x.row(k) = p.state.x.segment<3>(3 * k).transpose();
      const Frame fr(m.V);
      const Eigen::Matrix2d E = green_strain(m.V, x);
      const double area = 0.5 * (b - a).cross(c - a).norm();
      const double ref = area * mat.thickness * basar_psi(E, fr.coords(warps[0]), yw, yf, g12, nu);
      REQUIRE(ref > 0);
      CHECK(std::abs(p.model.energy(p.state) - ref) <= 1e-13 * ref);
      // Item 19 on the density: Basar's form equals the (lambda, mu, a, b) form with ahat = the weft.
      const Eigen::Vector2d w2 = fr.coords(warps[0]);
      const double psi_lame = lame_psi(E, Eigen::Vector2d(-w2[1], w2[0]), membrane::material_lame(mat));
      const double psi_basar = basar_psi(E, w2, yw, yf, g12, nu);
      CHECK(std::abs(psi_lame - psi_basar) <= 1e-13 * std::abs(psi_basar));
    }
  }

  TEST_CASE("stvk_membrane orthotropic: Basar form equals the (lambda mu a b) form for random strains (methods/shells §9 item 19)") {
    support::Rng rng(900);
    for (int k = 0; k < 50; ++k) {
      const double yw = rng.uniform(0.1, 10), yf = rng.uniform(0.1, 10), g12 = rng.uniform(0.01, 5);
      const double nu = rng.uniform(-0.99, 0.99) * std::sqrt(yw / yf);
      Eigen::Matrix2d E;
      E(0, 0) = rng.uniform(-1, 1), E(1, 1) = rng.uniform(-1, 1), E(0, 1) = E(1, 0) = rng.uniform(-1, 1);
      const double phi = rng.uniform(0, 6.3);
      const Eigen::Vector2d warp(std::cos(phi), std::sin(phi)), weft(-warp[1], warp[0]);
      const ShellMaterial mat = support::orthotropic_material(yw, yf, g12, nu);
      const double ref = basar_psi(E, warp, yw, yf, g12, nu);
      CAPTURE(k);
      CHECK(std::abs(lame_psi(E, weft, membrane::material_lame(mat)) - ref) <= 1e-12 * (std::abs(ref) + 1e-3 * E.squaredNorm() * yw));
      // The sign of ahat does not matter.
      CHECK(std::abs(lame_psi(E, -weft, membrane::material_lame(mat)) - ref) <= 1e-12 * (std::abs(ref) + 1e-3 * E.squaredNorm() * yw));
    }
  }

  TEST_CASE("stvk_membrane orthotropic: eta = 1 and G = Y/(1+nu) reduce to the isotropic T for any direction (methods/shells §9 item 17)") {
    for (std::uint32_t seed = 1; seed <= 5; ++seed) {
      CAPTURE(seed);
      support::Rng rng(1000 + seed);
      const double Y = rng.uniform(0.5, 3), nu = rng.uniform(-0.9, 0.9), h = rng.uniform(0.1, 1);
      ShellMaterial iso = support::unit_material();
      iso.youngs_modulus = Y, iso.poisson_ratio = nu, iso.thickness = h;
      const ShellMaterial ortho = support::orthotropic_material(Y, Y, Y / (2 * (1 + nu)), nu, h);  // G = 2 G12 = Y / (1 + nu)
      const membrane::LameConstants c = membrane::material_lame(ortho), ci = membrane::isotropic_lame(Y, nu);
      CHECK(std::abs(c.a) <= 1e-14 * Y);
      CHECK(std::abs(c.b) <= 1e-14 * Y);
      CHECK(std::abs(c.lambda - ci.lambda) <= 1e-14 * Y);
      CHECK(std::abs(c.mu - ci.mu) <= 1e-14 * Y);
      const MeshData m = support::random_patch(seed, /*curved=*/true);
      const Eigen::VectorXd x = support::stack(m.V);
      const auto warps = support::random_warps(m, 1100 + seed);
      std::vector<Eigen::Vector3d> flipped(warps.size());
      for (size_t f = 0; f < warps.size(); ++f) flipped[f] = -warps[f];
      auto pi = support::make_patch<Iso>(m, x, {}, iso);
      auto po = support::make_patch<Ortho>(m, x, {}, ortho, warps);
      auto pf = support::make_patch<Ortho>(m, x, {}, ortho, flipped);
      auto pr = support::make_patch<Ortho>(m, x, {}, ortho, rotated_warps(m, warps));  // ahat and ahat_perp swapped
      auto pio = support::make_patch<Ortho>(m, x, {}, iso);  // an isotropic material in the orthotropic model
      for (int f = 0; f < pi.model.num_elements(); ++f) {
        CAPTURE(f);
        const Eigen::Matrix3d& Ti = pi.model.element(f).T;
        REQUIRE(Ti.norm() > 0);
        CHECK((po.model.element(f).T - Ti).norm() <= 1e-14 * Ti.norm());
        CHECK((pf.model.element(f).T - Ti).norm() <= 1e-14 * Ti.norm());
        CHECK((pr.model.element(f).T - Ti).norm() <= 1e-14 * Ti.norm());
        CHECK((pio.model.element(f).T - Ti).norm() == 0.0);
      }
    }
  }

  TEST_CASE("stvk_membrane orthotropic: the sign of ahat does not change T") {
    const MeshData m = support::random_patch(11, /*curved=*/true);
    const auto warps = support::random_warps(m, 12);
    std::vector<Eigen::Vector3d> flipped(warps.size());
    for (size_t f = 0; f < warps.size(); ++f) flipped[f] = -warps[f];
    const Eigen::VectorXd x = support::stack(m.V);
    auto p = support::make_patch<Ortho>(m, x, {}, fd_material(), warps);
    auto q = support::make_patch<Ortho>(m, x, {}, fd_material(), flipped);
    auto r = support::make_patch<Ortho>(m, x, {}, fd_material(), rotated_warps(m, warps));
    for (int f = 0; f < p.model.num_elements(); ++f) {
      CAPTURE(f);
      const Eigen::Matrix3d& T = p.model.element(f).T;
      CHECK((q.model.element(f).T - T).norm() <= 1e-14 * T.norm());
      CHECK((r.model.element(f).T - T).norm() > 1e-2 * T.norm());  // but warp and weft are not interchangeable
    }
    // stvk_T with ahat and with -ahat.
    Eigen::Matrix3d rest;
    rest << 0.1, 0.2, 0.3, 1.2, 0.1, -0.2, 0.3, 0.9, 0.4;
    const Eigen::Vector3d n = Eigen::Vector3d(rest.row(1) - rest.row(0)).cross(Eigen::Vector3d(rest.row(2) - rest.row(0))).normalized();
    const Eigen::Vector3d ahat = n.cross(Eigen::Vector3d(0.3, -0.5, 0.8)).normalized();
    const membrane::LameConstants c = membrane::material_lame(fd_material());
    const Eigen::Matrix3d T = membrane::stvk_T(rest, 1.0, c, ahat);
    CHECK((membrane::stvk_T(rest, 1.0, c, -ahat) - T).norm() <= 1e-14 * T.norm());
  }

  TEST_CASE("stvk_membrane orthotropic: engineering constants recovered along and across ahat and off axis (methods/shells §9 item 18)") {
    // Probe psi(E) = W / (Abar h) through the full model with deformations that realise a
    // given Green strain exactly (in the warp/weft frame), so the stiffness is exact (StVK is
    // quadratic in E; no small-strain truncation), then invert it.
    const double yw = 2.0, yf = 0.7, g12 = 0.3, nu = 0.45, h = 0.4;  // eta nu^2 = 0.0709
    const double eta = yf / yw;
    const ShellMaterial mat = support::orthotropic_material(yw, yf, g12, nu, h);
    support::Rng rng(1200);
    const Eigen::Matrix3d Q = rng.rotation();
    Eigen::Matrix3d rest;
    rest.row(0) = (Q * Eigen::Vector3d(0.1, 0.2, 0)).transpose();
    rest.row(1) = (Q * Eigen::Vector3d(1.3, 0.1, 0)).transpose();
    rest.row(2) = (Q * Eigen::Vector3d(0.5, 1.0, 0)).transpose();
    const Eigen::Vector3d warp = Q * Eigen::Vector3d(std::cos(0.7), std::sin(0.7), 0);
    const MeshData m = support::triangle(rest.row(0), rest.row(1), rest.row(2));
    auto p = support::make_patch<Ortho>(m, support::stack(m.V), {}, mat, {warp});
    const double area = 0.5 * Eigen::Vector3d(rest.row(1) - rest.row(0)).cross(Eigen::Vector3d(rest.row(2) - rest.row(0))).norm();
    const Eigen::Matrix3d R = rng.rotation();
    auto psi = [&](const Eigen::Vector3d& ev) {  // ev = (E_xx, E_yy, E_xy), x = warp, y = weft
      Eigen::Matrix2d E;
      E << ev[0], ev[2], ev[2], ev[1];
      const Eigen::Matrix3d x = corners_with_strain(rest, warp, E, R);
      for (int k = 0; k < 3; ++k) p.state.x.segment<3>(3 * k) = x.row(k).transpose();
      return p.model.energy(p.state) / (area * h);
    };
    // K = d^2 psi / d ev^2 by polarisation (exact for a quadratic).
    const double d = 0.05;
    Eigen::Matrix3d K;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const Eigen::Vector3d ei = d * Eigen::Vector3d::Unit(i), ej = d * Eigen::Vector3d::Unit(j);
        K(i, j) = (psi(ei + ej) - psi(ei) - psi(ej)) / (d * d);
      }
    K = (0.5 * (K + K.transpose())).eval();
    // Stresses: S_xx = dpsi/dE_xx, S_yy = dpsi/dE_yy, S_xy = 1/2 dpsi/dE_xy (E_xy = E_yx).
    Eigen::Matrix3d C = K;
    C.row(2) *= 0.5;
    const Eigen::Matrix3d D = C.inverse();  // strain (E_xx, E_yy, E_xy) per stress (S_xx, S_yy, S_xy)
    const Eigen::Vector3d along_warp = D.col(0), along_weft = D.col(1), shear = D.col(2);
    CHECK(1.0 / along_warp[0] == doctest::Approx(yw).epsilon(1e-10));                // Y
    CHECK(-along_warp[1] / along_warp[0] == doctest::Approx(nu).epsilon(1e-10));      // nu
    CHECK(std::abs(along_warp[2]) <= 1e-10 * std::abs(along_warp[0]));               // no shear coupling
    CHECK(1.0 / along_weft[1] == doctest::Approx(eta * yw).epsilon(1e-10));          // eta Y
    CHECK(-along_weft[0] / along_weft[1] == doctest::Approx(eta * nu).epsilon(1e-10));  // eta nu
    CHECK(1.0 / shear[2] == doctest::Approx(2 * g12).epsilon(1e-10));               // tau / E_xy = G = 2 G12
    CHECK(std::abs(shear[0]) + std::abs(shear[1]) <= 1e-10 * shear[2]);
    // Off-axis moduli (Wu et al. 2003) with the engineering G12 = G / 2.
    for (double phi : {0.0, 0.2, 0.5, 0.785, 1.1, 1.4, 1.5707963267948966, 2.3}) {
      CAPTURE(phi);
      const double c = std::cos(phi), s = std::sin(phi);
      const Eigen::Vector3d E = D * Eigen::Vector3d(c * c, s * s, c * s);  // uniaxial unit stress along (c, s)
      const double Y_phi = 1.0 / (c * c * E[0] + s * s * E[1] + 2 * c * s * E[2]);
      const double wu = 1.0 / (std::pow(c, 4) / yw + (1.0 / g12 - 2 * nu / yw) * c * c * s * s + std::pow(s, 4) / yf);
      CHECK(Y_phi == doctest::Approx(wu).epsilon(1e-10));
    }
    // The thesis' print with 1/G instead of 1/G12 is off for 0 < phi < pi/2 (methods/shells §3.2).
    const double c = std::cos(0.5), s = std::sin(0.5);
    const Eigen::Vector3d E = D * Eigen::Vector3d(c * c, s * s, c * s);
    const double thesis = 1.0 / (std::pow(c, 4) / yw + (1.0 / (2 * g12) - 2 * nu / yw) * c * c * s * s + std::pow(s, 4) / yf);
    CHECK(std::abs(1.0 / (c * c * E[0] + s * s * E[1] + 2 * c * s * E[2]) - thesis) > 1e-3 * thesis);
  }

  TEST_CASE("stvk_membrane orthotropic: exact uniaxial stretch along and across ahat (methods/shells §9 item 22)") {
    const double L = 2.0, Bw = 1.0, s = 1.3, yw = 3.0, yf = 1.2, g12 = 0.4, nu = 0.35, h = 0.2;
    const ShellMaterial mat = support::orthotropic_material(yw, yf, g12, nu, h);
    const MeshData m = support::grid(5, 3, L, Bw);
    for (bool along_warp : {true, false}) {
      CAPTURE(along_warp);
      // Length along x. along_warp: x = warp = ahat_perp -> modulus Y, contraction nu.
      // Otherwise x = weft = ahat -> eta Y and eta nu.
      const double Yl = along_warp ? yw : yf, nul = along_warp ? nu : (yf / yw) * nu;
      const double t = std::sqrt(1 - nul * (s * s - 1));
      support::Rng rng(1300);
      const Eigen::Matrix3d R = rng.rotation();
      const Eigen::Vector3d c = rng.vec3();
      const Eigen::Vector3d warp = along_warp ? Eigen::Vector3d(1, 0, 0) : Eigen::Vector3d(0, -1, 0);
      auto p = support::make_patch<Ortho>(m, support::uniaxial_positions(m, s, t, R, c), {}, mat, support::projected_warps(m, warp));
      support::check_uniaxial_stretch(p, m, R, L, Bw, h, s, Yl);
    }
  }

  TEST_CASE_TEMPLATE("stvk_membrane: compression instability at s = 1/sqrt(3) for nu = 0 (methods/shells §9 item 23)", Model, Iso, Ortho) {
    // d^2W/ds^2 = D^T H D for x(s) = (s X, Y): A h Y / 2 (3 s^2 - 1) (nu = 0: no lateral strain).
    const MeshData m = support::triangle({0, 0, 0}, {1, 0, 0}, {0.3, 0.8, 0});
    ShellMaterial iso = support::unit_material();
    iso.poisson_ratio = 0;
    for (bool along_warp : {true, false}) {
      CAPTURE(along_warp);
      const ShellMaterial mat = std::is_same_v<Model, Ortho> ? support::orthotropic_material(1.0, 2.5, 0.3, 0.0) : iso;
      const double Yl = std::is_same_v<Model, Ortho> && !along_warp ? 2.5 : 1.0;
      const auto warps = support::projected_warps(m, along_warp ? Eigen::Vector3d(1, 0, 0) : Eigen::Vector3d(0, 1, 0));
      auto p = support::make_patch<Model>(m, support::stack(m.V), {}, mat, warps);
      Eigen::VectorXd D = Eigen::VectorXd::Zero(9);
      for (int i = 0; i < 3; ++i) D[3 * i] = m.V(i, 0);
      const double area = 0.4;
      auto curvature = [&](double s) {
        for (int i = 0; i < 3; ++i) p.state.x.template segment<3>(3 * i) = Eigen::Vector3d(s * m.V(i, 0), m.V(i, 1), 0);
        return D.dot(support::dense_hessian(p.model, p.state, HessianMode::exact) * D);
      };
      const double sc = 1.0 / std::sqrt(3.0);
      for (double s : {0.3, 0.5, 0.57, 0.58, 0.7, 1.0, 1.4}) {
        CAPTURE(s);
        CHECK(curvature(s) == doctest::Approx(area * Yl / 2 * (3 * s * s - 1)).epsilon(1e-12).scale(area * Yl));
      }
      CHECK(curvature(sc - 1e-3) < 0);
      CHECK(curvature(sc + 1e-3) > 0);
      CHECK(std::abs(curvature(sc)) <= 1e-14 * area * Yl);
      // The projected Hessian stays PSD in compression.
      for (int i = 0; i < 3; ++i) p.state.x.template segment<3>(3 * i) = Eigen::Vector3d(0.4 * m.V(i, 0), m.V(i, 1), 0);
      CHECK(min_eigenvalue(support::dense_hessian(p.model, p.state, HessianMode::projected)) >= -1e-14);
    }
  }

  TEST_CASE("stvk_membrane orthotropic: stability validation rejects each violated inequality (methods/shells §9 item 20)") {
    const MeshData m = support::triangle({0, 0, 0}, {1, 0, 0}, {0, 1, 0});
    const std::vector<Eigen::Vector3d> warp = {Eigen::Vector3d(1, 0, 0)};
    auto error_of = [&](const ShellMaterial& mat) -> std::string {
      try {
        Ortho(support::make_scene(m, mat, warp), {});
      } catch (const ConfigError& e) {
        return e.what();
      }
      return "";
    };
    struct Case {
      const char* name;
      ShellMaterial mat;
      const char* message;
    };
    const Case cases[] = {
        {"Y_warp <= 0", support::orthotropic_material(-1, 1, 0.2, 0.3), "cloths.0.material.youngs_modulus_warp = -1 violates 'Y_warp > 0'"},
        {"Y_weft <= 0", support::orthotropic_material(1, 0, 0.2, 0.3), "cloths.0.material.youngs_modulus_weft = 0 violates 'Y_weft > 0'"},
        {"G12 <= 0", support::orthotropic_material(1, 1, -0.1, 0.3), "cloths.0.material.shear_modulus = -0.1 violates 'G12 > 0'"},
        {"eta nu^2 = 1", support::orthotropic_material(1, 4, 0.2, 0.5), "cloths.0.material.poisson_ratio = 0.5 violates 'eta nu^2 < 1"},
        {"eta nu^2 > 1", support::orthotropic_material(2, 1, 0.2, -1.5), "cloths.0.material.poisson_ratio = -1.5 violates 'eta nu^2 < 1"},
        {"thickness", support::orthotropic_material(1, 1, 0.2, 0.3, 0), "cloths.0.material.thickness = 0 violates '> 0'"},
    };
    for (const auto& c : cases) {
      CAPTURE(c.name);
      const std::string e = error_of(c.mat);
      CAPTURE(e);
      CHECK(e.find(c.message) != std::string::npos);
    }
    // Accepted: nu_xy > 1 is stable when eta is small enough (eta nu^2 = 0.4).
    CHECK(error_of(support::orthotropic_material(10, 1, 0.2, 2.0)).empty());
    // Every violation at once.
    const std::string all = error_of(support::orthotropic_material(-1, -1, -1, 0.3));
    CHECK(all.find("Y_warp > 0") != std::string::npos);
    CHECK(all.find("Y_weft > 0") != std::string::npos);
    CHECK(all.find("G12 > 0") != std::string::npos);
    // Missing constants.
    ShellMaterial missing = support::orthotropic_material(1, 1, 0.2, 0.3);
    missing.shear_modulus.reset();
    CHECK(error_of(missing).find("cloths.0.material.shear_modulus is required when model = orthotropic") != std::string::npos);
    // Isotropic 2D bound: |nu| >= 1 rejected, nu = 0.6 (above the 3D bound 0.5) accepted.
    for (double nu : {1.0, -1.0, 1.5}) {
      CAPTURE(nu);
      ShellMaterial iso = support::unit_material();
      iso.poisson_ratio = nu;
      CHECK(error_of(iso).find(fmt::format("cloths.0.material.poisson_ratio = {} violates 'in (-1, 1)", nu)) != std::string::npos);
      CHECK_THROWS_AS(Iso(support::make_scene(m, iso), {}), ConfigError);
    }
    ShellMaterial iso = support::unit_material();
    iso.poisson_ratio = 0.6;
    CHECK(error_of(iso).empty());
    CHECK_NOTHROW(Iso(support::make_scene(m, iso), {}));
    // Orthotropic constants on an isotropic material are not silently ignored.
    iso.youngs_modulus_warp = 2.0;
    CHECK(error_of(iso).find("youngs_modulus_warp is only read when model = orthotropic") != std::string::npos);
  }

  TEST_CASE("stvk_membrane: the isotropic model rejects an orthotropic material naming the key and the remedy") {
    const MeshData m = support::triangle({0, 0, 0}, {1, 0, 0}, {0, 1, 0});
    const Scene scene = support::make_scene(m, {support::unit_material(), support::orthotropic_material(1, 2, 0.3, 0.2)}, {1},
                                            {Eigen::Vector3d(1, 0, 0)});
    CHECK_THROWS_AS(Iso(scene, {}), ConfigError);
    CHECK_THROWS_WITH(Iso(scene, {}), doctest::Contains("cloths.1.material.model = orthotropic"));
    CHECK_THROWS_WITH(Iso(scene, {}), doctest::Contains("StvkMembrane<Isotropic>"));
    CHECK_THROWS_WITH(Iso(scene, {}), doctest::Contains("membrane(stvk, orthotropic)"));
    CHECK_NOTHROW(Ortho(scene, {}));
  }

  TEST_CASE("stvk_membrane orthotropic: a face without a warp direction is a configuration error") {
    const MeshData m = support::random_patch(3, /*curved=*/false);
    const ShellMaterial mat = fd_material();
    CHECK_THROWS_WITH_AS(Ortho(support::make_scene(m, mat), {}), doctest::Contains("Scene::face_warp"), ConfigError);
    auto warps = support::random_warps(m, 5);
    warps[4] = Eigen::Vector3d(0, 0, 1);  // normal to the (xy) rest plane
    CHECK_THROWS_WITH_AS(Ortho(support::make_scene(m, mat, warps), {}), doctest::Contains("face 4 has no warp direction in its rest plane"),
                         ConfigError);
    // An isotropic material needs none.
    CHECK_NOTHROW(Ortho(support::make_scene(m, support::unit_material()), {}));
  }

  TEST_CASE("stvk_membrane orthotropic: an out-of-plane warp is projected onto the rest plane") {
    const MeshData m = support::random_patch(6, /*curved=*/true);
    const Eigen::Vector3d dir(0.3, 0.8, -0.5);
    std::vector<Eigen::Vector3d> raw(static_cast<size_t>(m.F.rows()), dir);
    auto p = support::make_patch<Ortho>(m, support::stack(m.V), {}, fd_material(), raw);
    auto q = support::make_patch<Ortho>(m, support::stack(m.V), {}, fd_material(), support::projected_warps(m, dir));
    for (int f = 0; f < p.model.num_elements(); ++f) {
      CAPTURE(f);
      CHECK((p.model.element(f).T - q.model.element(f).T).norm() <= 1e-13 * q.model.element(f).T.norm());
    }
  }

  TEST_CASE("shell material: orthotropic bending stiffness by direction and its geometric mean") {
    ShellMaterial o = support::orthotropic_material(4.0, 1.0, 0.5, 0.6, 0.1);  // eta = 0.25, eta nu^2 = 0.09
    o.bending_stiffness.reset();
    CHECK(o.bending_k() == doctest::Approx(std::sqrt(4.0 * 1.0) * 1e-3 / (72 * (1 - 0.09))).epsilon(1e-14));
    // Along the warp / the weft: that direction's plate rigidity, D = Y h^3 / 12 (1 - eta nu^2), over 6;
    // between them Huber's (sqrt(D_warp) cos^2 + sqrt(D_weft) sin^2)^2.
    const double dx = 4.0 * 1e-3 / (12 * (1 - 0.09)), dy = 1.0 * 1e-3 / (12 * (1 - 0.09));
    CHECK(o.rigidity_warp() == doctest::Approx(dx).epsilon(1e-14));
    CHECK(o.rigidity_weft() == doctest::Approx(dy).epsilon(1e-14));
    CHECK(o.bending_k(1.0) == doctest::Approx(dx / 6).epsilon(1e-14));
    CHECK(o.bending_k(0.0) == doctest::Approx(dy / 6).epsilon(1e-14));
    const double c = std::cos(0.4), huber = std::sqrt(dx) * c * c + std::sqrt(dy) * (1 - c * c);
    CHECK(o.bending_k(c) == doctest::Approx(huber * huber / 6).epsilon(1e-14));
    CHECK(o.bending_k(c) < o.bending_k(1.0));
    CHECK(o.bending_k(c) > o.bending_k(0.0));
    // The thesis' calibration (Eq. 5.11): k = D / 2, three times the plate calibration's.
    o.bending_calibration = BendingCalibration::thesis;
    CHECK(o.bending_k() == doctest::Approx(std::sqrt(4.0 * 1.0) * 1e-3 / (24 * (1 - 0.09))).epsilon(1e-14));
    // Measured rigidities replace the plate's; one given for the warp holds for the weft too.
    o.bending_calibration = BendingCalibration::plate;
    o.bending_rigidity = 3e-5;
    CHECK(o.rigidity_weft() == 3e-5);
    CHECK(o.bending_k(0.3) == doctest::Approx(3e-5 / 6).epsilon(1e-14));
    o.bending_rigidity_weft = 1e-5;
    CHECK(o.bending_k(1.0) == doctest::Approx(3e-5 / 6).epsilon(1e-14));
    CHECK(o.bending_k(0.0) == doctest::Approx(1e-5 / 6).epsilon(1e-14));
    ShellMaterial iso = support::unit_material();
    iso.bending_stiffness.reset();
    iso.youngs_modulus = 3.0, iso.poisson_ratio = 0.3, iso.thickness = 0.1;
    ShellMaterial same = support::orthotropic_material(3.0, 3.0, 0.7, 0.3, 0.1);
    same.bending_stiffness.reset();
    CHECK(same.bending_k() == doctest::Approx(iso.bending_k()).epsilon(1e-14));
    same.bending_stiffness = 0.25;
    CHECK(same.bending_k() == 0.25);
  }
}
