#pragma once
/// \file stability.hpp
/// `weft stability`: a grid of runs (time step against one scene parameter) per
/// combination, each classified as stable, diverged (NaN or energy blow-up), not converged
/// (a step's Newton or linear solve failed) or excessive strain. Writes a CSV table, prints
/// a map and, with python3-matplotlib, draws it (stability_map.png and .svg).
#include <string>
#include <vector>

namespace weft {
struct Scene;
struct State;
}  // namespace weft

namespace weft::app {

enum class Stability { stable, diverged, not_converged, excessive_strain, invalid };

struct StabilityOptions {
  std::string scene;
  std::vector<double> dts;                 ///< time steps [s]
  std::string vary_key;                    ///< dotted scene key, "" for none
  std::vector<std::string> vary_values;    ///< values of vary_key (JSON literals or strings)
  std::vector<std::string> combos;         ///< "" = the scene's own
  std::vector<std::string> overrides;      ///< applied to every run
  std::string out_dir = "out-stability";
  double duration = 0;                     ///< [s]; 0 = the scene's
  double strain_threshold = 0.5;           ///< largest admissible edge strain |l/l0 - 1|
  double energy_growth = 0.1;              ///< blow-up: total energy rises above E0 + energy_growth * scale (scenes without scripted motion)
  bool quiet = false;
  bool plots = true;                       ///< stability_map.{png,svg} through scripts/weft_plot.py (python3-matplotlib)
};

/// One grid cell.
struct StabilityResult {
  std::string combo;
  double dt = 0;
  std::string value;
  Stability outcome = Stability::stable;
  int steps = 0, steps_planned = 0;
  double max_strain = 0, energy_ratio = 0, wall_seconds = 0, newton_mean = 0;
  int newton_max = 0;
  /// Steps with at least one contact. A run that never touched anything says nothing about
  /// a contact method: the map marks it `o` when other runs of the sweep had contacts.
  int contact_steps = 0;
  std::string message;
};

const char* to_string(Stability s);

/// Largest edge strain |l / l_rest - 1| over the rods' edges and the cloth mesh's edges.
double max_edge_strain(const Scene& scene, const State& s);

/// Runs the grid; returns the exit code (0, or 2 for a configuration error before any run).
int run_stability(const StabilityOptions& options, std::vector<StabilityResult>* results = nullptr);

}  // namespace weft::app
