// The convergent multi-contact solver on an explicit W (contact/contact_newton.hpp), the
// one linear compliance on cloth uses with `contact.solver = newton`: contacts on a chain
// as cloth contacts are (several per edge, two-vertex stencils: more contacts than DoFs,
// W singular), with friction. Gauss-Seidel stalls on some of them and is slow on all;
// semismooth Newton from its iterate reaches the tolerance, and the result satisfies
// Signorini-Coulomb contact by contact.
#include <doctest/doctest.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <random>
#include <vector>

#include "contact/contact_gauss_seidel.hpp"
#include "contact/contact_newton.hpp"
#include "contact/coulomb.hpp"

using namespace weft::contact;
using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;

namespace {

/// A chain of `N` unit-mass vertices, springs of stiffness `k` between neighbours (in all
/// three directions) and to fixed ends: A = I + k L (x) I_3, D = A^-1.
MatrixXd chain_compliance(int N, double k) {
  MatrixXd A = MatrixXd::Identity(3 * N, 3 * N);
  for (int i = 0; i < N; ++i)
    for (int c = 0; c < 3; ++c) {
      A(3 * i + c, 3 * i + c) += 2 * k;
      if (i + 1 < N) A(3 * i + c, 3 * (i + 1) + c) = A(3 * (i + 1) + c, 3 * i + c) = -k;
    }
  return A.ldlt().solve(MatrixXd::Identity(3 * N, 3 * N));
}

/// Contacts on a chain of N vertices as cloth contacts are: `per_edge` per edge, each on the
/// edge's two vertices with weights (1 - t, t), normal near +z. More contacts than vertices
/// make W = H D H^T singular (redundant contacts), as in a sheet resting on another.
MatrixXd chain_contacts(int N, int per_edge, std::mt19937& rng) {
  std::uniform_real_distribution<double> U(0, 1);
  const int m = (N - 1) * per_edge;
  MatrixXd H = MatrixXd::Zero(3 * m, 3 * N);
  for (int e = 0, k = 0; e + 1 < N; ++e)
    for (int j = 0; j < per_edge; ++j, ++k) {
      const double t = (j + 0.5) / per_edge;
      Vector3d n(0.2 * (U(rng) - 0.5), 0.2 * (U(rng) - 0.5), 1);
      n.normalize();
      const Vector3d t1 = n.cross(Vector3d::UnitX()).normalized(), t2 = n.cross(t1);
      Eigen::Matrix3d F;
      F << n.transpose(), t1.transpose(), t2.transpose();
      H.block<3, 3>(3 * k, 3 * e) = (1 - t) * F;
      H.block<3, 3>(3 * k, 3 * (e + 1)) = t * F;
    }
  return H;
}

/// A frictional problem on the chain: every contact approaching (u_f,n in [-1, -0.2]),
/// small random tangential velocities, mu uniform in [0, 0.3]; seeded.
struct ChainProblem {
  MatrixXd W;
  VectorXd uf;
  std::vector<double> mu;
};
ChainProblem chain_problem(int per_edge, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  const int N = 30, m = (N - 1) * per_edge;
  const MatrixXd H = chain_contacts(N, per_edge, rng);
  ChainProblem p{H * chain_compliance(N, 1.0) * H.transpose(), VectorXd(3 * m), std::vector<double>(m)};
  for (int k = 0; k < m; ++k) {
    p.uf[3 * k] = -1 + 0.8 * U(rng);
    p.uf[3 * k + 1] = 0.1 * (U(rng) - 0.5);
    p.uf[3 * k + 2] = 0.1 * (U(rng) - 0.5);
    p.mu[k] = 0.3 * U(rng);
  }
  return p;
}

/// Newton from Gauss-Seidel's iterate reaches `tol`, and the result satisfies the laws
/// contact by contact with u recomputed from scratch.
NewtonContactResult check_newton(const ChainProblem& p, DenseDelassus& op, std::vector<Vector3d>& r, double tol,
                                 NewtonContactOptions opt = {}) {
  const int m = static_cast<int>(p.mu.size());
  opt.tolerance = tol;
  opt.max_iterations = 50;
  const NewtonContactResult nr = solve_contacts_newton(op, p.mu, r, opt);
  MESSAGE("Newton: " << nr.iterations << " steps (" << nr.fallbacks << " fallbacks, " << nr.stick_steps << " stick steps), residual "
                     << nr.residual);
  CHECK(nr.residual <= tol);
  CHECK(nr.iterations >= 1);
  CHECK(nr.iterations < 50);
  VectorXd lam(3 * m);
  for (int k = 0; k < m; ++k) lam.segment<3>(3 * k) = r[k];
  const VectorXd u = p.W * lam + p.uf;
  CHECK((u - op.velocities()).norm() <= 1e-9 * (1 + u.norm()));
  double worst = 0;
  int pressed = 0;
  for (int k = 0; k < m; ++k) {
    const double s = coulomb_scale(p.W.block<3, 3>(3 * k, 3 * k));
    worst = std::max(worst, fischer_burmeister(r[k], u.segment<3>(3 * k), p.mu[k], s));
    CHECK(r[k][0] >= -2 * tol / s);  // Phi <= tol bounds s r_n from below by -tol
    CHECK(r[k].tail<2>().norm() <= p.mu[k] * r[k][0] + 1e-9);
    CHECK(u[3 * k] >= -1e-8);
    CHECK(std::abs(r[k][0] * u[3 * k]) <= 1e-8);
    pressed += r[k][0] > 0 ? 1 : 0;
  }
  CHECK(worst <= 2 * tol);
  CHECK(pressed > 0);
  return nr;
}

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("contact newton: redundant frictional contacts where Gauss-Seidel stalls converge to the tolerance") {
    const double tol = 1e-10;
    // Two of 58 problems of this family on which 1000 sweeps stall (the rest need 57-826).
    for (const auto& [per_edge, seed] : {std::pair{3, 7u}, std::pair{5, 16u}}) {
      CAPTURE(seed);
      const ChainProblem p = chain_problem(per_edge, seed);
      DenseDelassus op(p.W, p.uf);
      std::vector<Vector3d> r;
      const GaussSeidelReport gs = gauss_seidel(op, p.mu, r, {.tolerance = tol, .max_sweeps = 1000});
      MESSAGE("Gauss-Seidel: " << gs.sweeps << " sweeps, residual " << gs.residual);
      REQUIRE_FALSE(gs.converged);  // the guard: else the test shows nothing
      CHECK(gs.residual > 1e3 * tol);
      check_newton(p, op, r, tol);
    }
  }

