// `weft bench contact --quick`: the table is printed, the CSV has its columns and one row per
// resolution, the shares are fractions of the step time, and the exact intersection check
// found nothing. A bad resolution is a configuration error (exit 2) before any work. A suite
// (`--suite shrunk`) runs each of its cases, checks every step for intersections and obstacle
// crossings and reports the step-time spread and whether each run completed.
#include <doctest/doctest.h>

#include <unistd.h>

#include <cmath>
#include <sstream>

#include "cli_support.hpp"

using namespace weft::test;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::string item;
  std::stringstream ss(line);
  while (std::getline(ss, item, ',')) out.push_back(item);
  return out;
}

// The field of a CSV row under the header's column `name`.
std::string column(const std::vector<std::string>& header, const std::vector<std::string>& row, const std::string& name) {
  const auto it = std::find(header.begin(), header.end(), name);
  REQUIRE_MESSAGE(it != header.end(), name);
  return row.at(it - header.begin());
}

}  // namespace

TEST_SUITE("apps") {
  TEST_CASE("bench: weft bench contact --quick writes one CSV row per resolution") {
    const auto dir = temp_dir("bench_contact_" + std::to_string(getpid()));
    // The dropHorizontal box at two tiny resolutions, dropped from 3 mm so that the four
    // counted steps have obstacle contacts.
    const Result r = run_weft(fmt::format("--threads 1 bench contact {}/scenes/drop_horizontal.json --quick --check "
                                          "--resolutions 7 9 --skip 2 --out {} 'cloths.0.mesh.center=[0,0,0.003]'",
                                          WEFT_SOURCE_DIR, dir.string()));
    CAPTURE(r.output);
    REQUIRE(r.code == 0);
    for (const char* s : {"weft bench contact: drop_horizontal", "Hardware:", "| 7x7 | 49 |", "| 9x9 | 81 |", "detection",
                          "counted steps 3..6"})
      CHECK_MESSAGE(r.output.find(s) != std::string::npos, s);

    std::stringstream csv(slurp(dir / "bench_contact.csv"));
    std::string line;
    REQUIRE(std::getline(csv, line));
    const std::vector<std::string> header = split(line);
    for (const char* col : {"scene", "combo", "resolution", "vertices", "steps", "seconds_per_step", "detection_share",
                            "response_share", "solve_share", "contacts_per_step", "ccd_hits_per_step", "impact_zones_per_step",
                            "newton_per_step", "linear_per_step", "intersections", "status"})
      CHECK_MESSAGE(std::find(header.begin(), header.end(), col) != header.end(), col);
    auto col = [&](const std::vector<std::string>& row, const std::string& name) { return column(header, row, name); };
    int rows = 0;
    while (std::getline(csv, line)) {
      const std::vector<std::string> row = split(line);
      CAPTURE(line);
      REQUIRE(row.size() == header.size());
      ++rows;
      CHECK(col(row, "combo") == "cloth_ip_barrier_sa_ppcg");  // the scene's
      CHECK(col(row, "vertices") == (rows == 1 ? "49" : "81"));
      CHECK(std::stoi(col(row, "steps")) == 4);
      CHECK(std::stod(col(row, "seconds_per_step")) > 0);
      double shares = 0;
      for (const char* s : {"detection_share", "response_share", "solve_share"}) {
        const double x = std::stod(col(row, s));
        CHECK(x >= 0);
        shares += x;
      }
      CHECK(shares > 0.3);
      CHECK(shares <= 1.01);  // separately timed stages of sub-millisecond steps: clock granularity
      CHECK(std::stod(col(row, "detection_share")) > 0);
      CHECK(std::stod(col(row, "contacts_per_step")) > 0);
      CHECK(std::stod(col(row, "newton_per_step")) >= 1);
      CHECK(col(row, "intersections") == "0");
      CHECK(col(row, "status") == "\"ok\"");
    }
    CHECK(rows == 2);
    // One JSON line per step (2 skipped + 4 counted, two resolutions), per resolution, and the meta record.
    const auto lines = read_jsonl(dir / "bench_contact.jsonl");
    CHECK(lines.size() == 1 + 2 * (6 + 1));
    CHECK(lines.front().at("record") == "meta");
    fs::remove_all(dir);

    const Result bad = run_weft(fmt::format("bench contact --quick --resolutions 7y --out {}", dir.string()));
    CHECK(bad.code == 2);
    CHECK(bad.output.find("--resolutions") != std::string::npos);
    fs::remove_all(dir);
  }

  TEST_CASE("bench: weft bench contact --suite runs every case and checks each step") {
    const auto dir = temp_dir("bench_contact_suite_" + std::to_string(getpid()));
    // The shipped shrunk suite, three steps of each case under the barrier.
    const Result r = run_weft(fmt::format("--threads 1 bench contact --suite shrunk --combo cloth_ip_barrier_direct --steps 3 --out {}",
                                          dir.string()));
    CAPTURE(r.output);
    REQUIRE(r.code == 0);
    for (const char* s : {"dropVertical_13", "dropHorizontal_15", "twisted_21x9", "sheet_stack_8x9", "drape_11", "p95",
                          "obstacle crossings", "substepped", "completed"})
      CHECK_MESSAGE(r.output.find(s) != std::string::npos, s);
    std::stringstream csv(slurp(dir / "bench_contact.csv"));
    std::string line;
    REQUIRE(std::getline(csv, line));
    const std::vector<std::string> header = split(line);
    auto col = [&](const std::vector<std::string>& row, const std::string& name) { return column(header, row, name); };
    int rows = 0, stack_vertices = 0;
    while (std::getline(csv, line)) {
      const std::vector<std::string> row = split(line);
      CAPTURE(line);
      REQUIRE(row.size() == header.size());
      ++rows;
      CHECK(col(row, "combo") == "cloth_ip_barrier_direct");
      CHECK(std::stoi(col(row, "steps")) == 3);
      const double mean = std::stod(col(row, "seconds_per_step")), p95 = std::stod(col(row, "p95_step_s")),
                   max = std::stod(col(row, "max_step_s"));
      CHECK(mean > 0);
      CHECK(p95 <= max * (1 + 1e-9));
      CHECK(max >= mean * (1 - 1e-9));
      CHECK(col(row, "intersecting_steps") == "0");
      CHECK(col(row, "obstacle_crossing_steps") == "0");
      CHECK(col(row, "completed") == "1");
      CHECK(col(row, "subdivided_steps") == "0");  // the first steps need no substeps
      if (col(row, "case") == "\"sheet_stack_8x9\"") stack_vertices = std::stoi(col(row, "vertices"));
    }
    CHECK(rows == 5);
    CHECK(stack_vertices == 8 * 81);  // every cloth of the stack shrunk by the case's overrides
    // Step records name their case: 5 x 3 steps, 5 run records and the meta record.
    const auto lines = read_jsonl(dir / "bench_contact.jsonl");
    CHECK(lines.size() == 1 + 5 * (3 + 1));
    CHECK(lines.at(1).at("case") == "dropVertical_13");
    CHECK(lines.at(1).contains("obstacle_crossings"));
    fs::remove_all(dir);

    // A suite file with an unknown key is refused before any work, naming the key.
    fs::create_directories(dir);
    const fs::path bad = dir / "bad_suite.json";
    std::ofstream(bad) << R"({"cases": [{"scene": "scenes/drape_sphere.json", "step": 3}]})";
    const Result refused = run_weft(fmt::format("bench contact --suite {} --out {}", bad.string(), (dir / "out").string()));
    CHECK(refused.code == 2);
    CHECK(refused.output.find("cases.0.step") != std::string::npos);
    CHECK(!fs::exists(dir / "out"));

    // Overrides after --suite apply to every case, after the case's own: the drape at 9 x 9.
    const fs::path one = dir / "one_case.json";
    std::ofstream(one) << R"({"cases": [{"scene": "scenes/drape_sphere.json", "overrides": ["cloths.0.mesh.resolution=[11,11]"], "steps": 1}]})";
    const Result over = run_weft(fmt::format("--threads 1 bench contact --suite {} --out {} 'cloths.0.mesh.resolution=[9,9]'",
                                             one.string(), (dir / "over").string()));
    CAPTURE(over.output);
    REQUIRE(over.code == 0);
    std::stringstream one_csv(slurp(dir / "over" / "bench_contact.csv"));
    REQUIRE(std::getline(one_csv, line));
    const std::vector<std::string> one_header = split(line);
    REQUIRE(std::getline(one_csv, line));
    CHECK(column(one_header, split(line), "vertices") == "81");
    fs::remove_all(dir);
  }
}
