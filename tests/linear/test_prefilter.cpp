// Prefiltering (methods/multigrid §7.3, checklist V1-V2): filter algebra and the prefiltered matrix.
#include <doctest/doctest.h>

#include <Eigen/Eigenvalues>

#include "linear/prefilter.hpp"
#include "tests/support/linear_fixtures.hpp"

using namespace weft;

TEST_CASE("filters are orthogonal projectors with trace 3 - k") {
  support::Rng rng(3);
  ConstraintSet c(200);
  for (int i = 0; i < 200; ++i) {
    const int k = i % 4;
    for (int m = 0; m < k; ++m) c.add_direction(i, rng.vec3(), rng.uniform(-1, 1));
  }
  int seen[4] = {0, 0, 0, 0};
  for (int i = 0; i < 200; ++i) {
    const Block3 S = c.filter(i);
    ++seen[c.count(i)];
    CHECK(c.count(i) == i % 4);
    CHECK((S * S - S).norm() <= 4e-15);
    CHECK((S - S.transpose()).norm() == 0.0);
    CHECK(std::abs(S.trace() - (3 - c.count(i))) <= 1e-14);
    const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(S).eigenvalues();
    for (int k = 0; k < 3; ++k) CHECK(std::min(std::abs(ev[k]), std::abs(ev[k] - 1)) <= 1e-14);
  }
  for (int k = 0; k < 4; ++k) CHECK(seen[k] == 50);
  CHECK(c.constrained_vertices() == 150);
}

TEST_CASE("constraint targets satisfy the prescribed values along the given directions") {
  ConstraintSet c(1);
  const Eigen::Vector3d n1(1, 1, 0), n2(1, 0, 1);
  CHECK(c.add_direction(0, n1, 0.3));
  CHECK(c.add_direction(0, n2, -0.2));
  CHECK_FALSE(c.add_direction(0, n1 + 2 * n2, 0.0));  // in the span: refused
  const Eigen::Vector3d z = c.target().segment<3>(0);
  CHECK(std::abs(n1.dot(z) - 0.3) <= 1e-15);
  CHECK(std::abs(n2.dot(z) + 0.2) <= 1e-15);
  CHECK(c.violation(c.target()) <= 1e-16);
  Eigen::VectorXd off = c.target();
  off[0] += 1e-3;
  CHECK(c.violation(off) > 1e-4);
}

TEST_CASE("the prefiltered cloth matrix keeps the pattern and symmetry and is positive definite") {
  support::ClothSystem sys = support::cloth_system(9, Tessellation::regular, support::Pins::two_sides);
  REQUIRE(sys.pins.constrained_vertices() == 18);
  BlockCsr Ahat = sys.A;
  linear::prefilter_matrix(sys.A, sys.pins, Ahat);
  CHECK(Ahat.col() == sys.A.col());
  CHECK(Ahat.asymmetry() <= 1e-15);
  const Eigen::MatrixXd D = Ahat.to_dense(), D0 = sys.A.to_dense();
  Eigen::LLT<Eigen::MatrixXd> llt(D);
  CHECK(llt.info() == Eigen::Success);
  // kappa(Ahat) <= kappa(A) with Sigma = tr(A_ii)/3 inside A's spectrum (V2).
  const Eigen::VectorXd e = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(D).eigenvalues();
  const Eigen::VectorXd e0 = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(D0).eigenvalues();
  REQUIRE(e0[0] > 0);
  CHECK(e.maxCoeff() / e.minCoeff() <= e0.maxCoeff() / e0.minCoeff() * (1 + 1e-12));
  // A Sigma far outside A's spectrum (1e3 here, where A's entries are ~1e-2) degrades kappa.
  BlockCsr Aunit = sys.A;
  linear::prefilter_matrix(sys.A, sys.pins, Aunit);
  for (int i = 0; i < Aunit.block_rows(); ++i)
    if (sys.pins.count(i) == 3) Aunit.block(Aunit.diagonal(i)) = 1e3 * Block3::Identity();
  const Eigen::VectorXd eu = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Aunit.to_dense()).eigenvalues();
  CHECK(eu.maxCoeff() / eu.minCoeff() > 10 * e0.maxCoeff() / e0.minCoeff());
  CHECK(e0.maxCoeff() < 1e2);
  // The pinned rows are decoupled: Ahat_ij = 0 for a pinned i and j != i.
  for (int i = 0; i < Ahat.block_rows(); ++i)
    if (sys.pins.count(i) == 3)
      for (int k = Ahat.row_ptr()[i]; k < Ahat.row_ptr()[i + 1]; ++k)
        if (Ahat.col()[k] != i) CHECK(Ahat.block(k).norm() == 0.0);
}

