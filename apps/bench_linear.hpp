#pragma once
/// \file bench_linear.hpp
/// `weft bench linear`: thesis Table 11.1 (methods/multigrid §10). The five examples (pinned, drooping,
/// re-entrant, dropHorizontal, dropVertical; apps/bench_linear_systems.hpp) on regular and
/// irregular tessellations of (m+1)^2 vertices are simulated with a Baraff-Witkin linearly
/// implicit step; every selected solver solves the same system of every step (same A, b,
/// constraints), timed separately (setup = analyze_pattern when the pattern changed +
/// factorize; solve). The simulation advances with the reference solver's answer (the direct
/// solver when selected), which also gives x* for the energy error. The report compares the
/// speedups of SA+PPCG over Diag-PCG and over the direct solver with the thesis's.
///
/// The solvers are reached through a small type-erased interface (`AnySolver`), implemented
/// for any `LinearSolver` by a template adapter (apps/bench_linear_solvers.cpp), which also
/// holds the list of the solvers that this build provides.
#include <Eigen/Core>

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/constraints.hpp"
#include "framework/status.hpp"

namespace weft::linear {
struct SaLevelStats;  // linear/sa_amg.hpp
}

namespace weft::app {

struct BenchLinearOptions {
  std::vector<std::string> examples;       ///< empty: all five (pinned drooping re-entrant dropHorizontal dropVertical)
  std::vector<std::string> tessellations;  ///< empty: regular irregular
  std::vector<int> sizes;                  ///< grid intervals m ((m+1)^2 vertices); empty: the thesis's 12 (quick: 30)
  long long max_vertices = 0;              ///< > 0: drop sizes with more vertices
  std::vector<std::string> solvers;        ///< empty: every available one (see `weft bench linear --list-solvers`)
  int steps = 0;                           ///< > 0: steps per case (before the cap); 0: the thesis's frames at 30 fps
  double step_budget = 4e6;                ///< cap: steps <= max(2, step_budget / vertices)
  int max_iterations = 20000;              ///< CG iteration limit of the iterative solvers
  double tolerance = 1e-5;                 ///< relative M^-1-norm residual (thesis)
  /// KEY=VALUE settings of the smoothed-aggregation preconditioner of sa_ppcg and sa_mpcg
  /// (the keys of the scene's linear.preconditioner section, `weft keys`), e.g. cycle_gamma=2.
  std::vector<std::string> sa_settings;
  std::string out_dir;                     ///< "" = out/bench_linear
  bool quick = false;                      ///< m = 30 (961 vertices) only, 2 steps (for tests)
  int threads = 0;                         ///< OpenMP threads (0: all)
  bool list_solvers = false;               ///< print the available solvers and exit
};

/// Runs the benchmark; prints the Markdown report to stdout. Returns an exit code.
int bench_linear(const BenchLinearOptions& options);

namespace benchlin {

/// A linear solver behind a virtual interface (the LinearSolver life cycle plus the context).
class AnySolver {
 public:
  virtual ~AnySolver() = default;
  /// Constraints and positions of the next factorize.
  virtual void set_context(const SolveContext& ctx) = 0;
  virtual Status analyze_pattern(const BlockCsr& A) = 0;
  virtual Status factorize(const BlockCsr& A) = 0;
  /// A new time step begins (each benchmark step is one system): a preconditioner kept per
  /// time step (`reuse = step`) refreshes at the next factorize.
  virtual void begin_step() = 0;
  /// x holds the initial guess on entry.
  virtual LinearReport solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) = 0;
  /// A known solution for the solver's own energy-error report; false if it has none.
  virtual bool set_reference(const Eigen::VectorXd* x_star) = 0;
  /// The multigrid hierarchy of the last setup, finest level first (empty: no multigrid).
  virtual std::vector<weft::linear::SaLevelStats> hierarchy() const = 0;
  /// The last setup's time split [s] by phase (empty: no multigrid).
  virtual std::vector<std::pair<std::string, double>> setup_split() const = 0;
};

/// One solver this build provides.
struct SolverEntry {
  std::string key;          ///< --solvers name, e.g. "sa_ppcg"
  std::string label;        ///< for the report, e.g. "SA+PPCG"
  std::string description;
  bool direct = false;      ///< a direct solver (candidate reference)
  std::function<std::unique_ptr<AnySolver>()> make;
};

struct SolverSettings {
  double tolerance = 1e-5;
  int max_iterations = 20000;
  std::vector<std::string> sa_settings;  ///< KEY=VALUE of the SA preconditioner (BenchLinearOptions::sa_settings)
};

/// Every solver of this build, in report order (apps/bench_linear_solvers.cpp).
std::vector<SolverEntry> available_solvers(const SolverSettings& settings);

/// "sa_ppcg:KEY=VALUE[:KEY=VALUE...]": SA+PPCG with these preconditioner settings on top of
/// --sa, so that settings are compared side by side in one run. Throws ConfigError naming a
/// bad base solver, key or value.
SolverEntry sa_ppcg_with(const SolverSettings& settings, const std::string& token);

}  // namespace benchlin
}  // namespace weft::app
