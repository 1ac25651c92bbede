// `linear.solver`: a scene swaps the linear solver of its combination for a pre-built sibling.
#include <doctest/doctest.h>

#include <cmath>

#include "cli_support.hpp"
#include "policies/registry.hpp"

using namespace weft::test;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct Run {
  Result r;
  json summary;
};

Run run_with(const std::string& name, const json& scene, const std::string& args) {
  const auto dir = temp_dir(name);
  const std::string path = write_file(dir / "scene.json", scene.dump(2));
  Run run{run_weft(fmt::format("run -q {} --out {} {}", path, (dir / "out").string(), args)), {}};
  if (fs::exists(dir / "out" / "summary.json")) run.summary = json::parse(slurp(dir / "out" / "summary.json"));
  return run;
}

/// Whether this build has the pre-built combination `key` (the back ends add theirs).
bool built(std::string_view key) {
  for (const auto& c : weft::combos())
    if (c.key == key) return true;
  return false;
}

/// The small pinned sheet swinging under gravity for 0.1 s: Newton systems with pins.
json swinging_sheet() {
  json s = small_scene();
  s["output"] = {{"obj", false}, {"vtp", false}, {"stats", false}};
  return s;
}

}  // namespace

TEST_SUITE("apps") {
  TEST_CASE("linear.solver: each solver this build has runs the sheet to the end with the same motion") {
    const json scene = swinging_sheet();
    const Run ref = run_with("lsk_ref", scene, "");
    REQUIRE_MESSAGE(ref.r.code == 0, ref.r.output);
    REQUIRE(ref.summary["combo"] == "cloth_ip_direct");
    const double ref_gravity = ref.summary["final_energy"]["gravity"].get<double>();
    const double ref_kinetic = ref.summary["final_energy"]["kinetic"].get<double>();
    // Guard: the sheet has moved, so equal energies say the same motion, not a sheet at rest.
    REQUIRE(ref_kinetic > 1e-3 * std::abs(ref_gravity));
    std::vector<std::string> solvers = {"direct", "diag_pcg", "diag_ppcg", "sa_ppcg", "sa_mpcg"};
    for (const char* backend : {"cholmod", "petsc_gamg"})
      if (built(std::string("cloth_ip_") + backend)) solvers.emplace_back(backend);
    for (const std::string& solver : solvers) {
      CAPTURE(solver);
      const Run run = run_with("lsk_" + solver, scene, "linear.solver=" + solver);
      REQUIRE_MESSAGE(run.r.code == 0, run.r.output);
      CHECK(run.summary["combo"] == "cloth_ip_" + solver);
      CHECK(run.summary["status"] == "completed");
      CHECK(run.summary["steps"] == ref.summary["steps"]);
      // Iterative solvers report their iterations; the direct ones none: the swap happened.
      const bool direct = solver == "direct" || solver == "cholmod";
      CHECK((run.summary["linear_iterations"]["total"].get<long long>() > 0) == !direct);
      // Every solve meets the Newton tolerance: the same trajectory to well within its motion.
      CHECK(run.summary["final_energy"]["gravity"].get<double>() == doctest::Approx(ref_gravity).epsilon(1e-4));
      CHECK(run.summary["final_energy"]["kinetic"].get<double>() == doctest::Approx(ref_kinetic).epsilon(1e-3));
      // The effective scene the run wrote runs it again: the combination that ran, the same end.
      const json effective = json::parse(slurp(fs::temp_directory_path() / ("weft_test_lsk_" + solver) / "out" / "scene.json"));
      CHECK(effective["combo"] == "cloth_ip_" + solver);
      const Run again = run_with("lsk_again_" + solver, effective, "");
      REQUIRE_MESSAGE(again.r.code == 0, again.r.output);
      CHECK(again.summary["final_energy"] == run.summary["final_energy"]);
      if (solver == "sa_ppcg") CHECK(effective["linear"]["preconditioner"] == json{{"preset", "auto"}});  // auto picks again by size
    }
  }

  TEST_CASE("linear.solver = auto takes the direct solver below its size threshold and SA+PPCG from it on") {
    const int threshold = weft::auto_iterative_min_vertices;
    const int n_large = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(threshold))));
    const int n_small = n_large - 1;
    REQUIRE(n_small * n_small < threshold);
    REQUIRE(n_large * n_large >= threshold);
    json scene = swinging_sheet();
    scene["time"]["duration"] = 0.01;  // one step
    for (const auto& [n, combo] : {std::pair{n_small, "cloth_ip_direct"}, std::pair{n_large, "cloth_ip_sa_ppcg"}}) {
      CAPTURE(n);
      scene["cloths"][0]["mesh"]["resolution"] = {n, n};
      const Run run = run_with("lsk_auto_" + std::to_string(n), scene, "linear.solver=auto");
      REQUIRE_MESSAGE(run.r.code == 0, run.r.output);
      CHECK(run.summary["combo"] == combo);
      CHECK(run.summary["vertices"] == n * n);
    }
    // A family without SA+PPCG keeps its own solver at any size (the tangent bending energy: direct only).
    scene["combo"] = "cloth_tan_ip_direct";
    const Run tan = run_with("lsk_auto_tan", scene, "linear.solver=auto");
    REQUIRE_MESSAGE(tan.r.code == 0, tan.r.output);
    CHECK(tan.summary["combo"] == "cloth_tan_ip_direct");
  }

  TEST_CASE("linear.solver: a name the build or the family lacks is refused with exit 2 before any work") {
    struct Bad {
      std::string value;
      std::string combo;
      std::vector<std::string> fragments;
    };
    std::vector<Bad> bad = {
        {"\"superlu\"", "cloth_ip_direct", {"linear.solver = \"superlu\" is not a linear solver: valid are auto, direct, cholmod"}},
        {"3", "cloth_ip_direct", {"linear.solver = 3: a solver name is expected"}},
        {"\"diag_ppcg\"", "cloth_ip_impulse_direct",
         {"linear.solver = \"diag_ppcg\": no pre-built combination has the energy, integrator and contact of combo = "
          "\"cloth_ip_impulse_direct\"",
          "direct (cloth_ip_impulse_direct), sa_ppcg (cloth_ip_impulse_sa_ppcg)"}},
    };
    if (!built("cloth_ip_cholmod")) bad.push_back({"\"cholmod\"", "cloth_ip_direct", {"no cholmod back end", "-DWEFT_WITH_CHOLMOD=ON"}});
    if (!built("cloth_ip_petsc_gamg"))
      bad.push_back({"\"petsc_gamg\"", "cloth_ip_direct", {"no petsc_gamg back end", "-DWEFT_WITH_PETSC=ON"}});
    for (const Bad& b : bad) {
      CAPTURE(b.value);
      json scene = swinging_sheet();
      scene["combo"] = b.combo;
      scene["linear"] = {{"solver", json::parse(b.value)}};
      const auto dir = temp_dir("lsk_bad");
      const std::string path = write_file(dir / "scene.json", scene.dump(2));
      const Result r = run_weft(fmt::format("run -q {} --out {}", path, (dir / "out").string()));
      CAPTURE(r.output);
      CHECK(r.code == 2);
      CHECK(r.output.find(path) != std::string::npos);
      for (const auto& f : b.fragments) CHECK_MESSAGE(r.output.find(f) != std::string::npos, f);
      CHECK_FALSE(fs::exists(dir / "out"));
    }
  }

  TEST_CASE("linear.solver: a combination named on the command line keeps its own solver") {
    // The scene asks for SA+PPCG; `weft ablate --combos cloth_ip_direct` must still run LDL^T.
    json scene = swinging_sheet();
    scene["linear"] = {{"solver", "sa_ppcg"}};
    std::vector<std::string> ov;
    weft::append_combo_overrides(ov, "cloth_ip_direct");
    REQUIRE(ov == std::vector<std::string>{"combo=cloth_ip_direct", "linear.solver=direct"});
    const Run swapped = run_with("lsk_scene_key", scene, "");
    REQUIRE_MESSAGE(swapped.r.code == 0, swapped.r.output);
    CHECK(swapped.summary["combo"] == "cloth_ip_sa_ppcg");
    const Run pinned = run_with("lsk_pinned", scene, fmt::format("{} {}", ov[0], ov[1]));
    REQUIRE_MESSAGE(pinned.r.code == 0, pinned.r.output);
    CHECK(pinned.summary["combo"] == "cloth_ip_direct");
  }
}
