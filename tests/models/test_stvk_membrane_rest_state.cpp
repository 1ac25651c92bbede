// Animated rest state of StvkMembrane (methods/shells §5): rest lengths lbar_e (1 - w + w s(t)).
#include <doctest/doctest.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <cmath>
#include <string>
#include <vector>

#include "models/energy_sum.hpp"
#include "models/stvk_membrane.hpp"
#include "tests/support/fd.hpp"
#include "tests/support/model_fixtures.hpp"

namespace {

using namespace weft;
using namespace weft::models;
using Ortho = StvkMembrane<Orthotropic>;
using Iso = StvkMembrane<Isotropic>;
using support::MeshData;

RestStateSpec script(std::vector<std::pair<double, double>> keys, double weight = 1.0) {
  RestStateSpec r;
  for (const auto& [t, s] : keys) r.keyframes.push_back({t, s});
  r.weight = weight;
  return r;
}

template <class Model>
ShellMaterial material_for() {
  return std::is_same_v<Model, Ortho> ? support::orthotropic_material(1.0, 2.5, 0.2, 0.35) : support::unit_material();
}

/// A scene of one cloth with a rest-state script (random warps for orthotropic materials).
Scene animated_scene(const MeshData& m, const ShellMaterial& mat, const RestStateSpec& rs, std::uint32_t warp_seed = 1) {
  Scene s = support::make_scene(m, mat, support::random_warps(m, warp_seed));
  s.spec.cloths[0].rest_state = rs;
  return s;
}

/// Reference T of one face under per-edge factors, through positions only: the blended
/// triangle is laid out in the plane from its three lengths, the warp direction is carried
/// along by the affine map between the rest triangle and the blended one (it keeps its
/// coordinates w.r.t. the edges), and stvk_T evaluates it with ahat = n x warp.
Eigen::Matrix3d reference_T(const Eigen::Matrix3d& rest, const Eigen::Vector3d& warp, const Eigen::Vector3d& factors, double h,
                            const membrane::LameConstants& c) {
  // Cyclic edges e0 = v2 - v1, e1 = v0 - v2, e2 = v1 - v0.
  Eigen::Vector3d l;
  l[0] = (rest.row(2) - rest.row(1)).norm() * factors[0];
  l[1] = (rest.row(0) - rest.row(2)).norm() * factors[1];
  l[2] = (rest.row(1) - rest.row(0)).norm() * factors[2];
  // v0 = 0, v1 = (l2, 0), v2 from |v2 - v0| = l1, |v2 - v1| = l0.
  const double x2 = (l[2] * l[2] + l[1] * l[1] - l[0] * l[0]) / (2 * l[2]);
  Eigen::Matrix3d blended;
  blended << 0, 0, 0, l[2], 0, 0, x2, std::sqrt(l[1] * l[1] - x2 * x2), 0;
  // Affine map rest -> blended on the edge vectors (v1 - v0, v2 - v0).
  Eigen::Matrix<double, 3, 2> A, B;
  A.col(0) = rest.row(1) - rest.row(0), A.col(1) = rest.row(2) - rest.row(0);
  B.col(0) = blended.row(1) - blended.row(0), B.col(1) = blended.row(2) - blended.row(0);
  const Eigen::Vector2d coeff = (A.transpose() * A).ldlt().solve(A.transpose() * warp);  // warp = A coeff (in plane)
  const Eigen::Vector3d wb = B * coeff;
  const Eigen::Vector3d ahat = Eigen::Vector3d::UnitZ().cross(wb).normalized();
  return membrane::stvk_T(blended, h, c, ahat);
}

}  // namespace

