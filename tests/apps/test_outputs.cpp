#include <doctest/doctest.h>

#include <regex>
#include <set>

#include "cli_support.hpp"
#include "framework/obj_io.hpp"

using namespace weft::test;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {
// Files listed by a .pvd, in order.
std::vector<std::string> pvd_files(const fs::path& pvd) {
  std::vector<std::string> files;
  const std::string text = slurp(pvd);
  const std::regex re("file=\"([^\"]+)\"");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator(); ++it)
    files.push_back((*it)[1]);
  return files;
}

int count_files(const fs::path& dir, const std::string& ext) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir)) n += e.path().extension() == ext;
  return n;
}
}  // namespace

TEST_SUITE("apps") {
  TEST_CASE("run: output files parse back (OBJ / VTP series / JSON lines / summary)") {
    const auto dir = temp_dir("run_ok");
    const std::string path = write_file(dir / "scene.json", small_scene().dump(2));
    const auto out = dir / "out";
    const Result r = run_weft(fmt::format("run {} --out {}", path, out.string()));
    CAPTURE(r.output);
    REQUIRE(r.code == 0);
    // 0.1 s at 50 frames/s: frames 0..5, each an OBJ and a VTP of the 25-vertex sheet.
    CHECK(count_files(out, ".obj") == 6);
    CHECK(count_files(out, ".vtp") == 6);
    for (int f = 0; f <= 5; ++f) {
      const auto m = weft::read_obj((out / fmt::format("cloth_{:04d}.obj", f)).string());
      CHECK(m.V.rows() == 25);
      CHECK(m.F.rows() == 32);
      CHECK(m.V.allFinite());
    }
    const auto files = pvd_files(out / "frames.pvd");
    REQUIRE(files.size() == 6);
    for (const auto& f : files) {
      CHECK(fs::exists(out / f));
      const std::string vtp = slurp(out / f);
      CHECK(vtp.find("NumberOfPoints=\"25\"") != std::string::npos);
      CHECK(vtp.find("NumberOfPolys=\"32\"") != std::string::npos);
    }
    const auto stats = read_jsonl(out / "stats.jsonl");
    REQUIRE(stats.size() == 10);
    for (size_t k = 0; k < stats.size(); ++k) {
      CHECK(stats[k]["step"] == k + 1);
      CHECK(stats[k]["status"] == "success");
      CHECK(stats[k]["time"].get<double>() == doctest::Approx(0.01 * (k + 1)));
      CHECK(stats[k]["newton"]["iterations"].get<int>() >= 1);
      CHECK(stats[k]["newton"]["method"] == "minimise E_inc, line search backtracking, Hessian adaptive");
      CHECK(stats[k]["newton"]["final_residual"].get<double>() <= stats[k]["newton"]["tolerance"].get<double>());
      for (const char* key : {"kinetic", "potential", "membrane", "bending", "gravity"}) CHECK(stats[k]["energy"].contains(key));
      CHECK(stats[k]["seconds"].contains("linear_solve"));
    }
    // The falling sheet loses potential energy.
    CHECK(stats.back()["energy"]["gravity"].get<double>() < stats.front()["energy"]["gravity"].get<double>());
    const json summary = json::parse(slurp(out / "summary.json"));
    CHECK(summary["status"] == "completed");
    CHECK(summary["steps"] == 10);
    CHECK(summary["frames_written"] == 6);
    CHECK(summary["newton_iterations"]["total"].get<int>() >= 10);
    const json effective = json::parse(slurp(out / "scene.json"));
    CHECK(effective["integrator"]["line_search"] == "backtracking");  // defaults written out

    // A second run into the same directory replaces, never mixes, the outputs.
    const Result again = run_weft(fmt::format("run {} --out {} time.duration=0.04", path, out.string()));
    REQUIRE(again.code == 0);
    CHECK(count_files(out, ".obj") == 3);
    CHECK(pvd_files(out / "frames.pvd").size() == 3);
  }

  TEST_CASE("run: a step that fails stops with exit code 3 and keeps everything written before it") {
    json s = small_scene();
    // At t = 0.05 s the pinned edge is yanked at 1e5 m/s: Newton cannot converge in 3 iterations.
    s["cloths"][0]["pins"][0]["motion"] = {{"velocity", {0, 0, 1e5}}, {"start", 0.05}};
    s["integrator"] = {{"max_iterations", 3}};
    const auto dir = temp_dir("run_fail");
    const std::string path = write_file(dir / "scene.json", s.dump(2));
    const auto out = dir / "out";
    const Result r = run_weft(fmt::format("run {} --out {}", path, out.string()));
    CAPTURE(r.output);
    CHECK(r.code == 3);
    CHECK(r.output.find("failed in stage") != std::string::npos);
    const json summary = json::parse(slurp(out / "summary.json"));
    CHECK(summary["status"] == "failed");
    const int failed_step = summary["failure"]["step"];
    CHECK(failed_step == 6);  // the first step after t = 0.05 s
    CHECK(summary["failure"]["stage"] == "newton");
    CHECK(summary["failure"]["status"] == "no_convergence");
    const auto stats = read_jsonl(out / "stats.jsonl");  // every line is valid JSON
    REQUIRE(stats.size() == static_cast<size_t>(failed_step));
    CHECK(stats.back()["status"] == "no_convergence");
    CHECK(stats[stats.size() - 2]["status"] == "success");
    // Frames 0..2 (t = 0, 0.02, 0.04) were written before the failure, listed and intact.
    const auto files = pvd_files(out / "frames.pvd");
    CHECK(files.size() == 3);
    for (const auto& f : files) CHECK(fs::exists(out / f));
    CHECK(count_files(out, ".obj") == 3);
    CHECK(count_files(out, ".tmp") == 0);
  }

  TEST_CASE("run: the summary counts the steps retried as substeps") {
    // The hanging cloth at dt = 1/48 s: its first step needs 5 Newton iterations, its halves
    // at most 4 (tests/integrators/test_step_subdivision.cpp); with a cap of 4 only the
    // subdivision lets the run finish. The control, with the default cap, subdivides nothing.
    const std::string scene = std::string(WEFT_SOURCE_DIR) + "/scenes/hanging_cloth.json";
    const std::string common = "cloths.0.mesh.resolution=[11,11] combo=cloth_ip_direct time.dt=0.020833333333333332 "
                               "time.duration=0.08333333333333333 time.max_subdivisions=3";
    for (const int cap : {4, 100}) {
      CAPTURE(cap);
      const auto out = temp_dir(fmt::format("run_substeps_{}", cap));
      const Result r = run_weft(fmt::format("run {} {} integrator.max_iterations={} --out {}", scene, common, cap, out.string()));
      CAPTURE(r.output);
      REQUIRE(r.code == 0);
      const json summary = json::parse(slurp(out / "summary.json"));
      const int count = summary["subdivided_steps"]["count"], deepest = summary["subdivided_steps"]["deepest"];
      if (cap == 4) {
        CHECK(count >= 1);
        CHECK(deepest >= 1);
        CHECK(r.output.find("retried as substeps") != std::string::npos);
        int listed = 0;
        for (const json& step : read_jsonl(out / "stats.jsonl")) listed += step.value("substeps", 1) > 1;
        CHECK(listed == count);
      } else {
        CHECK(count == 0);
        CHECK(deepest == 0);
        CHECK(r.output.find("retried as substeps") == std::string::npos);
      }
    }
  }

  TEST_CASE("run: SIGINT stops between steps - the summary says interrupted and the output is intact") {
    json s = small_scene();
    s["time"]["duration"] = 1000.0;
    s["cloths"][0]["mesh"]["resolution"] = {15, 15};
    const auto dir = temp_dir("run_sigint");
    const std::string path = write_file(dir / "scene.json", s.dump(2));
    const auto out = dir / "out";
    const Result r = run_weft(fmt::format("run {} --out {}", path, out.string()), "timeout --preserve-status -s INT 2");
    CAPTURE(r.output);
    CHECK(r.code == 130);
    const json summary = json::parse(slurp(out / "summary.json"));
    CHECK(summary["status"] == "interrupted");
    CHECK(summary["failure"]["signal"] == "SIGINT");
    const int steps = summary["steps"];
    CHECK(steps > 0);
    CHECK(read_jsonl(out / "stats.jsonl").size() == static_cast<size_t>(steps));
    for (const auto& f : pvd_files(out / "frames.pvd")) CHECK(fs::exists(out / f));
    CHECK(count_files(out, ".tmp") == 0);
  }
}

