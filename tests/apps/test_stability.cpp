#include <doctest/doctest.h>

#include <cstdlib>

#include <algorithm>
#include <utility>

#include "apps/stability.hpp"
#include "cli_support.hpp"
#include "tests/support/rod_fixtures.hpp"

using namespace weft::app;
using namespace weft::test;

namespace {
StabilityOptions small_grid(const std::string& name) {
  StabilityOptions o = quiet_run<StabilityOptions>("hanging_cloth.json", {"cloths.0.mesh.resolution=[7,7]"}, 0.25, name);
  o.dts = {1.0 / 240, 1.0 / 24};
  o.vary_key = "cloths.0.material.youngs_modulus";
  o.vary_values = {"1e6", "1e8"};
  return o;
}
}  // namespace

TEST_SUITE("apps") {
  TEST_CASE("stability: one classified row per grid cell in the CSV and the map") {
    StabilityOptions o = small_grid("stab_grid");
    o.plots = true;
    std::vector<StabilityResult> r;
    REQUIRE(run_stability(o, &r) == 0);
    REQUIRE(r.size() == 4);
    const std::string csv = slurp(std::filesystem::path(o.out_dir) / "stability.csv");
    CHECK(std::count(csv.begin(), csv.end(), '\n') == 5);  // header + 4 rows
    for (const auto& c : r) {
      CAPTURE(c.dt);
      CAPTURE(c.value);
      CHECK(c.outcome == Stability::stable);  // this small grid is benign for the default combination
      CHECK(c.steps == c.steps_planned);
      CHECK(c.energy_ratio <= 0.1);
    }
    CHECK(slurp(std::filesystem::path(o.out_dir) / "stability_map.txt").find("cloth_ip_sa_ppcg") != std::string::npos);
    // The map as an image when Debian's matplotlib is there (the plot is skipped with a message otherwise).
    if (std::system("/usr/bin/python3 -c 'import matplotlib' >/dev/null 2>&1") == 0)
      for (const char* f : {"stability_map.png", "stability_map.svg"}) CHECK_MESSAGE(std::filesystem::exists(std::filesystem::path(o.out_dir) / f), f);
  }

  TEST_CASE("stability: failures are classified by kind") {
    StabilityOptions o = small_grid("stab_kinds");
    o.dts = {1.0 / 24};
    o.vary_values = {"1e8"};
    std::vector<StabilityResult> r;
    o.strain_threshold = 1e-9;  // any stretch at all is "excessive"
    REQUIRE(run_stability(o, &r) == 0);
    CHECK(r.at(0).outcome == Stability::excessive_strain);
    o.strain_threshold = 0.5;
    o.overrides.push_back("integrator.max_iterations=1");
    o.overrides.push_back("integrator.relative_tolerance=1e-12");
    REQUIRE(run_stability(o, &r) == 0);
    CHECK(r.at(0).outcome == Stability::not_converged);
    CHECK(r.at(0).message.find("newton") != std::string::npos);
  }

  TEST_CASE("stability: a stable run that never touched anything is told apart from one in contact") {
    // The whip at 20 rad/s: at 50 ms the rod lags behind the handle and never reaches the
    // wall; at 5 ms it strikes it. Both are stable: the map marks the first `o`.
    StabilityOptions o;
    o.scene = std::string(WEFT_SOURCE_DIR) + "/scenes/whip.json";
    o.overrides = weft::support::whip_sweep_overrides();
    o.overrides.push_back("rods.0.motion.angular_velocity=[0,0,20]");
    o.duration = 0.4;
    o.dts = {0.05, 0.005};
    o.combos = {"rods_adonis"};
    o.out_dir = temp_dir("stab_contact").string();
    o.quiet = true;
    o.plots = false;
    std::vector<StabilityResult> r;
    REQUIRE(run_stability(o, &r) == 0);
    REQUIRE(r.size() == 2);
    CHECK(r[0].outcome == Stability::stable);
    CHECK(r[0].contact_steps == 0);
    CHECK(r[1].outcome == Stability::stable);
    CHECK(r[1].contact_steps > 0);
    const std::string csv = slurp(std::filesystem::path(o.out_dir) / "stability.csv");
    CHECK(csv.find(",contact_steps,message") != std::string::npos);
    const std::string map = slurp(std::filesystem::path(o.out_dir) / "stability_map.txt");
    CHECK(map.find("o stable without any contact") != std::string::npos);
    CHECK(map.find("| o") != std::string::npos);  // the 50 ms row
  }

  TEST_CASE("stability: an invalid grid is reported before any run") {
    StabilityOptions o = small_grid("stab_invalid");
    o.combos = {"no_such_combo"};
    CHECK(run_stability(o) == 2);
    CHECK_FALSE(std::filesystem::exists(std::filesystem::path(o.out_dir) / "stability.csv"));
  }
}

