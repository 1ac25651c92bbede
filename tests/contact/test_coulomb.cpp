// The single-contact Coulomb solver (contact/coulomb.hpp, methods/rod-contact §9, V-04) and the
// Gauss-Seidel contact solve over it (contact/contact_gauss_seidel.hpp): the analytic
// cases, thousands of random SPD problems with each regime checked against its
// definition, anisotropic W, mu = 0, degenerate W; GS on random multi-contact problems
// with an explicit W and with the compliance applied (same answer).
#include <doctest/doctest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/QR>

#include <cmath>
#include <random>

#include "contact/contact_gauss_seidel.hpp"
#include "contact/coulomb.hpp"

using namespace weft::contact;
using Eigen::Matrix3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

namespace {

/// Random SPD 3x3 with eigenvalues log-uniform in [lo, hi].
Matrix3d random_spd(std::mt19937& rng, double lo, double hi) {
  std::normal_distribution<double> N(0, 1);
  std::uniform_real_distribution<double> U(std::log(lo), std::log(hi));
  Matrix3d G;
  for (int i = 0; i < 9; ++i) G(i) = N(rng);
  const Matrix3d Q = Eigen::HouseholderQR<Matrix3d>(G).householderQ();
  const Vector3d l(std::exp(U(rng)), std::exp(U(rng)), std::exp(U(rng)));
  return Q * l.asDiagonal() * Q.transpose();
}

/// The regime by its definition (methods/rod-contact §9.1), for an invertible W.
CoulombRegime expected_regime(const Matrix3d& W, const Vector3d& b, double mu) {
  if (b[0] >= 0) return CoulombRegime::take_off;
  const Vector3d r = W.fullPivLu().solve(-b);
  if (mu > 0 && r[0] > 0 && r.tail<2>().norm() <= mu * r[0]) return CoulombRegime::stick;
  return CoulombRegime::slide;
}

/// Checks Signorini-Coulomb at a result, with tolerance `eps` on velocities.
void check_laws(const CoulombResult& c, const Matrix3d& W, const Vector3d& b, double mu, double eps) {
  const Vector3d u = W * c.r + b;
  CHECK(c.r[0] >= -1e-14 * b.norm());
  CHECK(c.r.tail<2>().norm() <= mu * c.r[0] * (1 + 1e-9) + 1e-14 * b.norm());
  CHECK(u[0] >= -eps);
  const double s = coulomb_scale(W);
  CHECK(std::abs(s * c.r[0] * u[0]) <= 10 * eps * (s * c.r.norm() + b.norm()));  // complementarity
  if (c.regime == CoulombRegime::slide && mu > 0) {
    const Vector2d ut = u.tail<2>(), rt = c.r.tail<2>();
    CHECK(std::abs(u[0]) <= eps);
    CHECK(rt.norm() == doctest::Approx(mu * c.r[0]).epsilon(1e-8));
    if (ut.norm() > 1e-6 * b.norm()) CHECK(rt.dot(ut) / (rt.norm() * ut.norm()) <= -1 + 1e-6);  // anti-parallel
  }
  if (c.regime == CoulombRegime::stick) CHECK(u.norm() <= eps);
}

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("coulomb: the analytic cases of W = w I give take-off and stick and slide exactly (V-04)") {
    const double w = 2.5, mu = 0.4;
    // (i) take-off
    CoulombResult c = solve_coulomb(w * Matrix3d::Identity(), Vector3d(0.3, 1, -2), mu);
    CHECK(c.regime == CoulombRegime::take_off);
    CHECK(c.r.norm() == 0);
    CHECK(c.residual <= 1e-14);
    // (ii) stick: |b_t| <= mu |b_n|
    const Vector3d bs(-1, 0.2, -0.3);
    c = solve_coulomb(w * Matrix3d::Identity(), bs, mu);
    CHECK(c.regime == CoulombRegime::stick);
    CHECK((c.r + bs / w).norm() <= 1e-15);
    CHECK(c.u.norm() <= 1e-15);
    CHECK(c.residual <= 1e-14);
    // (iii) slide: alpha = -b_n / w, beta = -mu alpha b_t / |b_t|, u_t = b_t (1 - mu |b_n| / |b_t|)
    const Vector3d bl(-1, 0.6, -0.8);
    c = solve_coulomb(w * Matrix3d::Identity(), bl, mu);
    CHECK(c.regime == CoulombRegime::slide);
    const double alpha = 1 / w;
    CHECK(c.r[0] == doctest::Approx(alpha).epsilon(1e-12));
    CHECK((c.r.tail<2>() + mu * alpha * bl.tail<2>() / bl.tail<2>().norm()).norm() <= 1e-12);
    CHECK((c.u.tail<2>() - bl.tail<2>() * (1 - mu * 1.0 / bl.tail<2>().norm())).norm() <= 1e-12);
    CHECK(std::abs(c.u[0]) <= 1e-12);
    CHECK(c.residual <= 1e-12);
  }