TEST_SUITE("models") {
  TEST_CASE("rest state spec: piecewise-linear scale / constant outside / blended factor") {
    const RestStateSpec r = script({{0.5, 1.0}, {1.0, 1.2}, {2.0, 0.9}}, 0.5);
    CHECK(r.scale(0.0) == 1.0);
    CHECK(r.scale(0.75) == doctest::Approx(1.1).epsilon(1e-15));
    CHECK(r.scale(1.5) == doctest::Approx(1.05).epsilon(1e-15));
    CHECK(r.scale(3.0) == 0.9);
    CHECK(r.factor(1.0) == doctest::Approx(1.1).epsilon(1e-15));  // 1 - w + w s
    CHECK_FALSE(RestStateSpec{}.active());
    CHECK(RestStateSpec{}.factor(7.0) == 1.0);
  }

  TEST_CASE_TEMPLATE("rest state: uniform scaling gives zero energy and force at the scaled positions", Model, Iso, Ortho) {
    const MeshData m = support::random_patch(21, /*curved=*/true);
    const Eigen::VectorXd X = support::stack(m.V);
    for (double w : {1.0, 0.5}) {
      CAPTURE(w);
      Scene scene = animated_scene(m, material_for<Model>(), script({{0, 1.0}, {1.0, 1.2}}, w));
      Model model(scene, {});
      REQUIRE(model.animated());
      const double g = 1 - w + w * 1.2;
      State s = support::make_state(scene, X);
      // At t = 0 the mesh is the rest state; at t = 1 the rest lengths are g times longer.
      CHECK(std::abs(model.energy(s)) <= 1e-30);
      const Eigen::VectorXd scaled = support::rigid_motion(g * X, support::Rng(22).rotation(), {0.3, -0.2, 0.1});
      s.x = scaled;
      const double W_stretched = model.energy(s);
      const double g_stretched = support::gradient(model, s).norm();
      REQUIRE(W_stretched > 0);
      REQUIRE(g_stretched > 0);
      model.begin_step(s, 1.0);
      CHECK(std::abs(model.energy(s)) <= 1e-14 * W_stretched);
      CHECK(support::gradient(model, s).norm() <= 1e-13 * g_stretched);
      // The rest data equals a static model's on the scaled mesh (the orthotropic beta_i are
      // normalised by ||ahat_perp||, so T scales as 1 / g^2, not 1 / g^6).
      MeshData big = m;
      big.V *= g;
      Model reference(support::make_scene(big, material_for<Model>(), support::random_warps(m, 1)), {});
      for (int f = 0; f < model.num_elements(); ++f) {
        CAPTURE(f);
        const Eigen::Matrix3d& Tref = reference.element(f).T;
        CHECK((model.element(f).T - Tref).norm() <= 1e-13 * Tref.norm());
        const Eigen::Vector3d& l2 = reference.element(f).rest_length2;
        CHECK((model.element(f).rest_length2 - l2).norm() <= 1e-14 * l2.norm());
      }
      // Back to t = 0: the original rest data, bit for bit.
      Model fresh(scene, {});
      model.begin_step(s, 0.0);
      for (int f = 0; f < model.num_elements(); ++f) CHECK((model.element(f).T - fresh.element(f).T).norm() == 0.0);
    }
  }

  TEST_CASE_TEMPLATE("rest state: a box scales only its edges and T matches the blended triangle", Model, Iso, Ortho) {
    const MeshData m = support::grid(5, 5, 2.0, 2.0);
    RestStateSpec rs = script({{0, 1.0}, {2.0, 1.3}, {3.0, 0.8}});
    rs.box_min = Eigen::Vector3d(-0.1, -0.1, -1);
    rs.box_max = Eigen::Vector3d(1.1, 1.1, 1);  // the lower-left 3x3 vertices
    const ShellMaterial mat = material_for<Model>();
    const Scene scene = animated_scene(m, mat, rs, 3);
    Model model(scene, {});
    const std::vector<unsigned char> sel = rest_state_edges(scene);
    const double t = 1.0, g = rs.factor(t);
    CHECK(g == doctest::Approx(1.15).epsilon(1e-15));
    model.set_rest_time(t);
    int partial = 0, full = 0, none = 0;
    for (int f = 0; f < model.num_elements(); ++f) {
      CAPTURE(f);
      Eigen::Vector3d factors;
      for (int i = 0; i < 3; ++i) factors[i] = sel[scene.mesh.face_edges()[f][i]] ? g : 1.0;
      const int n = static_cast<int>((factors.array() != 1.0).count());
      partial += n == 1 || n == 2, full += n == 3, none += n == 0;
      Eigen::Matrix3d rest;
      for (int k = 0; k < 3; ++k) rest.row(k) = m.V.row(m.F(f, k));
      const Eigen::Matrix3d Tref =
          reference_T(rest, scene.face_warp.empty() ? Eigen::Vector3d::Zero() : scene.face_warp[f], factors, mat.thickness,
                      membrane::material_lame(mat));
      CHECK((model.element(f).T - Tref).norm() <= 1e-12 * Tref.norm());
      CHECK((model.element(f).rest_length2 - model.rest_shape(f).length2.cwiseProduct(factors.cwiseProduct(factors))).norm() == 0.0);
    }
    CHECK(partial > 0);  // the interesting case: triangles on the box boundary
    CHECK(full > 0);
    CHECK(none > 0);
  }

  TEST_CASE_TEMPLATE("rest state: energy / gradient and Hessian are FD-correct after a rest change", Model, Iso, Ortho) {
    const MeshData m = support::random_patch(23, /*curved=*/true);
    RestStateSpec rs = script({{0, 1.0}, {1.0, 0.85}});
    rs.box_min = m.V.colwise().minCoeff().transpose() - Eigen::Vector3d::Constant(0.01);
    rs.box_max = 0.5 * (m.V.colwise().minCoeff() + m.V.colwise().maxCoeff()).transpose();
    rs.box_max[2] = 10;  // half the patch (curved and rotated: a box in space)
    rs.box_max[1] = 10;
    const Scene scene = animated_scene(m, material_for<Model>(), rs, 24);
    Model model(scene, {});
    State s = support::make_state(scene, support::perturb(support::stack(m.V), 0.1, 25));
    const Eigen::VectorXd g0 = support::gradient(model, s);
    model.begin_step(s, 0.7);
    const Eigen::VectorXd g = support::gradient(model, s);
    REQUIRE(g.norm() > 0);
    REQUIRE(support::relative_error(g, g0) > 1e-3);  // the rest change is not vacuous
    CHECK(support::relative_error(g, support::fd_gradient(model, s, support::fd_step(scene.mesh))) <= 1e-6);
    const Eigen::MatrixXd H = support::dense_hessian(model, s, HessianMode::exact);
    REQUIRE(H.norm() > 0);
    CHECK(support::relative_error(H, support::fd_hessian(model, s, support::fd_step(scene.mesh))) <= 1e-6);
  }

  TEST_CASE("rest state: begin_step is a no-op for static scenes and repeated times") {
    const MeshData m = support::random_patch(26, /*curved=*/false);
    Iso still(support::make_scene(m), {});
    CHECK_FALSE(still.animated());
    const State s = support::make_state(support::make_scene(m), support::stack(m.V));
    const Eigen::Matrix3d T0 = still.element(0).T;
    still.begin_step(s, 5.0);
    CHECK((still.element(0).T - T0).norm() == 0.0);
    const Scene scene = animated_scene(m, support::unit_material(), script({{0, 1.0}, {1, 2.0}}));
    Iso model(scene, {});
    model.begin_step(s, 0.5);
    const Eigen::Matrix3d T1 = model.element(3).T;
    model.begin_step(s, 0.5);
    CHECK((model.element(3).T - T1).norm() == 0.0);
    model.begin_step(s, 0.25);
    CHECK((model.element(3).T - T1).norm() > 0.1 * T1.norm());
  }

  TEST_CASE("rest state: scripts that would break a triangle are configuration errors naming the face") {
    const MeshData m = support::grid(4, 4, 3.0, 3.0);
    RestStateSpec rs = script({{0, 1.0}, {1.0, 3.0}});
    rs.box_min = Eigen::Vector3d(-0.5, -0.5, -1);
    rs.box_max = Eigen::Vector3d(1.5, 1.5, 1);
    const Scene bad = animated_scene(m, support::unit_material(), rs);
    CHECK_THROWS_AS(Iso(bad, {}), ConfigError);
    CHECK_THROWS_WITH(Iso(bad, {}), doctest::Contains("cloths.0.rest_state: face"));
    CHECK_THROWS_WITH(Iso(bad, {}), doctest::Contains("violate the triangle inequality"));
    CHECK_THROWS_WITH(Iso(bad, {}), doctest::Contains("factor 1 - w + w s = 3"));
    // The same factor on every edge is always a triangle; a mild one with the box is too.
    rs.box_min = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    rs.box_max = -rs.box_min;
    CHECK_NOTHROW(Iso(animated_scene(m, support::unit_material(), rs), {}));
    rs = script({{0, 1.0}, {1.0, 1.5}});
    rs.box_min = Eigen::Vector3d(-0.5, -0.5, -1), rs.box_max = Eigen::Vector3d(1.5, 1.5, 1);
    CHECK_NOTHROW(Iso(animated_scene(m, support::unit_material(), rs), {}));
    // Shrinking hits the other inequality: at 0.3 the scaled edges of a boundary triangle are
    // too short to reach its unscaled one.
    rs = script({{0, 1.0}, {1.0, 0.3}});
    rs.box_min = Eigen::Vector3d(-0.5, -0.5, -1), rs.box_max = Eigen::Vector3d(1.5, 1.5, 1);
    CHECK_THROWS_WITH_AS(Iso(animated_scene(m, support::unit_material(), rs), {}), doctest::Contains("keyframe 1"), ConfigError);
    // A box that selects no edge.
    rs.box_min = Eigen::Vector3d(10, 10, 10), rs.box_max = Eigen::Vector3d(11, 11, 11);
    CHECK_THROWS_WITH_AS(Iso(animated_scene(m, support::unit_material(), rs), {}), doctest::Contains("selects no edge"), ConfigError);
  }

  TEST_CASE("rest state: a cloth whose rest lengths grow by 20% expands over a sequence of implicit steps") {
    // Backward Euler as minimisation, written out here (no policies): per step
    //   x = argmin 1/(2 dt^2) (x - xp)^T M (x - xp) + W(x; rest(t_end)),  xp = x + dt v,
    // damped Newton on the dense projected Hessian; v = (x - x_old) / dt, then mass damping.
    const MeshData m = support::grid(5, 5, 1.0, 1.0);
    const ShellMaterial mat = support::orthotropic_material(50.0, 20.0, 5.0, 0.3, 0.1);
    const Scene scene = animated_scene(m, mat, script({{0.0, 1.0}, {1.0, 1.2}}), 7);
    Ortho model(scene, {});
    State s = support::make_state(scene, support::stack(m.V));
    const Eigen::VectorXd M = s.mass.replicate(1, 3).transpose().reshaped();  // per coordinate
    auto area = [&](const Eigen::VectorXd& x) {
      double a = 0;
      for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
        const Eigen::Vector3d p = x.segment<3>(3 * m.F(f, 0)), q = x.segment<3>(3 * m.F(f, 1)), r = x.segment<3>(3 * m.F(f, 2));
        a += 0.5 * (q - p).cross(r - p).norm();
      }
      return a;
    };
    const double A0 = area(s.x), dt = 0.05;
    std::vector<double> areas;
    for (int step = 0; step < 60; ++step) {
      const double t_end = (step + 1) * dt;
      model.begin_step(s, t_end);
      const Eigen::VectorXd xp = s.x + dt * s.v;
      Eigen::VectorXd x = s.x;
      auto objective = [&](const Eigen::VectorXd& y) {
        State t = s;
        t.x = y;
        return 0.5 / (dt * dt) * (y - xp).dot(M.cwiseProduct(y - xp)) + model.energy(t);
      };
      for (int it = 0; it < 30; ++it) {
        State t = s;
        t.x = x;
        const Eigen::VectorXd grad = M.cwiseProduct(x - xp) / (dt * dt) + support::gradient(model, t);
        if (grad.norm() <= 1e-10 * (1 + M.cwiseProduct(xp).norm() / (dt * dt))) break;
        Eigen::MatrixXd H = support::dense_hessian(model, t, HessianMode::projected);
        H.diagonal() += M / (dt * dt);
        const Eigen::VectorXd dx = -H.ldlt().solve(grad);
        double alpha = 1, f0 = objective(x);
        while (objective(x + alpha * dx) > f0 + 1e-4 * alpha * grad.dot(dx) && alpha > 1e-8) alpha *= 0.5;
        x += alpha * dx;
      }
      s.v = std::exp(-4.0 * dt) * (x - s.x) / dt;
      s.x = x;
      areas.push_back(area(s.x));
    }
    CAPTURE(areas[9]);
    CAPTURE(areas[19]);
    CAPTURE(areas.back());
    CHECK(areas[9] > 1.05 * A0);   // t = 0.5: rest lengths 10% longer, the cloth follows
    CHECK(areas[19] > areas[9]);   // t = 1: 20%
    CHECK(areas.back() == doctest::Approx(1.44 * A0).epsilon(0.01));  // settled at (1.2)^2
    // Every edge 20% longer at the end (up to the residual motion).
    for (const auto& e : scene.mesh.edges()) {
      const double l = (s.x.segment<3>(3 * e[0]) - s.x.segment<3>(3 * e[1])).norm();
      const double l0 = (m.V.row(e[0]) - m.V.row(e[1])).norm();
      CHECK(l / l0 == doctest::Approx(1.2).epsilon(0.01));
    }
  }
}

