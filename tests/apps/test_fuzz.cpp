// The input fuzz harness: the shipped scenes, meshes and checkpoints, mutated (malformed
// syntax, extreme and non-finite values, wrong types, bad topology, truncation, flipped
// bytes), go through the readers weft run uses. Every case must either be accepted or be
// refused with a ConfigError whose message names something; any other exception, a crash
// or a hang fails the harness. In process (load_scene, build_scene, make_simulator,
// read_obj, read_checkpoint, restore) a few hundred cases take seconds; the "slow" suite
// runs more of them and whole `weft run`s of mutated scenes, checking the exit codes and
// that nothing is written outside --out.
#include <doctest/doctest.h>

#include <algorithm>
#include <cstring>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cli_support.hpp"
#include "framework/checkpoint.hpp"
#include "framework/error.hpp"
#include "framework/obj_io.hpp"
#include "framework/scene.hpp"
#include "policies/registry.hpp"

namespace {

namespace fs = std::filesystem;
using weft::Json;

const fs::path scenes_dir = fs::path(WEFT_SOURCE_DIR) / "scenes";

using weft::test::slurp;
const auto spit = weft::test::write_file;  // the scene, mesh or checkpoint bytes, as a user would save them

/// What the harness saw: cases accepted and refused, and the failures (anything else).
struct Tally {
  int accepted = 0, refused = 0;
  std::vector<std::string> failures;
  /// Runs `f`: accepted when it returns, refused on a ConfigError that says what is wrong
  /// (at least a few words), a failure on any other exception or an empty message.
  void run(const std::string& what, const std::function<void()>& f) {
    try {
      f();
      ++accepted;
    } catch (const weft::ConfigError& e) {
      const std::string m = e.what();
      if (m.size() < 16) failures.push_back(fmt::format("{}: a ConfigError that names nothing: '{}'", what, m));
      ++refused;
    } catch (const std::exception& e) {
      failures.push_back(fmt::format("{}: {} escaped: {}", what, typeid(e).name(), e.what()));
    }
  }
  int cases() const { return accepted + refused + static_cast<int>(failures.size()); }
  void report(const char* name, int min_refused) const {
    MESSAGE(fmt::format("{}: {} cases, {} accepted, {} refused, {} failures", name, cases(), accepted, refused, failures.size()));
    for (size_t i = 0; i < failures.size() && i < 20; ++i) FAIL_CHECK(failures[i]);
    CHECK(failures.empty());
    CHECK(refused >= min_refused);  // the mutations were real: most of them must be refused
  }
};

// Every leaf of a JSON document, as JSON pointers.
void leaves(const Json& j, const std::string& at, std::vector<std::string>& out) {
  if (j.is_object()) {
    for (const auto& [k, v] : j.items()) leaves(v, at + "/" + k, out);
  } else if (j.is_array() && !j.empty() && (j[0].is_object() || j[0].is_array())) {
    for (size_t i = 0; i < j.size(); ++i) leaves(j[i], fmt::format("{}/{}", at, i), out);
  } else {
    out.push_back(at);
  }
}

// The value a mutation puts in place of a leaf.
Json bad_value(std::mt19937_64& rng, const Json& old) {
  static const std::vector<Json> numbers = {0, -1, 1e300, -1e300, 1e-300, 2.5, 1e10, -2147483649LL, 4294967296LL, 3};
  static const std::vector<Json> others = {nullptr, Json::object(), Json::array(), "x", true, "../../escape", "a/b", "<&\"'>",
                                           Json::array({1, 2, 3}), Json::array({Json::array({1})}), std::string(300, 'a')};
  std::uniform_int_distribution<int> coin(0, 2);
  if ((old.is_number() || (old.is_array() && !old.empty() && old[0].is_number())) && coin(rng) > 0) {
    const Json n = numbers[std::uniform_int_distribution<size_t>(0, numbers.size() - 1)(rng)];
    if (!old.is_array()) return n;
    Json a = old;
    a[std::uniform_int_distribution<size_t>(0, a.size() - 1)(rng)] = n;
    return a;
  }
  return others[std::uniform_int_distribution<size_t>(0, others.size() - 1)(rng)];
}

// A shipped scene as a document (its // comments dropped).
Json scene_doc(const std::string& name) { return Json::parse(slurp(scenes_dir / name), nullptr, true, true); }

// The scenes the harness mutates: cloth (generated and OBJ meshes, obstacles of every
// shape, several cloths) and rods.
const std::vector<std::string> fuzz_scenes = {"hanging_cloth.json", "disk_obj.json",  "drop_on_mesh.json", "stacked_sheets.json",
                                              "folded_sheet.json",  "incline_sheet.json", "whip.json",      "rod_pile.json"};

// Small: the mutated scene is built (meshes, pins, rods) and its simulator composed, which
// validates the solver sections too.
void build(const Json& doc, const std::string& label) {
  weft::Scene scene = weft::build_scene(doc, scenes_dir.string(), label);
  auto sim = weft::make_simulator(scene);
  CHECK(sim->state().x.allFinite());
}

// Keys whose mutation would make the scene huge rather than wrong are kept small: the
// harness checks input validation, not memory (the size estimate has its own test).
Json shrink(Json doc) {
  if (doc.contains("cloths"))
    for (auto& c : doc["cloths"])
      if (c.contains("mesh") && c["mesh"].value("source", "rectangle") != "file") c["mesh"]["resolution"] = Json::array({5, 5});
  if (doc.contains("rods"))
    for (auto& r : doc["rods"]) r["count"] = std::min(r.value("count", 1), 4), r["vertices"] = std::min(r.value("vertices", 30), 12);
  return doc;
}

void fuzz_scene_values(int per_scene, std::uint64_t seed, Tally& t) {
  std::mt19937_64 rng(seed);
  for (const std::string& name : fuzz_scenes) {
    const Json base = shrink(scene_doc(name));
    std::vector<std::string> paths;
    leaves(base, "", paths);
    for (int k = 0; k < per_scene; ++k) {
      Json doc = base;
      const std::string at = paths[std::uniform_int_distribution<size_t>(0, paths.size() - 1)(rng)];
      const Json::json_pointer ptr(at);
      const Json value = bad_value(rng, doc[ptr]);
      doc[ptr] = value;
      t.run(fmt::format("{} {} = {}", name, at, value.dump().substr(0, 60)), [&] { build(doc, name); });
    }
    // Structure: a key removed, an unknown key, a part duplicated, a section of the wrong kind.
    for (int k = 0; k < per_scene / 4; ++k) {
      Json doc = base;
      const std::string at = paths[std::uniform_int_distribution<size_t>(0, paths.size() - 1)(rng)];
      const Json::json_pointer ptr(at);
      switch (k % 4) {
        case 0: doc[ptr.parent_pointer()].erase(ptr.back()); break;
        case 1: doc[ptr.parent_pointer()]["no_such_key"] = 1; break;
        case 2:
          if (doc.contains("cloths")) doc["cloths"].push_back(doc["cloths"][0]);
          if (doc.contains("rods")) doc["rods"].push_back(doc["rods"][0]);
          break;
        default: doc[ptr.parent_pointer()] = Json::array({1, 2}); break;
      }
      t.run(fmt::format("{} structure {} at {}", name, k % 4, at), [&] { build(doc, name); });
    }
  }
}

void fuzz_scene_text(int per_scene, std::uint64_t seed, const fs::path& dir, Tally& t) {
  std::mt19937_64 rng(seed);
  for (const std::string& name : fuzz_scenes) {
    const std::string text = shrink(scene_doc(name)).dump(1);
    for (int k = 0; k < per_scene; ++k) {
      std::string m = text;
      const size_t at = std::uniform_int_distribution<size_t>(0, m.size() - 1)(rng);
      switch (k % 6) {
        case 0: m.resize(at); break;                                        // truncated
        case 1: m[at] = static_cast<char>(rng() & 0xff); break;             // a flipped byte
        case 2: m.insert(at, "}{,]\"\\u0000"); break;                      // garbage
        case 3: m = "\xEF\xBB\xBF" + m; break;                              // a byte-order mark
        case 4: m += "trailing"; break;
        default: m.insert(at, std::string(1, '\0')); break;
      }
      const fs::path p = dir / fmt::format("text_{}_{}.json", k, name);
      spit(p, m);
      t.run(fmt::format("{} text mutation {} at byte {}", name, k % 6, at), [&] {
        weft::Scene scene = weft::load_scene(p.string());
        (void)weft::make_simulator(scene);
      });
    }
  }
}

void fuzz_overrides(int count, std::uint64_t seed, Tally& t) {
  std::mt19937_64 rng(seed);
  static const std::vector<std::string> values = {"1e999", "-1e999", "nan", "inf", "-inf", "[", "{}", "\"x\"", "", "0x10", "1e-320",
                                                  "[1e999]", "null", "-0", "99999999999999999999", "[2.5, 3]", "true"};
  static const std::vector<std::string> extra_keys = {"time.dt", "time.duration", "time.frame_rate", "cloths.0.name", "cloths.0.mesh.resolution",
                                                      "cloths.9.name", "no.such.key", "cloths.-1.name", "time..dt", "=", "cloths.0"};
  const Json base = shrink(scene_doc("hanging_cloth.json"));
  std::vector<std::string> paths;
  leaves(base, "", paths);
  for (int k = 0; k < count; ++k) {
    std::string key;
    if (k % 3 == 0) {
      key = extra_keys[std::uniform_int_distribution<size_t>(0, extra_keys.size() - 1)(rng)];
    } else {
      key = paths[std::uniform_int_distribution<size_t>(0, paths.size() - 1)(rng)].substr(1);
      std::replace(key.begin(), key.end(), '/', '.');
    }
    const std::string o = key + "=" + values[std::uniform_int_distribution<size_t>(0, values.size() - 1)(rng)];
    t.run("override " + o, [&] {
      weft::Scene scene = weft::load_scene((scenes_dir / "hanging_cloth.json").string(), {"cloths.0.mesh.resolution=[5,5]", o});
      (void)weft::make_simulator(scene);
    });
  }
}

// OBJ meshes: line-level mutations of the shipped meshes, read alone, as a cloth and as an
// obstacle of a scene.
void fuzz_meshes(int per_mesh, std::uint64_t seed, const fs::path& dir, Tally& t) {
  std::mt19937_64 rng(seed);
  for (const char* mesh : {"disk.obj", "sheet11_flat.obj", "block_with_hole.obj"}) {
    std::vector<std::string> lines;
    {
      std::istringstream in(slurp(scenes_dir / "meshes" / mesh));
      for (std::string l; std::getline(in, l);) lines.push_back(l);
    }
    std::vector<size_t> v_lines, f_lines;
    for (size_t i = 0; i < lines.size(); ++i) (lines[i].rfind("v ", 0) == 0 ? v_lines : lines[i].rfind("f ", 0) == 0 ? f_lines : v_lines).push_back(i);
    const long nv = static_cast<long>(v_lines.size());
    for (int k = 0; k < per_mesh; ++k) {
      std::vector<std::string> m = lines;
      const size_t fi = f_lines[std::uniform_int_distribution<size_t>(0, f_lines.size() - 1)(rng)];
      const size_t vi = v_lines[std::uniform_int_distribution<size_t>(0, v_lines.size() - 1)(rng)];
      switch (k % 12) {
        case 0: m.resize(std::uniform_int_distribution<size_t>(0, m.size())(rng)); break;  // truncated at a line
        case 1: m[fi] = "f 0 1 2"; break;
        case 2: m[fi] = fmt::format("f 1 2 {}", nv + 1); break;
        case 3: m[fi] = fmt::format("f 1 2 -{}", nv + 5); break;
        case 4: m[vi] = "v nan 0 0"; break;
        case 5: m[vi] = "v 1e300 0 -1e300"; break;
        case 6: m[vi] = "v inf 1"; break;
        case 7: m.push_back(m[fi]); m.push_back(m[fi]); break;  // a face three times: non-manifold edges
        case 8: {                                               // one face turned over
          std::istringstream ss(m[fi]);
          std::string f, a, b, c;
          ss >> f >> a >> b >> c;
          m[fi] = fmt::format("f {} {} {}", a, c, b);
          break;
        }
        case 9: m[fi] = "f 1 1 2"; break;
        case 10: m.insert(m.begin() + static_cast<long>(fi), "f 1/99 2/1 3/1"); break;
        default: m[fi] = "f 1 2 99999999999999999999"; break;
      }
      std::string text;
      for (const auto& l : m) text += l + "\n";
      const fs::path p = dir / fmt::format("mesh_{}_{}", k, mesh);
      spit(p, text);
      t.run(fmt::format("{} mutation {}", mesh, k % 12), [&] {
        const weft::MeshData d = weft::read_obj(p.string());
        CHECK(d.V.allFinite());
      });
      Json cloth = scene_doc("disk_obj.json");
      cloth["cloths"][0]["mesh"]["file"] = p.string();
      t.run(fmt::format("{} mutation {} as a cloth", mesh, k % 12), [&] { build(cloth, "disk_obj.json"); });
      Json obstacle = shrink(scene_doc("drop_on_mesh.json"));
      obstacle["obstacles"][0]["file"] = p.string();
      t.run(fmt::format("{} mutation {} as an obstacle", mesh, k % 12), [&] { build(obstacle, "drop_on_mesh.json"); });
    }
  }
  t.run("a directory as a mesh", [&] { (void)weft::read_obj(dir.string()); });
}

// Checkpoints of a cloth and a rod run: truncated, bytes flipped in the header and the
// data, header fields edited; read, then restored into the scene's simulator.
void fuzz_checkpoints(int per_kind, std::uint64_t seed, const fs::path& dir, Tally& t) {
  std::mt19937_64 rng(seed);
  const std::vector<std::pair<std::string, std::vector<std::string>>> runs = {
      {"hanging_cloth.json", {"cloths.0.mesh.resolution=[5,5]"}}, {"whip.json", {"rods.0.vertices=12"}}};
  for (const auto& [name, ov] : runs) {
    const std::string scene_path = (scenes_dir / name).string();
    auto sim = weft::make_simulator(weft::load_scene(scene_path, ov));
    REQUIRE(sim->step().ok());
    const fs::path good = dir / (name + ".wckp");
    weft::write_checkpoint(good.string(), sim->checkpoint());
    const std::string bytes = slurp(good);
    const weft::State start = sim->state();
    std::uint64_t length = 0;
    std::memcpy(&length, bytes.data() + 8, 8);
    for (int k = 0; k < per_kind; ++k) {
      std::string m = bytes;
      switch (k % 6) {
        case 0: m.resize(std::uniform_int_distribution<size_t>(0, m.size() - 1)(rng)); break;
        case 1: m[std::uniform_int_distribution<size_t>(16, 15 + length)(rng)] ^= static_cast<char>(1 + rng() % 255); break;  // header
        case 2: m[std::uniform_int_distribution<size_t>(16 + length, m.size() - 1)(rng)] ^= static_cast<char>(1 + rng() % 255); break;  // data
        case 3: {  // a value of the data set to NaN
          const double nan = std::nan("");
          std::memcpy(m.data() + 16 + length + 8 * std::uniform_int_distribution<size_t>(0, (m.size() - 16 - length) / 8 - 1)(rng), &nan, 8);
          break;
        }
        case 4: m[std::uniform_int_distribution<size_t>(8, 15)(rng)] ^= static_cast<char>(1 + rng() % 255); break;  // header length
        default: m += std::string(1 + rng() % 9, 'x'); break;
      }
      const fs::path p = dir / fmt::format("ckpt_{}_{}.wckp", k, name);
      spit(p, m);
      t.run(fmt::format("{} checkpoint mutation {}", name, k % 6), [&] {
        const weft::Checkpoint c = weft::read_checkpoint(p.string());
        sim->restore(c);
        CHECK(sim->state().x.allFinite());
        CHECK(sim->state().v.allFinite());
      });
    }
    // Edited header fields (the digest covers the data only).
    for (const auto& [key, value] : std::vector<std::pair<std::string, Json>>{
             {"time", -1.0}, {"time", 1e300}, {"step", -5}, {"vertices", 4}, {"kind", "rods"}, {"kind", "cloth"}, {"rod_dofs", Json::array({1})},
             {"topology", "0"}, {"rest_shape", "0"}, {"format", 2}}) {
      weft::Checkpoint c = weft::read_checkpoint(good.string());
      c.header[key] = value;
      const fs::path p = dir / ("edited_" + name + ".wckp");
      weft::write_checkpoint(p.string(), c);
      t.run(fmt::format("{} checkpoint with {} = {}", name, key, value.dump()), [&] {
        sim->restore(weft::read_checkpoint(p.string()));
        CHECK(sim->state().x.allFinite());
      });
    }
    t.run("a directory as a checkpoint", [&] { (void)weft::read_checkpoint(dir.string()); });
  }
}

// A JSON value with no null (nlohmann writes NaN and Inf as null) anywhere in it.
bool all_finite(const Json& j) {
  if (j.is_null()) return false;
  if (j.is_number_float()) return std::isfinite(j.get<double>());
  if (j.is_structured())
    for (const auto& v : j) if (!all_finite(v)) return false;
  return true;
}

// Whole runs of mutated scenes, as a user makes them: `weft run` in a sandbox holding the
// scene and its meshes. Exit 0, 2 or 3 (with a message), nothing written beside `out`, and a
// run that says it completed simulated every step with finite numbers.
void fuzz_runs(int count, std::uint64_t seed, Tally& t) {
  std::mt19937_64 rng(seed);
  for (int k = 0; k < count; ++k) {
    const std::string name = fuzz_scenes[static_cast<size_t>(k) % fuzz_scenes.size()];
    const fs::path box = weft::test::temp_dir(fmt::format("fuzz_run_{}", k));
    fs::copy(scenes_dir / "meshes", box / "meshes");
    Json doc = shrink(scene_doc(name));
    doc["time"]["duration"] = 2 * doc["time"].value("dt", 1.0 / 240.0);
    doc["time"]["frame_rate"] = 1.0 / doc["time"]["duration"].get<double>();
    // Extreme numbers, where a scene that loads must then run or fail cleanly.
    std::vector<std::string> all, paths;
    leaves(doc, "", all);
    for (const auto& p : all)
      if (doc[Json::json_pointer(p)].is_number()) paths.push_back(p);
    static const std::vector<double> extremes = {0, -1, 1e300, -1e300, 1e-300, 1e10, 1e-10, 2.5, 1e6, -1e6};
    const std::string at = paths[std::uniform_int_distribution<size_t>(0, paths.size() - 1)(rng)];
    const Json value = extremes[std::uniform_int_distribution<size_t>(0, extremes.size() - 1)(rng)];
    doc[Json::json_pointer(at)] = value;
    spit(box / "scene.json", doc.dump(1));
    const std::string what = fmt::format("weft run {} with {} = {}", name, at, value.dump().substr(0, 60));
    const auto r = weft::test::run_shell(fmt::format("cd {} && timeout 300 {} run scene.json --out out -q", box.string(), WEFT_BINARY));
    std::set<std::string> beside;
    for (const auto& e : fs::directory_iterator(box)) beside.insert(e.path().filename().string());
    if (beside != std::set<std::string>{"meshes", "scene.json", "out"} && beside != std::set<std::string>{"meshes", "scene.json"})
      t.failures.push_back(fmt::format("{}: files written beside --out: {}", what, fmt::join(beside, " ")));
    if (r.code == 0) {
      ++t.accepted;
      const Json summary = Json::parse(slurp(box / "out" / "summary.json"));
      if (summary["status"] != "completed" || summary["steps"] != summary["steps_planned"] || !all_finite(summary["final_energy"]) ||
          !all_finite(summary["stage_seconds"]))
        t.failures.push_back(fmt::format("{}: exit 0 with summary {}", what, summary.dump().substr(0, 300)));
      std::ifstream stats(box / "out" / "stats.jsonl");
      for (std::string line; std::getline(stats, line);)
        if (const Json j = Json::parse(line); !all_finite(j["energy"])) t.failures.push_back(fmt::format("{}: exit 0 with a non-finite energy: {}", what, line.substr(0, 200)));
    } else if ((r.code == 2 || r.code == 3) && r.output.find("error") != std::string::npos) {
      ++t.refused;
    } else {
      t.failures.push_back(fmt::format("{}: exit code {} (timeout: 124, killed by a signal: -1): {}", what, r.code, r.output.substr(0, 400)));
    }
  }
}

}  // namespace

