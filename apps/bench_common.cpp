#include "apps/bench_common.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string_view>
#include <thread>

#include <unistd.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "framework/build_info.hpp"
#include "framework/scene.hpp"
#include "linear/lapack_info.hpp"

#ifndef WEFT_CXX_FLAGS
#define WEFT_CXX_FLAGS "unknown"
#endif

namespace weft::app {

std::string data_dir() {
  if (const char* env = std::getenv("WEFT_DATA_DIR"); env && *env) return env;
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return "share/weft";
  return (exe.parent_path().parent_path() / "share" / "weft").string();
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

std::string whole_steps_duration(const std::string& scene, const std::vector<std::string>& ov, double dt, double duration) {
  const double d = duration > 0 ? duration : load_scene(scene, ov).spec.time.duration;
  return fmt::format("time.duration={}", static_cast<double>(std::max(1LL, std::llround(d / dt))) * dt);
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

Json meta_record(std::string_view bench, const std::string& cpu, int threads) {
  return {{"record", "meta"},
          {"bench", bench},
          {"git", build_commit()},
          {"build", build_commit()},
          {"compiler", __VERSION__},
          {"flags", build_flags()},
          {"cpu", cpu},
          {"hardware_threads", static_cast<int>(std::thread::hardware_concurrency())},
          {"lapack", linear::lapack_library()},
          {"heap_pages", huge_pages_status()},
          {"threads", threads}};
}

int worker_threads() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

namespace {

constexpr std::string_view hugetlb_tunable = "glibc.malloc.hugetlb=1";

/// The kernel's THP mode: "always", "madvise", "never" or "" (unknown).
std::string thp_mode() {
  std::ifstream f("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string line;
  if (!std::getline(f, line)) return "";
  const auto open = line.find('['), close = line.find(']');
  return open == std::string::npos || close == std::string::npos ? "" : line.substr(open + 1, close - open - 1);
}

bool tunable_set() {
  const char* t = std::getenv("GLIBC_TUNABLES");
  return t && std::string_view(t).find("glibc.malloc.hugetlb") != std::string_view::npos;
}

bool opted_out() {
  const char* e = std::getenv("WEFT_HUGE_PAGES");
  return e && (std::string_view(e) == "0" || std::string_view(e) == "off");
}

}  // namespace

void reexec_with_environment(char** argv) {
  // Worker threads that wait passively (OMP_WAIT_POLICY, read by the OpenMP runtime when it
  // loads, hence the re-execution): spinning threads take the core from other work on a shared
  // machine, where two threads ran 60 steps of a small scene in 23.7 s against 15.0 s on one.
  // The user's own setting is kept.
  const bool wait_policy = std::getenv("OMP_WAIT_POLICY") == nullptr;
  const bool huge = !tunable_set() && !opted_out() && thp_mode() == "madvise";
  if (!wait_policy && !huge) return;
  const char* old = std::getenv("GLIBC_TUNABLES");
  const std::string old_tunables = old ? old : "";
  if (huge) {
    std::string value = old && *old ? old_tunables + ":" : std::string();
    value += hugetlb_tunable;
    if (setenv("GLIBC_TUNABLES", value.c_str(), 1) != 0) return;
  }
  if (wait_policy) setenv("OMP_WAIT_POLICY", "PASSIVE", 1);
  execv("/proc/self/exe", argv);
  // Not re-executed: go on with 4 KiB pages and the runtime's wait policy, and say so in the reports.
  if (wait_policy) unsetenv("OMP_WAIT_POLICY");
  if (huge) {
    if (old)
      setenv("GLIBC_TUNABLES", old_tunables.c_str(), 1);
    else
      unsetenv("GLIBC_TUNABLES");
  }
}

std::string huge_pages_status() {
  const std::string mode = thp_mode();
  if (mode == "always") return "huge (THP always)";
  if (mode == "madvise" && tunable_set()) {
    const std::string t = std::getenv("GLIBC_TUNABLES");
    if (t.find(hugetlb_tunable) == std::string::npos) return "4 KiB or explicit (GLIBC_TUNABLES=" + t + ")";
    return "huge (glibc.malloc.hugetlb=1, THP madvise)";
  }
  if (mode == "madvise") return opted_out() ? "4 KiB (WEFT_HUGE_PAGES=0)" : "4 KiB (GLIBC_TUNABLES not applied)";
  return mode.empty() ? "4 KiB (THP unknown)" : "4 KiB (THP " + mode + ")";
}

}  // namespace weft::app
