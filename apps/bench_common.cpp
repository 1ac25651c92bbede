#include "apps/bench_common.hpp"

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <thread>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "framework/build_info.hpp"
#include "linear/lapack_info.hpp"

#ifndef WEFT_SOURCE_DIR
#define WEFT_SOURCE_DIR ""
#endif
#ifndef WEFT_CXX_FLAGS
#define WEFT_CXX_FLAGS "unknown"
#endif

namespace weft::app {

std::string source_dir() {
  const char* env = std::getenv("WEFT_SOURCE_DIR");
  return env ? env : WEFT_SOURCE_DIR;
}

const char* build_flags() { return WEFT_CXX_FLAGS; }

std::string csv_field(const std::string& s) {
  std::string q(1, '"');
  for (char c : s) {
    if (c == '"') q.append("\"\"");
    else q.push_back(c == '\n' ? ' ' : c);
  }
  q.push_back('"');
  return q;
}

std::string cpu_model() {
  std::ifstream f("/proc/cpuinfo");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("model name", 0) == 0) {
      const auto p = line.find(':');
      if (p != std::string::npos) return line.substr(p + 2);
    }
  return "unknown";
}

std::string git_describe(const std::string& source_dir) {
  if (source_dir.empty()) return "unknown";
  const std::string cmd = "git -C '" + source_dir + "' describe --always --dirty 2>/dev/null";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return "unknown";
  char buf[128] = {0};
  std::string out = fgets(buf, sizeof buf, p) ? buf : "";
  pclose(p);
  while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
  return out.empty() ? "unknown" : out;
}

Json meta_record(std::string_view bench, const std::string& git, const std::string& cpu, int threads) {
  return {{"record", "meta"},
          {"bench", bench},
          {"git", git},
          {"build", build_commit()},
          {"compiler", __VERSION__},
          {"flags", build_flags()},
          {"cpu", cpu},
          {"hardware_threads", static_cast<int>(std::thread::hardware_concurrency())},
          {"lapack", linear::lapack_library()},
          {"threads", threads}};
}

int worker_threads() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

}  // namespace weft::app