namespace {
/// Largest time step h of a column such that h and every smaller step of it are stable (0 if
/// none); with `in_contact`, h must also be a run that had contacts (a run that never reached
/// the wall did not test the contact method).
double largest_stable(const std::vector<StabilityResult>& r, const std::string& combo, bool in_contact = false) {
  std::vector<const StabilityResult*> col;
  for (const auto& c : r)
    if (c.combo == combo) col.push_back(&c);
  std::sort(col.begin(), col.end(), [](auto* a, auto* b) { return a->dt < b->dt; });
  double best = 0;
  for (const StabilityResult* c : col) {
    if (c->outcome != Stability::stable) break;
    if (!in_contact || c->contact_steps > 0) best = c->dt;
  }
  return best;
}
/// The whip sweep of Figure 9.2 at `speed` rad/s for the three response methods:
/// scenes/whip.json set up as bench/rods/figure_9_2.sh sets it up (the handle 0.3 rad before
/// the wall, no gravity; `near_wall`: the wall's edge 7 cm from the axis), 1 s simulated, plus
/// `extra` overrides.
StabilityOptions whip_at(const std::string& speed, const std::string& name, std::vector<double> dts,
                         const std::vector<std::string>& extra = {}, bool near_wall = false) {
  StabilityOptions o;
  o.scene = std::string(WEFT_SOURCE_DIR) + "/scenes/whip.json";
  o.overrides = weft::support::whip_sweep_overrides(near_wall);
  o.overrides.insert(o.overrides.end(), extra.begin(), extra.end());
  o.duration = 1.0;
  o.dts = std::move(dts);
  o.vary_key = "rods.0.motion.angular_velocity.2";
  o.vary_values = {speed};
  o.combos = {"rods_impulse", "rods_linear", "rods_adonis"};
  o.out_dir = temp_dir(name).string();
  o.quiet = true;
  return o;
}

/// The whip against the near wall (edge 7 cm from the axis: every run strikes it) at `speed`
/// rad/s over `dts`, with the contact re-detection and Newton limits raised as in the
/// resolution sweep (bench/results/rods/figure_9_2_resolution/), plus `extra`: `check` runs
/// on every cell, each required to strike the wall.
template <class Check>
void near_wall_cells(const std::string& speed, const std::string& name, std::vector<double> dts, std::vector<std::string> extra,
                     Check check) {
  for (const char* o : {"contact.redetections=20", "integrator.max_iterations=200"}) extra.insert(extra.begin(), o);
  const size_t cells = 3 * dts.size();
  std::vector<StabilityResult> r;
  REQUIRE(run_stability(whip_at(speed, name, std::move(dts), extra, true), &r) == 0);
  REQUIRE(r.size() == cells);
  for (const auto& c : r) {
    CAPTURE(c.combo);
    CAPTURE(c.dt);
    CAPTURE(c.message);
    CAPTURE(c.max_strain);
    CHECK(c.contact_steps > 0);
    check(c);
  }
}
}  // namespace

TEST_CASE("V-20 with the start gap: on the near-wall whip at 10 rad/s ADONIS holds at 50 ms where linear compliance fails at 5 ms and impulses at 2 ms") {
  // contact.gap = start: a contact found by CCD may approach up to its plane (n^T d >= -gap_0)
  // instead of not at all (the thesis' n^T d >= 0, which at 50 ms froze a vertex 2 cm short of
  // the wall while the handle turned a radian and stretched the rod by 194 %). The sweep with
  // it (bench/results/rods/figure_9_2_gap_start/, 30 vertices, 1 s) gives impulses 1 ms,
  // linear compliance 2 ms and ADONIS 50 ms at this speed. Four of its steps, about 2 s.
  near_wall_cells("10", "stab_v20_gap", {0.05, 0.02, 0.005, 0.002}, {"contact.gap=start"}, [](const StabilityResult& c) {
    if (c.combo == "rods_adonis") {
      CHECK(c.outcome == Stability::stable);
      CHECK(c.max_strain <= (c.dt <= 0.02 ? 0.0101 : 0.3));  // within its stretch tolerance up to 20 ms
    } else if (c.combo == "rods_impulse") {
      CHECK(c.outcome == Stability::excessive_strain);
    } else if (c.dt == 0.005) {
      CHECK(c.outcome == Stability::excessive_strain);  // linear compliance, 10x below ADONIS's 50 ms
    } else if (c.dt == 0.002) {
      CHECK(c.outcome == Stability::stable);
      CHECK(c.max_strain > 0.02);  // but 4 % where ADONIS keeps 1 %
    }
  });
}

