#include <doctest/doctest.h>

#include <cmath>
#include <random>

#include "integrators/line_search.hpp"

using namespace weft::integrators;

TEST_SUITE("integrators") {
  TEST_CASE("line searches: the accepted step satisfies the conditions each one promises") {
    // phi(s) = (s - 2)^2 - 4 + 0.1 (s - 2)^4: minimum at s = 2, phi'(0) < 0.
    auto phi = [](double s) { return (s - 2) * (s - 2) - 4 + 0.1 * std::pow(s - 2, 4); };
    auto dphi = [](double s) { return 2 * (s - 2) + 0.4 * std::pow(s - 2, 3); };
    const double phi0 = phi(0), slope0 = dphi(0);
    REQUIRE(slope0 < 0);
    LineSearchParams prm;
    const auto bt = backtracking(phi, phi0, slope0, prm);
    REQUIRE(bt.accepted);
    CHECK(bt.value <= phi0 + prm.c1 * bt.step * slope0);
    const PhiWithSlope both = [&](double s) { return std::make_pair(phi(s), dphi(s)); };
    const auto mt = more_thuente(both, phi0, slope0, prm);
    REQUIRE(mt.accepted);
    CHECK(mt.value <= phi0 + prm.c1 * mt.step * slope0);
    CHECK(std::abs(dphi(mt.step)) <= prm.c2 * std::abs(slope0));  // strong Wolfe
    const auto hz = hager_zhang(both, phi0, slope0, prm);
    REQUIRE(hz.accepted);
    CHECK(dphi(hz.step) >= prm.c2 * slope0);
    CHECK(hz.value <= phi0 + 1e-6 * std::abs(phi0));
    MESSAGE("backtracking s = " << bt.step << " (" << bt.evaluations << " evaluations), More-Thuente s = " << mt.step << " ("
                                << mt.evaluations << "), Hager-Zhang s = " << hz.step << " (" << hz.evaluations << ")");
  }

  TEST_CASE("line searches: Wolfe searches extend beyond s = 1 when the minimum lies further") {
    // Minimum at s = 6: backtracking stops at 1, the Wolfe searches go past it (with c2 = 0.5
    // s = 1 violates the curvature condition: |phi'(1)| = 10 > 0.5 |phi'(0)| = 6).
    auto phi = [](double s) { return (s - 6) * (s - 6); };
    auto dphi = [](double s) { return 2 * (s - 6); };
    const PhiWithSlope both = [&](double s) { return std::make_pair(phi(s), dphi(s)); };
    LineSearchParams prm;
    prm.c2 = 0.5;
    CHECK(backtracking(phi, phi(0), dphi(0), prm).step == 1.0);
    const auto mt = more_thuente(both, phi(0), dphi(0), prm);
    REQUIRE(mt.accepted);
    CHECK(mt.step > 1.0);
    CHECK(std::abs(dphi(mt.step)) <= prm.c2 * std::abs(dphi(0)));
    const auto hz = hager_zhang(both, phi(0), dphi(0), prm);
    REQUIRE(hz.accepted);
    CHECK(hz.step > 1.0);
  }

  TEST_CASE("line searches: Hager-Zhang decides by derivatives where values are below round-off") {
    // phi(s) = 1e8 + 1e-9 (s - 1)^2 with round-off noise in the values: phi(s) - phi(0) is
    // invisible in double precision, phi' is exact. The approximate Wolfe test still finds
    // a step near the minimiser s = 1; a value-based Armijo test only sees noise.
    std::mt19937 rng(1);
    std::uniform_int_distribution<int> ulps(-2, 2);
    auto noisy = [&](double s) { return std::nextafter(1e8 + 1e-9 * (s - 1) * (s - 1), ulps(rng) > 0 ? 2e8 : 0.0); };
    auto dphi = [](double s) { return 2e-9 * (s - 1); };
    const PhiWithSlope both = [&](double s) { return std::make_pair(noisy(s), dphi(s)); };
    LineSearchParams prm;
    const auto hz = hager_zhang(both, noisy(0), dphi(0), prm);
    REQUIRE(hz.accepted);
    CHECK(std::abs(hz.step - 1.0) < 0.9);
    CHECK(dphi(hz.step) >= prm.c2 * dphi(0));
  }

  TEST_CASE("line searches: non-finite trial values shrink the step") {
    auto phi = [](double s) { return s > 0.3 ? std::numeric_limits<double>::infinity() : -s; };
    auto dphi = [](double s) { return s > 0.3 ? std::numeric_limits<double>::infinity() : -1.0; };
    const PhiWithSlope both = [&](double s) { return std::make_pair(phi(s), dphi(s)); };
    LineSearchParams prm;
    const auto bt = backtracking(phi, 0.0, -1.0, prm);
    REQUIRE(bt.accepted);
    CHECK(bt.step <= 0.3);
    const auto mt = more_thuente(both, 0.0, -1.0, prm);
    REQUIRE(mt.accepted);
    CHECK(mt.step <= 0.3);
    const auto hz = hager_zhang(both, 0.0, -1.0, prm);
    CHECK((!hz.accepted || hz.step <= 0.3));
  }
}
