#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <string>

#include "framework/params_json.hpp"
#include "models/energy_sum.hpp"
#include "models/gravity.hpp"
#include "models/hinge_bending.hpp"
#include "models/stvk_membrane.hpp"
#include "tests/support/fd.hpp"
#include "tests/support/model_fixtures.hpp"

namespace {

using namespace weft;
using namespace weft::models;
using support::MeshData;
using Cloth = EnergySum<StvkMembrane<Isotropic>, HingeBending<ThetaEnergy>, Gravity>;

/// A scene with a non-default gravity and density, so every term is O(1).
Scene scene_for(const MeshData& m) {
  ShellMaterial mat = support::unit_material();
  mat.density = 0.7;
  Scene s = support::make_scene(m, mat);
  s.spec.gravity = Eigen::Vector3d(0.3, -0.5, -2.0);
  return s;
}

}  // namespace

TEST_SUITE("models") {
  TEST_CASE("gravity: potential and gradient of the lumped masses") {
    const MeshData m = support::random_patch(41, /*curved=*/true);
    const Scene scene = scene_for(m);
    const Gravity gravity(scene, {});
    const Eigen::VectorXd mass = support::reference_masses(scene);
    REQUIRE(mass.minCoeff() > 0);
    CHECK((gravity.masses() - mass).norm() <= 1e-14 * mass.norm());
    const State s = support::make_state(scene, support::perturb(support::stack(m.V), 0.3, 42));
    double V = 0;
    for (int i = 0; i < s.num_vertices(); ++i) V -= mass[i] * scene.spec.gravity.dot(s.x.segment<3>(3 * i));
    REQUIRE(std::abs(V) > 0);
    CHECK(std::abs(gravity.energy(s) - V) <= 1e-14 * std::abs(V));
    const Eigen::VectorXd g = support::gradient(gravity, s);
    for (int i = 0; i < s.num_vertices(); ++i) {
      CAPTURE(i);
      CHECK((g.segment<3>(3 * i) + mass[i] * scene.spec.gravity).norm() <= 1e-15 * mass[i] * scene.spec.gravity.norm());
    }
    const Eigen::VectorXd g_fd = support::fd_gradient(gravity, s, support::fd_step(scene.mesh));
    REQUIRE(g.norm() > 0);
    CHECK(support::relative_error(g, g_fd) <= 1e-6);
    EnergyTerms terms;
    gravity.energy_terms(s, terms);
    REQUIRE(terms.size() == 1);
    CHECK(terms[0].first == "gravity");
    CHECK(terms[0].second == doctest::Approx(V).epsilon(1e-14));
  }

  TEST_CASE("gravity: no Hessian and no stencil") {
    const MeshData m = support::random_patch(43, /*curved=*/false);
    const Scene scene = scene_for(m);
    Gravity gravity(scene, {});
    AssemblyPlan plan;
    gravity.declare(plan);
    CHECK(plan.num_groups() == 0);
    const State s = support::rest_state(scene);
    CHECK(support::dense_hessian(gravity, s, HessianMode::exact).norm() <= 0.0);
    CHECK(support::fd_hessian(gravity, s, support::fd_step(scene.mesh)).norm() <= 1e-12);
    CHECK(gravity.admissible(s));
  }

  TEST_CASE("energy_sum: energy and terms are the sums of its terms'") {
    const MeshData m = support::random_patch(44, /*curved=*/true);
    const Scene scene = scene_for(m);
    const Cloth cloth(scene, {});
    const State s = support::make_state(scene, support::perturb(support::stack(m.V), 0.2, 45));
    const double wm = cloth.term<0>().energy(s), wb = cloth.term<1>().energy(s), wg = cloth.term<2>().energy(s);
    REQUIRE(wm > 0);
    REQUIRE(wb > 0);
    REQUIRE(std::abs(wg) > 0);
    CHECK(std::abs(cloth.energy(s) - (wm + wb + wg)) <= 1e-15 * (wm + wb + std::abs(wg)));
    EnergyTerms terms;
    cloth.energy_terms(s, terms);
    REQUIRE(terms.size() == 3);
    CHECK(terms[0].first == "membrane");
    CHECK(terms[1].first == "bending");
    CHECK(terms[2].first == "gravity");
    CHECK(terms[0].second == doctest::Approx(wm).epsilon(1e-15));
    CHECK(terms[1].second == doctest::Approx(wb).epsilon(1e-15));
    CHECK(terms[2].second == doctest::Approx(wg).epsilon(1e-15));
    const Eigen::VectorXd g = support::gradient(cloth, s);
    const Eigen::VectorXd g_sum = support::gradient(cloth.term<0>(), s) + support::gradient(cloth.term<1>(), s) +
                                  support::gradient(cloth.term<2>(), s);
    REQUIRE(g.norm() > 0);
    CHECK((g - g_sum).norm() <= 1e-14 * g.norm());
  }

  TEST_CASE("energy_sum: gradient and Hessian match central differences") {
    for (bool curved : {false, true}) {
      CAPTURE(curved);
      const MeshData m = support::random_patch(46 + curved, curved);
      const Scene scene = scene_for(m);
      Cloth cloth(scene, {});
      const State s = support::make_state(scene, support::perturb(support::stack(m.V), 0.2, 48 + curved));
      const double h = support::fd_step(scene.mesh);
      const Eigen::VectorXd g = support::gradient(cloth, s);
      REQUIRE(g.norm() > 0);
      CHECK(support::relative_error(g, support::fd_gradient(cloth, s, h)) <= 1e-6);
      const BlockCsr H = support::assembled_hessian(cloth, s, HessianMode::exact);
      const Eigen::MatrixXd Hd = H.to_dense();
      REQUIRE(Hd.norm() > 0);
      CHECK(support::relative_error(Hd, support::fd_hessian(cloth, s, h)) <= 1e-6);
      CHECK(H.asymmetry() <= 1e-14);
      // The assembled sum is the sum of the terms' assembled Hessians.
      auto membrane = cloth.term<0>();
      auto bending = cloth.term<1>();
      const Eigen::MatrixXd H_terms =
          support::dense_hessian(membrane, s, HessianMode::exact) + support::dense_hessian(bending, s, HessianMode::exact);
      CHECK((Hd - H_terms).norm() <= 1e-14 * Hd.norm());
    }
  }

  TEST_CASE("energy_sum: admissible only if every term is") {
    const MeshData rest = support::known_hinge(0.2);
    const Scene scene = scene_for(rest);
    const Cloth cloth(scene, {});
    State s = support::rest_state(scene);
    CHECK(cloth.admissible(s));
    s.x.segment<3>(0) = Eigen::Vector3d(0.5, 0, 0);  // wing on the hinge line
    CHECK_FALSE(cloth.term<1>().admissible(s));
    CHECK(cloth.term<0>().admissible(s));
    CHECK_FALSE(cloth.admissible(s));
    CHECK(cloth.energy(s) == std::numeric_limits<double>::infinity());
  }

  TEST_CASE("energy_sum: params have one section per term named after the term") {
    Json doc = Json::parse(R"({"hinge_bending": {"altitude_tolerance": 1e-6}, "stvk_membrane": {}})");
    const auto prm = read_params<Cloth::Params>(doc, "energy", "Invalid energy parameters:");
    CHECK(std::get<1>(prm.terms).altitude_tolerance == doctest::Approx(1e-6));
    CHECK(std::get<1>(prm.terms).edge_tolerance == doctest::Approx(1e-9));
    const Json out = write_params(prm);
    CHECK(out.contains("stvk_membrane"));
    CHECK(out.contains("hinge_bending"));
    CHECK(out.contains("gravity"));
    CHECK(out["hinge_bending"]["altitude_tolerance"].get<double>() == doctest::Approx(1e-6));
    Json bad = Json::parse(R"({"hinge_bending": {"altitude_tol": 1e-6}, "bogus": {}})");
    CHECK_THROWS_AS(read_params<Cloth::Params>(bad, "energy", "Invalid energy parameters:"), ConfigError);
    CHECK_THROWS_WITH(read_params<Cloth::Params>(bad, "energy", "Invalid energy parameters:"),
                      doctest::Contains("energy.hinge_bending.altitude_tol"));
    CHECK_THROWS_WITH(read_params<Cloth::Params>(bad, "energy", "Invalid energy parameters:"), doctest::Contains("bogus"));
    // Cross-field validation is forwarded to the terms.
    Cloth::Params out_of_range;
    CHECK(Cloth::validate(out_of_range).ok());
    std::get<1>(out_of_range.terms).edge_tolerance = 2;
    const Checker c = Cloth::validate(out_of_range);
    REQUIRE_FALSE(c.ok());
    CHECK(c.violations().at(0).find("edge_tolerance") != std::string::npos);
  }
}
