// `weft validate`: the references against limits they must meet (linear beam theory, Peirce's
// bending length, the StVK closed form); the quick suite's membrane, friction and rod problems
// pass and its exit status says whether every problem did; a three times too stiff bending
// constant (the thesis' k = D / 2) misses the cantilevers, a pinned instead of clamped rod root
// the rod cantilever, and gravity the resting helix; bad input is refused before any run.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>

#include "apps/references.hpp"
#include "apps/validate.hpp"

using namespace weft::app;

namespace {
ValidateOptions quick_suite(const std::string& name) {
  setenv("WEFT_DATA_DIR", WEFT_SOURCE_DIR, 1);
  ValidateOptions o;
  o.quick = true;
  o.quiet = true;
  o.plots = false;
  o.out_dir = (std::filesystem::temp_directory_path() / ("weft_validate_" + name)).string();
  std::filesystem::remove_all(o.out_dir);
  return o;
}
}  // namespace

TEST_SUITE("apps") {
  TEST_CASE("validate: the elastica meets linear beam theory at small loads and Peirce's bending length") {
    for (double alpha : {1e-4, 1e-3, 1e-2}) {
      const reference::Elastica e = reference::cantilever_elastica(alpha);
      CHECK(e.drop == doctest::Approx(alpha / 8).epsilon(alpha));  // wL^4 / 8D, corrections of order alpha^2
      CHECK(e.tip_slope == doctest::Approx(alpha / 6).epsilon(alpha));
    }
    // Larger loads bend less than the linear beam, and the tip reaches less far.
    const reference::Elastica e4 = reference::cantilever_elastica(4.184578125);
    CHECK(e4.drop < 4.184578125 / 8);
    CHECK(e4.drop == doctest::Approx(0.43928).epsilon(1e-4));  // the 16 mm beam: an independent RK4 shooting
    CHECK(e4.reach < 1.0);
    CHECK(e4.drop * e4.drop + e4.reach * e4.reach < 1.0);  // inextensible: the chord is shorter than the arc
    // ASTM D1388: at a chord angle of 41.5 degrees w l^3 / D = 8 (Peirce 1930), l = 2 c.
    CHECK(reference::elastica_alpha_at_chord_angle(41.5 * std::numbers::pi / 180) == doctest::Approx(8.0).epsilon(0.01));
  }

  TEST_CASE("validate: a shallow arc cantilever is the straight one and torsion works in a quarter ring") {
    // R phi = L fixed, phi -> 0: q L^4 / 8 EI, the torsion share vanishing as phi^2
    const double L = 0.3, q = 2.0, EI = 0.5, GJ = 0.4;
    for (double phi : {1e-2, 1e-3}) {
      const double d = reference::arc_cantilever_deflection(phi, L / phi, q, EI, GJ);
      CHECK(d == doctest::Approx(q * L * L * L * L / (8 * EI)).epsilon(phi));
    }
    const double quarter = std::numbers::pi / 2, R = 0.05;
    const double bend = reference::arc_cantilever_deflection(quarter, R, q, EI, 1e300);
    CHECK(bend == doctest::Approx(q * std::pow(R, 4) / (2 * EI)).epsilon(1e-14));
    const double both = reference::arc_cantilever_deflection(quarter, R, q, EI, GJ);
    CHECK(both - bend == doctest::Approx(q * std::pow(R, 4) * std::pow(quarter - 1, 2) / (2 * GJ)).epsilon(1e-12));
  }

  TEST_CASE("validate: StVK lateral stretch in uniaxial stress") {
    CHECK(reference::stvk_uniaxial_lateral_stretch(1.0, 0.3) == 1.0);
    const double l = reference::stvk_uniaxial_lateral_stretch(1.2, 0.3);
    CHECK(l == doctest::Approx(std::sqrt(1 - 0.3 * 0.44)).epsilon(1e-15));
    CHECK(l < 1 - 0.3 * 0.2);  // below linear elasticity's 0.94
    CHECK(reference::incline_acceleration(9.81, std::numbers::pi / 6, 0.5) ==
          doctest::Approx(9.81 * (0.5 - 0.5 * std::sqrt(3.0) / 2)).epsilon(1e-14));
    CHECK(reference::incline_acceleration(9.81, std::numbers::pi / 6, 0.6) == 0.0);
  }

  TEST_CASE("validate: the quick suite measures every problem and its exit status says whether all passed") {
    const ValidateOptions o = quick_suite("quick");
    std::vector<ValidationRow> rows;
    const int rc = run_validate(o, &rows);
    REQUIRE(rows.size() == validation_problems(true).size());
    REQUIRE(rows.size() >= 6);
    bool all = true;
    for (const ValidationRow& r : rows) {
      CAPTURE(r.problem);
      CAPTURE(r.measured);
      CAPTURE(r.reference);
      CHECK(r.status == "ok");
      CHECK(r.pass == (r.error <= r.tolerance));
      if (!r.absolute) CHECK(std::abs(r.reference) > 0);
      CHECK(!r.source.empty());
      all = all && r.pass;
      // The membrane, friction and rod references hold to their tolerance; the hinge cantilevers
      // are reported (docs/validation.md: within 25 % on these meshes, not yet 5 %).
      if (r.problem.rfind("cantilever/", 0) == 0) CHECK(r.error < 0.25);
      else CHECK(r.pass);
    }
    CHECK(rc == (all ? 0 : exit_validation_missed));
    std::ifstream csv(o.out_dir + "/validate.csv");
    std::string line;
    int n = 0;
    while (std::getline(csv, line)) ++n;
    CHECK(n == static_cast<int>(rows.size()) + 1);
    CHECK(std::filesystem::exists(o.out_dir + "/report.md"));
    CHECK(std::filesystem::exists(o.out_dir + "/validate.json"));
  }

  TEST_CASE("validate: the thesis' bending constant misses the cantilevers by far more than the plate calibration") {
    ValidateOptions o = quick_suite("plate_k");
    o.only = {"cantilever/"};
    std::vector<ValidationRow> plate, thesis;
    run_validate(o, &plate);
    o = quick_suite("thesis_k");
    o.only = {"cantilever/"};
    o.overrides = {"cloths.0.material.bending_calibration=thesis"};
    CHECK(run_validate(o, &thesis) == exit_validation_missed);
    REQUIRE(!plate.empty());
    REQUIRE(plate.size() == thesis.size());
    for (size_t i = 0; i < plate.size(); ++i) {
      CAPTURE(plate[i].problem);
      CHECK(thesis[i].status == "ok");
      CHECK(!thesis[i].pass);
      CHECK(thesis[i].measured < 0.6 * thesis[i].reference);  // three times as stiff: about half the drop
      CHECK(thesis[i].error > 2 * plate[i].error);
    }
  }

  TEST_CASE("validate: a pinned rod root misses the rod cantilever and gravity moves the helix") {
    ValidateOptions o = quick_suite("rods_wrong");
    o.only = {"rod/cantilever", "rod/helix"};
    std::vector<ValidationRow> right, wrong;
    CHECK(run_validate(o, &right) == 0);
    o = quick_suite("rods_wrong2");
    o.only = {"rod/cantilever", "rod/helix"};
    // a pinned root vertex instead of a clamped edge lets the rod hang; gravity uncoils the helix;
    // the cloth override must not reach the rod scenes
    o.overrides = {"rods.0.root_held=vertex", "gravity=[0,0,-9.81]", "cloths.0.material.bending_calibration=thesis"};
    CHECK(run_validate(o, &wrong) == exit_validation_missed);
    REQUIRE(right.size() == 2);
    REQUIRE(wrong.size() == 2);
    for (size_t i = 0; i < right.size(); ++i) {
      CAPTURE(right[i].problem);
      CHECK(right[i].pass);
      CHECK(wrong[i].status == "ok");
      CHECK(!wrong[i].pass);
      CHECK(wrong[i].error > 10 * wrong[i].tolerance);
    }
  }

  TEST_CASE("validate: the quarter ring's deflection follows its torsional stiffness") {
    ValidateOptions o = quick_suite("ring");
    o.only = {"rod/ring"};
    std::vector<ValidationRow> stiff, soft;
    CHECK(run_validate(o, &stiff) == 0);
    o = quick_suite("ring_soft");
    o.only = {"rod/ring"};
    o.overrides = {"rods.0.material.shear_modulus=0.17 GPa"};  // half the torsional stiffness
    CHECK(run_validate(o, &soft) == 0);
    REQUIRE(stiff.size() == 1);
    REQUIRE(soft.size() == 1);
    CHECK(stiff[0].pass);
    CHECK(soft[0].pass);
    // a third of the deflection is torsion: halving GJ adds about that much, in the run as in
    // the closed form (a rod that ignored the twist would miss the softer case by 25 %)
    CHECK(soft[0].measured > 1.25 * stiff[0].measured);
    CHECK(soft[0].measured / stiff[0].measured == doctest::Approx(soft[0].reference / stiff[0].reference).epsilon(0.01));
  }

  TEST_CASE("validate: an unknown problem or a bad override is refused before any run") {
    ValidateOptions o = quick_suite("bad");
    o.only = {"no-such-problem"};
    CHECK(run_validate(o) == 2);
    CHECK(!std::filesystem::exists(o.out_dir));
    o.only.clear();
    o.overrides = {"cloths.0.material.bending_calibration=soft"};
    CHECK(run_validate(o) == 2);
    CHECK(!std::filesystem::exists(o.out_dir));
  }
}
