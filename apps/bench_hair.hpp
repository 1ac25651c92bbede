#pragma once
/// \file bench_hair.hpp
/// `weft bench hair`: the hair-ball stability study of thesis §9.2 (Figure 9.12, methods/rod-contact
/// §14.2, V-21 and V-22). Runs one hair-ball scene under each rod strategy at each time
/// step for a (scaled-down) duration and reports, per run: success or failure (the
/// classification of `weft stability`: a failed step, a non-finite state or energy, or an
/// edge strain |l / l_rest - 1| above --strain), wall time, contacts per step (mean, max),
/// contact groups per step, constrained Newton (outer) iterations per contact group (mean
/// over the groups, mean weighted by the group's contacts, max), Gauss-Seidel sweeps and
/// re-linearised rods per step, with the thesis' table alongside.
///
/// Files in --out: bench_hair.csv (one row per strategy and time step, written as soon as
/// the run ends), bench_hair.jsonl (a meta record, one line per step, one per run),
/// bench_hair.md (the tables, rewritten after every run). An interrupted campaign keeps
/// every finished run; --resume skips the runs bench_hair.csv already holds.
#include <string>
#include <vector>

namespace weft::app {

struct BenchHairOptions {
  std::string scene;                     ///< "" = <source dir>/scenes/hairball_1000.json
  std::vector<std::string> overrides;    ///< key=value applied to every run
  std::vector<std::string> strategies;   ///< combinations; empty: rods_impulse, rods_linear, rods_adonis
  std::vector<double> dts;               ///< [s]; empty: 0.1, 0.01, 0.005, 0.001 (quick: 0.01, 0.005)
  double duration = 0;                   ///< [s] simulated per run; 0: the scene's (quick: 0.02)
  double strain_threshold = 0.5;         ///< failure above this edge strain
  bool quick = false;                    ///< tiny run for tests: 8 rods of the scene, 2 time steps, 0.02 s
  bool resume = false;                   ///< keep bench_hair.csv and skip the runs it holds
  std::string out_dir;                   ///< "" = out/bench_hair
};

/// Runs the study; prints Markdown tables to stdout. Returns an exit code (0 also when runs
/// fail: a failure is a result; 2 for a configuration error before any run).
int bench_hair(const BenchHairOptions& options);

}  // namespace weft::app