TEST_CASE("prefiltered right-hand side and final projection meet the constraints exactly") {
  support::ClothSystem sys = support::cloth_system(7, Tessellation::irregular, support::Pins::boundary);
  BlockCsr Ahat = sys.A;
  linear::prefilter_matrix(sys.A, sys.pins, Ahat);
  Eigen::VectorXd c;
  linear::prefilter_rhs(sys.A, sys.pins, sys.b, c);
  const Eigen::VectorXd y = Ahat.to_dense().llt().solve(c);
  Eigen::VectorXd x;
  linear::unfilter_solution(sys.pins, y, x);
  CHECK(sys.pins.violation(x) <= 1e-14 * sys.pins.target().cwiseAbs().maxCoeff());
  // S (b - A x) = 0: the free residual vanishes.
  Eigen::VectorXd Ax;
  sys.A.multiply(x, Ax);
  Eigen::VectorXd r = sys.b - Ax;
  sys.pins.filter(r);
  CHECK(r.norm() <= 1e-10 * sys.b.norm());
  CHECK(sys.b.norm() > 0);
}

TEST_CASE("a matrix whose fixed rows are already decoupled is used as is without a copy") {
  support::ClothSystem sys = support::cloth_system(21);
  // The same pins with zero increments (as the simulator's fixed rows), as full constraints.
  ConstraintSet pins(sys.A.block_rows());
  std::vector<unsigned char> fixed(sys.A.block_rows(), 0);
  for (int i = 0; i < sys.A.block_rows(); ++i)
    if (sys.pins.count(i) == 3) {
      pins.fix(i, Eigen::Vector3d::Zero());
      fixed[i] = 1;
    }
  REQUIRE(pins.constrained_vertices() > 0);
  CHECK_FALSE(linear::already_prefiltered(sys.A, pins));  // couplings still there
  BlockCsr F = sys.A;
  F.filter_rows(fixed, -1.0);
  CHECK(linear::already_prefiltered(F, pins));
  // Exactly what prefiltering would produce: the shortcut changes nothing but the copy.
  BlockCsr Ahat = sys.A;
  linear::prefilter_matrix(sys.A, pins, Ahat);
  CHECK(Ahat.values() == F.values());
  linear::PrefilteredSystem pre;
  pre.set_context(SolveContext{&pins, &sys.x});
  CHECK(&pre.matrix(F) == &F);
  CHECK(&pre.matrix(sys.A) != &sys.A);
  // A partial constraint (a contact normal) needs the copy.
  ConstraintSet contact = pins;
  const int free_vertex = sys.A.block_rows() / 2;
  REQUIRE(contact.count(free_vertex) == 0);
  contact.add_direction(free_vertex, Eigen::Vector3d::UnitZ(), 0.0);
  CHECK_FALSE(linear::already_prefiltered(F, contact));
  // A fixed row whose diagonal is not a multiple of the identity is not prefiltered.
  BlockCsr G = F;
  int fixed_vertex = 0;
  while (!fixed[fixed_vertex]) ++fixed_vertex;
  G.block(G.diagonal(fixed_vertex))(0, 0) *= 2;
  CHECK_FALSE(linear::already_prefiltered(G, pins));
}