  TEST_CASE("contact newton: after 50 sweeps Newton finishes what Gauss-Seidel would take hundreds of sweeps for") {
    const double tol = 1e-10;
    for (unsigned seed = 1; seed <= 6; ++seed) {
      CAPTURE(seed);
      const ChainProblem p = chain_problem(3, seed);
      DenseDelassus op(p.W, p.uf);
      std::vector<Vector3d> r;
      const GaussSeidelReport gs = gauss_seidel(op, p.mu, r, {.tolerance = tol, .max_sweeps = 50});
      REQUIRE_FALSE(gs.converged);
      check_newton(p, op, r, tol);
    }
  }

  TEST_CASE("contact newton: the sparse path converges whether or not the damped step competes with a decreasing Newton step") {
    // dense_limit = 0 sends these problems through the sparse factorisations, where by default
    // the Levenberg-Marquardt step is tried only when neither the Newton nor the stick step
    // decreases the merit (its LDL^T of J^T J is the costly part on large rod groups).
    const double tol = 1e-10;
    int fallbacks[2] = {0, 0};
    // Five of 100 problems of this family (3-12 contacts per edge, seeds 1-25) where the damped
    // step wins at least twice when it competes.
    int iterations[2] = {0, 0};
    for (const auto& [per_edge, seed] : {std::pair{5, 25u}, std::pair{8, 10u}, std::pair{8, 15u}, std::pair{12, 20u}, std::pair{12, 24u}}) {
      for (const bool stuck_only : {false, true}) {
        CAPTURE(seed);
        CAPTURE(stuck_only);
        const ChainProblem p = chain_problem(per_edge, seed);
        DenseDelassus op(p.W, p.uf);
        std::vector<Vector3d> r;
        REQUIRE_FALSE(gauss_seidel(op, p.mu, r, {.tolerance = tol, .max_sweeps = 50}).converged);
        const NewtonContactResult nr = check_newton(p, op, r, tol, {.dense_limit = 0, .sparse_lm_only_when_stuck = stuck_only});
        fallbacks[stuck_only] += nr.fallbacks;
        iterations[stuck_only] += nr.iterations;
      }
    }
    MESSAGE("damped steps taken: " << fallbacks[0] << " when it competes whenever the Newton step falls short, " << fallbacks[1]
                                   << " when only when stuck; Newton steps " << iterations[0] << " and " << iterations[1]);
    CHECK(fallbacks[0] > 0);  // the damped step wins somewhere here: else the option changes nothing
    CHECK(fallbacks[1] < fallbacks[0]);
  }

  TEST_CASE("contact newton: a problem Gauss-Seidel has already solved is left as it is") {
    const int m = 8;
    const MatrixXd W = chain_compliance(m, 1.0);
    VectorXd uf = VectorXd::Zero(3 * m);
    for (int k = 0; k < m; ++k) uf[3 * k] = -0.1;
    std::vector<double> mu(m, 0.3);
    DenseDelassus op(W, uf);
    std::vector<Vector3d> r;
    const GaussSeidelReport gs = gauss_seidel(op, mu, r, {.tolerance = 1e-12, .max_sweeps = 10000});
    REQUIRE(gs.converged);
    const std::vector<Vector3d> before = r;
    const NewtonContactResult nr = solve_contacts_newton(op, mu, r, {.tolerance = 1e-12});
    CHECK(nr.iterations == 0);
    CHECK(nr.residual <= 1e-12);
    for (int k = 0; k < m; ++k) CHECK(r[k] == before[k]);
  }
}
