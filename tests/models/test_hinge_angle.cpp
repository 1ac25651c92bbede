#include <doctest/doctest.h>

#include <Eigen/Eigenvalues>

#include <cmath>
#include <numbers>

#include "models/hinge_bending.hpp"
#include "tests/support/fd.hpp"
#include "tests/support/model_fixtures.hpp"

namespace {

using namespace weft;
using namespace weft::models;
using support::MeshData;

bending::HingeFrames frames_at(const Eigen::VectorXd& x) {
  return bending::hinge_frames(x.segment<3>(0), x.segment<3>(3), x.segment<3>(6), x.segment<3>(9));
}
double theta_at(const Eigen::VectorXd& x) { return bending::hinge_angle(frames_at(x)).theta; }

}  // namespace

TEST_SUITE("models") {
  TEST_CASE("hinge angle: known dihedral angles (methods/shells §9 item 24)") {
    for (double phi : {0.3, 1.0, 2.5, -1.0, 1e-4}) {
      CAPTURE(phi);
      const auto f = frames_at(support::stack(support::known_hinge(phi).V));
      const auto a = bending::hinge_angle(f);
      CHECK(std::abs(a.theta - phi) <= 1e-15 * std::max(1.0, std::abs(phi)));
      CHECK(std::abs(a.tan_half - std::tan(phi / 2)) <= 1e-15 * std::max(1.0, std::abs(std::tan(phi / 2))));
      CHECK(std::abs(a.normal_sum - 2 * std::cos(phi / 2)) <= 1e-15);
      CHECK((f.T.n - Eigen::Vector3d::UnitZ()).norm() <= 1e-15);
    }
  }

  TEST_CASE("hinge angle: gradient and Hessian of theta match central differences (methods/shells §9 item 4)") {
    std::uint32_t seed = 20;
    for (double phi : {-2.5, -1.0, 1e-4, 0.3, 1.0, 2.5}) {
      for (double wing : {-1.0, 1e-3}) {  // random shape, or a wing altitude 1e-3 of the hinge edge
        CAPTURE(phi);
        CAPTURE(wing);
        const Eigen::VectorXd x = support::stack(support::random_hinge(++seed, phi, wing).V);
        const double h = 1e-6;  // edges are O(1)
        const bending::Vec12 g = bending::grad_theta(frames_at(x));
        const Eigen::VectorXd g_fd = support::fd_gradient(theta_at, x, h);
        REQUIRE(g.norm() > 0);
        CHECK(support::relative_error(g, g_fd) <= 1e-6);
        const bending::Mat12 H = bending::hess_theta(frames_at(x));
        const Eigen::MatrixXd H_fd =
            support::fd_jacobian([](const Eigen::VectorXd& y) -> Eigen::VectorXd { return bending::grad_theta(frames_at(y)); }, x, h);
        REQUIRE(H.norm() > 0);
        CHECK(support::relative_error(H, H_fd) <= 1e-6);
      }
    }
  }

  TEST_CASE("hinge angle: gradient structure (methods/shells §6.4)") {
    for (std::uint32_t seed = 30; seed < 35; ++seed) {
      CAPTURE(seed);
      support::Rng rng(seed);
      const Eigen::VectorXd x = support::stack(support::random_hinge(seed, rng.uniform(-2.5, 2.5)).V);
      const auto f = frames_at(x);
      const bending::Vec12 g = bending::grad_theta(f);
      const Eigen::Vector3d sum = g.segment<3>(0) + g.segment<3>(3) + g.segment<3>(6) + g.segment<3>(9);
      CHECK(sum.norm() <= 1e-14 * g.norm());
      CHECK(std::abs(g.segment<3>(0).norm() * f.T.h[0] - 1) <= 1e-14);
      CHECK(std::abs(g.segment<3>(9).norm() * f.Tt.h[0] - 1) <= 1e-14);
    }
  }

  TEST_CASE("hinge angle: Hess theta has 4 positive and 4 negative and 4 zero eigenvalues (methods/shells §9 item 16)") {
    for (std::uint32_t seed = 40; seed < 50; ++seed) {
      support::Rng rng(seed);
      const double phi = rng.uniform(0.05, 2.5) * (seed % 2 ? 1 : -1);
      CAPTURE(seed);
      CAPTURE(phi);
      const bending::Mat12 H = bending::hess_theta(frames_at(support::stack(support::random_hinge(seed, phi).V)));
      const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<bending::Mat12>(H).eigenvalues();
      const double tol = 1e-9 * ev.cwiseAbs().maxCoeff();
      REQUIRE(tol > 0);
      CHECK((ev.array() > tol).count() == 4);
      CHECK((ev.array() < -tol).count() == 4);
      CHECK((ev.array().abs() <= tol).count() == 4);
    }
  }

  TEST_CASE("hinge angle: N0 + N0~ is symmetric and either transposition choice gives the same Hessian (methods/shells §9 items 13 and 14)") {
    for (std::uint32_t seed = 50; seed < 55; ++seed) {
      CAPTURE(seed);
      const auto f = frames_at(support::stack(support::random_hinge(seed, 0.2 * (seed - 52)).V));
      const Eigen::Matrix3d N0 = f.T.n * f.T.m[0].transpose() / (f.T.l[0] * f.T.l[0]);
      const Eigen::Matrix3d Nt0 = f.Tt.n * f.Tt.m[0].transpose() / (f.Tt.l[0] * f.Tt.l[0]);
      const Eigen::Matrix3d S = N0 + Nt0;
      CHECK((S - S.transpose()).norm() <= 1e-14 * (N0.norm() + Nt0.norm()));
      // The other choice: T~ transposes instead of T.
      bending::Mat12 H = bending::Mat12::Zero();
      const bending::Mat9 BT = bending::half_hinge_hessian(f.T, false), BTt = bending::half_hinge_hessian(f.Tt, true);
      const int mT[3] = {0, 1, 2}, mTt[3] = {3, 2, 1};
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
          H.block<3, 3>(3 * mT[a], 3 * mT[b]) += BT.block<3, 3>(3 * a, 3 * b);
          H.block<3, 3>(3 * mTt[a], 3 * mTt[b]) += BTt.block<3, 3>(3 * a, 3 * b);
        }
      const bending::Mat12 H_ref = bending::hess_theta(f);
      REQUIRE(H_ref.norm() > 0);
      CHECK((H - H_ref).norm() <= 1e-14 * H_ref.norm());
    }
  }

  TEST_CASE("hinge angle: swapping the roles of T and T~ leaves theta and its derivatives unchanged") {
    for (std::uint32_t seed = 60; seed < 64; ++seed) {
      CAPTURE(seed);
      const Eigen::VectorXd x = support::stack(support::random_hinge(seed, 0.7 * (seed - 61.5)).V);
      // Relabel: x0' = x3, x1' = x2, x2' = x1, x3' = x0.
      const int perm[4] = {3, 2, 1, 0};
      Eigen::VectorXd y(12);
      for (int k = 0; k < 4; ++k) y.segment<3>(3 * k) = x.segment<3>(3 * perm[k]);
      CHECK(std::abs(theta_at(x) - theta_at(y)) <= 1e-15 * std::max(1.0, std::abs(theta_at(x))));
      const bending::Vec12 gx = bending::grad_theta(frames_at(x)), gy = bending::grad_theta(frames_at(y));
      const bending::Mat12 Hx = bending::hess_theta(frames_at(x)), Hy = bending::hess_theta(frames_at(y));
      bending::Vec12 gy_back;
      bending::Mat12 Hy_back;
      for (int a = 0; a < 4; ++a) {
        gy_back.segment<3>(3 * perm[a]) = gy.segment<3>(3 * a);
        for (int b = 0; b < 4; ++b) Hy_back.block<3, 3>(3 * perm[a], 3 * perm[b]) = Hy.block<3, 3>(3 * a, 3 * b);
      }
      CHECK((gx - gy_back).norm() <= 1e-14 * gx.norm());
      CHECK((Hx - Hy_back).norm() <= 1e-14 * Hx.norm());
    }
  }

  TEST_CASE("hinge angle: altitude-collapse sequence stays finite (methods/shells §9 item 28)") {
    for (int k = 1; k <= 8; ++k) {
      const double h0 = std::pow(10.0, -k);
      CAPTURE(h0);
      const Eigen::VectorXd x = support::stack(support::hinge({0.4, h0, 0}, {0, 0, 0}, {1, 0, 0}, {0.6, -0.8, -0.5}).V);
      const auto f = frames_at(x);
      const bending::Vec12 g = bending::grad_theta(f);
      const bending::Mat12 H = bending::hess_theta(f);
      CHECK(g.allFinite());
      CHECK(H.allFinite());
      CHECK(std::abs(g.segment<3>(0).norm() * h0 - 1) <= 1e-15 / h0 + 1e-15);
    }
  }
}
