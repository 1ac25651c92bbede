// `weft run --checkpoint-every` / `--resume` and the failed-step checkpoint, as a user runs
// them: a run stopped (by its duration, by SIGINT, by a failing step) and resumed writes the
// same frames and energies as the run that never stopped; bad checkpoint input is refused
// with exit code 2 before anything is written.
#include <doctest/doctest.h>

#include <cmath>
#include <regex>

#include "cli_support.hpp"

using namespace weft::test;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {
const std::string whip = std::string(WEFT_SOURCE_DIR) + "/scenes/whip_edge.json";

int pvd_entries(const fs::path& pvd) {
  const std::string text = slurp(pvd);
  const std::regex re("<DataSet ");
  return static_cast<int>(std::distance(std::sregex_iterator(text.begin(), text.end(), re), std::sregex_iterator()));
}
}  // namespace

TEST_SUITE("apps") {
  TEST_CASE("run: a run resumed from --checkpoint-every writes the frames and energies of the run that never stopped") {
    const auto dir = temp_dir("checkpoint_resume");
    const auto full = dir / "full", part = dir / "part";
    const Result a = run_weft(fmt::format("run {} time.duration=0.2 -q -o {}", whip, full.string()));
    REQUIRE_MESSAGE(a.code == 0, a.output);
    const Result b = run_weft(fmt::format("run {} time.duration=0.1 -q --checkpoint-every 5 -o {}", whip, part.string()));
    REQUIRE_MESSAGE(b.code == 0, b.output);
    REQUIRE(fs::exists(part / "checkpoint.wckp"));
    // Resume into the same directory: the first half's frames and statistics stay.
    const Result c = run_weft(fmt::format("run {} time.duration=0.2 --resume {} -o {}", whip, (part / "checkpoint.wckp").string(), part.string()));
    CAPTURE(c.output);
    REQUIRE(c.code == 0);
    CHECK(c.output.find("resumed from") != std::string::npos);
    for (const char* frame : {"rods_0005.obj", "rods_0007.obj", "rods_0010.obj"}) {
      CAPTURE(frame);
      CHECK(slurp(full / frame) == slurp(part / frame));  // positions written with round-trip precision
    }
    const auto sa = read_jsonl(full / "stats.jsonl"), sb = read_jsonl(part / "stats.jsonl");
    REQUIRE(sa.size() == 200);
    REQUIRE(sb.size() == 200);
    int contacts = 0;
    for (size_t k = 0; k < sa.size(); ++k) {
      CAPTURE(k);
      CHECK(sb[k]["step"] == k + 1);
      CHECK(sb[k]["energy"] == sa[k]["energy"]);
      contacts += sb[k]["contact"]["contacts"].get<int>();
    }
    CHECK(contacts > 0);  // the whip strikes the edge
    CHECK(pvd_entries(part / "frames.pvd") == pvd_entries(full / "frames.pvd"));
    const json summary = json::parse(slurp(part / "summary.json"));
    CHECK(summary["status"] == "completed");
    CHECK(summary["steps"] == 200);
    CHECK(summary["resumed_from"]["step"] == 100);
    CHECK(summary["resumed_from"]["steps_run"] == 100);
    CHECK(summary["final_energy"] == json::parse(slurp(full / "summary.json"))["final_energy"]);
  }

  TEST_CASE("run: SIGINT writes a checkpoint from which the run continues bitwise") {
    const auto dir = temp_dir("checkpoint_sigint");
    const auto stopped = dir / "stopped";
    const Result r = run_weft(fmt::format("run {} time.duration=1000 -o {}", whip, stopped.string()), "timeout --preserve-status -s INT 2");
    CAPTURE(r.output);
    REQUIRE(r.code == 130);
    const json s = json::parse(slurp(stopped / "summary.json"));
    CHECK(s["failure"]["checkpoint"] == "checkpoint.wckp");
    const int steps = s["steps"];
    REQUIRE(steps > 20);
    // Continue to two frames past the interruption, and compare with a run that never stopped.
    const double end = 0.02 * (std::floor(steps / 20) + 2);
    const Result c = run_weft(fmt::format("run {} time.duration={} -q --resume {} -o {}", whip, end, (stopped / "checkpoint.wckp").string(),
                                          (dir / "continued").string()));
    REQUIRE_MESSAGE(c.code == 0, c.output);
    const Result f = run_weft(fmt::format("run {} time.duration={} -q -o {}", whip, end, (dir / "full").string()));
    REQUIRE_MESSAGE(f.code == 0, f.output);
    const json a = json::parse(slurp(dir / "continued" / "summary.json")), b = json::parse(slurp(dir / "full" / "summary.json"));
    CHECK(a["resumed_from"]["step"] == steps);
    CHECK(a["steps"] == b["steps"]);
    CHECK(a["final_energy"] == b["final_energy"]);
    const std::string last = fmt::format("rods_{:04d}.obj", static_cast<int>(std::lround(end / 0.02)));
    CHECK(slurp(dir / "continued" / last) == slurp(dir / "full" / last));
  }

  TEST_CASE("run: a failing rod step leaves failed_step.wckp which replays the failure in one step") {
    const auto dir = temp_dir("checkpoint_failed");
    // Two Newton iterations are too few for the rod DEL of the first step.
    const Result r = run_weft(fmt::format("run {} time.duration=0.1 integrator.max_iterations=2 -o {}", whip, (dir / "a").string()));
    CAPTURE(r.output);
    REQUIRE(r.code == 3);
    CHECK(r.output.find("replays it") != std::string::npos);
    const json s = json::parse(slurp(dir / "a" / "summary.json"));
    CHECK(s["failure"]["checkpoint"] == "failed_step.wckp");
    const Result replay = run_weft(fmt::format("run {} time.duration=0.1 integrator.max_iterations=2 --resume {} -o {}", whip,
                                               (dir / "a" / "failed_step.wckp").string(), (dir / "b").string()));
    CHECK(replay.code == 3);
    const json t = json::parse(slurp(dir / "b" / "summary.json"));
    CHECK(t["failure"]["step"] == s["failure"]["step"]);
    CHECK(t["failure"]["reason"] == s["failure"]["reason"]);
    CHECK(t["resumed_from"]["steps_run"] == 1);  // the failing step alone
    // With enough iterations the same state goes on.
    const Result fixed = run_weft(fmt::format("run {} time.duration=0.1 -q --resume {} -o {}", whip, (dir / "a" / "failed_step.wckp").string(),
                                              (dir / "c").string()));
    CHECK_MESSAGE(fixed.code == 0, fixed.output);
  }

  TEST_CASE("run: a cloth run with contact resumed from a checkpoint or from the step that failed goes on as the run that never stopped") {
    // Two coarse sheets falling on a sphere under obstacle constraints with friction: the
    // contact set and its friction modes carry from step to step (the checkpoint holds them).
    const std::string scene = std::string(WEFT_SOURCE_DIR) + "/scenes/sheets_on_sphere.json";
    const std::string o = "combo=cloth_ip_constraints_direct cloths.0.mesh.resolution=[9,9] cloths.1.mesh.resolution=[7,7] "
                          "cloths.1.mesh.center=[0.03,0.02,0.0045] obstacles.0.center=[0,0,-0.2018] "
                          "cloths.0.initial_velocity=[0,0,-1] cloths.1.initial_velocity=[0,0,-1]";
    const auto dir = temp_dir("checkpoint_cloth");
    const auto full = dir / "full", part = dir / "part";
    const Result a = run_weft(fmt::format("run {} {} time.duration=0.25 -q -o {}", scene, o, full.string()));
    REQUIRE_MESSAGE(a.code == 0, a.output);
    const Result b = run_weft(fmt::format("run {} {} time.duration=0.1375 -q --checkpoint-every 1 -o {}", scene, o, part.string()));
    REQUIRE_MESSAGE(b.code == 0, b.output);
    const Result c = run_weft(fmt::format("run {} {} time.duration=0.25 --resume {} -o {}", scene, o, (part / "checkpoint.wckp").string(), part.string()));
    REQUIRE_MESSAGE(c.code == 0, c.output);
    CHECK(c.output.find("resumed from") != std::string::npos);
    for (const char* frame : {"lower0_0003.obj", "upper1_0003.obj", "lower0_0006.obj", "upper1_0006.obj"}) {
      CAPTURE(frame);
      REQUIRE(fs::exists(full / frame));
      CHECK(slurp(full / frame) == slurp(part / frame));
    }
    const auto sa = read_jsonl(full / "stats.jsonl"), sb = read_jsonl(part / "stats.jsonl");
    REQUIRE(sa.size() == 60);
    REQUIRE(sb.size() == 60);
    int contacts = 0;
    for (size_t k = 33; k < sa.size(); ++k) {
      CAPTURE(k);
      CHECK(sb[k]["energy"] == sa[k]["energy"]);
      contacts += sb[k]["contact"]["obstacle_contacts"].get<int>();
    }
    CHECK(contacts > 0);  // the resumed steps carry obstacle contacts

    // A step that fails leaves failed_step.wckp, the state at its start, contact set
    // included (the failed attempt's detection is undone): continued from step 33 with at
    // most 6 Newton iterations, a step after the first two fails (step 36 takes 7). The
    // checkpoint replays the same failure in one step; with the default iterations it goes on
    // and ends where the run that never failed ends.
    const std::string at33 = (part / "checkpoint.wckp").string();
    const Result f = run_weft(fmt::format("run {} {} time.duration=0.25 integrator.max_iterations=6 --resume {} -o {}", scene, o, at33,
                                          (dir / "f").string()));
    CAPTURE(f.output);
    REQUIRE(f.code == 3);
    const json s = json::parse(slurp(dir / "f" / "summary.json"));
    REQUIRE(s["failure"]["checkpoint"] == "failed_step.wckp");
    CHECK(s["failure"]["step"].get<int>() > 34);
    const std::string failed = (dir / "f" / "failed_step.wckp").string();
    const Result replay = run_weft(fmt::format("run {} {} time.duration=0.25 integrator.max_iterations=6 --resume {} -o {}", scene, o, failed,
                                               (dir / "g").string()));
    CHECK(replay.code == 3);
    const json t = json::parse(slurp(dir / "g" / "summary.json"));
    CHECK(t["failure"]["step"] == s["failure"]["step"]);
    CHECK(t["failure"]["reason"] == s["failure"]["reason"]);
    CHECK(t["resumed_from"]["steps_run"] == 1);
    const Result on = run_weft(fmt::format("run {} {} time.duration=0.25 -q --resume {} -o {}", scene, o, failed, (dir / "h").string()));
    REQUIRE_MESSAGE(on.code == 0, on.output);
    CHECK(slurp(dir / "h" / "lower0_0006.obj") == slurp(full / "lower0_0006.obj"));
    CHECK(slurp(dir / "h" / "upper1_0006.obj") == slurp(full / "upper1_0006.obj"));
    MESSAGE("the cloth step that fails with 6 Newton iterations: " << s["failure"]["step"] << ", " << s["failure"]["reason"]);
  }

  TEST_CASE("run: --resume warns when the checkpoint names why the run will not repeat the uninterrupted one to the bit") {
    // A preconditioner frozen per pattern is rebuilt at the first solve after the restore.
    const std::string scene = std::string(WEFT_SOURCE_DIR) + "/scenes/hanging_cloth.json";
    const std::string o = "cloths.0.mesh.resolution=[9,9] combo=cloth_ip_sa_ppcg linear.setup=once_per_pattern";
    const auto dir = temp_dir("checkpoint_caveat");
    const Result a = run_weft(fmt::format("run {} {} time.duration=0.1 -q --checkpoint-every 1 -o {}", scene, o, (dir / "a").string()));
    REQUIRE_MESSAGE(a.code == 0, a.output);
    const Result b = run_weft(fmt::format("run {} {} time.duration=0.2 --resume {} -o {}", scene, o, (dir / "a" / "checkpoint.wckp").string(),
                                          (dir / "b").string()));
    CAPTURE(b.output);
    REQUIRE(b.code == 0);
    CHECK(b.output.find("will not repeat the uninterrupted one to the bit: linear.setup = once_per_pattern") != std::string::npos);
    // The default SA keeps its aggregates between setups: named too. Rebuilt at every setup,
    // nothing is kept and nothing is said.
    for (const bool kept : {true, false}) {
      CAPTURE(kept);
      const std::string k = fmt::format("cloths.0.mesh.resolution=[9,9] combo=cloth_ip_sa_ppcg{}", kept ? "" : " linear.preconditioner.reuse=none");
      const auto run_dir = dir / (kept ? "c" : "e");
      const Result c = run_weft(fmt::format("run {} {} time.duration=0.1 -q --checkpoint-every 1 -o {}", scene, k, run_dir.string()));
      REQUIRE_MESSAGE(c.code == 0, c.output);
      const Result d = run_weft(fmt::format("run {} {} time.duration=0.2 --resume {} -o {}", scene, k, (run_dir / "checkpoint.wckp").string(),
                                            (run_dir.string() + "_resumed")));
      REQUIRE_MESSAGE(d.code == 0, d.output);
      CHECK((d.output.find("will not repeat the uninterrupted one to the bit: linear.preconditioner.reuse") != std::string::npos) == kept);
      CHECK((d.output.find("will not repeat") != std::string::npos) == kept);
    }
  }

  TEST_CASE("run: checkpoint options that cannot work are refused with exit code 2 before anything is written") {
    const auto dir = temp_dir("checkpoint_refused");
    const auto out = dir / "out";
    const auto refused = [&](const std::string& args, const std::string& fault) {
      const Result r = run_weft(args + " -o " + out.string());
      CAPTURE(r.output);
      CHECK(r.code == 2);
      CHECK(r.output.find(fault) != std::string::npos);
      CHECK(!fs::exists(out));
    };
    refused(fmt::format("run {} --checkpoint-every -1", whip), "--checkpoint-every -1: must be a number of frames >= 1 (0: none)");
    refused(fmt::format("run {} --resume {}", whip, whip), "not a weft checkpoint");
    refused(fmt::format("run {} --resume {}", whip, (dir / "none.wckp").string()), "file not found");
    // A checkpoint at the scene's end, and one of other rods.
    const Result end = run_weft(fmt::format("run {} time.duration=0.04 -q --checkpoint-every 1 -o {}", whip, (dir / "end").string()));
    REQUIRE(end.code == 0);
    const std::string at_end = (dir / "end" / "checkpoint.wckp").string();
    refused(fmt::format("run {} time.duration=0.04 --resume {}", whip, at_end), "at or after the scene's end, t = 0.04 s (2 frames of 0.02 s");
    // The scene ends at time.duration, also inside a frame: 0.05 s of 0.02 s frames resumes
    // from 0.04 s for its last 10 steps.
    const Result longer = run_weft(fmt::format("run {} time.duration=0.05 -q --resume {} -o {}", whip, at_end, (dir / "longer").string()));
    CHECK_MESSAGE(longer.code == 0, longer.output);
    CHECK(json::parse(slurp(dir / "longer" / "summary.json"))["resumed_from"]["steps_run"] == 10);
    refused(fmt::format("run {} rods.0.vertices=40 --resume {}", whip, at_end), "checkpoint rod 0 has 119 DoFs; this scene's rod 0 has 159");
    const std::string cloth = std::string(WEFT_SOURCE_DIR) + "/scenes/hanging_cloth.json";
    refused(fmt::format("run {} time.dt=0.01 time.frame_rate=25 --resume {}", cloth, at_end), "checkpoint holds a 'rods' state; this combination simulates cloth");
    // A state at t = 2.068 s (step 1034 of 2 ms) is not on the grid of 5 ms steps.
    const std::string at_2068 = std::string(WEFT_SOURCE_DIR) + "/tests/data/checkpoints/near_wall_whip_30v_2ms_after_step1034.wckp";
    refused(fmt::format("run {} time.dt=0.005 time.duration=3 --resume {}", whip, at_2068), "is not a multiple of time.dt = 0.005 s");
  }
}