TEST_SUITE("models") {
  TEST_CASE("stvk_membrane: a scene file's orthotropic material and rest_state reach the model") {
    const Json doc = Json::parse(R"({
      "cloths": [{"mesh": {"source": "rectangle", "resolution": [4, 3], "size": [1.5, 1.0], "plane": "xz"},
                  "material": {"model": "orthotropic", "youngs_modulus_warp": 2.0, "youngs_modulus_weft": 0.5,
                               "shear_modulus": 0.3, "poisson_ratio": 0.4, "thickness": 0.1, "warp_angle": "20 deg"},
                  "rest_state": {"keyframes": [{"time": 0, "scale": 1}, {"time": 1, "scale": 1.1}]}}],
      "time": {"dt": 0.01, "duration": 0.1, "frame_rate": 25}
    })");
    const Scene scene = build_scene(doc, ".", "test.json");
    // StvkMembrane<Isotropic> refuses it, naming the key.
    CHECK_THROWS_WITH_AS(Iso(scene, {}), doctest::Contains("cloths.0.material.model = orthotropic"), ConfigError);
    Ortho model(scene, {});
    CHECK(model.animated());
    // Same T as a model built in code with the warp at 20 degrees from x in the xz plane.
    const double a = 20 * M_PI / 180;
    MeshData m{scene.mesh.rest(), scene.mesh.faces()};
    Ortho ref(support::make_scene(m, scene.spec.cloths[0].material, support::projected_warps(m, {std::cos(a), 0, std::sin(a)})), {});
    for (int f = 0; f < model.num_elements(); ++f) {
      CAPTURE(f);
      CHECK((model.element(f).T - ref.element(f).T).norm() <= 1e-13 * ref.element(f).T.norm());
    }
    // EnergySum forwards begin_step: at t = 1 the membrane is stress-free at 1.1 x.
    models::EnergySum<Ortho> sum(scene, {});
    State s = support::make_state(scene, 1.1 * support::stack(m.V));
    const double W = sum.energy(s);
    REQUIRE(W > 0);
    sum.begin_step(s, 1.0);
    CHECK(std::abs(sum.energy(s)) <= 1e-14 * W);
  }
}