TEST_SUITE("fuzz") {
  TEST_CASE("fuzz: whole runs of mutated scenes exit 0 2 or 3 and write only under --out") {
    Tally t;
    fuzz_runs(16, 6, t);
    t.report("runs", 1);
  }
  TEST_CASE("fuzz: mutated scene values and structure are accepted or refused with a message") {
    Tally t;
    fuzz_scene_values(40, 1, t);
    t.report("scene values", 100);
  }
  TEST_CASE("fuzz: mutated scene text and overrides are accepted or refused with a message") {
    const fs::path dir = weft::test::temp_dir("fuzz_text");
    Tally t;
    fuzz_scene_text(8, 2, dir, t);
    fuzz_overrides(60, 3, t);
    t.report("scene text and overrides", 70);
  }
  TEST_CASE("fuzz: mutated OBJ meshes are accepted or refused with a message") {
    const fs::path dir = weft::test::temp_dir("fuzz_meshes");
    Tally t;
    fuzz_meshes(24, 4, dir, t);
    t.report("meshes", 120);
  }
  TEST_CASE("fuzz: mutated checkpoints are refused with a message - never restored damaged") {
    const fs::path dir = weft::test::temp_dir("fuzz_checkpoints");
    Tally t;
    fuzz_checkpoints(36, 5, dir, t);
    t.report("checkpoints", 60);
  }
}

TEST_SUITE("slow") {
  TEST_CASE("fuzz: many more mutated scenes meshes and checkpoints in process") {
    const fs::path dir = weft::test::temp_dir("fuzz_many");
    Tally t;
    fuzz_scene_values(3000, 11, t);
    fuzz_scene_text(200, 12, dir, t);
    fuzz_overrides(2000, 13, t);
    fuzz_meshes(600, 14, dir, t);
    fuzz_checkpoints(900, 15, dir, t);
    t.report("all inputs", 8000);
  }
  TEST_CASE("fuzz: many whole runs of mutated scenes") {
    Tally t;
    fuzz_runs(600, 16, t);
    t.report("runs", 20);
  }
}
