#include <doctest/doctest.h>

#include <cstdint>
#include <regex>

#include "cli_support.hpp"

using namespace weft::test;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {
// Runs `weft run` on a scene and checks the configuration-error contract: exit code 2,
// the message names the file and every given fragment, and no output directory appears.
void expect_config_error(const std::string& name, const json& scene, std::vector<std::string> fragments,
                         const std::string& extra_args = "") {
  const auto dir = temp_dir(name);
  const std::string path = write_file(dir / "scene.json", scene.dump(2));
  const auto out = dir / "out";
  const Result r = run_weft(fmt::format("run {} --out {} {}", path, out.string(), extra_args));
  CAPTURE(r.output);
  CHECK(r.code == 2);
  CHECK(r.output.find(path) != std::string::npos);
  for (const auto& f : fragments) CHECK_MESSAGE(r.output.find(f) != std::string::npos, f);
  CHECK_FALSE(fs::exists(out));
}
}  // namespace

TEST_SUITE("apps") {
  TEST_CASE("cli: --help and list describe the command and the pre-built combinations") {
    const Result help = run_weft("--help");
    CHECK(help.code == 0);
    for (const char* s : {"run", "list", "keys"}) CHECK(help.output.find(s) != std::string::npos);
    const Result list = run_weft("list");
    CHECK(list.code == 0);
    for (const char* s : {"cloth_ip_direct", "cloth_tan_ip_direct", "incremental_potential", "direct"})
      CHECK(list.output.find(s) != std::string::npos);
    const Result bad = run_weft("frobnicate");
    CHECK(bad.code != 0);
  }

  TEST_CASE("cli: --version and summary.json and checkpoints and stability sweeps name the commit the binary was built from") {
    const Result v = run_weft("--version");
    REQUIRE(v.code == 0);
    std::smatch m;
    REQUIRE_MESSAGE(std::regex_match(v.output, m, std::regex(R"(weft (\d+\.\d+\.\d+), built from (.+)\n)")), v.output);
    const std::string build = m[2];
    // Where git reads the source tree (CI's clone; not a tarball, nor a tree git refuses as
    // another user's): an abbreviated commit (after a tag's name, if any), "-dirty" when the
    // tree had uncommitted changes at build time.
    if (run_shell(fmt::format("git -C '{}' rev-parse HEAD", WEFT_SOURCE_DIR)).code == 0)
      CHECK_MESSAGE(std::regex_match(build, std::regex("(.*-g)?[0-9a-f]{12}(-dirty)?")), build);
    else
      CHECK_MESSAGE(build.rfind("unknown", 0) == 0, build);
    const auto dir = temp_dir("build_records");
    const std::string whip = std::string(WEFT_SOURCE_DIR) + "/scenes/whip_edge.json";
    const Result r = run_weft(fmt::format("run {} time.duration=0.02 -q --checkpoint-every 1 -o {}", whip, (dir / "run").string()));
    REQUIRE_MESSAGE(r.code == 0, r.output);
    CHECK(json::parse(slurp(dir / "run" / "summary.json"))["build"] == build);
    // The checkpoint's JSON header: after the 8-byte magic and its 8-byte length.
    std::ifstream in(dir / "run" / "checkpoint.wckp", std::ios::binary);
    char magic[8];
    std::uint64_t length = 0;
    REQUIRE(in.read(magic, 8));
    REQUIRE(in.read(reinterpret_cast<char*>(&length), 8));
    REQUIRE(length < 1000000);
    std::string header(length, '\0');
    REQUIRE(in.read(header.data(), static_cast<std::streamsize>(length)));
    CHECK(json::parse(header)["run"]["build"] == build);
    const Result st = run_weft(fmt::format("stability {} --dt 0.01 --duration 0.02 --combos rods_impulse --no-plots -o {}", whip, (dir / "stab").string()));
    REQUIRE_MESSAGE(st.code == 0, st.output);
    const json meta = json::parse(slurp(dir / "stab" / "stability_meta.json"));
    CHECK(meta["build"] == build);
    CHECK(meta["scene"] == whip);
    CHECK(meta["dts"] == json::array({0.01}));
    CHECK(meta["combos"] == json::array({"rods_impulse"}));
  }

  TEST_CASE("cli: unknown key / wrong type and out-of-range value are all reported / nothing written") {
    json s = small_scene();
    s["cloths"][0]["mesh"]["colour"] = "red";
    s["time"]["duration"] = "long";
    s["cloths"][0]["material"]["poisson_ratio"] = 2;
    expect_config_error("cfg_many", s,
                        {"cloths.0.mesh.colour is not a known key", "time.duration = \"long\"",
                         "cloths.0.material.poisson_ratio = 2 is out of range: valid in (-1, 1)"});
  }

  TEST_CASE("cli: solver parameters are validated strictly too") {
    json s = small_scene();
    s["integrator"] = {{"max_iterations", 0}, {"line_serch", "backtracking"}};
    s["linear"] = {{"check_residual", 3}};
    expect_config_error("cfg_solver", s,
                        {"integrator.max_iterations = 0 is out of range: valid in [1, 10000]",
                         "integrator.line_serch is not a known key", "linear.check_residual = 3 has the wrong type"});
  }

  TEST_CASE("cli: missing and malformed mesh files") {
    json s = small_scene();
    s["cloths"][0]["mesh"] = {{"source", "file"}, {"file", "nowhere.obj"}};
    expect_config_error("cfg_missing_mesh", s, {"cloths.0.mesh", "nowhere.obj: mesh file not found"});
    const auto dir = temp_dir("cfg_bad_obj");
    write_file(dir / "bad.obj", "v 0 0 0\nv 1 0 0\nf 1 2 7\n");
    s["cloths"][0]["mesh"]["file"] = "bad.obj";
    const std::string path = write_file(dir / "scene.json", s.dump());
    const Result r = run_weft(fmt::format("run {} --out {}", path, (dir / "out").string()));
    CAPTURE(r.output);
    CHECK(r.code == 2);
    CHECK(r.output.find("bad.obj:3: malformed OBJ: face corner '7' references vertex 7 of the 2 defined before this line") != std::string::npos);
    CHECK_FALSE(fs::exists(dir / "out"));
  }

  TEST_CASE("cli: malformed JSON / unknown combo / unknown override / missing scene") {
    const auto dir = temp_dir("cfg_json");
    const std::string path = write_file(dir / "scene.json", "{\"cloths\": [");
    Result r = run_weft(fmt::format("run {} --out {}", path, (dir / "out").string()));
    CHECK(r.code == 2);
    CHECK(r.output.find("malformed JSON") != std::string::npos);
    CHECK_FALSE(fs::exists(dir / "out"));

    json s = small_scene();
    s["combo"] = "cloth_magic";
    expect_config_error("cfg_combo", s, {"combo = \"cloth_magic\" is not a pre-built combination", "cloth_ip_direct"});
    expect_config_error("cfg_override", small_scene(), {"integrator.tolerence is not a known key"}, "integrator.tolerence=1e-8");
    expect_config_error("cfg_override_syntax", small_scene(), {"not of the form key=value"}, "time.dt");
    expect_config_error("cfg_override_range", small_scene(), {"time.dt = 2 s is out of range"}, "time.dt=2");

    r = run_weft("run /nonexistent/scene.json");
    CHECK(r.code == 2);
    CHECK(r.output.find("/nonexistent/scene.json: scene file not found") != std::string::npos);
  }

  TEST_CASE("cli: an override after a list option's values is an override - parse errors and bad names exit 2") {
    const auto dir = temp_dir("cli_order");
    const std::string scene = write_file(dir / "scene.json", small_scene().dump());
    // time.dt=0.02 after --combos: read as an override (the list would otherwise swallow it and
    // fail with "unknown combination").
    Result r = run_weft(fmt::format("ablate {} --combos cloth_ip_direct time.dt=0.02 --duration 0.1 --no-plots -q --out {}", scene,
                                    (dir / "ablate").string()));
    CAPTURE(r.output);
    REQUIRE(r.code == 0);
    const json a = json::parse(slurp(dir / "ablate" / "ablate.json"));
    CHECK(a.at("rows").size() == 1);
    CHECK(a.at("rows")[0].at("combo") == "cloth_ip_direct");
    CHECK(a.at("overrides") == json::array({"time.dt=0.02"}));
    for (const char* bad : {"run --no-such-flag", "--threads 100000 run x.json", "run"}) {
      r = run_weft(bad);
      CAPTURE(bad);
      CHECK(r.code == 2);
    }
    r = run_weft(fmt::format("run {} --out {} cloths.0.name=../../evil", scene, (dir / "out" / "t").string()));
    CHECK(r.code == 2);
    CHECK(r.output.find("cloths.0.name = \"../../evil\"") != std::string::npos);
    CHECK_FALSE(fs::exists(dir / "out"));
    CHECK_FALSE(fs::exists(dir / "evil_0000.obj"));
  }

  TEST_CASE("cli: obstacles without a contact strategy are rejected / with the reason") {
    json s = small_scene();
    s["obstacles"] = json::array({{{"shape", "sphere"}, {"center", {0, 0, -0.5}}, {"radius", 0.2}}});
    expect_config_error("cfg_obstacle", s, {"contact = none would let the cloth pass through them"});
  }

  TEST_CASE("cli: the scene reference document is generated from the code and up to date") {
    const Result r = run_weft("keys");
    REQUIRE(r.code == 0);
    const std::string doc = slurp(fs::path(WEFT_SOURCE_DIR) / "docs" / "scene-reference.md");
    CHECK(r.output.find("cloths.N.material.youngs_modulus") != std::string::npos);
    CHECK(r.output.find("integrator.max_iterations") != std::string::npos);
    CHECK_MESSAGE(doc == r.output, "docs/scene-reference.md is stale: regenerate it with `weft keys > docs/scene-reference.md`");
  }
}

