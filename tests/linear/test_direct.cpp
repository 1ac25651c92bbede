#include <doctest/doctest.h>

#include <Eigen/Dense>

#include "framework/mesh_generators.hpp"
#include "framework/triangle_mesh.hpp"
#include "linear/direct.hpp"

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
}
