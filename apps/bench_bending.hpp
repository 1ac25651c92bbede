#pragma once
/// \file bench_bending.hpp
/// `weft bench bending`: the bending benchmark of thesis chapter 5 (Tables 5.1 and 5.2,
/// methods/shells §8). Three implementations of the same hinge energy -- refactored per triangle
/// (N), closed form per hinge (S, standing in for the thesis' symbolic code) and forward-mode
/// automatic differentiation (A) -- are timed on the 36 drape resolutions n = 11, 13, ..., 81
/// (n x n vertices, 1 m square). The cloth-sphere contact of the thesis does not exist yet, so
/// the configurations are recorded from a hanging cloth (scenes/hanging_cloth.json at each
/// resolution), which the output says.
#include <string>
#include <vector>

namespace weft::app {

struct BenchBendingOptions {
  std::string out_dir;        ///< "" = "out/bench_bending": JSON lines, CSV and the Markdown report
  std::string scene;          ///< "" = <source dir>/scenes/hanging_cloth.json
  bool quick = false;         ///< 4 resolutions, 1 recorded state, short timings (for tests)
  double budget = -1;         ///< [s] timing budget per resolution and method (< 0: 0.2, quick 0.02)
  int max_reps = 30;          ///< repetitions per timing at most (at least 3, after one warm-up)
  double record_dt = 1.0 / 60;    ///< [s] time step of the recording run (4x the scene's 1/240 s)
  double record_time = 4.0 / 60;  ///< [s] simulated time of the recording run (quick: 4 steps)
  int states = 3;                 ///< recorded states per resolution (quick: 1): the last steps of the run
  std::vector<int> resolutions;   ///< n of the n x n grids; empty: 11, 13, ..., 81 (quick: 11, 15, 19, 23)
};

/// Runs the benchmark; prints the Markdown report to stdout. Returns an exit code.
int bench_bending(const BenchBendingOptions& options);

}  // namespace weft::app
