#pragma once
/// \file bench_common.hpp
/// What the `weft` reports share: where they ran (CPU, source revision, build flags), where
/// the source tree is, wall-clock timing and CSV quoting.
#include <chrono>
#include <string>
#include <string_view>

#include "framework/params_json.hpp"

namespace weft::app {

using Clock = std::chrono::steady_clock;
/// Seconds since t0.
inline double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// The CPU's "model name" from /proc/cpuinfo ("unknown" elsewhere).
std::string cpu_model();
/// `git describe --always --dirty` of the source tree ("unknown" without git).
std::string git_describe(const std::string& source_dir);
/// The source tree (default scenes, scripts): $WEFT_SOURCE_DIR, else the one this binary was configured from.
std::string source_dir();
/// The compiler flags of this build (for the reports).
const char* build_flags();
/// A CSV field: double-quoted, inner quotes doubled, newlines turned into spaces.
std::string csv_field(const std::string& s);
/// The first JSONL record of a bench: {"record": "meta", "bench", "git", "compiler", "flags",
/// "cpu", "hardware_threads", "threads"}; the bench adds its own keys.
Json meta_record(std::string_view bench, const std::string& git, const std::string& cpu, int threads);

/// OpenMP worker threads of the next parallel region (1 without OpenMP).
int worker_threads();

}  // namespace weft::app
