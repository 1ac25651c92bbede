// `weft bench hair --quick`: one CSV row per (strategy, time step) with its columns, the
// Markdown report with the thesis' table, one JSON line per step; --resume skips what the
// CSV holds; an unknown strategy is a configuration error (exit 2) before any run.
#include <doctest/doctest.h>

#include <unistd.h>

#include <algorithm>
#include <set>
#include <sstream>

#include "cli_support.hpp"

using namespace weft::test;
namespace fs = std::filesystem;

namespace {

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::string item;
  std::stringstream ss(line);
  while (std::getline(ss, item, ',')) out.push_back(item);
  return out;
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string line;
  while (std::getline(ss, line)) out.push_back(line);
  return out;
}

}  // namespace

TEST_SUITE("apps") {
  TEST_CASE("bench: weft bench hair --quick writes one CSV row per strategy and time step") {
    const auto dir = temp_dir("bench_hair_" + std::to_string(getpid()));
    const Result r = run_weft(fmt::format("--threads 1 bench hair --quick --out {}", dir.string()));
    CAPTURE(r.output);
    REQUIRE(r.code == 0);
    for (const char* s : {"weft bench hair: hairball_1000 (8 rods of 30 vertices)", "Hardware:", "rods_adonis", "10 ms", "5 ms"})
      CHECK_MESSAGE(r.output.find(s) != std::string::npos, s);

    const std::vector<std::string> csv = lines_of(slurp(dir / "bench_hair.csv"));
    REQUIRE(csv.size() == 1 + 3 * 2);
    const std::vector<std::string> header = split(csv[0]);
    for (const char* col : {"scene", "rods", "strategy", "dt", "outcome", "success", "steps", "steps_planned", "wall_s",
                            "contacts_mean", "contacts_max", "groups_mean", "newton_per_group_mean", "newton_per_group_weighted",
                            "newton_per_group_max", "gs_sweeps_per_step", "max_strain", "message"})
      CHECK_MESSAGE(std::find(header.begin(), header.end(), col) != header.end(), col);
    auto col = [&](const std::vector<std::string>& row, const std::string& name) {
      const auto it = std::find(header.begin(), header.end(), name);
      REQUIRE(it != header.end());
      return row.at(it - header.begin());
    };
    std::set<std::pair<std::string, std::string>> runs;
    for (size_t i = 1; i < csv.size(); ++i) {
      const std::vector<std::string> row = split(csv[i]);
      CAPTURE(csv[i]);
      REQUIRE(row.size() >= header.size());  // the quoted message may hold commas
      runs.insert({col(row, "strategy"), col(row, "dt")});
      CHECK(col(row, "rods") == "8");
      const std::string outcome = col(row, "outcome");
      CHECK((outcome == "stable" || outcome == "diverged" || outcome == "not_converged" || outcome == "excessive_strain"));
      CHECK(std::stoi(col(row, "steps_planned")) == (col(row, "dt") == "0.01" ? 2 : 4));
      if (outcome == "stable") CHECK(col(row, "steps") == col(row, "steps_planned"));
      CHECK(std::stod(col(row, "wall_s")) > 0);
      CHECK(std::stod(col(row, "newton_per_group_mean")) >= 0);
      CHECK(std::stod(col(row, "max_strain")) >= 0);
    }
    CHECK(runs == std::set<std::pair<std::string, std::string>>{{"rods_impulse", "0.01"}, {"rods_impulse", "0.005"},
                                                                 {"rods_linear", "0.01"},  {"rods_linear", "0.005"},
                                                                 {"rods_adonis", "0.01"},  {"rods_adonis", "0.005"}});
    const std::string md = slurp(dir / "bench_hair.md");
    for (const char* s : {"| strategy | 10 ms | 5 ms |", "| 1K | ADONIS | ✗ | 3h42m |", "Newton/group mean"})
      CHECK_MESSAGE(md.find(s) != std::string::npos, s);
    // A meta record, one line per step (2 + 4 per strategy when stable) and one per run.
    const auto jl = read_jsonl(dir / "bench_hair.jsonl");
    REQUIRE(!jl.empty());
    CHECK(jl.front().at("record") == "meta");
    int steps = 0, run_records = 0;
    for (const auto& j : jl) {
      steps += j.at("record") == "step";
      run_records += j.at("record") == "run";
    }
    CHECK(run_records == 6);
    CHECK(steps <= 3 * 6);
    CHECK(steps > 0);

    // --resume: nothing left to run, the CSV is kept.
    const Result again = run_weft(fmt::format("--threads 1 bench hair --quick --resume --out {}", dir.string()));
    CHECK(again.code == 0);
    CHECK(lines_of(slurp(dir / "bench_hair.csv")).size() == 1 + 3 * 2);

    const Result bad = run_weft(fmt::format("bench hair --quick --strategies rods_bogus --out {}", dir.string()));
    CHECK(bad.code == 2);
    CHECK(bad.output.find("rods_bogus") != std::string::npos);
    fs::remove_all(dir);
  }
}
