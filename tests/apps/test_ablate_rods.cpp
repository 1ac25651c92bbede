// `weft ablate` on rods: the ablation driver of tests/apps/test_ablate.cpp, on a
// rod scene with contact instead of cloth. The rod pile of scenes/rod_pile.json reduced to one
// rod per layer at 8 vertices, 0.06 s (3 frames at 50 frames/s, 30 steps at 2 ms): the lowest
// layer lands on the ground plane at about 45 ms, so every run has contacts.
#include <doctest/doctest.h>

#include <algorithm>

#include "ablate_support.hpp"
#include "apps/ablate.hpp"
#include "cli_support.hpp"
#include "framework/timers.hpp"
#include "policies/registry.hpp"

using namespace weft;
using namespace weft::app;
using namespace weft::test;

namespace {
AblateOptions tiny_pile(const std::string& name) {
  std::vector<std::string> overrides;
  for (int layer = 0; layer < 4; ++layer) {
    overrides.push_back(fmt::format("rods.{}.count=1", layer));
    overrides.push_back(fmt::format("rods.{}.vertices=8", layer));
  }
  return quiet_run<AblateOptions>("rod_pile.json", std::move(overrides), 0.06, name);
}
}  // namespace

TEST_SUITE("apps") {
  TEST_CASE("ablate rods: the reference has zero error against itself on a tiny rod pile") {
    const AblateRow row = self_reference(tiny_pile("ablate_rods_self"), "rods_impulse");
    CHECK(row.status == "ok");
    CHECK(row.steps == 30);
    CHECK(row.frames_compared == 3);
    CHECK(row.contacts > 0);  // the comparison includes contact, not only free fall
    CHECK(row.rms_error == 0);
    CHECK(row.max_error == 0);
    CHECK(row.newton_iterations > 0);
    CHECK(row.penetrations_max == 0);
  }

  TEST_CASE("ablate rods: one CSV row per applicable rod combination against a tightened direct reference") {
    AblateOptions o = tiny_pile("ablate_rods_applicable");
    o.combos = {"applicable"};
    o.reference_substeps = 2;
    std::vector<AblateRow> rows;
    REQUIRE(run_ablate(o, &rows) == 0);
    const Scene scene = load_scene(o.scene, o.overrides);
    std::vector<std::string> applicable;
    for (const ComboInfo& c : combos())
      if (not_applicable_reason(c, scene).empty()) applicable.emplace_back(c.key);
    CHECK(applicable.size() >= 3);  // impulse, linear compliance, ADONIS (and staggered projections)
    for (const std::string& c : applicable) {
      CAPTURE(c);
      CHECK(c.rfind("rods_", 0) == 0);  // a rod scene never instantiates a cloth simulator
      CHECK(c != "rods_none");          // the ground plane needs a contact strategy
    }
    REQUIRE(rows.size() == applicable.size());
    const std::string csv = slurp(std::filesystem::path(o.out_dir) / "ablate.csv");
    CHECK(std::count(csv.begin(), csv.end(), '\n') == static_cast<long>(applicable.size()) + 1);
    for (size_t k = 0; k < rows.size(); ++k) {
      const AblateRow& r = rows[k];
      CAPTURE(r.combo);
      CHECK(r.combo == applicable[k]);
      CHECK(r.status == "ok");
      CHECK(r.frames_compared == 3);
      CHECK(r.contacts > 0);
      CHECK(r.stage_seconds[static_cast<int>(Stage::contact)] > 0);
      CHECK(r.rms_error > 0);      // dt against dt / 2: not the reference itself
      CHECK(r.rms_error < 0.01);   // but close to it: millimetres on a 15 cm pile
      CHECK(r.max_error >= r.rms_error);
      CHECK(r.penetrations_max == 0);
    }
    // The reference: the scene's own combination (rods solve with a banded direct solver),
    // with the rod integrator's own tolerance tightened (the cloth keys do not apply to rods).
    const nlohmann::json doc = nlohmann::json::parse(slurp(std::filesystem::path(o.out_dir) / "ablate.json"));
    CHECK(doc["reference"]["combo"] == "rods_adonis");
    CHECK(doc["reference"]["status"] == "ok");
    const auto& ov = doc["reference"]["overrides"];
    CHECK(std::find(ov.begin(), ov.end(), "integrator.tolerance=1e-12") != ov.end());
    CHECK(std::find(ov.begin(), ov.end(), "time.dt=0.001") != ov.end());
  }
}
