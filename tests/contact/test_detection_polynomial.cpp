// Root isolation for the CCD cubic: quadratic roots with vanishing leading coefficients,
// cubic roots against their construction, and the band {|p| <= delta} against dense sampling.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "contact/detection/polynomial.hpp"

using namespace weft::contact::detection;

namespace {
// k (t - r0)(t - r1)(t - r2).
Cubic from_roots(double k, double r0, double r1, double r2) {
  Cubic p;
  p.c = {-k * r0 * r1 * r2, k * (r0 * r1 + r1 * r2 + r0 * r2), -k * (r0 + r1 + r2), k};
  return p;
}

bool in_band(const Intervals& b, double t) {
  for (int i = 0; i < b.n; ++i)
    if (t >= b.iv[i][0] && t <= b.iv[i][1]) return true;
  return false;
}
}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("detection polynomial: quadratic roots including vanishing leading coefficients") {
    auto roots = [](double a, double b, double c) {
      const Roots r = quadratic_roots_in_unit(a, b, c);
      return std::vector<double>(r.t.begin(), r.t.begin() + r.n);
    };
    CHECK(roots(1, -1, 0.21).size() == 2);  // (t - 0.3)(t - 0.7)
    CHECK(roots(1, -1, 0.21)[0] == doctest::Approx(0.3).epsilon(1e-14));
    CHECK(roots(1, -1, 0.21)[1] == doctest::Approx(0.7).epsilon(1e-14));
    CHECK(roots(0, 2, -1) == std::vector<double>{0.5});           // linear
    CHECK(roots(1e-300, 2, -1).size() == 1);                      // nearly linear: the large root is outside
    CHECK(roots(1e-300, 2, -1)[0] == doctest::Approx(0.5).epsilon(1e-15));
    CHECK(roots(1e-17, 1, -0.25)[0] == doctest::Approx(0.25).epsilon(1e-15));
    CHECK(roots(1, -1, 0.25) == std::vector<double>{0.5});        // double root
    CHECK(roots(1, 0, 1).empty());                                // complex
    CHECK(roots(0, 0, 0).empty());
    CHECK(roots(0, 0, 1).empty());
    CHECK(roots(1, -3, 2).empty());  // roots 1 and 2: not in the open interval
    // Cancellation-prone: roots 1e-9 and 0.5 of a scaled polynomial.
    const auto r = roots(1e8, -1e8 * (0.5 + 1e-9), 1e8 * 0.5e-9);
    REQUIRE(r.size() == 2);
    CHECK(r[0] == doctest::Approx(1e-9).epsilon(1e-12));
    CHECK(r[1] == doctest::Approx(0.5).epsilon(1e-14));
  }

  TEST_CASE("detection polynomial: cubic roots in the unit interval match their construction") {
    std::mt19937 rng(21);
    std::uniform_real_distribution<double> u(-0.5, 1.5), scale(-3, 3);
    int with_roots = 0;
    for (int trial = 0; trial < 2000; ++trial) {
      CAPTURE(trial);
      double r[3] = {u(rng), u(rng), u(rng)};
      std::sort(r, r + 3);
      if (r[1] - r[0] < 1e-3 || r[2] - r[1] < 1e-3) continue;  // well separated here; multiple roots below
      const double k = std::pow(10.0, scale(rng)) * (trial % 2 ? 1 : -1);
      const Roots found = cubic_roots_in_unit(from_roots(k, r[0], r[1], r[2]));
      std::vector<double> expected;
      for (double x : r)
        if (x >= 0 && x <= 1) expected.push_back(x);
      with_roots += !expected.empty();
      REQUIRE(found.n == static_cast<int>(expected.size()));
      for (int i = 0; i < found.n; ++i) CHECK(found.t[i] == doctest::Approx(expected[i]).epsilon(1e-10));
    }
    CHECK(with_roots > 1000);
    // A cubic with a nearly vanishing leading coefficient behaves as its quadratic.
    Cubic q;
    q.c = {0.21, -1, 1, 1e-18};
    const Roots qr = cubic_roots_in_unit(q);
    REQUIRE(qr.n == 2);
    CHECK(qr.t[0] == doctest::Approx(0.3).epsilon(1e-12));
    CHECK(qr.t[1] == doctest::Approx(0.7).epsilon(1e-12));
    // Triple root: found within the cube root of the rounding level.
    const Roots tr = cubic_roots_in_unit(from_roots(1, 0.4, 0.4, 0.4));
    REQUIRE(tr.n >= 1);
    CHECK(std::abs(tr.t[0] - 0.4) < 1e-4);
  }

  TEST_CASE("detection polynomial: band equals the dense-sampled set including double roots") {
    std::mt19937 rng(22);
    std::uniform_real_distribution<double> u(-0.5, 1.5), d(0, 1);
    int nonempty = 0, split = 0;
    for (int trial = 0; trial < 400; ++trial) {
      CAPTURE(trial);
      // Every fourth case has a double root inside [0, 1].
      const double r0 = u(rng), r1 = trial % 4 == 0 ? r0 : u(rng), r2 = u(rng);
      const Cubic p = from_roots(trial % 3 ? 1.0 : -2.5, r0, r1, r2);
      const double delta = 1e-3 * std::pow(10.0, -6 * d(rng));
      const Intervals b = band(p, delta);
      nonempty += b.n > 0;
      split += b.n > 1;
      for (int i = 0; i < b.n; ++i) {
        CHECK(b.iv[i][0] <= b.iv[i][1]);
        if (i > 0) CHECK(b.iv[i - 1][1] < b.iv[i][0]);
      }
      int missing = 0, extra = 0;
      for (int k = 0; k <= 20000; ++k) {
        const double t = k / 20000.0;
        const double v = std::abs(p(t));
        missing += v <= delta * (1 - 1e-9) && !in_band(b, t);
        extra += v > delta * (1 + 1e-9) + 1e-15 && in_band(b, t);
      }
      CHECK(missing == 0);
      CHECK(extra == 0);
      // A double root in [0, 1] is in the band however small delta is.
      if (trial % 4 == 0 && r0 >= 0 && r0 <= 1) CHECK(in_band(band(p, 1e-14), r0));
    }
    CHECK(nonempty > 200);
    CHECK(split > 20);
  }

  TEST_CASE("detection polynomial: zero and constant polynomials") {
    const Intervals all = band(Cubic{}, 0.0);
    REQUIRE(all.n == 1);
    CHECK(all.iv[0][0] == 0);
    CHECK(all.iv[0][1] == 1);
    Cubic c;
    c.c = {1e-3, 0, 0, 0};
    CHECK(band(c, 1e-4).n == 0);
    CHECK(band(c, 1e-3).n == 1);
    // Rounding-level coefficients (an always-coplanar motion evaluated in floating point).
    c.c = {3e-17, -2e-17, 1e-17, -4e-18};
    const Intervals tiny = band(c, 1e-12);
    REQUIRE(tiny.n == 1);
    CHECK(tiny.iv[0][0] == 0);
    CHECK(tiny.iv[0][1] == 1);
  }

  TEST_CASE("detection polynomial: solve_monotone brackets the crossing tightly") {
    const Cubic p = from_roots(1, -0.5, 0.3, 2.0);  // decreasing on [0, 0.6] (critical points -0.17, 1.37)
    const auto br = solve_monotone(p, 0.0, 0.0, 0.6);
    CHECK(br[0] <= 0.3);
    CHECK(br[1] >= 0.3 - 1e-15);
    CHECK(br[1] - br[0] <= 1e-14);
    // A level other than zero.
    const double y = p(0.45);
    const auto by = solve_monotone(p, y, 0.3, 0.6);
    CHECK(by[0] <= 0.45 + 1e-15);
    CHECK(by[1] >= 0.45 - 1e-15);
    CHECK(by[1] - by[0] <= 1e-14);
  }
}
