#include <doctest/doctest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "models/stvk_membrane.hpp"
#include "tests/support/fd.hpp"
#include "tests/support/model_fixtures.hpp"
#include "tests/support/uniaxial.hpp"

namespace {

using namespace weft;
using namespace weft::models;
using Membrane = StvkMembrane<Isotropic>;
using support::MeshData;

/// A mesh and deformed positions for derivative checks.
struct Config {
  std::string name;
  MeshData mesh;
  Eigen::VectorXd x;
};

MeshData unit_right_triangle() { return support::triangle({0, 0, 0}, {1, 0, 0}, {0, 1, 0}); }

std::vector<Config> derivative_configs() {
  std::vector<Config> c;
  for (std::uint32_t seed : {1u, 2u, 3u}) {
    // Random well-shaped rest patch in 3D, randomly deformed (stretch and compression).
    MeshData m = support::random_patch(seed, /*curved=*/true);
    c.push_back({"random curved patch, seed " + std::to_string(seed), m, support::perturb(support::stack(m.V), 0.2, 100 + seed)});
  }
  {
    // One altitude 1e-3 of its edge in the deformed state (rest well-shaped).
    MeshData m = support::triangle({0, 0, 0}, {1, 0, 0}, {0.4, 0.9, 0});
    Eigen::VectorXd x(9);
    x << 0, 0, 0, 1.05, 0.02, 0, 0.5, 1e-3, 0;
    c.push_back({"near-degenerate deformed triangle", m, support::rigid_motion(x, support::Rng(5).rotation(), {0.1, 0.2, 0.3})});
  }
  {
    // Near-degenerate rest triangle (altitude 1e-3 of its base), deformed across the thin
    // direction: T ~ 1 / Abar^3 is large, W stays exactly quartic.
    MeshData m = support::triangle({0, 0, 0}, {1, 0, 0}, {0.5, 1e-3, 0});
    Eigen::VectorXd x(9);
    x << 0, 0, 0, 1.0, 0, 0, 0.5, 1.3e-3, 2e-4;
    c.push_back({"near-degenerate rest triangle", m, x});
  }
  {
    // Inverted element: vertex 2 pushed through the opposite edge (0, 1).
    MeshData m = support::triangle({0, 0, 0}, {1, 0, 0}, {0.4, 0.9, 0});
    Eigen::VectorXd x(9);
    x << 0, 0, 0, 1.1, 0, 0.05, 0.5, -0.4, 0.1;
    c.push_back({"inverted triangle", m, x});
  }
  {
    // Inverted element inside a patch: an interior vertex pushed through an opposite edge.
    MeshData m = support::random_patch(4, /*curved=*/false);
    Eigen::VectorXd x = support::perturb(support::stack(m.V), 0.05, 104);
    x.segment<3>(3 * 5) += Eigen::Vector3d(1.3, 1.1, 0.2);  // vertex 5 is interior in the 4x4 grid
    c.push_back({"patch with inverted elements", m, x});
  }
  return c;
}

/// Reference energy via the deformation gradient (methods/shells §4.1): W = Abar h psi(E).
double reference_energy(const Eigen::Matrix3d& rest, const Eigen::Matrix3d& x, double Y, double nu, double h) {
  const Eigen::Vector3d r1 = rest.row(1) - rest.row(0), r2 = rest.row(2) - rest.row(0);
  const Eigen::Vector3d n = r1.cross(r2).normalized(), t1 = r1.normalized(), t2 = n.cross(t1);
  Eigen::Matrix2d Dm;
  Dm << t1.dot(r1), t1.dot(r2), t2.dot(r1), t2.dot(r2);
  Eigen::Matrix<double, 3, 2> Ds;
  Ds.col(0) = x.row(1) - x.row(0);
  Ds.col(1) = x.row(2) - x.row(0);
  const Eigen::Matrix<double, 3, 2> F = Ds * Dm.inverse();
  const Eigen::Matrix2d E = 0.5 * (F.transpose() * F - Eigen::Matrix2d::Identity());
  const double lambda = Y * nu / (1 - nu * nu), mu = Y / (2 * (1 + nu));
  const double psi = 0.5 * lambda * E.trace() * E.trace() + mu * (E * E).trace();
  return 0.5 * r1.cross(r2).norm() * h * psi;
}

/// A patch of `Model` on `mesh` at positions x: the unit isotropic material, or for
/// StvkMembrane<Orthotropic> a strongly orthotropic one with random warp directions.
template <class Model>
support::Patch<Model> patch_for(const MeshData& mesh, const Eigen::VectorXd& x, std::uint32_t seed) {
  if constexpr (std::is_same_v<Model, StvkMembrane<Orthotropic>>)
    return support::make_patch<Model>(mesh, x, {}, support::orthotropic_material(1.0, 3.0, 0.1, 0.4), support::random_warps(mesh, seed));
  else
    return support::make_patch<Model>(mesh, x);
}

double min_eigenvalue(const Eigen::MatrixXd& H) { return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(H).eigenvalues().minCoeff(); }
double max_abs_eigenvalue(const Eigen::MatrixXd& H) {
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(H).eigenvalues().cwiseAbs().maxCoeff();
}

}  // namespace

