#pragma once
/// \file runner.hpp
/// `weft run`: load and validate a scene, then step it, writing frames, per-step
/// statistics and a summary. Failures keep everything written so far.
#include <string>
#include <vector>

namespace weft::app {

/// Exit codes of the weft command.
enum ExitCode : int {
  exit_ok = 0,
  exit_usage = 1,    ///< bad command line (CLI11)
  exit_config = 2,   ///< invalid scene, parameter, override or mesh: nothing was written
  exit_failed = 3,   ///< a step failed (NaN, no convergence): output up to the failure is intact
  // interrupted by signal s: 128 + s (130 for SIGINT, 143 for SIGTERM)
};

struct RunOptions {
  std::string scene;
  std::string out_dir;               ///< "" = "out"
  std::vector<std::string> overrides;
  int progress = -1;                 ///< -1: bar if stderr is a terminal; 0: plain lines; 1: bar
  bool quiet = false;
  int checkpoint_every = 0;          ///< write checkpoint.wckp every this many frames (0: only on interrupt and failure)
  std::string resume;                ///< checkpoint to continue from ("" = start at t = 0)
  bool threads_given = false;        ///< --threads or OMP_NUM_THREADS: keep it; else pick by the scene's size
};

/// Below this many simulated vertices `weft run` uses one thread unless told otherwise. The
/// hanging cloth for 24 steps, 2-vCPU EPYC, idle (2026-12-02), 1 / 2 threads: 961 vertices
/// 0.59 / 0.68 s, 1,681 1.42 / 1.18 s, 2,601 1.73 / 1.94 s, 3,721 3.64 / 3.11 s, 10,201
/// 9.75 / 7.98 s: the second thread pays from a few thousand vertices, and below that it
/// loses when the other core is busy (60 steps of a small scene took 23.7 s on two threads
/// against 15.0 s on one on a loaded machine).
inline constexpr long long parallel_min_vertices = 3000;

/// Runs a scene; returns the exit code. Messages go to stderr.
int run_scene(const RunOptions& options);

}  // namespace weft::app
