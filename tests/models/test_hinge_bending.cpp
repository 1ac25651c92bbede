#include <doctest/doctest.h>

#include <Eigen/Eigenvalues>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "models/hinge_bending.hpp"
#include "tests/support/fd.hpp"
#include "tests/support/model_fixtures.hpp"

namespace {

using namespace weft;
using namespace weft::models;
using support::MeshData;

/// Rest mesh and deformed positions for derivative checks.
struct Config {
  std::string name;
  MeshData mesh;
  Eigen::VectorXd x;
};

/// Positions of the hinge mesh `shape` (same topology as `rest`).
Eigen::VectorXd positions(const MeshData& shape) { return support::stack(shape.V); }

template <class Angle>
std::vector<Config> derivative_configs() {
  // The tan energy is checked for |theta| <= 2 (methods/shells §9 item 1), the theta energy up to 2.5.
  const double big = Angle::requires_open_interval ? 2.0 : 2.5;
  std::vector<Config> c;
  for (std::uint32_t seed : {1u, 2u}) {
    const MeshData flat = support::random_patch(seed, /*curved=*/false);
    c.push_back({"flat rest patch, seed " + std::to_string(seed), flat, support::perturb(positions(flat), 0.25, 200 + seed)});
    const MeshData curved = support::random_patch(seed + 10, /*curved=*/true);
    c.push_back({"curved rest patch, seed " + std::to_string(seed), curved, support::perturb(positions(curved), 0.2, 210 + seed)});
  }
  // Single hinges: rest angle thetabar, deformed angle theta, random shapes.
  const double pairs[][2] = {{0.0, 1.0}, {0.5, -1.2}, {-1.0, big}, {1.5, -big}, {-big, 0.3}};
  std::uint32_t seed = 300;
  for (const auto& p : pairs)
    c.push_back({fmt::format("hinge thetabar {} theta {}", p[0], p[1]), support::random_hinge(++seed, p[0]),
                 positions(support::random_hinge(++seed, p[1]))});
  // Near-flat hinges (theta ~ 1e-4), with a flat and a bent rest state.
  for (double rest : {0.0, 0.3})
    c.push_back({fmt::format("near-flat hinge, thetabar {}", rest), support::random_hinge(++seed, rest),
                 positions(support::random_hinge(++seed, 1e-4))});
  // Near-degenerate: the wing x0 at altitude 1e-3 of the hinge edge.
  for (double theta : {0.4, -1.0})
    c.push_back({fmt::format("near-degenerate hinge, theta {}", theta), support::random_hinge(++seed, 0.2),
                 positions(support::random_hinge(++seed, theta, 1e-3))});
  return c;
}

/// methods/shells §9 items 10, 11: sum_i g_i = 0, sum_i x_i x g_i = 0, H (1 (x) t) = 0 and
/// H (w x x_i)_i = (w x g_i)_i.
void check_balance(const Eigen::VectorXd& x, const Eigen::VectorXd& g, const Eigen::MatrixXd& H) {
  const Eigen::Index n = x.size() / 3;
  Eigen::Vector3d force = Eigen::Vector3d::Zero(), torque = Eigen::Vector3d::Zero();
  double arm = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    force += g.segment<3>(3 * i);
    torque += x.segment<3>(3 * i).cross(g.segment<3>(3 * i));
    arm = std::max(arm, x.segment<3>(3 * i).norm());
  }
  CHECK(force.norm() <= 1e-13 * g.norm());
  CHECK(torque.norm() <= 1e-13 * g.norm() * arm);
  const Eigen::Vector3d t(0.3, -0.7, 0.5), w(-0.2, 0.4, 0.9);
  Eigen::VectorXd T(3 * n), Wx(3 * n), Wg(3 * n);
  for (Eigen::Index i = 0; i < n; ++i) {
    T.segment<3>(3 * i) = t;
    Wx.segment<3>(3 * i) = w.cross(Eigen::Vector3d(x.segment<3>(3 * i)));
    Wg.segment<3>(3 * i) = w.cross(Eigen::Vector3d(g.segment<3>(3 * i)));
  }
  CHECK((H * T).norm() <= 1e-13 * H.norm() * t.norm());
  CHECK((H * Wx - Wg).norm() <= 1e-12 * (H.norm() * Wx.norm() + Wg.norm()));
}

