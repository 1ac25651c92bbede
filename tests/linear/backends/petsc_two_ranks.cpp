// Run under `mpirun -n 2` (ctest: backends.petsc_gamg_two_ranks): every rank builds the same
// cloth system, solves it distributed over all ranks and alone (PETSC_COMM_SELF), and the
// two solutions must agree.
#include <doctest/doctest.h>

#include <cstdlib>
#include <string>

#include "linear/backends/petsc_gamg.hpp"
#include "tests/support/linear_fixtures.hpp"

using namespace weft;
using support::Pins;

TEST_SUITE("backends") {
  TEST_CASE("petsc_gamg: the distributed solve matches the one-rank solve") {
    const auto sys = support::cloth_system(31, Tessellation::irregular, Pins::two_sides);
    auto solve = [&](bool single) {
      linear::PetscGamg solver({.tolerance = 1e-10, .single_process = single});
      solver.set_context({&sys.pins, &sys.x});
      REQUIRE(solver.analyze_pattern(sys.A) == Status::success);
      REQUIRE(solver.factorize(sys.A) == Status::success);
      Eigen::VectorXd x;
      const LinearReport r = solver.solve(sys.b, x);
      REQUIRE(r.status == Status::success);
      MESSAGE("rank " << solver.rank() << " of " << solver.ranks() << ": " << r.iterations << " iterations, "
                      << r.levels << " levels");
      return std::pair{x, solver.ranks()};
    };
    const auto [x_all, ranks] = solve(false);
    const auto [x_one, one] = solve(true);
    CHECK(one == 1);
    if (const char* expect = std::getenv("WEFT_EXPECT_RANKS")) CHECK(ranks == std::stoi(expect));
    REQUIRE(x_one.norm() > 0);
    CHECK((x_all - x_one).norm() <= 1e-6 * x_one.norm());
    CHECK(sys.pins.violation(x_all) <= 1e-14);
  }
}
