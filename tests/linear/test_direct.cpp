#include <doctest/doctest.h>

#include <Eigen/Dense>

#include "framework/mesh_generators.hpp"
#include "framework/triangle_mesh.hpp"
#include "linear/direct.hpp"
#include "tests/support/linear_fixtures.hpp"

using namespace weft;

namespace {
// SPD block "Laplacian + mass" on a sheet's edge graph: K = M + k sum_e (I3 per edge).
BlockCsr block_laplacian(const TriangleMesh& m, double k, double mass) {
  std::vector<std::vector<int>> cols(m.num_vertices());
  for (const auto& e : m.edges()) cols[e[0]].push_back(e[1]), cols[e[1]].push_back(e[0]);
  BlockCsr A(cols);
  for (const auto& e : m.edges()) {
    A.block(A.diagonal(e[0])) += k * Block3::Identity();
    A.block(A.diagonal(e[1])) += k * Block3::Identity();
    A.block(A.find(e[0], e[1])) -= k * Block3::Identity();
    A.block(A.find(e[1], e[0])) -= k * Block3::Identity();
  }
  A.add_diagonal(Eigen::VectorXd::Constant(A.rows(), mass));
  return A;
}

}  // namespace

TEST_SUITE("linear") {
  TEST_CASE("direct: solves an SPD block Laplacian to round-off - the pattern analysis is reused") {
    const auto g = make_rectangle({1, 1}, {12, 9}, Tessellation::irregular, 2);
    const TriangleMesh mesh(g.V, g.F);
    BlockCsr A = block_laplacian(mesh, 100.0, 1e-3);
    linear::Direct solver({});
    REQUIRE(solver.analyze_pattern(A) == Status::success);
    for (double k : {100.0, 1e4}) {  // new values, same pattern: factorize only
      CAPTURE(k);
      A = block_laplacian(mesh, k, 1e-3);
      REQUIRE(solver.factorize(A) == Status::success);
      const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(A.rows(), -1.0, 1.0);
      Eigen::VectorXd x = Eigen::VectorXd::Zero(A.rows());
      const LinearReport r = solver.solve(b, x);
      CHECK(r.status == Status::success);
      CHECK(r.negative_pivots == 0);
      const Eigen::VectorXd ref = Eigen::MatrixXd(A.to_dense()).ldlt().solve(b);
      REQUIRE(ref.norm() > 0);
      CHECK((x - ref).norm() <= 1e-9 * ref.norm());
      CHECK(r.relative_residual <= 1e-9);  // backward stable at condition number ~1e7
    }
  }

  TEST_CASE("direct: reports negative pivots of an indefinite matrix and fails on a singular one") {
    const auto g = make_rectangle({1, 1}, {4, 4}, Tessellation::regular, 1);
    const TriangleMesh mesh(g.V, g.F);
    BlockCsr A = block_laplacian(mesh, 1.0, -0.01);  // shifted below zero: indefinite
    linear::Direct solver({});
    REQUIRE(solver.analyze_pattern(A) == Status::success);
    REQUIRE(solver.factorize(A) == Status::success);
    Eigen::VectorXd x, b = Eigen::VectorXd::Ones(A.rows());
    CHECK(solver.solve(b, x).negative_pivots >= 3);
    A = block_laplacian(mesh, 1.0, 0.0);  // pure Laplacian: singular (translations)
    CHECK(solver.factorize(A) != Status::success);
    CHECK(solver.solve(b, x).status == Status::numerical_issue);
  }

  TEST_CASE("direct: with constraints it matches the KKT solution and keeps the analysis across contact changes") {
    const support::ClothSystem sys = support::cloth_system(9, Tessellation::irregular, support::Pins::two_sides);
    linear::Direct solver({});
    ConstraintSet c = sys.pins;
    solver.set_context({&c, &sys.x});
    REQUIRE(solver.analyze_pattern(sys.A) == Status::success);  // once: the pattern of Ahat is A's
    support::Rng rng(9);
    for (int round = 0; round < 3; ++round) {
      CAPTURE(round);
      // A changing contact set: 1 or 2 directions on a few free vertices.
      c = sys.pins;
      for (int i = round; i < c.num_vertices(); i += 6)
        if (c.count(i) == 0)
          for (int k = 0; k <= (i + round) % 2; ++k) c.add_direction(i, rng.vec3(), 1e-3 * rng.uniform(-1, 1));
      REQUIRE(c.constrained_vertices() > sys.pins.constrained_vertices());
      REQUIRE(solver.factorize(sys.A) == Status::success);
      Eigen::VectorXd x;
      const LinearReport r = solver.solve(sys.b, x);
      CHECK(r.status == Status::success);
      CHECK(r.negative_pivots == 0);
      const Eigen::VectorXd ref = support::dense_kkt_solve(sys.A, sys.b, c);
      REQUIRE(ref.norm() > 0);
      CHECK((x - ref).norm() <= 1e-9 * ref.norm());
      CHECK(r.constraint_violation == c.violation(x));
      CHECK(r.constraint_violation <= 1e-14 * c.target().cwiseAbs().maxCoeff());
      CHECK(r.relative_residual <= 1e-10);  // ||S (b - A x)|| / ||S b||
      CHECK(r.memory_bytes > sizeof(double) * static_cast<std::size_t>(sys.A.rows()));
      CHECK(r.prefilter_seconds > 0);
    }
    // Without constraints (an empty set) it solves A x = b itself.
    const ConstraintSet none(sys.A.block_rows());
    solver.set_context({&none, nullptr});
    REQUIRE(solver.factorize(sys.A) == Status::success);
    Eigen::VectorXd x;
    const LinearReport r = solver.solve(sys.b, x);
    const Eigen::VectorXd ref = sys.A.to_dense().llt().solve(sys.b);
    CHECK((x - ref).norm() <= 1e-9 * ref.norm());
    CHECK(r.constraint_violation == 0.0);
    CHECK(r.prefilter_seconds == 0.0);
  }

  TEST_CASE("direct: a constraint set of the wrong size is refused") {
    const support::ClothSystem sys = support::cloth_system(5, Tessellation::regular, support::Pins::boundary);
    ConstraintSet c(3);
    c.fix(0, Eigen::Vector3d::Zero());
    linear::Direct solver({});
    solver.set_context({&c, nullptr});
    REQUIRE(solver.analyze_pattern(sys.A) == Status::success);
    CHECK(solver.factorize(sys.A) == Status::invalid_input);
    Eigen::VectorXd x;
    CHECK(solver.solve(sys.b, x).status != Status::success);
  }
}
