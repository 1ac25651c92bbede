#include <doctest/doctest.h>

#include <Eigen/Dense>

#include "linear/backends/cholmod_direct.hpp"
#include "tests/support/linear_fixtures.hpp"

using namespace weft;
using support::Pins;

TEST_SUITE("backends") {
  TEST_CASE("cholmod: solves SPD block Laplacians to round-off - the analysis is reused") {
    BlockCsr A = support::block_laplacian(14, 1e-3);
    linear::CholmodDirect solver({});
    REQUIRE(solver.analyze_pattern(A) == Status::success);
    CHECK(solver.factor_nonzeros() > 0);
    for (double shift : {1e-3, 10.0}) {  // new values, same pattern: factorize only
      CAPTURE(shift);
      A = support::block_laplacian(14, shift);
      REQUIRE(solver.factorize(A) == Status::success);
      const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(A.rows(), -1.0, 1.0);
      Eigen::VectorXd x = Eigen::VectorXd::Zero(A.rows());
      const LinearReport r = solver.solve(b, x);
      REQUIRE(r.status == Status::success);
      const Eigen::VectorXd ref = Eigen::MatrixXd(A.to_dense()).llt().solve(b);
      CHECK((x - ref).norm() <= 1e-9 * ref.norm());
      CHECK(r.relative_residual <= 1e-12);
      CHECK(r.memory_bytes > 0);
      CHECK(r.setup_seconds > 0);
    }
    MESSAGE("CHOLMOD ordering: " << solver.ordering() << "; BLAS: " << linear::CholmodDirect::blas_library());
  }

  TEST_CASE("cholmod: pinned cloth systems match a dense KKT solve") {
    for (auto [m, t, pins] : {std::tuple{11, Tessellation::regular, Pins::boundary},
                              std::tuple{12, Tessellation::irregular, Pins::two_sides},
                              std::tuple{11, Tessellation::regular, Pins::reentrant}}) {
      CAPTURE(m);
      CAPTURE(static_cast<int>(pins));
      const auto sys = support::cloth_system(m, t, pins);
      REQUIRE(!sys.pins.empty());
      linear::CholmodDirect solver({});
      solver.set_context({&sys.pins, &sys.x});
      REQUIRE(solver.analyze_pattern(sys.A) == Status::success);
      REQUIRE(solver.factorize(sys.A) == Status::success);
      Eigen::VectorXd x;
      const LinearReport r = solver.solve(sys.b, x);
      REQUIRE(r.status == Status::success);
      const Eigen::VectorXd ref = support::dense_kkt_solve(sys.A, sys.b, sys.pins);
      CHECK((x - ref).norm() <= 1e-9 * ref.norm());
      CHECK(r.constraint_violation <= 1e-14);
      CHECK(r.relative_residual <= 1e-10);
    }
  }

  TEST_CASE("cholmod: a new constraint set needs no new analysis") {
    const auto boundary = support::cloth_system(9, Tessellation::regular, Pins::boundary);
    const auto sides = support::cloth_system(9, Tessellation::regular, Pins::two_sides);
    linear::CholmodDirect solver({});
    REQUIRE(solver.analyze_pattern(boundary.A) == Status::success);
    for (const auto* sys : {&boundary, &sides}) {
      solver.set_context({&sys->pins, &sys->x});
      REQUIRE(solver.factorize(sys->A) == Status::success);
      Eigen::VectorXd x;
      REQUIRE(solver.solve(sys->b, x).status == Status::success);
      const Eigen::VectorXd ref = support::dense_kkt_solve(sys->A, sys->b, sys->pins);
      CHECK((x - ref).norm() <= 1e-9 * ref.norm());
    }
  }

  TEST_CASE("cholmod: singular and indefinite matrices fail with a clear status") {
    linear::CholmodDirect solver({});
    BlockCsr A = support::block_laplacian(8, 0.0);  // translations in the kernel
    REQUIRE(solver.analyze_pattern(A) == Status::success);
    Eigen::VectorXd x, b = Eigen::VectorXd::Ones(A.rows());
    CHECK(solver.factorize(A) == Status::numerical_issue);
    LinearReport r = solver.solve(b, x);
    CHECK(r.status == Status::numerical_issue);
    CHECK(!r.message.empty());
    MESSAGE(r.message);
    A = support::block_laplacian(8, -0.5);  // shifted below zero: indefinite
    CHECK(solver.factorize(A) == Status::numerical_issue);
    r = solver.solve(b, x);
    CHECK(r.status == Status::numerical_issue);
    CHECK(r.indefinite);
    CHECK(r.message.find("column") != std::string::npos);
    MESSAGE(r.message);
    A = support::block_laplacian(8, 1.0);  // and it recovers on an SPD matrix
    CHECK(solver.factorize(A) == Status::success);
    CHECK(solver.solve(b, x).status == Status::success);
  }
}
