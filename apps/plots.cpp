#include "apps/plots.hpp"

#include "apps/bench_common.hpp"

#include <fmt/format.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>

namespace weft::app {
namespace {
std::string quoted(const std::string& s) {
  std::string q(1, '\'');
  for (char c : s) {
    if (c == '\'') q.append("'\\''");  // close, escaped quote, reopen
    else q.push_back(c);
  }
  q.push_back('\'');
  return q;
}
}  // namespace

PlotOutcome plot(const std::string& kind, const std::string& input, const std::string& out, const std::vector<std::string>& extra) {
  const std::string python = "/usr/bin/python3";
  const std::string script = data_dir() + "/scripts/weft_plot.py";
  for (const std::string& f : {python, script})
    if (!std::filesystem::exists(f)) {
      fmt::print(stderr, "{} plot skipped: {} not found\n", kind, f);
      return PlotOutcome::skipped;
    }
  std::string cmd = fmt::format("{} {} {} {} --out {}", quoted(python), quoted(script), kind, quoted(input), quoted(out));
  for (const std::string& e : extra) {
    cmd.push_back(' ');
    cmd.append(quoted(e));
  }
  cmd.append(" >/dev/null");
  const int rc = std::system(cmd.c_str());
  const int code = rc != -1 && WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  if (code == 0) return PlotOutcome::written;
  if (code == 3) {
    fmt::print(stderr, "{} plot skipped: python3-matplotlib is not installed (apt-get install python3-matplotlib)\n", kind);
    return PlotOutcome::skipped;
  }
  fmt::print(stderr, "{} plot failed (exit {}): {}\n", kind, code, cmd);
  return PlotOutcome::failed;
}

int run_python_tool(const std::string& script_name, const std::vector<std::string>& args) {
  const std::string python = "/usr/bin/python3";
  const std::string script = data_dir() + "/scripts/" + script_name;
  for (const std::string& f : {python, script})
    if (!std::filesystem::exists(f)) {
      fmt::print(stderr, "error: {} not found{}\n", f, f == python ? " (apt-get install python3)" : "");
      return 127;
    }
  std::string cmd = quoted(python) + " " + quoted(script);
  for (const std::string& a : args) {
    cmd.push_back(' ');
    cmd.append(quoted(a));
  }
  const int rc = std::system(cmd.c_str());
  return rc != -1 && WIFEXITED(rc) ? WEXITSTATUS(rc) : 1;
}

}  // namespace weft::app
