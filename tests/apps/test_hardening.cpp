// One test per class of fault a run must survive: counts that overflow, a duration that is
// not a whole number of frames, a disk that fills up, a signal inside a long contact solve,
// an internal error inside a step, a checkpoint of another mesh, meshes that are wrong in
// ways a message must name, and scenes too large for the machine.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include "cli_support.hpp"
#include "contact/no_contact.hpp"
#include "framework/checkpoint.hpp"
#include "framework/error.hpp"
#include "framework/scene.hpp"
#include "framework/simulator.hpp"
#include "integrators/incremental_potential.hpp"
#include "linear/direct.hpp"
#include "models/energy_sum.hpp"
#include "models/gravity.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using weft::test::Result;
using weft::test::run_shell;
using weft::test::read_jsonl;
using weft::test::run_weft;
using weft::test::slurp;
using weft::test::temp_dir;

const std::string scenes = std::string(WEFT_SOURCE_DIR) + "/scenes/";
const std::string cloth = scenes + "hanging_cloth.json";

// An energy that throws at its n-th gradient evaluation, as a broken invariant would.
struct Tripwire {
  struct Params {
    int at = 1;
    template <class V>
    void visit(V& v) {
      v.field("at", at, {weft::Unit::none, weft::Range::ge(1), "the gradient evaluation that throws"});
    }
  };
  static constexpr std::string_view name = "tripwire";
  static constexpr bool stateless = true;
  Tripwire(const weft::Scene&, const Params& p) : at(p.at) {}
  void declare(weft::AssemblyPlan&) {}
  double energy(const weft::State&) const { return 0; }
  void add_gradient(const weft::State&, Eigen::VectorXd&) const {
    if (++calls == at) throw weft::InvariantError("tripwire: a broken invariant");
  }
  void add_hessian(const weft::State&, weft::ElementBuffer&, weft::HessianMode) const {}
  void energy_terms(const weft::State&, weft::EnergyTerms&) const {}
  bool admissible(const weft::State&) const { return true; }
  int at;
  mutable int calls = 0;
};
using TripSim = weft::Simulator<weft::models::EnergySum<weft::models::Gravity, Tripwire>, weft::integrators::IncrementalPotential,
                                weft::contact::NoContact, weft::linear::Direct>;

}  // namespace