  TEST_CASE("coulomb: 20000 random SPD problems are solved to the FB tolerance in the regime of their definition") {
    std::mt19937 rng(12345);
    std::normal_distribution<double> N(0, 1);
    std::uniform_real_distribution<double> U(0, 1);
    int counts[4] = {0, 0, 0, 0}, enumerative = 0, wrong = 0;
    double worst = 0;
    for (int t = 0; t < 20000; ++t) {
      const Matrix3d W = random_spd(rng, 1e-3, 1e3);  // condition <= 1e6
      const Vector3d b(N(rng), N(rng), N(rng));
      const double mu = t % 10 == 0 ? 0.0 : 2 * U(rng);
      const CoulombResult c = solve_coulomb(W, b, mu);
      CAPTURE(t);
      CAPTURE(mu);
      ++counts[static_cast<int>(c.regime)];
      enumerative += c.enumerative ? 1 : 0;
      // Relative to the problem's scale |b| + s |r| (the rounding floor of u = W r + b when
      // ill-conditioned W needs a large response).
      const double scale = b.norm() + coulomb_scale(W) * c.r.norm();
      const double rel = c.residual / scale;
      worst = std::max(worst, rel);
      CHECK(rel <= 1e-10);
      const CoulombRegime e = expected_regime(W, b, mu);
      if (c.regime != e) ++wrong;
      check_laws(c, W, b, mu, 1e-9 * scale);
      // lambda . u~ = 0 (De Saxce)
      const Vector3d u = W * c.r + b;
      const Vector3d ut(u[0] + mu * u.tail<2>().norm(), u[1], u[2]);
      CHECK(std::abs(c.r.dot(ut)) * coulomb_scale(W) <= 1e-8 * b.norm() * (b.norm() + coulomb_scale(W) * c.r.norm()));
    }
    MESSAGE("take-off " << counts[0] << ", stick " << counts[1] << ", slide " << counts[2] << ", failed " << counts[3]
                        << ", enumerative failsafe " << enumerative << ", worst relative FB residual " << worst);
    CHECK(wrong == 0);
    CHECK(counts[3] == 0);
    CHECK(counts[0] > 5000);  // every regime well represented
    CHECK(counts[1] > 1000);
    CHECK(counts[2] > 3000);
    CHECK(enumerative < 200);  // Newton settles nearly all slides
  }

  TEST_CASE("coulomb: with anisotropic W the slide direction is against the final sliding velocity and not against b_t") {
    Matrix3d W;
    W << 1.0, 0.1, 0.0,  //
        0.1, 1.0, 0.0,   //
        0.0, 0.0, 10.0;
    const Vector3d b(-1, 1, 1);
    const double mu = 0.3;
    const CoulombResult c = solve_coulomb(W, b, mu);
    REQUIRE(c.regime == CoulombRegime::slide);
    CHECK(c.residual <= 1e-12);
    check_laws(c, W, b, mu, 1e-11);
    const Vector2d rt = c.r.tail<2>(), bt = b.tail<2>();
    const double cos_b = -rt.dot(bt) / (rt.norm() * bt.norm());
    CHECK(cos_b < std::cos(5.0 * 3.141592653589793 / 180));  // more than 5 degrees off -b_t
    MESSAGE("angle between r_t and -b_t: " << std::acos(cos_b) * 180 / 3.141592653589793 << " degrees");
  }

  TEST_CASE("coulomb: mu = 0 is frictionless") {
    std::mt19937 rng(7);
    std::normal_distribution<double> N(0, 1);
    for (int t = 0; t < 200; ++t) {
      const Matrix3d W = random_spd(rng, 1e-2, 1e2);
      const Vector3d b(-std::abs(N(rng)), N(rng), N(rng));
      const CoulombResult c = solve_coulomb(W, b, 0.0);
      CHECK(c.regime == CoulombRegime::slide);
      CHECK(c.r.tail<2>().norm() == 0);
      CHECK(c.r[0] > 0);
      CHECK(std::abs((W * c.r + b)[0]) <= 1e-12 * b.norm());
      CHECK(c.residual <= 1e-12 * b.norm());
    }
  }