TEST_SUITE("models") {
  TEST_CASE("stvk_membrane: golden values of methods/shells §9 item 7") {
    const MeshData m = unit_right_triangle();
    auto p = support::make_patch<Membrane>(m, Eigen::VectorXd::Zero(9));
    p.state.x << 0, 0, 0, 1.1, 0, 0, 0.2, 0.9, 0.3;
    const double W = p.model.energy(p.state);
    CHECK(std::abs(W - 0.00741071428571429) <= 1e-13 * 0.00741071428571429);
    const Eigen::VectorXd f = -support::gradient(p.model, p.state);
    CHECK(std::abs(f[0] - 0.113186813187) <= 1e-11);
    CHECK(std::abs(f[1] - 0.038818681319) <= 1e-11);
    CHECK(std::abs(f[2] - 0.012939560440) <= 1e-11);
  }

  TEST_CASE("stvk_membrane: T from (lambda mu a b) reproduces the orthotropic golden values") {
    // The runtime kernel is material-independent; only T changes (methods/shells §4.4). Check the
    // orthotropic terms T3, T4 of the precompute with the golden values of §9 item 7.
    Eigen::Matrix3d rest, x;
    rest << 0, 0, 0, 1, 0, 0, 0, 1, 0;
    x << 0, 0, 0, 1.1, 0, 0, 0.2, 0.9, 0.3;
    const membrane::LameConstants c{0.647120418848, 0.2, -0.490052356021, 0.228272251309};
    membrane::Element el;
    el.rest_length2 = Eigen::Vector3d(2, 1, 1);
    el.T = membrane::stvk_T(rest, 1.0, c, Eigen::Vector3d(0, 1, 0));
    const double W = membrane::element_energy(x, el);
    // The constants are given to 12 digits, so W agrees to about 1e-11.
    CHECK(std::abs(W - 0.00517654450261780) <= 1e-10 * 0.00517654450261780);
    const membrane::Vec9 f = -membrane::element_gradient(x, el);
    CHECK(std::abs(f[0] - 0.086558115183) <= 1e-10);
    CHECK(std::abs(f[1] - 0.020153403141) <= 1e-10);
    CHECK(std::abs(f[2] - 0.006717801047) <= 1e-10);
    // Isotropic constants through the general path give the isotropic T whatever the direction.
    const membrane::LameConstants iso = membrane::isotropic_lame(1.0, 0.3);
    const Eigen::Matrix3d T_iso = membrane::stvk_T(rest, 1.0, iso);
    REQUIRE(T_iso.norm() > 0);
    CHECK((membrane::stvk_T(rest, 1.0, iso, Eigen::Vector3d(0.6, 0.8, 0)) - T_iso).norm() <= 1e-15 * T_iso.norm());
  }

  TEST_CASE("stvk_membrane: edge-based energy equals the deformation-gradient reference") {
    for (std::uint32_t seed = 1; seed <= 5; ++seed) {
      CAPTURE(seed);
      support::Rng rng(seed);
      const Eigen::Vector3d a = rng.vec3(), b = a + rng.rotation() * Eigen::Vector3d(1, 0, 0),
                            c = a + rng.rotation() * Eigen::Vector3d(0.3, 0.9, 0.2);
      ShellMaterial mat = support::unit_material();
      mat.youngs_modulus = rng.uniform(0.5, 2);
      mat.poisson_ratio = rng.uniform(-0.5, 0.9);
      mat.thickness = rng.uniform(0.1, 1);
      CAPTURE(mat.poisson_ratio);
      const MeshData m = support::triangle(a, b, c);
      auto p = support::make_patch<Membrane>(m, support::perturb(support::stack(m.V), 0.3, 50 + seed), {}, mat);
      Eigen::Matrix3d x;
      for (int k = 0; k < 3; ++k) x.row(k) = p.state.x.template segment<3>(3 * k).transpose();
      const double ref = reference_energy(m.V, x, mat.youngs_modulus, mat.poisson_ratio, mat.thickness);
      REQUIRE(ref > 0);
      CHECK(std::abs(p.model.energy(p.state) - ref) <= 1e-13 * ref);
    }
  }

  TEST_CASE("stvk_membrane: gradient matches central differences") {
    for (const auto& c : derivative_configs()) {
      CAPTURE(c.name);
      auto p = support::make_patch<Membrane>(c.mesh, c.x);
      const Eigen::VectorXd g = support::gradient(p.model, p.state);
      const Eigen::VectorXd g_fd = support::fd_gradient(p.model, p.state, support::fd_step(p.scene.mesh));
      REQUIRE(g.norm() > 0);  // a zero gradient matches anything
      CHECK(support::relative_error(g, g_fd) <= 1e-6);
    }
  }

  TEST_CASE("stvk_membrane: Hessian matches central differences of the gradient") {
    for (const auto& c : derivative_configs()) {
      CAPTURE(c.name);
      auto p = support::make_patch<Membrane>(c.mesh, c.x);
      const Eigen::MatrixXd H = support::dense_hessian(p.model, p.state, HessianMode::exact);
      const Eigen::MatrixXd H_fd = support::fd_hessian(p.model, p.state, support::fd_step(p.scene.mesh));
      REQUIRE(H.norm() > 0);
      CHECK(support::relative_error(H, H_fd) <= 1e-6);
    }
  }

  TEST_CASE_TEMPLATE("stvk_membrane: zero energy and gradient at rest and at a rigidly moved rest state (methods/shells §9 item 8)", Model,
                     StvkMembrane<Isotropic>, StvkMembrane<Orthotropic>) {
    const MeshData m = support::random_patch(7, /*curved=*/true);
    const Eigen::VectorXd rest = support::stack(m.V);
    auto p = patch_for<Model>(m, 1.1 * rest, 70);
    const double g_scale = support::gradient(p.model, p.state).norm();  // forces at 10% stretch
    const double w_scale = p.model.energy(p.state);
    REQUIRE(g_scale > 0);
    support::Rng rng(8);
    for (bool moved : {false, true}) {
      CAPTURE(moved);
      p.state.x = moved ? support::rigid_motion(rest, rng.rotation(), rng.vec3()) : rest;
      CHECK(std::abs(p.model.energy(p.state)) <= 1e-14 * w_scale);
      CHECK(support::gradient(p.model, p.state).norm() <= 1e-14 * g_scale);
    }
  }

  TEST_CASE_TEMPLATE("stvk_membrane: energy and forces and Hessian are invariant under rigid motions (methods/shells §9 item 9)", Model,
                     StvkMembrane<Isotropic>, StvkMembrane<Orthotropic>) {
    const MeshData m = support::random_patch(9, /*curved=*/true);
    auto p = patch_for<Model>(m, support::perturb(support::stack(m.V), 0.2, 10), 90);
    support::Rng rng(11);
    const Eigen::Matrix3d R = rng.rotation();
    const Eigen::Vector3d c = rng.vec3();
    const double W = p.model.energy(p.state);
    const Eigen::VectorXd g = support::gradient(p.model, p.state);
    const Eigen::MatrixXd H = support::dense_hessian(p.model, p.state, HessianMode::exact);
    REQUIRE(W > 0);
    State moved = p.state;
    moved.x = support::rigid_motion(p.state.x, R, c);
    CHECK(std::abs(p.model.energy(moved) - W) <= 1e-13 * W);
    CHECK(support::relative_error(support::rotate_blocks(g, R), support::gradient(p.model, moved)) <= 1e-12);
    Eigen::MatrixXd Q = Eigen::MatrixXd::Zero(H.rows(), H.cols());
    for (int i = 0; i < H.rows() / 3; ++i) Q.block<3, 3>(3 * i, 3 * i) = R;
    CHECK(support::relative_error(Q * H * Q.transpose(), support::dense_hessian(p.model, moved, HessianMode::exact)) <= 1e-12);
  }

  TEST_CASE_TEMPLATE("stvk_membrane: forces and torques balance and H annihilates rigid motions (methods/shells §9 items 10 and 11)", Model,
                     StvkMembrane<Isotropic>, StvkMembrane<Orthotropic>) {
    for (const auto& c : derivative_configs()) {
      CAPTURE(c.name);
      auto p = patch_for<Model>(c.mesh, c.x, 110);
      const Eigen::VectorXd g = support::gradient(p.model, p.state);
      const int n = p.state.num_vertices();
      Eigen::Vector3d force = Eigen::Vector3d::Zero(), torque = Eigen::Vector3d::Zero();
      double arm = 0;
      for (int i = 0; i < n; ++i) {
        force += g.segment<3>(3 * i);
        torque += p.state.x.template segment<3>(3 * i).cross(g.segment<3>(3 * i));
        arm = std::max(arm, p.state.x.template segment<3>(3 * i).norm());
      }
      REQUIRE(g.norm() > 0);
      CHECK(force.norm() <= 1e-13 * g.norm());
      CHECK(torque.norm() <= 1e-13 * g.norm() * arm);
      const Eigen::MatrixXd H = support::dense_hessian(p.model, p.state, HessianMode::exact);
      const Eigen::Vector3d t(0.3, -0.7, 0.5), w(-0.2, 0.4, 0.9);
      Eigen::VectorXd T(3 * n), Wx(3 * n), Wg(3 * n);
      for (int i = 0; i < n; ++i) {
        T.segment<3>(3 * i) = t;
        Wx.segment<3>(3 * i) = w.cross(Eigen::Vector3d(p.state.x.template segment<3>(3 * i)));
        Wg.segment<3>(3 * i) = w.cross(Eigen::Vector3d(g.segment<3>(3 * i)));
      }
      CHECK((H * T).norm() <= 1e-13 * H.norm() * t.norm());
      CHECK((H * Wx - Wg).norm() <= 1e-12 * (H.norm() * Wx.norm() + Wg.norm()));
    }
  }

  TEST_CASE_TEMPLATE("stvk_membrane: assembled Hessian is symmetric", Model, StvkMembrane<Isotropic>, StvkMembrane<Orthotropic>) {
    const MeshData m = support::random_patch(12, /*curved=*/true);
    auto p = patch_for<Model>(m, support::perturb(support::stack(m.V), 0.3, 13), 120);
    for (HessianMode mode : {HessianMode::exact, HessianMode::projected}) {
      CAPTURE(enum_name(mode, hessian_mode_names));
      const BlockCsr H = support::assembled_hessian(p.model, p.state, mode);
      REQUIRE(H.to_dense().norm() > 0);
      CHECK(H.asymmetry() <= 1e-14);
    }
  }

  TEST_CASE("stvk_membrane: exact uniaxial stretch (methods/shells §9 item 22)") {
    const double L = 2.0, Bw = 1.0, s = 1.3;
    ShellMaterial mat = support::unit_material();
    mat.youngs_modulus = 3.0;
    mat.poisson_ratio = 0.3;
    mat.thickness = 0.2;
    const MeshData m = support::grid(5, 3, L, Bw);
    const double nu = mat.poisson_ratio, Y = mat.youngs_modulus, h = mat.thickness;
    const double t = std::sqrt(1 - nu * (s * s - 1));
    support::Rng rng(14);
    const Eigen::Matrix3d R = rng.rotation();
    const Eigen::Vector3d c = rng.vec3();
    auto p = support::make_patch<Membrane>(m, support::uniaxial_positions(m, s, t, R, c), {}, mat);
    support::check_uniaxial_stretch(p, m, R, L, Bw, h, s, Y);
  }

  TEST_CASE_TEMPLATE("stvk_membrane: projected Hessian is positive semi-definite", Model, StvkMembrane<Isotropic>,
                     StvkMembrane<Orthotropic>) {
    const MeshData m = support::random_patch(15, /*curved=*/false);
    // Compressed and perturbed: edges with r_i < 0 make the exact Hessian indefinite.
    auto p = patch_for<Model>(m, support::perturb(0.7 * support::stack(m.V), 0.1, 16), 150);
    const Eigen::MatrixXd He = support::dense_hessian(p.model, p.state, HessianMode::exact);
    const Eigen::MatrixXd Hp = support::dense_hessian(p.model, p.state, HessianMode::projected);
    REQUIRE(min_eigenvalue(He) < -1e-6 * max_abs_eigenvalue(He));  // the projection has work to do
    CHECK(min_eigenvalue(Hp) >= -1e-12 * max_abs_eigenvalue(Hp));
    for (int f = 0; f < p.model.num_elements(); ++f) {
      CAPTURE(f);
      membrane::Corners x;
      for (int k = 0; k < 3; ++k) x.row(k) = p.state.x.template segment<3>(3 * m.F(f, k)).transpose();
      const Eigen::MatrixXd Hf = membrane::element_hessian(x, p.model.element(f), true);
      CHECK(min_eigenvalue(Hf) >= -1e-12 * max_abs_eigenvalue(Hf));
    }
  }

  TEST_CASE("stvk_membrane: energy terms and admissibility") {
    const MeshData m = unit_right_triangle();
    auto p = support::make_patch<Membrane>(m, support::perturb(support::stack(m.V), 0.1, 17));
    EnergyTerms terms;
    p.model.energy_terms(p.state, terms);
    REQUIRE(terms.size() == 1);
    CHECK(terms[0].first == "membrane");
    CHECK(terms[0].second == doctest::Approx(p.model.energy(p.state)).epsilon(1e-15));
    CHECK(p.model.admissible(p.state));
    p.state.x[4] = std::numeric_limits<double>::quiet_NaN();
    CHECK_FALSE(p.model.admissible(p.state));
  }

  TEST_CASE("stvk_membrane: a zero-area rest face is a configuration error naming the face") {
    MeshData m;
    m.V.resize(5, 3);
    m.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 0, 0, 3, 0, 0;
    m.F.resize(2, 3);
    m.F << 0, 1, 2, 1, 3, 4;  // face 1 is colinear
    const Scene scene = support::make_scene(m);
    CHECK_THROWS_AS(Membrane(scene, {}), ConfigError);
    CHECK_THROWS_WITH(Membrane(scene, {}), doctest::Contains("face 1 "));
  }

  TEST_CASE("stvk_membrane: invalid material constants are configuration errors") {
    ShellMaterial mat = support::unit_material();
    mat.poisson_ratio = 1.2;
    mat.thickness = -1;
    const Scene scene = support::make_scene(unit_right_triangle(), mat);
    CHECK_THROWS_AS(Membrane(scene, {}), ConfigError);
    CHECK_THROWS_WITH(Membrane(scene, {}), doctest::Contains("poisson_ratio"));
    CHECK_THROWS_WITH(Membrane(scene, {}), doctest::Contains("thickness"));
  }
}
