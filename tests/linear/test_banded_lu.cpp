#include <doctest/doctest.h>

#include <Eigen/Dense>

#include <filesystem>
#include <random>

#include "framework/band_matrix.hpp"
#include "linear/banded_lu.hpp"
#include "linear/lapack_info.hpp"

using namespace weft;

namespace {

constexpr int kBand = 10;  // half-bandwidth of a discrete elastic rod Hessian

/// A matrix of discrete-elastic-rod structure (methods/rod-contact §13, V-03): n = 4V - 1 interleaved
/// DoFs, one random symmetric 11 x 11 block per interior vertex i at DoF 4(i - 1) (the
/// stencil x_{i-1}, theta_{i-1}, x_i, theta_i, x_{i+1}), plus `shift` on the diagonal.
/// spd: every block is B B^T (PSD); otherwise each block is symmetric with random signs.
BandMatrix rod_structured(int V, bool spd, double shift, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int n = 4 * V - 1;
  BandMatrix A(n, kBand);
  for (int i = 1; i + 1 < V; ++i) {
    Eigen::Matrix<double, 11, 11> R;
    for (int a = 0; a < 11; ++a)
      for (int b = 0; b < 11; ++b) R(a, b) = u(rng);
    const Eigen::Matrix<double, 11, 11> S = spd ? Eigen::Matrix<double, 11, 11>(R * R.transpose() / 11.0)
                                                : Eigen::Matrix<double, 11, 11>(R + R.transpose());
    const int o = 4 * (i - 1);
    for (int a = 0; a < 11; ++a)
      for (int b = 0; b < 11; ++b) A(o + a, o + b) += S(a, b);
  }
  for (int i = 0; i < n; ++i) A(i, i) += shift;
  return A;
}

Eigen::MatrixXd random_rhs(int n, int m, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixXd B(n, m);
  for (int j = 0; j < m; ++j)
    for (int i = 0; i < n; ++i) B(i, j) = u(rng);
  return B;
}

}  // namespace

TEST_SUITE("linear") {
  TEST_CASE("band matrix: entries outside the band are zero and multiply matches dense") {
    const BandMatrix A = rod_structured(30, false, 0.0, 3);
    const Eigen::MatrixXd D = A.dense();
    REQUIRE(D.rows() == 119);
    REQUIRE(A.ldab() == 31);
    double outside = 0;
    for (int i = 0; i < D.rows(); ++i)
      for (int j = 0; j < D.cols(); ++j)
        if (std::abs(i - j) > kBand) outside = std::max(outside, std::abs(D(i, j)));
    CHECK(outside == 0.0);
    REQUIRE(D.norm() > 0);
    // The layout is LAPACK's: A(i, j) at ab[(2k + i - j) + j ldab].
    CHECK(A.data()[(2 * kBand + 5 - 3) + 3 * A.ldab()] == D(5, 3));
    CHECK(A(0, 50) == 0.0);
    const Eigen::VectorXd x = random_rhs(119, 1, 4).col(0);
    Eigen::VectorXd y;
    A.multiply(x, y);
    CHECK((y - D * x).norm() <= 1e-14 * (D * x).norm());
  }

  TEST_CASE("banded lu: SPD and indefinite rod-structured matrices solve like a dense LU") {
    for (bool spd : {true, false}) {
      for (unsigned seed : {11u, 12u, 13u}) {
        CAPTURE(spd);
        CAPTURE(seed);
        // SPD: a small shift keeps it definite. Indefinite: no shift, random signs.
        const BandMatrix A = rod_structured(30, spd, spd ? 1e-2 : 0.0, seed);
        const Eigen::MatrixXd D = A.dense();
        const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(D).eigenvalues();
        if (spd) {
          REQUIRE(ev.minCoeff() > 0);
        } else {
          REQUIRE(ev.minCoeff() < 0);  // genuinely indefinite
          REQUIRE(ev.maxCoeff() > 0);
        }
        const double cond = ev.cwiseAbs().maxCoeff() / ev.cwiseAbs().minCoeff();
        CAPTURE(cond);
        REQUIRE(cond < 1e6);  // so a 1e-10 agreement of two backward-stable solvers is meaningful
        linear::BandedLu lu;
        REQUIRE(lu.factorize(A) == Status::success);
        CHECK(lu.size() == 119);
        const Eigen::MatrixXd B = random_rhs(119, 3, seed + 100);
        Eigen::MatrixXd X = B;
        lu.solve(X);
        const Eigen::MatrixXd Xd = D.partialPivLu().solve(B);
        CHECK((X - Xd).norm() <= 1e-10 * Xd.norm());
        CHECK((D * X - B).norm() <= 1e-12 * D.norm() * X.norm());
        // Solving one column through a block of a larger matrix (a strided Ref).
        Eigen::MatrixXd big = Eigen::MatrixXd::Zero(130, 2);
        big.block(5, 1, 119, 1) = B.col(0);
        lu.solve(big.block(5, 1, 119, 1));
        CHECK((big.block(5, 1, 119, 1) - Xd.col(0)).norm() <= 1e-10 * Xd.col(0).norm());
      }
    }
  }

  TEST_CASE("banded lu: a singular matrix returns a failing status that names the zero pivot") {
    BandMatrix A = rod_structured(30, true, 1e-2, 21);
    const int dead = 37;  // zero row and column: the pivot search finds nothing in column 37
    for (int j = 0; j < A.rows(); ++j)
      if (A.in_band(dead, j)) A(dead, j) = A(j, dead) = 0.0;
    linear::BandedLu lu;
    const Status s = lu.factorize(A);
    CHECK(s == Status::numerical_issue);
    CHECK_FALSE(lu.factorized());
    CHECK(lu.message().find("singular") != std::string::npos);
    CHECK(lu.message().find("37") != std::string::npos);
    // A later nonsingular factorisation succeeds and clears the message.
    REQUIRE(lu.factorize(rod_structured(30, true, 1e-2, 22)) == Status::success);
    CHECK(lu.message().empty());
  }

  TEST_CASE("banded lu: the LAPACK library it runs on is named by a path that exists") {
    // Recorded in every run's summary.json and bench header: reference LAPACK and OpenBLAS
    // round differently, and a chaotic run follows whichever liblapack.so.3 points to.
    const std::string lib = linear::lapack_library();
    MESSAGE("LAPACK: " << lib);
    CHECK(lib != "unknown");
    CHECK(std::filesystem::exists(lib));
    CHECK(lib.find("lapack") != std::string::npos);
  }
}
