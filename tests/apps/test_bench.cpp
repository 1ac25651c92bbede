// `weft bench bending --quick`: the report is printed, the three Hessians agree, the fits
// are finite and the files are written.
#include <doctest/doctest.h>

#include <unistd.h>

#include <cmath>

#include "cli_support.hpp"

using namespace weft::test;
namespace fs = std::filesystem;
using nlohmann::json;

TEST_SUITE("apps") {
  TEST_CASE("bench: weft bench bending --quick prints the Table 5.1 and 5.2 report") {
    const auto dir = temp_dir("bench_bending_" + std::to_string(getpid()));
    const Result r = run_weft(fmt::format("bench bending --quick --out {} --scene {}/scenes/hanging_cloth.json", dir.string(), WEFT_SOURCE_DIR));
    CAPTURE(r.output);
    REQUIRE(r.code == 0);
    for (const char* s : {"Table 5.2", "Table 5.1", "HANGING CLOTH", "not** the thesis' cloth-sphere", "Hardware:", "| 23 |",
                          "speedup of N vs S", "speedup of N vs A", "N vs S", "N vs A", "S vs A", "hinges/s",
                          "repetition count in parentheses", "(4 steps)", "PSD-projected Hessian", "P/S"})
      CHECK_MESSAGE(r.output.find(s) != std::string::npos, s);

    // One JSON line per resolution and method, then the fit.
    const auto lines = read_jsonl(dir / "bench_bending.jsonl");
    REQUIRE(lines.size() == 4 * 3 + 1);
    for (size_t i = 0; i + 1 < lines.size(); ++i) {
      const json& j = lines[i];
      CAPTURE(j.dump());
      CHECK(j.at("forces_hessian").at("reps").get<int>() >= 3);
      CHECK(j.at("forces_hessian").at("min_s").get<double>() > 0);
      CHECK(j.at("forces_hessian_assembly").at("min_s").get<double>() > 0);  // no timing comparisons: the builder is shared
      CHECK(j.at("projected_forces_hessian").at("reps").get<int>() >= 3);
      CHECK(j.at("projected_forces_hessian").at("min_s").get<double>() > 0);
      CHECK(j.at("recording").at("steps").get<int>() == 4);
      for (const char* p : {"refactored_per_hinge", "refactored_autodiff", "per_hinge_autodiff"}) {
        const double u = j.at("ulp").at(p).get<double>();
        CHECK(std::isfinite(u));
        CHECK(u < 16);
      }
      CHECK(j.at("max_theta").at(0).get<double>() > 0);
    }
    const json& fit = lines.back();
    CAPTURE(fit.dump());
    for (const char* part : {"forces_hessian", "forces_hessian_assembly"}) {
      CHECK(std::isfinite(fit.at(part).at("k_common").get<double>()));
      for (const char* m : {"refactored", "per_hinge", "autodiff"}) {
        CHECK(std::isfinite(fit.at(part).at(m).at("k_own").get<double>()));
        CHECK(std::isfinite(fit.at(part).at(m).at("ln_a").get<double>()));
      }
    }
    CHECK(fs::exists(dir / "bench_bending.csv"));
    CHECK(slurp(dir / "bench_bending.md").find("Table 5.2") != std::string::npos);
    fs::remove_all(dir);
  }
}