TEST_SUITE("apps") {
  TEST_CASE("cli: list --scene says which combinations apply and why others do not") {
    json s = small_scene();
    s["obstacles"] = json::array({{{"shape", "plane"}, {"center", {0, 0, -1}}}});
    const auto dir = temp_dir("list_scene");
    const std::string path = write_file(dir / "scene.json", s.dump());
    const Result r = run_weft("list --scene " + path);
    CAPTURE(r.output);
    CHECK(r.code == 0);
    CHECK(r.output.find("no, the scene has 1 obstacle(s)") != std::string::npos);
    const Result ok = run_weft("list --scene " + write_file(dir / "plain.json", small_scene().dump()));
    CHECK(ok.output.find("applies to") != std::string::npos);
    CHECK(ok.output.find(": yes") != std::string::npos);
  }
}

TEST_SUITE("slow") {
  TEST_CASE("demo: the default hanging cloth runs to the end at full resolution and comes to rest") {
    const auto dir = temp_dir("demo_full");
    const Result r = run_weft(fmt::format("run {}/scenes/hanging_cloth.json --out {} --quiet", WEFT_SOURCE_DIR, dir.string()));
    CAPTURE(r.output);
    REQUIRE(r.code == 0);
    const json summary = json::parse(slurp(dir / "summary.json"));
    CHECK(summary["status"] == "completed");
    const auto stats = read_jsonl(dir / "stats.jsonl");
    REQUIRE(stats.size() == 960u);
    double ke_peak = 0;
    for (const auto& s : stats) ke_peak = std::max(ke_peak, s["energy"]["kinetic"].get<double>());
    // The swing's kinetic energy is dissipated by the end: drag 1/s alone leaves e^-3 of it
    // 3 s after the peak, and backward Euler dissipates more.
    CHECK(stats.back()["energy"]["kinetic"].get<double>() < 0.05 * ke_peak);
    CHECK(summary["newton_iterations"]["max"].get<int>() < 100);
  }
}