TEST_SUITE("apps") {
  TEST_CASE("hardening: step and frame counts that overflow are refused naming the key and the limit") {
    const auto dir = temp_dir("overflow");
    const Result tiny = run_weft(fmt::format("run {} time.dt=1e-12 -o {}", cloth, (dir / "a").string()));
    CHECK(tiny.code == 2);
    CHECK(tiny.output.find("time.dt = 1e-12") != std::string::npos);
    CHECK(tiny.output.find("steps per frame") != std::string::npos);
    const Result long_run = run_weft(fmt::format("run {} time.duration=1e8 -o {}", cloth, (dir / "b").string()));
    CHECK(long_run.code == 2);
    CHECK(long_run.output.find("time.duration = 100000000") != std::string::npos);
    CHECK(long_run.output.find("frames") != std::string::npos);
    CHECK_FALSE(fs::exists(dir / "a" / "summary.json"));
    CHECK_FALSE(fs::exists(dir / "b" / "summary.json"));
  }

  TEST_CASE("hardening: a duration that is not a whole number of frames is simulated to its end - or refused when not whole steps") {
    const auto dir = temp_dir("duration");
    const std::string small = "cloths.0.mesh.resolution=[5,5]";
    // 0.1 s at 24 frames/s: 2.4 frames; the last frame is the state at t = 0.1 s.
    const Result r = run_weft(fmt::format("run {} {} time.duration=0.1 -q -o {}", cloth, small, (dir / "a").string()));
    REQUIRE_MESSAGE(r.code == 0, r.output);
    const json s = json::parse(slurp(dir / "a" / "summary.json"));
    CHECK(s["simulated_time"].get<double>() == doctest::Approx(0.1).epsilon(1e-12));
    CHECK(s["steps"] == 24);
    CHECK(s["frames_written"] == 4);  // t = 0, 1/24, 2/24 and 0.1 s
    CHECK(fs::exists(dir / "a" / "cloth_0003.obj"));
    const std::string pvd = slurp(dir / "a" / "frames.pvd");
    std::smatch last;
    const std::regex timestep("timestep=\"([^\"]+)\"");
    for (auto it = std::sregex_iterator(pvd.begin(), pvd.end(), timestep); it != std::sregex_iterator(); ++it) last = *it;
    REQUIRE(last.size() == 2);
    CHECK(std::stod(last[1].str()) == doctest::Approx(0.1).epsilon(1e-12));
    // 0.1 s is not a whole number of steps of 3 ms: refused, with the nearest valid durations.
    const Result bad = run_weft(fmt::format("run {} {} time.dt=0.003 time.frame_rate=111.11111111111111 time.duration=0.1 -o {}", cloth, small,
                                            (dir / "b").string()));
    CHECK(bad.code == 2);
    CHECK_MESSAGE(bad.output.find("whole number of steps") != std::string::npos, bad.output);
    CHECK(bad.output.find("0.099") != std::string::npos);
  }

  TEST_CASE("hardening: a full disk stops the run with exit 3 and keeps every complete statistics line and frame") {
    const auto dir = temp_dir("full_disk");
    // A file size limit of 24 KiB (SIGXFSZ ignored, so writes fail with EFBIG as on a full
    // disk): with frames off, stats.jsonl reaches it after a few dozen steps.
    const auto stats_only = dir / "stats_only";
    const Result a = run_shell(fmt::format("bash -c \"trap '' XFSZ; ulimit -f 24; exec {} run {} cloths.0.mesh.resolution=[5,5] time.duration=2 "
                                           "output.obj=false output.vtp=false -q -o {}\"",
                                           WEFT_BINARY, cloth, stats_only.string()));
    CAPTURE(a.output);
    CHECK(a.code == 3);
    CHECK(a.output.find("stats.jsonl") != std::string::npos);
    const auto lines = read_jsonl(stats_only / "stats.jsonl");  // every line parses: the cut one was removed
    CHECK(lines.size() > 5);
    const json s = json::parse(slurp(stats_only / "summary.json"));
    CHECK(s["status"] == "failed");
    CHECK(s["failure"]["stage"] == "output");
    CHECK(s["steps"].get<size_t>() >= lines.size());
    // With frames: a frame too large for the limit is not left half written.
    const auto frames = dir / "frames";
    const Result b = run_shell(fmt::format("bash -c \"trap '' XFSZ; ulimit -f 24; exec {} run {} cloths.0.mesh.resolution=[31,31] time.duration=0.5 "
                                           "-q -o {}\"",
                                           WEFT_BINARY, cloth, frames.string()));
    CAPTURE(b.output);
    CHECK(b.code == 3);
    for (const auto& e : fs::directory_iterator(frames)) {
      CHECK(e.path().extension() != ".tmp");
      CHECK(e.path().extension() != ".vtp");  // the first frame's .vtp exceeds the limit, so frame 0 is not on disk at all
    }
  }

  TEST_CASE("hardening: an --out that cannot be a directory is refused before anything runs") {
    const auto dir = temp_dir("out_file");
    std::ofstream(dir / "file") << "x";
    const Result r = run_weft(fmt::format("run {} -o {}", cloth, (dir / "file").string()));
    CHECK(r.code == 2);
    CHECK(r.output.find("output directory") != std::string::npos);
    CHECK(slurp(dir / "file") == "x");
  }

  TEST_CASE("hardening: SIGTERM inside an endless rod contact solve stops the run in seconds with a checkpoint of the step's start") {
    const auto dir = temp_dir("sigterm_contact");
    // A tolerance no Gauss-Seidel sweep reaches and a sweep limit of a million: once the pile
    // touches the ground (step 22), a step never ends unless the solver polls the signal.
    // SIGTERM once the run has stalled in that step: 10 steps written and 2 s without a new one.
    const auto out = dir / "a";
    const std::string stats = (out / "stats.jsonl").string();
    const std::string script = fmt::format(
        "{} run {}rod_pile.json contact.contact_tol=1e-300 contact.gs_max=1000000 contact.newton_max=100000 -q -o {} & pid=$!; "
        "for i in $(seq 600); do n=$(cat {} 2>/dev/null | wc -l); [ \"$n\" -ge 10 ] && [ \"$n\" = \"$last\" ] && break; last=$n; sleep 2; done; "
        "start=$(date +%s%N); kill -TERM $pid; wait $pid; code=$?; echo \"stopped after $(( ($(date +%s%N) - start) / 1000000 )) ms\"; exit $code",
        WEFT_BINARY, scenes, out.string(), stats);
    const Result r = run_shell("bash -c '" + script + "'");
    std::smatch m;
    REQUIRE(std::regex_search(r.output, m, std::regex("stopped after ([0-9]+) ms")));
    const double wall = 1e-3 * std::stod(m[1].str());
    CAPTURE(r.output);
    CHECK(r.code == 143);
    MESSAGE("from SIGTERM to the exit: " << wall << " s, after " << r.output.size() << " bytes of output");
    CHECK(wall < 10);  // from the signal to the exit
    const json s = json::parse(slurp(dir / "a" / "summary.json"));
    CHECK(s["status"] == "interrupted");
    CHECK(s["failure"]["signal"] == "SIGTERM");
    REQUIRE(s["failure"].contains("checkpoint"));
    const weft::Checkpoint c = weft::read_checkpoint((dir / "a" / "checkpoint.wckp").string());
    CHECK(c.header["step"] == s["steps"]);  // the interrupted step is not counted; its start is kept
    CHECK(c.header["time"].get<double>() == doctest::Approx(s["steps"].get<double>() * 0.002));
    CHECK(s["steps"].get<int>() >= 10);  // stopped inside a contact step, not before the pile fell
  }

  TEST_CASE("hardening: an internal error inside a step is a failed step whose start state is kept and replays") {
    const weft::Scene scene = weft::load_scene(cloth, {"cloths.0.mesh.resolution=[5,5]"});
    TripSim::Params prm;
    std::get<1>(prm.energy.terms).at = 1000000;
    TripSim ok(scene, prm);
    REQUIRE(ok.step().ok());
    const int calls = ok.energy_model().term<1>().calls;
    REQUIRE(calls > 1);
    // The same run with the wire at the second step's first gradient evaluation.
    std::get<1>(prm.energy.terms).at = calls + 1;
    TripSim sim(scene, prm);
    REQUIRE(sim.step().ok());
    const weft::State after_one = sim.state();
    const weft::StepReport r = sim.step();
    CHECK_FALSE(r.ok());
    CHECK(r.failed_stage == "internal");
    CHECK(r.message.find("tripwire") != std::string::npos);
    CHECK(sim.state().t == after_one.t);
    CHECK(sim.state().x == after_one.x);
    CHECK(sim.state().v == after_one.v);
    // A checkpoint of it replays the step (the wire does not trip again).
    weft::Checkpoint c;
    sim.save(c);
    TripSim replay(scene, prm);
    replay.restore(c);
    CHECK(replay.state().x == after_one.x);
    CHECK(sim.step().ok());
  }

  TEST_CASE("hardening: a rod step whose solve ends with a non-finite residual fails with its replay instead of succeeding") {
    const auto dir = temp_dir("nonfinite_residual");
    // A density of 1e300 kg/m^3: forces overflow, and the DEL's stopping test passed on inf.
    const Result r = run_weft(fmt::format("run {}whip.json rods.0.material.density=1e300 time.duration=0.02 -o {}", scenes, (dir / "a").string()));
    CAPTURE(r.output);
    CHECK(r.code == 3);
    CHECK(r.output.find("non-finite residual") != std::string::npos);
    const json s = json::parse(slurp(dir / "a" / "summary.json"));
    CHECK(s["status"] == "failed");
    CHECK(s["failure"]["checkpoint"] == "failed_step.wckp");
    CHECK(fs::exists(dir / "a" / "failed_step.wckp"));
  }

  TEST_CASE("hardening: a checkpoint of another mesh with as many vertices is refused naming what differs") {
    const auto dir = temp_dir("other_mesh");
    const std::string small = "cloths.0.mesh.resolution=[5,5] time.duration=0.25";
    const Result a = run_weft(fmt::format("run {} {} --checkpoint-every 1 -q -o {}", cloth, small, (dir / "a").string()));
    REQUIRE_MESSAGE(a.code == 0, a.output);
    const std::string ckpt = (dir / "a" / "checkpoint.wckp").string();
    // Another size: the same faces, other rest positions.
    const Result b = run_weft(fmt::format("run {} {} time.duration=1 cloths.0.mesh.size=[2,2] --resume {} -o {}", cloth, small, ckpt, (dir / "b").string()));
    CHECK(b.code == 2);
    CHECK_MESSAGE(b.output.find("another rest shape") != std::string::npos, b.output);
    // Another tessellation: other triangles on the same vertices.
    const Result c = run_weft(fmt::format("run {} {} time.duration=1 cloths.0.mesh.tessellation=irregular --resume {} -o {}", cloth, small, ckpt,
                                          (dir / "c").string()));
    CHECK(c.code == 2);
    CHECK_MESSAGE(c.output.find("another mesh") != std::string::npos, c.output);
    // The scene that wrote it resumes.
    const Result d = run_weft(fmt::format("run {} {} time.duration=0.5 --resume {} -q -o {}", cloth, small, ckpt, (dir / "d").string()));
    CHECK_MESSAGE(d.code == 0, d.output);
  }

  TEST_CASE("hardening: wrong meshes get messages that name the file or the line or the vertex and what is valid") {
    const auto dir = temp_dir("mesh_messages");
    const std::string sheet = slurp(scenes + "meshes/sheet11_flat.obj");
    const auto scene_with = [&](const std::string& mesh_file) {
      json s = json::parse(slurp(scenes + "folded_sheet.json"), nullptr, true, true);
      s["cloths"][0]["mesh"] = {{"source", "file"}, {"file", mesh_file}};
      const auto p = dir / ("scene_" + fs::path(mesh_file).filename().string() + ".json");
      std::ofstream(p) << s.dump();
      return p.string();
    };
    // Huge coordinates: named as such, not as a zero-area face.
    std::ofstream(dir / "huge.obj") << std::regex_replace(sheet, std::regex("\nv ([^ ]+) "), "\nv 1e300 ", std::regex_constants::format_first_only);
    const Result huge = run_weft(fmt::format("run {} -o {}", scene_with((dir / "huge.obj").string()), (dir / "o1").string()));
    CHECK(huge.code == 2);
    CHECK_MESSAGE(huge.output.find("coordinate x = 1e+300") != std::string::npos, huge.output);
    CHECK(huge.output.find("zero rest area") == std::string::npos);
    // A face index beyond the vertices: the line is named.
    std::ofstream(dir / "index.obj") << sheet << "f 1 2 1000\n";
    const Result index = run_weft(fmt::format("run {} -o {}", scene_with((dir / "index.obj").string()), (dir / "o2").string()));
    CHECK(index.code == 2);
    CHECK_MESSAGE(std::regex_search(index.output, std::regex("index\\.obj:[0-9]+: malformed OBJ: face corner '1000' references vertex 1000")), index.output);
    CHECK(index.output.find("orientation") == std::string::npos);
    // A FIFO is not a missing file.
    REQUIRE(run_shell(fmt::format("mkfifo {}", (dir / "pipe.obj").string())).code == 0);
    const Result fifo = run_weft(fmt::format("run {} -o {}", scene_with((dir / "pipe.obj").string()), (dir / "o3").string()));
    CHECK(fifo.code == 2);
    CHECK_MESSAGE(fifo.output.find("FIFO") != std::string::npos, fifo.output);
    // A topology error names the cloth and its file.
    std::ofstream(dir / "flipped.obj") << sheet << "f 1 2 13\nf 1 2 13\n";
    const Result topo = run_weft(fmt::format("run {} -o {}", scene_with((dir / "flipped.obj").string()), (dir / "o4").string()));
    CHECK(topo.code == 2);
    CHECK_MESSAGE(topo.output.find("cloths.0.mesh.file = \"" + (dir / "flipped.obj").string() + "\"") != std::string::npos, topo.output);
  }

  TEST_CASE("hardening: a scene too large for the counters or the memory is refused with the estimate before it is built") {
    const auto dir = temp_dir("too_large");
    const Result rods = run_weft(fmt::format("run {}whip.json rods.0.count=1000000 rods.0.vertices=100000 -o {}", scenes, (dir / "a").string()));
    CHECK(rods.code == 2);
    CHECK_MESSAGE(rods.output.find("rods.0.count = 1000000 x vertices = 100000: 100,000,000,000 vertices") != std::string::npos, rods.output);
    const double ram = weft::physical_memory_bytes();
    REQUIRE(ram > 0);
    // Sheets whose estimate exceeds this machine's memory (of any size up to 4 TB).
    const int sheets = static_cast<int>(std::ceil(ram / (25e6 * weft::SizeEstimate::cloth_bytes_per_vertex))) + 1;
    REQUIRE(sheets <= 40);
    std::string o;
    json s = json::parse(slurp(scenes + "stacked_sheets.json"), nullptr, true, true);
    const json one = s["cloths"][0];
    s["cloths"] = json::array();
    for (int k = 0; k < sheets; ++k) {
      json c = one;
      c["name"] = fmt::format("sheet{}", k);
      c["mesh"]["resolution"] = {5000, 5000};
      s["cloths"].push_back(c);
    }
    std::ofstream(dir / "big.json") << s.dump();
    const auto t0 = std::chrono::steady_clock::now();
    const Result big = run_weft(fmt::format("run {} -o {}", (dir / "big.json").string(), (dir / "b").string()));
    CHECK(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < 20);  // refused before any mesh is built
    CHECK(big.code == 2);
    CHECK_MESSAGE(big.output.find("GB of memory") != std::string::npos, big.output);
    CHECK(big.output.find("this machine has") != std::string::npos);
  }
}