TEST_SUITE("apps") {
  TEST_CASE("run: a diverging configuration ends with the failure report and exit code 3") {
    json s = small_scene();
    s["combo"] = "cloth_lie_direct";
    s["cloths"][0]["initial_velocity"] = {0, 0, 1e300};  // the first linearised step leaves the doubles
    const auto dir = temp_dir("run_diverge");
    const std::string path = write_file(dir / "scene.json", s.dump(2));
    const Result r = run_weft(fmt::format("run {} --out {}", path, (dir / "out").string()));
    CAPTURE(r.output);
    CHECK(r.code == 3);
    const json summary = json::parse(slurp(dir / "out" / "summary.json"));
    CHECK(summary["status"] == "failed");
    CHECK(summary["failure"]["status"] == "numerical_issue");
    CHECK(summary["failure"]["step"] == 1);
    CHECK(read_jsonl(dir / "out" / "stats.jsonl").size() == 1u);
  }
}

TEST_SUITE("apps") {
  TEST_CASE("run: the summary reports cloth-cloth intersections and obstacle crossings of every frame") {
    // Two sheets that cross each other from the start (no contact: cloth_ip_direct), and the
    // same scene with the lower sheet moved clear.
    const auto dir = temp_dir("run_contact_check");
    json scene = small_scene();
    scene["cloths"][0].erase("pins");
    scene["gravity"] = {0, 0, 0};
    json upright = scene["cloths"][0];
    upright["mesh"]["plane"] = "xz";
    upright["mesh"]["center"] = {0.01, 0.013, 0};
    scene["cloths"].push_back(upright);
    const std::string crossing = write_file(dir / "crossing.json", scene.dump(2));
    const Result r = run_weft(fmt::format("run {} --out {}", crossing, (dir / "a").string()));
    CAPTURE(r.output);
    REQUIRE(r.code == 0);
    const json a = json::parse(slurp(dir / "a" / "summary.json"))["contact_check"];
    CHECK(a["checked_frames"] == 6);  // frames 0..5
    CHECK(a["frames_with_cloth_intersections"] == 6);
    CHECK(a["max_cloth_intersecting_pairs"].get<int>() > 0);
    CHECK(a["first_time"] == 0.0);
    CHECK(r.output.find("cloth-cloth intersections in 6") != std::string::npos);
    scene["cloths"][1]["mesh"]["center"] = {0.01, 0.013, 0.4};
    const std::string clear = write_file(dir / "clear.json", scene.dump(2));
    const Result c = run_weft(fmt::format("run {} --out {}", clear, (dir / "b").string()));
    REQUIRE(c.code == 0);
    const json b = json::parse(slurp(dir / "b" / "summary.json"))["contact_check"];
    CHECK(b["frames_with_cloth_intersections"] == 0);
    CHECK(b["frames_with_obstacle_crossings"] == 0);
    CHECK(b["deepest_penetration_m"] == 0.0);
    CHECK(c.output.find("no cloth-cloth intersection") != std::string::npos);
  }
}
