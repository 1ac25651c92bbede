#pragma once
/// \file bench_common.hpp
/// What the `weft` reports share: where they ran (CPU, source revision, build flags), where
/// the source tree is, wall-clock timing and CSV quoting.
#include <chrono>
#include <string>
#include <vector>
#include <string_view>

#include "framework/params_json.hpp"

namespace weft::app {

using Clock = std::chrono::steady_clock;
/// Seconds since t0.
inline double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// The CPU's "model name" from /proc/cpuinfo ("unknown" elsewhere).
std::string cpu_model();

/// "time.duration=D" with D the scene's duration (after the overrides `ov`; `duration` > 0
/// instead when given) rounded to a whole number of steps of `dt`, at least one: what a
/// sweep over dt runs, since a scene refuses a duration that is not whole steps.
std::string whole_steps_duration(const std::string& scene, const std::vector<std::string>& ov, double dt, double duration = 0);
/// weft's data (scripts/ for plots and renders, scenes/ for the default scenes): $WEFT_DATA_DIR,
/// else share/weft beside the binary's bin/ (installed: PREFIX/bin/weft and PREFIX/share/weft;
/// the build tree links build/<preset>/share/weft to the source's scripts and scenes).
std::string data_dir();
/// The compiler flags of this build (for the reports).
const char* build_flags();
/// A CSV field: double-quoted, inner quotes doubled, newlines turned into spaces.
std::string csv_field(const std::string& s);
/// The first JSONL record of a bench: {"record": "meta", "bench", "git" and "build" (both the
/// binary's build_commit()), "compiler", "flags",
/// "cpu", "hardware_threads", "threads"}; the bench adds its own keys.
Json meta_record(std::string_view bench, const std::string& cpu, int threads);

/// OpenMP worker threads of the next parallel region (1 without OpenMP).
int worker_threads();

/// Transparent huge pages for this process's heap. Where the kernel gives huge pages only to
/// memory that asks for them (/sys/kernel/mm/transparent_hugepage/enabled = madvise, Debian's
/// default), sets GLIBC_TUNABLES=glibc.malloc.hugetlb=1 (glibc >= 2.35: malloc advises its
/// large blocks) and re-executes the program, which is the only way glibc reads it. Why: SA's
/// setup allocates its hierarchy afresh, and every 4 KiB page of it is a page fault; on the
/// 2-vCPU EPYC VM of bench/results/table-11-1 the setup at 1M vertices took 22.8 s with 4 KiB
/// pages and 10.1 s with huge pages, the solve 8.0 s and 7.0 s (THP-lean2.md there). Returns (doing
/// nothing) when the tunable is already set, WEFT_HUGE_PAGES=0, the kernel mode is not
/// madvise, or the re-execution fails. In the same re-execution it sets OMP_WAIT_POLICY=PASSIVE
/// unless the user set it: idle OpenMP threads then sleep instead of spinning.
void reexec_with_environment(char** argv);
/// How the heap gets its pages, for the reports: "huge (glibc.malloc.hugetlb=1, THP madvise)",
/// "huge (THP always)" or "4 KiB (...why...)".
std::string huge_pages_status();

}  // namespace weft::app