TEST_SUITE("slow") {
  // methods/rod-contact V-20 in reduced form (bench/rods/figure_9_2.sh runs the full sweep): the whip of
  // scenes/whip.json at the highest speed of the sweep, 20 rad/s, set up as the figure's sweep
  // (the handle starting 0.3 rad before the wall, no gravity: see the script), 1 s simulated
  // instead of 5 s, on a coarse sweep of 8 steps from 0.5 ms to 100 ms. About 1-2 minutes.
  TEST_CASE("V-20 reduced: the whip at 20 rad/s - ADONIS's largest stable step in contact beats linear compliance's and is 10x impulses'") {
    const StabilityOptions o = whip_at("20", "stab_v20", {0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001, 0.0005});
    std::vector<StabilityResult> r;
    REQUIRE(run_stability(o, &r) == 0);
    REQUIRE(r.size() == 24);
    // At 20 ms and above the rod lags so far behind the handle under backward Euler that it
    // never reaches the wall: those runs are stable for every method and test nothing. Only
    // runs with contacts count (the thesis' 100x for ADONIS is not reproduced: see
    // bench/results/rods/figure_9_2/summary.md).
    const double impulse = largest_stable(r, "rods_impulse", true), linear = largest_stable(r, "rods_linear", true),
                 adonis = largest_stable(r, "rods_adonis", true);
    int no_contact = 0;
    for (const auto& c : r) no_contact += c.outcome == Stability::stable && c.contact_steps == 0;
    MESSAGE("largest stable step in contact: impulse " << impulse << " s, linear compliance " << linear << " s, ADONIS " << adonis
                                                        << " s (all runs: " << largest_stable(r, "rods_adonis") << " s; " << no_contact
                                                        << " stable runs never touched the wall)");
    REQUIRE(linear > 0);
    REQUIRE(impulse > 0);
    CHECK(adonis > linear);
    CHECK(adonis >= 10 * impulse * (1 - 1e-9));
    // ADONIS keeps the rod inextensible where it is in contact: the strain stays below 1 %
    // at every step size up to 50 ms (impulses and linear compliance stretch it by 8 % and
    // more). At 100 ms the step in contact ends at the iteration limit (20 Newton iterations),
    // where the strain depends on rounding: 0.36 % with OpenBLAS's SkylakeX kernels, 3.8 %
    // with its Haswell kernels; there it stays below 5 %.
    for (const auto& c : r)
      if (c.combo == "rods_adonis" && c.outcome == Stability::stable) {
        CAPTURE(c.dt);
        CHECK(c.max_strain < (c.dt <= 0.05 ? 0.01 : 0.05));
      }
    // V-20 also asks for the linear and impulse maxima within 3x of each other (the thesis'
    // regions "largely overlap"). Here linear compliance is stable up to 5 ms and impulses only
    // up to 0.5 ms (impulses stretch the whip beyond 50 % from 1 ms to 10 ms): a deviation
    // from the thesis reported in bench/results/rods/figure_9_2/summary.md, warned, not asserted.
    WARN_MESSAGE(std::max(linear, impulse) <= 3 * std::min(linear, impulse),
                 "V-20: linear and impulse maxima differ by more than 3x (" << linear << " s against " << impulse << " s)");
  }

  TEST_CASE("V-20 at 120 vertices: ADONIS stable at 20 ms and within 1 % at 10 ms where impulses fail at 0.5 ms and linear compliance stretches by more than 5 %") {
    // The whip against the near wall (every run strikes it) at 120 vertices (1.7 mm edges)
    // and 20 rad/s, with the contact re-detection and Newton limits raised as in the
    // resolution sweep (bench/results/rods/figure_9_2_resolution/). The full sweep gives
    // impulses 0.05 ms, linear compliance 5 ms and ADONIS 20 ms by the thesis' 50 % rule,
    // and at 1 % strain neither impulses nor linear compliance down to 50 us against 10 ms
    // for ADONIS. This checks four step sizes of it (about 15 s).
    near_wall_cells("20", "stab_v20_fine", {0.02, 0.01, 0.001, 0.0005}, {"rods.0.vertices=120"}, [](const StabilityResult& c) {
      if (c.combo == "rods_adonis") {
        CHECK(c.outcome == Stability::stable);
        if (c.dt <= 0.01) CHECK(c.max_strain <= 0.0101);  // its stretch tolerance, 1 %
      } else if (c.combo == "rods_impulse") {
        CHECK(c.outcome == Stability::excessive_strain);  // even at 0.5 ms: ADONIS / impulse >= 40 here
      } else if (c.dt >= 0.01) {
        CHECK(c.outcome == Stability::excessive_strain);  // linear compliance at 10 and 20 ms
      } else {
        CHECK(c.outcome == Stability::stable);
        CHECK(c.max_strain > 0.05);  // stable by the 50 % rule, but stretched by 10-35 %
      }
    });
  }
}