  TEST_CASE("coulomb: degenerate W") {
    SUBCASE("rank one: no tangential compliance, the contact slides against b_t") {
      const Matrix3d W = Vector3d(2, 0, 0).asDiagonal();
      const Vector3d b(-1, 0.3, -0.4);
      const CoulombResult c = solve_coulomb(W, b, 0.5);
      CHECK(c.regime == CoulombRegime::slide);
      CHECK(c.r[0] == doctest::Approx(0.5).epsilon(1e-12));
      CHECK((c.r.tail<2>() + 0.25 * b.tail<2>() / b.tail<2>().norm()).norm() <= 1e-12);
      CHECK(c.residual <= 1e-12);
    }
    SUBCASE("rank one with b_t = 0: stick (least-squares solution)") {
      const Matrix3d W = Vector3d(2, 0, 0).asDiagonal();
      const CoulombResult c = solve_coulomb(W, Vector3d(-1, 0, 0), 0.5);
      CHECK(c.regime != CoulombRegime::failed);
      CHECK(c.residual <= 1e-12);
      CHECK(c.r[0] == doctest::Approx(0.5));
    }
    SUBCASE("nearly singular (condition 1e12)") {
      std::mt19937 rng(3);
      std::normal_distribution<double> N(0, 1);
      int ok = 0;
      for (int t = 0; t < 500; ++t) {
        const Matrix3d W = random_spd(rng, 1e-6, 1e6);
        const Vector3d b(N(rng), N(rng), N(rng));
        const CoulombResult c = solve_coulomb(W, b, 1.0);
        if (c.regime != CoulombRegime::failed && c.residual <= 1e-8 * (b.norm() + coulomb_scale(W) * c.r.norm())) ++ok;
      }
      MESSAGE(ok << " of 500 solved to 1e-8 relative to |b| + s |r|");
      CHECK(ok >= 490);
    }
    SUBCASE("no normal compliance: a failure is reported, not a wrong answer") {
      const Matrix3d W = Vector3d(0, 1, 1).asDiagonal();
      const CoulombResult c = solve_coulomb(W, Vector3d(-1, 0.1, 0), 0.5);
      CHECK(c.regime == CoulombRegime::failed);
      CHECK(c.residual > 1e-3);
    }
  }

  TEST_CASE("contact gauss-seidel: random multi-contact problems converge below the tolerance with an explicit W or the compliance applied") {
    std::mt19937 rng(2024);
    std::normal_distribution<double> N(0, 1);
    std::uniform_real_distribution<double> U(0, 1);
    for (int trial = 0; trial < 20; ++trial) {
      CAPTURE(trial);
      const int m = 10, n = 60;  // contacts, DoFs (3m < n: W is SPD)
      Eigen::MatrixXd H(3 * m, n);
      for (int i = 0; i < H.size(); ++i) H(i) = U(rng) < 0.15 ? N(rng) : 0.0;
      for (int k = 0; k < 3 * m; ++k) H(k, k) += 2.0;  // full row rank
      Eigen::MatrixXd B(n, n);
      for (int i = 0; i < B.size(); ++i) B(i) = N(rng);
      const Eigen::MatrixXd D = (B * B.transpose() / n + Eigen::MatrixXd::Identity(n, n)).inverse();  // SPD compliance
      const Eigen::MatrixXd W = H * D * H.transpose();
      Eigen::VectorXd vfree(n);
      for (int i = 0; i < n; ++i) vfree[i] = N(rng);
      const Eigen::VectorXd uf = H * vfree;
      std::vector<double> mu(m);
      for (double& x : mu) x = U(rng);
      GaussSeidelParams prm;
      prm.tolerance = 1e-10;
      prm.max_sweeps = 5000;

      DenseDelassus dense(W, uf);
      std::vector<Vector3d> r;
      const GaussSeidelReport a = gauss_seidel(dense, mu, r, prm);
      CHECK(a.converged);
      CHECK(a.residual <= 1e-10);
      CHECK(a.failed == 0);
      // Every contact satisfies its laws with the final velocities.
      const Eigen::VectorXd u = W * Eigen::Map<const Eigen::VectorXd>(r[0].data(), 3 * m) + uf;
      for (int k = 0; k < m; ++k) {
        CHECK(r[k][0] >= 0);
        CHECK(r[k].tail<2>().norm() <= mu[k] * r[k][0] * (1 + 1e-9) + 1e-14);
        CHECK(u[3 * k] >= -1e-8);
      }

      // The same problem through the compliance: x = vfree + D H^T r, u_k = H_k x.
      Eigen::VectorXd x = vfree;
      std::vector<Eigen::Matrix3d> blocks(m);
      for (int k = 0; k < m; ++k) blocks[k] = W.block<3, 3>(3 * k, 3 * k);
      const Eigen::MatrixXd P = D * H.transpose();  // filtered contact basis, n x 3m
      ComplianceDelassus applied(
          blocks, [&](int k) { return Vector3d(H.middleRows<3>(3 * k) * x); },
          [&](int k, const Vector3d& dr) { x += P.middleCols<3>(3 * k) * dr; });
      std::vector<Vector3d> r2;
      const GaussSeidelReport b = gauss_seidel(applied, mu, r2, prm);
      CHECK(b.converged);
      CHECK(b.sweeps == doctest::Approx(a.sweeps).epsilon(0.2));
      for (int k = 0; k < m; ++k) CHECK((r2[k] - r[k]).norm() <= 1e-6 * (1 + r[k].norm()));
      if (trial == 0) MESSAGE("sweeps: dense " << a.sweeps << ", applied " << b.sweeps << "; stick " << a.stick << ", slide " << a.slide << ", take-off " << a.take_off);
    }
  }
}
