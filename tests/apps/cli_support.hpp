#pragma once
// Runs the weft binary as a user would, and reads back what it wrote.
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

namespace weft::test {

struct Result {
  int code = -1;
  std::string output;  // stdout and stderr
};

/// Runs a shell command: its exit code and its stdout and stderr.
inline Result run_shell(const std::string& command) {
  const std::string cmd = command + " 2>&1";
  Result r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) r.output.append(buf, n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

inline Result run_weft(const std::string& args, const std::string& prefix = "") {
  return run_shell(prefix + " " WEFT_BINARY " " + args);
}

/// A fresh temporary directory per test.
inline std::filesystem::path temp_dir(const std::string& name) {
  const auto d = std::filesystem::temp_directory_path() / ("weft_test_" + name);
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

/// Options of an in-process driver run (`run_ablate`, `run_stability`) on a scene of the
/// source tree: quiet, no plots, output in a fresh temporary directory named after the test.
template <class Options>
Options quiet_run(const std::string& scene_file, std::vector<std::string> overrides, double duration, const std::string& name) {
  Options o;
  o.scene = std::string(WEFT_SOURCE_DIR) + "/scenes/" + scene_file;
  o.overrides = std::move(overrides);
  o.duration = duration;
  o.out_dir = temp_dir(name).string();
  o.quiet = true;
  o.plots = false;
  return o;
}

inline std::string write_file(const std::filesystem::path& p, const std::string& text) {
  std::ofstream f(p);
  f << text;
  return p.string();
}

/// A small valid scene: 5x5 sheet pinned along one edge, 0.1 s at dt = 0.01.
inline nlohmann::json small_scene() {
  return nlohmann::json::parse(R"({
    "combo": "cloth_ip_direct",
    "cloths": [{"mesh": {"source": "rectangle", "size": [0.5, 0.5], "resolution": [5, 5]},
                "material": {"density": 0.15, "youngs_modulus": "20 MPa", "thickness": "0.3 mm"},
                "pins": [{"box_min": [-1, 0.24, -1], "box_max": [1, 1, 1]}]}],
    "time": {"dt": 0.01, "duration": 0.1, "frame_rate": 50},
    "output": {"obj": true, "vtp": true, "stats": true}
  })");
}

inline std::vector<nlohmann::json> read_jsonl(const std::filesystem::path& p) {
  std::vector<nlohmann::json> lines;
  std::ifstream f(p);
  std::string line;
  while (std::getline(f, line)) lines.push_back(nlohmann::json::parse(line));  // throws on invalid JSON
  return lines;
}

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

}  // namespace weft::test
