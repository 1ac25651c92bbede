#include <doctest/doctest.h>

#include <Eigen/Dense>

#include "linear/backends/petsc_gamg.hpp"
#include "tests/support/linear_fixtures.hpp"

using namespace weft;
using support::Pins;

namespace {

/// One solve of a cloth system by `solver`, required to succeed.
LinearReport solved(linear::PetscGamg& solver, const support::ClothSystem& sys, Eigen::VectorXd& x) {
  solver.set_context({&sys.pins, &sys.x});
  REQUIRE(solver.analyze_pattern(sys.A) == Status::success);
  REQUIRE(solver.factorize(sys.A) == Status::success);
  const LinearReport r = solver.solve(sys.b, x);
  CAPTURE(r.message);
  REQUIRE(r.status == Status::success);
  return r;
}

}  // namespace

TEST_SUITE("backends") {
  TEST_CASE("petsc_gamg: pinned cloth systems converge to the natural-norm tolerance") {
    for (auto [m, t, pins] : {std::tuple{25, Tessellation::regular, Pins::boundary},
                              std::tuple{24, Tessellation::irregular, Pins::two_sides},
                              std::tuple{25, Tessellation::regular, Pins::reentrant}}) {
      CAPTURE(m);
      CAPTURE(static_cast<int>(pins));
      const auto sys = support::cloth_system(m, t, pins);
      Eigen::VectorXd x;
      linear::PetscGamg solver({});
      const LinearReport r = solved(solver, sys, x);
      CHECK(r.iterations >= 1);
      CHECK(r.iterations <= 60);
      REQUIRE(r.residual_history.size() == static_cast<size_t>(r.iterations) + 1);
      CHECK(r.residual_history.front() == 1.0);
      CHECK(r.residual_history.back() < 1e-5);
      CHECK(r.residual_history[r.residual_history.size() - 2] >= 1e-5);  // stopped at the first pass
      CHECK(r.levels >= 2);
      CHECK(r.setup_seconds > 0);
      CHECK(r.constraint_violation <= 1e-14);
      CHECK(solver.threshold_used() == 0.0);  // PETSc's default threshold (the fastest on cloth)
      MESSAGE("m " << m << ": " << r.iterations << " iterations, " << r.levels << " levels, rate " << r.convergence_rate
                   << ", threshold " << solver.threshold_used());
    }
  }

  TEST_CASE("petsc_gamg: matches a dense KKT solve at tolerance 1e-8") {
    for (auto [m, t, pins] : {std::tuple{17, Tessellation::regular, Pins::boundary},
                              std::tuple{16, Tessellation::irregular, Pins::two_sides},
                              std::tuple{17, Tessellation::regular, Pins::reentrant}}) {
      CAPTURE(m);
      CAPTURE(static_cast<int>(pins));
      const auto sys = support::cloth_system(m, t, pins);
      linear::PetscGamg solver({.tolerance = 1e-8});
      solver.set_context({&sys.pins, &sys.x});
      REQUIRE(solver.analyze_pattern(sys.A) == Status::success);
      REQUIRE(solver.factorize(sys.A) == Status::success);
      Eigen::VectorXd x;
      const LinearReport r = solver.solve(sys.b, x);
      REQUIRE(r.status == Status::success);
      const Eigen::VectorXd ref = support::dense_kkt_solve(sys.A, sys.b, sys.pins);
      CHECK((x - ref).norm() <= 1e-4 * ref.norm());
      CHECK(r.relative_residual <= 1e-5);
    }
  }

  TEST_CASE("petsc peers: BoomerAMG and ML match a dense KKT solve and take their options") {
    // The peers of weft bench linear, with GAMG's CG and stopping rule: each reaches the
    // direct solution, and a solver's options reach its preconditioner (a stricter BoomerAMG
    // strength threshold changes the hierarchy and so the iteration count) without leaking
    // into the next solver built in the process.
    const auto sys = support::cloth_system(17, Tessellation::irregular, Pins::two_sides);
    const Eigen::VectorXd ref = support::dense_kkt_solve(sys.A, sys.b, sys.pins);
    const auto solve = [&](const linear::PetscGamg::Params& prm) {
      Eigen::VectorXd x;
      linear::PetscGamg solver(prm);
      const LinearReport r = solved(solver, sys, x);
      CHECK((x - ref).norm() <= 1e-4 * ref.norm());
      CHECK(r.constraint_violation <= 1e-14);
      return r;
    };
    const LinearReport ml = solve({.tolerance = 1e-8, .amg = linear::PetscAmg::ml});
    CHECK(ml.levels >= 2);
    // A level smoother's option is read when the hierarchy is built, and holds there too.
    const LinearReport ml_one = solve({.tolerance = 1e-8, .amg = linear::PetscAmg::ml, .options = "-mg_levels_ksp_max_it 1"});
    CHECK(ml_one.iterations > ml.iterations);
    const LinearReport boomer = solve({.tolerance = 1e-8, .amg = linear::PetscAmg::boomeramg});
    const LinearReport strict =
        solve({.tolerance = 1e-8, .amg = linear::PetscAmg::boomeramg, .options = "-pc_hypre_boomeramg_strong_threshold 0.9"});
    const LinearReport again = solve({.tolerance = 1e-8, .amg = linear::PetscAmg::boomeramg});
    MESSAGE("iterations to 1e-8: ML " << ml.iterations << " (one smoothing step per level " << ml_one.iterations << "), BoomerAMG " << boomer.iterations << ", strong threshold 0.9 "
                                      << strict.iterations << ", default again " << again.iterations);
    CHECK(strict.iterations != boomer.iterations);
    CHECK(again.iterations == boomer.iterations);
  }

  TEST_CASE("petsc_gamg: new values on the same pattern - rebuilt or reused interpolation") {
    const auto sys = support::cloth_system(21, Tessellation::regular, Pins::boundary, 2e-3);
    const auto stiff = support::cloth_system(21, Tessellation::regular, Pins::boundary, 8e-3);  // larger dt
    for (bool reuse : {false, true}) {
      CAPTURE(reuse);
      linear::PetscGamg solver({.tolerance = 1e-8, .reuse_interpolation = reuse});
      REQUIRE(solver.analyze_pattern(sys.A) == Status::success);
      for (const auto* s : {&sys, &stiff, &sys}) {
        solver.set_context({&s->pins, &s->x});
        REQUIRE(solver.factorize(s->A) == Status::success);
        Eigen::VectorXd x;
        const LinearReport r = solver.solve(s->b, x);
        REQUIRE(r.status == Status::success);
        const Eigen::VectorXd ref = support::dense_kkt_solve(s->A, s->b, s->pins);
        CHECK((x - ref).norm() <= 1e-4 * ref.norm());
      }
    }
  }

  TEST_CASE("petsc_gamg: unconstrained block Laplacian without positions - translations only") {
    const BlockCsr A = support::block_laplacian(30, 1e-2);
    linear::PetscGamg solver({.tolerance = 1e-8});
    REQUIRE(solver.analyze_pattern(A) == Status::success);
    REQUIRE(solver.factorize(A) == Status::success);
    const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(A.rows(), -1.0, 1.0);
    Eigen::VectorXd x;
    const LinearReport r = solver.solve(b, x);
    REQUIRE(r.status == Status::success);
    const Eigen::VectorXd ref = Eigen::MatrixXd(A.to_dense()).llt().solve(b);
    CHECK((x - ref).norm() <= 1e-4 * ref.norm());
    CHECK(r.iterations <= 60);
  }

  TEST_CASE("petsc_gamg: the iteration limit is reported as no convergence") {
    const auto sys = support::cloth_system(15, Tessellation::regular, Pins::boundary);
    linear::PetscGamg solver({.tolerance = 1e-12, .max_iterations = 2});
    solver.set_context({&sys.pins, &sys.x});
    REQUIRE(solver.analyze_pattern(sys.A) == Status::success);
    REQUIRE(solver.factorize(sys.A) == Status::success);
    Eigen::VectorXd x;
    const LinearReport r = solver.solve(sys.b, x);
    CHECK(r.status == Status::no_convergence);
    CHECK(r.iterations == 2);
  }
}