double min_eigenvalue(const Eigen::MatrixXd& H) { return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(H).eigenvalues().minCoeff(); }
double max_abs_eigenvalue(const Eigen::MatrixXd& H) {
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(H).eigenvalues().cwiseAbs().maxCoeff();
}

}  // namespace

TEST_SUITE("models") {
  TEST_CASE_TEMPLATE("hinge_bending: gradient matches central differences", Angle, ThetaEnergy, TanEnergy) {
    for (const auto& c : derivative_configs<Angle>()) {
      CAPTURE(c.name);
      auto p = support::make_patch<HingeBending<Angle>>(c.mesh, c.x);
      REQUIRE(p.model.admissible(p.state));
      const Eigen::VectorXd g = support::gradient(p.model, p.state);
      const Eigen::VectorXd g_fd = support::fd_gradient(p.model, p.state, support::fd_step(p.scene.mesh));
      REQUIRE(g.norm() > 0);  // a zero gradient matches anything
      CHECK(support::relative_error(g, g_fd) <= 1e-6);
    }
  }

  TEST_CASE_TEMPLATE("hinge_bending: Hessian matches central differences of the gradient", Angle, ThetaEnergy, TanEnergy) {
    for (const auto& c : derivative_configs<Angle>()) {
      CAPTURE(c.name);
      auto p = support::make_patch<HingeBending<Angle>>(c.mesh, c.x);
      const Eigen::MatrixXd H = support::dense_hessian(p.model, p.state, HessianMode::exact);
      const Eigen::MatrixXd H_fd = support::fd_hessian(p.model, p.state, support::fd_step(p.scene.mesh));
      REQUIRE(H.norm() > 0);
      CHECK(support::relative_error(H, H_fd) <= 1e-6);
    }
  }

  TEST_CASE_TEMPLATE("hinge_bending: energy of known dihedral angles (methods/shells §9 item 24)", Angle, ThetaEnergy, TanEnergy) {
    ShellMaterial mat = support::unit_material();
    mat.bending_stiffness = 0.7;
    const double k = 0.7;
    for (double rest : {0.0, 0.4}) {
      const Scene scene = support::make_scene(support::known_hinge(rest), mat);
      const HingeBending<Angle> model(scene, {});
      REQUIRE(model.num_hinges() == 1);
      CHECK(std::abs(model.hinge(0).theta_bar - rest) <= 1e-15);
      CHECK(std::abs(model.hinge(0).kappa - 3 * k) <= 1e-15);  // unit hinge edge, total area 1
      for (double phi : {0.3, 1.0, 2.5}) {
        CAPTURE(rest);
        CAPTURE(phi);
        const State s = support::make_state(scene, positions(support::known_hinge(phi)));
        CHECK(std::abs(model.angle(s, 0) - phi) <= 1e-15 * phi);
        const double expected = std::is_same_v<Angle, ThetaEnergy>
                                    ? 3 * k * (phi - rest) * (phi - rest)
                                    : 3 * k * std::pow(2 * std::tan(phi / 2) - 2 * std::tan(rest / 2), 2);
        REQUIRE(expected > 0);
        CHECK(std::abs(model.energy(s) - expected) <= 1e-14 * expected);
      }
    }
  }

  TEST_CASE("hinge_bending: stiffness is the mean of the two faces' k times 3 lbar^2 / (Abar_T + Abar_T~)") {
    ShellMaterial a = support::unit_material(), b = support::unit_material();
    a.bending_stiffness = 2.0;
    b.bending_stiffness.reset();  // D / 6 = Y h^3 / (72 (1 - nu^2))
    b.youngs_modulus = 5.0;
    b.thickness = 0.3;
    const MeshData m = support::hinge({0.3, 0.8, 0}, {0, 0, 0}, {1.5, 0, 0}, {0.9, -0.6, -0.1});
    const Scene scene = support::make_scene(m, {a, b}, {0, 1});
    const HingeBending<ThetaEnergy> model(scene, {});
    const double area_T = 0.5 * 1.5 * 0.8;
    const double area_Tt = 0.5 * (Eigen::Vector3d(1.5, 0, 0).cross(Eigen::Vector3d(0.9, -0.6, -0.1))).norm();
    const double k = 0.5 * (2.0 + b.bending_k());
    CHECK(b.bending_k() == doctest::Approx(5.0 * 0.027 / (72 * (1 - 0.09))).epsilon(1e-14));
    CHECK(model.hinge(0).kappa == doctest::Approx(k * 3 * 1.5 * 1.5 / (area_T + area_Tt)).epsilon(1e-14));
  }

  TEST_CASE_TEMPLATE("hinge_bending: zero energy and gradient at rest and at a rigidly moved rest state (methods/shells §9 item 8)", Angle,
                     ThetaEnergy, TanEnergy) {
    for (bool curved : {false, true}) {
      CAPTURE(curved);
      const MeshData m = support::random_patch(21, curved);
      const Eigen::VectorXd rest = positions(m);
      auto p = support::make_patch<HingeBending<Angle>>(m, support::perturb(rest, 0.1, 22));
      const double g_scale = support::gradient(p.model, p.state).norm();
      const double w_scale = p.model.energy(p.state);
      REQUIRE(g_scale > 0);
      support::Rng rng(23);
      for (bool moved : {false, true}) {
        CAPTURE(moved);
        p.state.x = moved ? support::rigid_motion(rest, rng.rotation(), rng.vec3()) : rest;
        CHECK(std::abs(p.model.energy(p.state)) <= 1e-14 * w_scale);
        CHECK(support::gradient(p.model, p.state).norm() <= 1e-14 * g_scale);
      }
    }
  }

  TEST_CASE_TEMPLATE("hinge_bending: energy and forces and Hessian are invariant under rigid motions (methods/shells §9 item 9)", Angle, ThetaEnergy,
                     TanEnergy) {
    const MeshData m = support::random_patch(24, /*curved=*/true);
    auto p = support::make_patch<HingeBending<Angle>>(m, support::perturb(positions(m), 0.2, 25));
    support::Rng rng(26);
    const Eigen::Matrix3d R = rng.rotation();
    const double W = p.model.energy(p.state);
    const Eigen::VectorXd g = support::gradient(p.model, p.state);
    const Eigen::MatrixXd H = support::dense_hessian(p.model, p.state, HessianMode::exact);
    REQUIRE(W > 0);
    State moved = p.state;
    moved.x = support::rigid_motion(p.state.x, R, rng.vec3());
    CHECK(std::abs(p.model.energy(moved) - W) <= 1e-13 * W);
    CHECK(support::relative_error(support::rotate_blocks(g, R), support::gradient(p.model, moved)) <= 1e-12);
    Eigen::MatrixXd Q = Eigen::MatrixXd::Zero(H.rows(), H.cols());
    for (int i = 0; i < H.rows() / 3; ++i) Q.block<3, 3>(3 * i, 3 * i) = R;
    CHECK(support::relative_error(Q * H * Q.transpose(), support::dense_hessian(p.model, moved, HessianMode::exact)) <= 1e-12);
  }

  TEST_CASE_TEMPLATE("hinge_bending: forces and torques balance and H annihilates rigid motions (methods/shells §9 items 10 and 11)",
                     Angle, ThetaEnergy, TanEnergy) {
    for (const auto& c : derivative_configs<Angle>()) {
      CAPTURE(c.name);
      auto p = support::make_patch<HingeBending<Angle>>(c.mesh, c.x);
      const Eigen::VectorXd g = support::gradient(p.model, p.state);
      REQUIRE(g.norm() > 0);
      check_balance(p.state.x, g, support::dense_hessian(p.model, p.state, HessianMode::exact));
    }
  }

  TEST_CASE_TEMPLATE("hinge_bending: assembled Hessian is symmetric (methods/shells §9 item 12)", Angle, ThetaEnergy, TanEnergy) {
    const MeshData m = support::random_patch(27, /*curved=*/true);
    auto p = support::make_patch<HingeBending<Angle>>(m, support::perturb(positions(m), 0.2, 28));
    for (HessianMode mode : {HessianMode::exact, HessianMode::projected}) {
      CAPTURE(enum_name(mode, hessian_mode_names));
      const BlockCsr H = support::assembled_hessian(p.model, p.state, mode);
      REQUIRE(H.to_dense().norm() > 0);
      CHECK(H.asymmetry() <= 1e-14);
    }
  }

  TEST_CASE_TEMPLATE("hinge_bending: projected Hessian is positive semi-definite", Angle, ThetaEnergy, TanEnergy) {
    const MeshData m = support::random_patch(29, /*curved=*/true);
    auto p = support::make_patch<HingeBending<Angle>>(m, support::perturb(positions(m), 0.3, 30));
    const Eigen::MatrixXd He = support::dense_hessian(p.model, p.state, HessianMode::exact);
    const Eigen::MatrixXd Hp = support::dense_hessian(p.model, p.state, HessianMode::projected);
    REQUIRE(min_eigenvalue(He) < -1e-6 * max_abs_eigenvalue(He));  // the projection has work to do
    CHECK(min_eigenvalue(Hp) >= -1e-12 * max_abs_eigenvalue(Hp));
    // Per hinge, through the element buffer.
    AssemblyPlan plan;
    p.model.declare(plan);
    plan.finalize(p.state.num_vertices());
    ElementBuffer buf = plan.make_buffer(AssemblyMode::stored);  // per-element slots, read back below
    p.model.add_hessian(p.state, buf, HessianMode::projected);
    for (int i = 0; i < p.model.num_hinges(); ++i) {
      CAPTURE(i);
      bending::Mat12 Hi;
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) Hi.block<3, 3>(3 * a, 3 * b) = buf.block(0, i, a, b);
      CHECK(min_eigenvalue(Hi) >= -1e-12 * max_abs_eigenvalue(Hi));
    }
  }

  TEST_CASE_TEMPLATE("hinge_bending: the Gauss-Newton projection is PSD and is the exact Hessian less psi' Hess(theta)", Angle,
                     ThetaEnergy, TanEnergy) {
    // projection = gauss_newton keeps max(psi'', 0) grad(theta) grad(theta)^T per hinge. On a
    // bent random patch: PSD, different from the exact Hessian (the guard), and equal to
    // exact - sum psi' Hess(theta) where psi'' >= 0; at the rest shape (psi' = 0) the two agree.
    const MeshData m = support::random_patch(29, /*curved=*/true);
    typename HingeBending<Angle>::Params prm;
    prm.projection = BendingProjection::gauss_newton;
    auto p = support::make_patch<HingeBending<Angle>>(m, support::perturb(positions(m), 0.3, 30), prm);
    const Eigen::MatrixXd He = support::dense_hessian(p.model, p.state, HessianMode::exact);
    const Eigen::MatrixXd Hg = support::dense_hessian(p.model, p.state, HessianMode::projected);
    CHECK(min_eigenvalue(Hg) >= -1e-12 * max_abs_eigenvalue(Hg));
    Eigen::MatrixXd expected = He;
    int negative = 0;
    for (int i = 0; i < p.model.num_hinges(); ++i) {
      const auto& h = p.model.hinge(i);
      const auto x = [&](int k) { return Eigen::Vector3d(p.state.x.template segment<3>(3 * h.v[k])); };
      const auto f = bending::hinge_frames(x(0), x(1), x(2), x(3));
      const bending::Psi psi = bending::psi<Angle>(bending::hinge_angle(f), h.phi_bar, h.kappa);
      const bending::Vec12 gt = bending::grad_theta(f);
      bending::Mat12 drop = psi.d1 * bending::hess_theta(f);
      if (psi.d2 < 0) drop += psi.d2 * gt * gt.transpose(), ++negative;
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) expected.block<3, 3>(3 * h.v[a], 3 * h.v[b]) -= drop.template block<3, 3>(3 * a, 3 * b);
    }
    MESSAGE(negative << " of " << p.model.num_hinges() << " hinges with psi'' < 0");
    REQUIRE(support::relative_error(Hg, He) > 1e-3);  // the curvature term matters here
    CHECK(support::relative_error(Hg, expected) <= 1e-12);
    auto rest = support::make_patch<HingeBending<Angle>>(m, positions(m), prm);
    const Eigen::MatrixXd Hr = support::dense_hessian(rest.model, rest.state, HessianMode::exact);
    REQUIRE(Hr.norm() > 0);
    CHECK(support::relative_error(support::dense_hessian(rest.model, rest.state, HessianMode::projected), Hr) <= 1e-10);
  }

  TEST_CASE_TEMPLATE("hinge_bending: the PSD projection on the translations' complement equals the 12x12 eigen projection",
                     Angle, ThetaEnergy, TanEnergy) {
    // project_psd decomposes the 9x9 Q^T H Q (Q: orthonormal complement of the translations),
    // which is exact for hinge Hessians only because they annihilate the translations. The
    // reference clamps the 12x12 eigen decomposition. Random, large-angle, near-flat and
    // near-degenerate hinges (derivative_configs).
    const auto reference = [](const bending::Mat12& H) {
      Eigen::SelfAdjointEigenSolver<bending::Mat12> es(H);
      const bending::Mat12 P = es.eigenvectors() * es.eigenvalues().cwiseMax(0.0).asDiagonal() * es.eigenvectors().transpose();
      return bending::Mat12(0.5 * (P + P.transpose()));
    };
    int indefinite = 0, hinges = 0;
    double worst = 0;
    for (const auto& c : derivative_configs<Angle>()) {
      CAPTURE(c.name);
      auto p = support::make_patch<HingeBending<Angle>>(c.mesh, c.x);
      for (int i = 0; i < p.model.num_hinges(); ++i) {
        CAPTURE(i);
        const auto& h = p.model.hinge(i);
        const auto x = [&](int k) { return Eigen::Vector3d(p.state.x.template segment<3>(3 * h.v[k])); };
        const auto f = bending::hinge_frames(x(0), x(1), x(2), x(3));
        const bending::Psi psi = bending::psi<Angle>(bending::hinge_angle(f), h.phi_bar, h.kappa);
        const bending::Vec12 gt = bending::grad_theta(f);
        const bending::Mat12 H = psi.d1 * bending::hess_theta(f) + psi.d2 * gt * gt.transpose();
        const double scale = max_abs_eigenvalue(H);
        if (!(scale > 0)) continue;
        ++hinges;
        indefinite += min_eigenvalue(H) < -1e-8 * scale;
        const double diff = (bending::project_psd(H) - reference(H)).norm();
        worst = std::max(worst, diff / scale);
        CHECK(diff <= 1e-12 * scale);
      }
    }
    MESSAGE(indefinite << " of " << hinges << " hinge Hessians indefinite; largest difference " << worst << " of |lambda|_max");
    CHECK(indefinite >= hinges / 4);  // the projection had work to do on many of them
    // Negative control: a matrix that does not annihilate the translations is not projected
    // like that (the precondition matters, so the comparison above can fail).
    bending::Mat12 R = bending::Mat12::Random();
    R = (R + R.transpose()).eval();
    CHECK((bending::project_psd(R) - reference(R)).norm() > 1e-3 * max_abs_eigenvalue(R));
  }

  TEST_CASE_TEMPLATE("hinge_bending: a flat mesh under an in-plane affine map has zero energy (methods/shells §9 item 27)", Angle,
                     ThetaEnergy, TanEnergy) {
    const MeshData m = support::random_patch(31, /*curved=*/false);
    Eigen::Matrix3d A;
    A << 1.3, 0.4, 0, -0.2, 0.8, 0, 0, 0, 1;  // det > 0, keeps z = 0
    const Eigen::Vector3d b(0.5, -0.3, 0);
    auto p = support::make_patch<HingeBending<Angle>>(m, support::rigid_motion(positions(m), A, b));
    REQUIRE(p.model.num_hinges() > 0);
    // The normals are exactly +-z, so every angle is exactly 0.
    CHECK(std::abs(p.model.energy(p.state)) <= 0.0);
    CHECK(support::gradient(p.model, p.state).norm() <= 0.0);
    // Rotated out of the plane: zero up to rounding.
    support::Rng rng(32);
    p.state.x = support::rigid_motion(p.state.x, rng.rotation(), rng.vec3());
    CHECK(std::abs(p.model.energy(p.state)) <= 1e-28);
  }

  TEST_CASE_TEMPLATE("hinge_bending: collapsed altitudes and edges are inadmissible and never NaN (methods/shells §9 item 28)", Angle, ThetaEnergy,
                     TanEnergy) {
    const MeshData rest = support::known_hinge(0.3);
    const Scene scene = support::make_scene(rest);
    const HingeBending<Angle> model(scene, {});
    struct Case {
      const char* name;
      MeshData shape;
      bool admissible;
    };
    const Case cases[] = {
        {"wing on the hinge line", support::hinge({0.5, 0, 0}, {0, 0, 0}, {1, 0, 0}, {0.5, -1, -0.3}), false},
        {"wing altitude 1e-11", support::hinge({0.5, 1e-11, 0}, {0, 0, 0}, {1, 0, 0}, {0.5, -1, -0.3}), false},
        {"wing altitude 1e-7", support::hinge({0.5, 1e-7, 0}, {0, 0, 0}, {1, 0, 0}, {0.5, -1, -0.3}), true},
        {"hinge edge 1e-12", support::hinge({0.5, 1, 0}, {0, 0, 0}, {1e-12, 0, 0}, {0.5, -1, -0.3}), false},
        {"hinge edge of zero length", support::hinge({0.5, 1, 0}, {0, 0, 0}, {0, 0, 0}, {0.5, -1, -0.3}), false},
    };
    for (const auto& c : cases) {
      CAPTURE(c.name);
      const State s = support::make_state(scene, positions(c.shape));
      CHECK(model.admissible(s) == c.admissible);
      const double W = model.energy(s);
      CHECK_FALSE(std::isnan(W));
      Eigen::VectorXd g = Eigen::VectorXd::Zero(s.x.size());
      AssemblyPlan plan;
      HingeBending<Angle> m = model;
      m.declare(plan);
      plan.finalize(s.num_vertices());
      ElementBuffer buf = plan.make_buffer(AssemblyMode::stored);
      if (c.admissible) {
        CHECK(std::isfinite(W));
        m.add_gradient(s, g);
        m.add_hessian(s, buf, HessianMode::exact);
        CHECK(g.allFinite());
        CHECK(support::dense_hessian(m, s, HessianMode::exact).allFinite());
      } else {
        CHECK(W == std::numeric_limits<double>::infinity());
        CHECK_THROWS_AS(m.add_gradient(s, g), InvariantError);
        CHECK_THROWS_WITH(m.add_gradient(s, g), doctest::Contains("hinge 0"));
        CHECK_THROWS_AS(m.add_hessian(s, buf, HessianMode::exact), InvariantError);
        CHECK(g.allFinite());
      }
    }
    // Non-finite positions.
    State s = support::make_state(scene, positions(rest));
    s.x[0] = std::numeric_limits<double>::quiet_NaN();
    CHECK_FALSE(model.admissible(s));
    CHECK_FALSE(std::isnan(model.energy(s)));
  }

  TEST_CASE("hinge_bending: the tan energy rejects hinges folded onto themselves (methods/shells §9 item 30)") {
    const Scene scene = support::make_scene(support::known_hinge(0.0));
    const HingeBending<TanEnergy> tan_model(scene, {});
    const HingeBending<ThetaEnergy> theta_model(scene, {});
    const State folded = support::make_state(scene, positions(support::known_hinge(std::numbers::pi - 1e-10)));
    CHECK_FALSE(tan_model.admissible(folded));
    CHECK(tan_model.energy(folded) == std::numeric_limits<double>::infinity());
    CHECK(theta_model.admissible(folded));
    CHECK(std::isfinite(theta_model.energy(folded)));
    // Energy and psi' grow monotonically towards pi.
    double last_w = 0, last_d = 0;
    for (double phi : {1.0, 2.0, 2.5, 3.0, 3.1, 3.14}) {
      CAPTURE(phi);
      const State s = support::make_state(scene, positions(support::known_hinge(phi)));
      const double w = tan_model.energy(s);
      const double d = support::gradient(tan_model, s).norm();
      CHECK(w > last_w);
      CHECK(d > last_d);
      last_w = w;
      last_d = d;
    }
  }

  TEST_CASE("hinge_bending: configuration errors name the hinge or the parameter") {
    // Rest angle at pi: fine for the theta energy, not for the tan energy.
    const Scene folded = support::make_scene(support::known_hinge(std::numbers::pi));
    CHECK_NOTHROW(HingeBending<ThetaEnergy>(folded, {}));
    CHECK_THROWS_AS(HingeBending<TanEnergy>(folded, {}), ConfigError);
    CHECK_THROWS_WITH(HingeBending<TanEnergy>(folded, {}), doctest::Contains("hinge 0"));
    // Degenerate rest triangle.
    const Scene flat_wing = support::make_scene(support::hinge({0.5, 0, 0}, {0, 0, 0}, {1, 0, 0}, {0.5, -1, 0}));
    CHECK_THROWS_WITH_AS(HingeBending<ThetaEnergy>(flat_wing, {}), doctest::Contains("hinge 0"), ConfigError);
    HingeBending<ThetaEnergy>::Params no_guards;
    no_guards.altitude_tolerance = 0;
    no_guards.edge_tolerance = 0;
    CHECK_THROWS_WITH_AS(HingeBending<ThetaEnergy>(flat_wing, no_guards), doctest::Contains("hinge 0"), ConfigError);
    // Parameters.
    HingeBending<ThetaEnergy>::Params prm;
    prm.altitude_tolerance = -1;
    const Scene ok = support::make_scene(support::known_hinge(0.2));
    CHECK_THROWS_WITH_AS(HingeBending<ThetaEnergy>(ok, prm), doctest::Contains("altitude_tolerance"), ConfigError);
  }

  TEST_CASE("hinge_bending: energy terms") {
    const Scene scene = support::make_scene(support::known_hinge(0.0));
    const HingeBending<ThetaEnergy> model(scene, {});
    const State s = support::make_state(scene, positions(support::known_hinge(0.5)));
    EnergyTerms terms;
    model.energy_terms(s, terms);
    REQUIRE(terms.size() == 1);
    CHECK(terms[0].first == "bending");
    CHECK(terms[0].second == doctest::Approx(3 * 0.25).epsilon(1e-14));
  }
}
