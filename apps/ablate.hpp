#pragma once
/// \file ablate.hpp
/// `weft ablate`: one scene under several combinations of policies, each measured against a
/// reference trajectory (the same scene under a direct solver, a smaller time step and tight
/// Newton tolerances, unless given): RMS and largest vertex distance at the frame times,
/// normalised by the scene's size; energy drift; penetrations (obstacles, cloth-cloth
/// intersections, rod overlaps); Newton and linear iterations; wall time split by stage.
/// With `--sweep`, every combination runs at every sweep point: the work-precision diagram (error
/// against run time, one curve per combination, the Pareto front over all points).
/// Writes ablate.csv, ablate.json and histories.jsonl, and plots them (error against run time
/// with the Pareto front, time per stage, convergence histories) through scripts/weft_plot.py
/// when Debian's python3-matplotlib is installed.
#include <string>
#include <vector>

namespace weft::app {

struct AblateOptions {
  std::string scene;
  std::vector<std::string> combos;     ///< names, or the single word "applicable" (every combination that applies)
  std::string reference;               ///< reference combination ("" = a direct-solver combination for the scene)
  int reference_substeps = 4;          ///< reference dt = scene dt / this
  bool reference_tighten = true;       ///< tight Newton tolerances for the reference
  std::vector<std::string> overrides;  ///< applied to every run, the reference included
  /// Work-precision sweeps: "key=v1,v2,..." each; every combination runs at every point of
  /// their product (one override per sweep), all against the one reference. A time.dt sweep
  /// makes the reference's step its smallest value / reference_substeps.
  std::vector<std::string> sweeps;
  std::string out_dir = "out-ablate";
  double duration = 0;                 ///< [s]; 0 = the scene's
  bool plots = true;
  bool quiet = false;
};

/// One combination's measurements.
struct AblateRow {
  std::string combo;
  std::string point;          ///< the sweep point, "key=value key=value" ("" without sweeps)
  std::string status = "ok";  ///< "ok", or "failed at step N (stage): why"
  int steps = 0, steps_planned = 0, frames_compared = 0;
  double rms_error = 0, max_error = 0;  ///< vertex distance to the reference / scene size
  double energy_drift = 0;              ///< (E_end - E_0) / energy scale
  int penetrations_max = 0, penetrations_end = 0;
  long newton_iterations = 0, linear_iterations = 0, contacts = 0;
  double wall_seconds = 0;
  std::vector<double> stage_seconds;    ///< per Stage (framework/timers.hpp)
};

/// Runs the comparison; returns the exit code (0; 2 for a configuration error before any
/// run; 3 when the reference itself fails).
int run_ablate(const AblateOptions& options, std::vector<AblateRow>* rows = nullptr);

}  // namespace weft::app
