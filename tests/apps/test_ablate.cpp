// `weft ablate`: the reference has zero error against itself; halving dt and
// tightening a tolerance do not increase the error; the CSV has one row per combination;
// plots are written when matplotlib is there and skipped with a message when it is not; a
// simulator without contact spends no time in contact code; bad input is refused before any run;
// `weft render` forwards to scripts/weft_render.py.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>

#include "ablate_support.hpp"
#include "apps/ablate.hpp"
#include "cli_support.hpp"
#include "framework/timers.hpp"
#include "policies/registry.hpp"

using namespace weft;
using namespace weft::app;
using namespace weft::test;

namespace {
/// The hanging cloth at 7 x 7 vertices over 0.25 s (6 frames at 24 frames/s).
AblateOptions tiny(const std::string& name) {
  return quiet_run<AblateOptions>("hanging_cloth.json", {"cloths.0.mesh.resolution=[7,7]"}, 0.25, name);
}
int lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }
}  // namespace

TEST_SUITE("apps") {
  TEST_CASE("ablate: the reference has zero error against itself") {
    const AblateRow row = self_reference(tiny("ablate_self"), "cloth_ip_direct");
    CHECK(row.status == "ok");
    CHECK(row.frames_compared == 6);
    CHECK(row.rms_error == 0);
    CHECK(row.max_error == 0);
    CHECK(row.newton_iterations > 0);
  }

  TEST_CASE("ablate: halving dt or tightening the Newton tolerance does not increase the error") {
    // The same reference every time: dt / 8 of the scene's step.
    AblateOptions coarse = tiny("ablate_dt1"), fine = tiny("ablate_dt2");
    coarse.combos = fine.combos = {"cloth_ip_direct"};
    coarse.reference_substeps = 8;
    fine.reference_substeps = 4;
    fine.overrides.push_back("time.dt=0.0020833333333333333");
    std::vector<AblateRow> a, b;
    REQUIRE(run_ablate(coarse, &a) == 0);
    REQUIRE(run_ablate(fine, &b) == 0);
    CHECK(a[0].rms_error > 0);
    CHECK(b[0].rms_error < a[0].rms_error);
    CHECK(b[0].max_error <= a[0].max_error);
    MESSAGE("rms error at dt, dt/2: " << a[0].rms_error << ", " << b[0].rms_error);

    // Against a reference at the same dt (tight tolerances) the error is the solver's alone.
    AblateOptions loose = tiny("ablate_tol1"), tight = tiny("ablate_tol2");
    loose.combos = tight.combos = {"cloth_ip_direct"};
    loose.reference_substeps = tight.reference_substeps = 1;
    loose.overrides.push_back("integrator.relative_tolerance=0.3");
    loose.overrides.push_back("integrator.length_tolerance=0");
    tight.overrides.push_back("integrator.relative_tolerance=1e-8");
    tight.overrides.push_back("integrator.length_tolerance=0");
    REQUIRE(run_ablate(loose, &a) == 0);
    REQUIRE(run_ablate(tight, &b) == 0);
    CHECK(b[0].newton_iterations > a[0].newton_iterations);  // the tolerance does bite
    CHECK(a[0].rms_error > 0);
    CHECK(b[0].rms_error < a[0].rms_error);
    MESSAGE("rms error at relative tolerance 0.3, 1e-8: " << a[0].rms_error << ", " << b[0].rms_error);
  }

  TEST_CASE("ablate: one CSV row per applicable combination and no contact time without contact") {
    AblateOptions o = tiny("ablate_applicable");
    o.combos = {"applicable"};
    o.duration = 1.0 / 24;
    std::vector<AblateRow> rows;
    REQUIRE(run_ablate(o, &rows) == 0);
    const Scene scene = load_scene(o.scene, o.overrides);
    int applicable = 0;
    for (const ComboInfo& c : combos()) applicable += not_applicable_reason(c, scene).empty();
    CHECK(applicable >= 5);
    CHECK(static_cast<int>(rows.size()) == applicable);
    const std::string csv = slurp(std::filesystem::path(o.out_dir) / "ablate.csv");
    CHECK(lines(csv) == applicable + 1);
    const nlohmann::json doc = nlohmann::json::parse(slurp(std::filesystem::path(o.out_dir) / "ablate.json"));
    CHECK(doc["rows"].size() == rows.size());
    int with_contact = 0;
    for (const AblateRow& r : rows) {
      CAPTURE(r.combo);
      CHECK(r.status == "ok");
      const double contact_seconds = r.stage_seconds[static_cast<int>(Stage::contact)];
      const bool has_contact = std::any_of(combos().begin(), combos().end(),
                                           [&](const ComboInfo& c) { return c.key == r.combo && c.contact != "none"; });
      // A simulator without contact never enters the contact stage: not one timer tick.
      if (!has_contact) CHECK(contact_seconds == 0);
      else {
        CHECK(contact_seconds > 0);
        ++with_contact;
      }
    }
    CHECK(with_contact > 0);
  }

  TEST_CASE("ablate: the command line writes plots when matplotlib is there and says why not otherwise") {
    const auto dir = temp_dir("ablate_cli");
    const Result r = run_weft(fmt::format("ablate {}/scenes/hanging_cloth.json cloths.0.mesh.resolution=[7,7] --combos cloth_ip_direct "
                                          "cloth_tan_ip_direct --duration 0.125 --out {} -q",
                                          WEFT_SOURCE_DIR, dir.string()));
    INFO(r.output);
    REQUIRE(r.code == 0);
    CHECK(r.output.find("| cloth_tan_ip_direct | ok |") != std::string::npos);
    const bool matplotlib = std::system("/usr/bin/python3 -c 'import matplotlib' >/dev/null 2>&1") == 0;
    if (matplotlib) {
      for (const char* f : {"pareto.png", "pareto.svg", "stages.png", "stages.svg", "histories.png"})
        CHECK_MESSAGE(std::filesystem::exists(dir / f), f);
    } else {
      CHECK(r.output.find("plot skipped: python3-matplotlib is not installed") != std::string::npos);
      CHECK(!std::filesystem::exists(dir / "pareto.png"));
    }
  }

  TEST_CASE("ablate: a time step sweep gives backward Euler's first-order error with one CSV row per point") {
    AblateOptions o = tiny("ablate_sweep");
    o.combos = {"cloth_ip_direct"};
    o.sweeps = {"time.dt=0.020833333333333332,0.010416666666666666,0.005208333333333333"};  // frame / 2, 4, 8
    std::vector<AblateRow> rows;
    REQUIRE(run_ablate(o, &rows) == 0);
    REQUIRE(rows.size() == 3);
    for (const AblateRow& r : rows) CHECK(r.status == "ok");
    CHECK(rows[0].point == "time.dt=0.020833333333333332");
    // The one reference runs at the smallest dt / 4; each halving of dt halves the error.
    for (int i = 0; i + 1 < 3; ++i) {
      CAPTURE(i);
      REQUIRE(rows[i + 1].rms_error > 0);
      CHECK(rows[i + 1].rms_error < rows[i].rms_error);
      const double slope = std::log2(rows[i].rms_error / rows[i + 1].rms_error);
      CAPTURE(slope);
      CHECK(slope > 0.7);
      CHECK(slope < 1.4);
    }
    std::ifstream csv(o.out_dir + "/ablate.csv");
    std::string header, line;
    std::getline(csv, header);
    CHECK(header.rfind("combo,point,label,", 0) == 0);
    int n = 0;
    while (std::getline(csv, line)) ++n;
    CHECK(n == 3);
    // Two sweeps: their product.
    AblateOptions two = tiny("ablate_sweep2");
    two.combos = {"cloth_ip_direct", "cloth_tan_ip_direct"};
    two.sweeps = {"time.dt=0.020833333333333332,0.010416666666666666", "integrator.relative_tolerance=1e-4,1e-8"};
    REQUIRE(run_ablate(two, &rows) == 0);
    CHECK(rows.size() == 8);
    CHECK(rows.back().point == "time.dt=0.010416666666666666 integrator.relative_tolerance=1e-8");
    // A malformed sweep is refused before any run.
    AblateOptions bad = tiny("ablate_sweep_bad");
    bad.combos = {"cloth_ip_direct"};
    bad.sweeps = {"time.dt"};
    CHECK(run_ablate(bad) == 2);
    CHECK(!std::filesystem::exists(bad.out_dir + "/ablate.csv"));
  }

  TEST_CASE("ablate: a combination that does not apply is refused before any run") {
    const auto dir = temp_dir("ablate_bad");
    const Result r = run_weft(fmt::format("ablate {}/scenes/hanging_cloth.json --combos cloth_ip_direct rods_adonis nonsense --out {}",
                                          WEFT_SOURCE_DIR, (dir / "out").string()));
    INFO(r.output);
    CHECK(r.code == 2);
    CHECK(r.output.find("\"rods_adonis\" does not apply to this scene: the scene has no rods") != std::string::npos);
    CHECK(r.output.find("\"nonsense\" is not a pre-built combination") != std::string::npos);
    CHECK(!std::filesystem::exists(dir / "out"));
  }

  TEST_CASE("render: the command forwards to the renderer which names bad input") {
    const Result r = run_weft("render /nonexistent_weft_run_dir");
    INFO(r.output);
    CHECK(r.code == 2);
    CHECK(r.output.find("/nonexistent_weft_run_dir: no such directory") != std::string::npos);
    const Result help = run_weft("render --help");
    CHECK(help.code == 0);
    CHECK(help.output.find("--side-by-side") != std::string::npos);
  }
}
