// The solvers of `weft bench linear`: a template adapter from any `LinearSolver` to the
// virtual `AnySolver`, and the list of the solvers this build provides (report order).
#include <boost/algorithm/string/split.hpp>

#include <type_traits>

#include "apps/bench_linear.hpp"
#include "framework/concepts.hpp"
#include "framework/params_json.hpp"
#include "linear/direct.hpp"
#include "linear/pcg.hpp"
#include "linear/prefilter.hpp"
#include "linear/sa_ppcg.hpp"
#ifdef WEFT_WITH_CHOLMOD
#include "linear/backends/cholmod_direct.hpp"
#endif
#ifdef WEFT_WITH_PETSC
#include "linear/backends/petsc_gamg.hpp"
#endif

namespace weft::app::benchlin {
namespace {

/// `AnySolver` for a `LinearSolver` L. A solver without `set_context` (no constraint support,
/// e.g. `linear::Direct`) gets the constrained system prefiltered by `PrefilteredSystem`
/// (Ahat = S A S + Sigma (I - S), chat = S (b - A z), x = z + S y): the same problem.
template <LinearSolver L>
class Adapter final : public AnySolver {
 public:
  explicit Adapter(const typename L::Params& prm) : solver_(prm) {}
  void set_context(const SolveContext& ctx) override {
    if constexpr (HasSolveContext<L>) solver_.set_context(ctx);
    else pre_.set_context(ctx);
  }
  Status analyze_pattern(const BlockCsr& A) override { return solver_.analyze_pattern(A); }
  void begin_step() override {
    if constexpr (HasStepHook<L>) solver_.begin_step();
  }
  Status factorize(const BlockCsr& A) override {
    if constexpr (HasSolveContext<L>) return solver_.factorize(A);
    else return solver_.factorize(pre_.matrix(A));
  }
  LinearReport solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) override {
    if constexpr (HasSolveContext<L>) {
      return solver_.solve(b, x);
    } else {
      const Eigen::VectorXd& c = pre_.rhs(b);
      LinearReport r = solver_.solve(c, x);
      pre_.finish(x);
      r.prefilter_seconds += pre_.take_seconds();
      if (pre_.active()) r.constraint_violation = pre_.context().constraints->violation(x);
      return r;
    }
  }
  bool set_reference(const Eigen::VectorXd* x_star) override {
    if constexpr (requires(L& l) { l.set_reference(x_star); }) {
      solver_.set_reference(x_star);
      return true;
    } else {
      return false;
    }
  }
  std::vector<weft::linear::SaLevelStats> hierarchy() const override {
    if constexpr (requires(const L& l) { l.preconditioner().stats().levels; })
      return solver_.preconditioner().stats().levels;
    else
      return {};
  }
  std::vector<std::pair<std::string, double>> setup_split() const override {
    if constexpr (requires(const L& l) { l.preconditioner().stats().times; }) {
      const auto& t = solver_.preconditioner().stats().times;
      return {{"strength", t.strength}, {"aggregation", t.aggregation}, {"qr", t.qr},       {"smoothing", t.smoothing},
              {"galerkin", t.galerkin}, {"lanczos", t.lanczos},         {"other", t.other}, {"total", t.total}};
    } else {
      return {};
    }
  }

 private:
  L solver_;
  linear::PrefilteredSystem pre_;  // only for solvers without set_context
};

template <class L>
std::function<std::unique_ptr<AnySolver>()> maker(typename L::Params prm) {
  return [prm] { return std::unique_ptr<AnySolver>(std::make_unique<Adapter<L>>(prm)); };
}

template <class L>
typename L::Params krylov(const SolverSettings& s) {
  typename L::Params p;
  p.tolerance = s.tolerance;
  p.max_iterations = s.max_iterations;
  return p;
}

/// The SA solvers' parameters with the --sa KEY=VALUE settings read like the scene's
/// linear.preconditioner section (unknown keys and out-of-range values throw ConfigError
/// naming them). A VALUE is read as JSON (numbers, true/false), else as a string.
template <class L>
typename L::Params sa_krylov(const SolverSettings& s) {
  Json pre = Json::object();
  for (const std::string& kv : s.sa_settings) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos || eq == 0)
      throw ConfigError("invalid --sa setting:", {fmt::format("'{}' is not KEY=VALUE (e.g. cycle_gamma=2)", kv)});
    const std::string value = kv.substr(eq + 1);
    Json v = Json::parse(value, nullptr, false);
    pre[kv.substr(0, eq)] = v.is_discarded() ? Json(value) : v;
  }
  typename L::Params p = read_params<typename L::Params>(Json{{"preconditioner", pre}}, "--sa", "invalid --sa setting:");
  p.tolerance = s.tolerance;
  p.max_iterations = s.max_iterations;
  L::Params::validate(p).throw_if_failed("invalid --sa setting:");
  return p;
}

}  // namespace

namespace {

/// SA+PPCG with `settings` (linear.preconditioner KEY=VALUE) on top of --sa.
SolverEntry sa_ppcg_entry(const SolverSettings& s, std::string key, std::string label, std::string description,
                          const std::vector<std::string>& settings) {
  SolverSettings t = s;
  t.sa_settings.insert(t.sa_settings.end(), settings.begin(), settings.end());
  return {std::move(key), std::move(label), std::move(description), false, maker<linear::SaPpcg>(sa_krylov<linear::SaPpcg>(t))};
}

}  // namespace

SolverEntry sa_ppcg_with(const SolverSettings& s, const std::string& token) {
  std::vector<std::string> parts;
  boost::algorithm::split(parts, token, [](char c) { return c == ':'; });
  if (parts.front() != "sa_ppcg")
    throw ConfigError("invalid --solvers entry:", {fmt::format("'{}': only sa_ppcg takes settings (sa_ppcg:KEY=VALUE[:KEY=VALUE...])", token)});
  const std::vector<std::string> own(parts.begin() + 1, parts.end());
  return sa_ppcg_entry(s, token, fmt::format("SA+PPCG {}", fmt::join(own, " ")), fmt::format("SA+PPCG with {}", fmt::join(own, ", ")), own);
}

std::vector<SolverEntry> available_solvers(const SolverSettings& s) {
  std::vector<SolverEntry> list;
#ifdef WEFT_WITH_CHOLMOD
  list.push_back({"cholmod", "CHOLMOD", "supernodal sparse Cholesky of the prefiltered matrix (CHOLMOD; stands in for PARDISO)", true,
                  maker<linear::CholmodDirect>({})});
#endif
  list.push_back({"direct", "Eigen LDLT", "simplicial sparse LDL^T (Eigen, AMD ordering) of the prefiltered matrix", true,
                  maker<linear::Direct>({})});
  list.push_back({"diag_pcg", "Diag-PCG", "BW98 modified PCG, 3x3 block-Jacobi preconditioner (thesis baseline)", false,
                  maker<linear::DiagPcg>(krylov<linear::DiagPcg>(s))});
  list.push_back({"diag_ppcg", "Diag+PPCG", "prefiltered PCG, 3x3 block-Jacobi preconditioner of Ahat", false,
                  maker<linear::DiagPpcg>(krylov<linear::DiagPpcg>(s))});
  using linear::SaMpcg;
  using linear::SaPpcg;
  list.push_back({"sa_ppcg", "SA+PPCG", "prefiltered PCG, smoothed aggregation preconditioner built from Ahat (preset auto, as in a scene)",
                  false, maker<SaPpcg>(sa_krylov<SaPpcg>(s))});
  // The other presets, to run beside the default in one run (any other setting: sa_ppcg:KEY=VALUE).
  list.push_back(sa_ppcg_entry(s, "sa_ppcg_thesis", "SA+PPCG thesis",
                               "SA+PPCG with the thesis' V(1,1) hierarchy rebuilt at every setup (preset thesis: Table 11.1)",
                               {"preset=thesis"}));
  list.push_back(sa_ppcg_entry(s, "sa_ppcg_large", "SA+PPCG large",
                               "SA+PPCG with the large preset: degree-2 fine prolongator truncated and repaired, W-cycle on "
                               "levels 1-2, aggregates split into sheets (iterations within 2x from 10k to 1M vertices)",
                               {"preset=large"}));
  list.push_back({"sa_mpcg", "SA+MPCG", "BW98 modified PCG, smoothed aggregation built from the unfiltered A (ablation)", false,
                  maker<SaMpcg>(sa_krylov<SaMpcg>(s))});
#ifdef WEFT_WITH_PETSC
  // The peers through PETSc, with the same CG and stopping rule, each with the best setting of
  // the sweep at 90k vertices (bench/peers_sweep.sh, bench/results/peers); PETSC_OPTIONS
  // ("-weft_...") changes them on top.
  auto peer = [&](linear::PetscAmg amg, std::string options) {
    linear::PetscGamg::Params p = krylov<linear::PetscGamg>(s);
    p.amg = amg;
    p.options = std::move(options);
    return maker<linear::PetscGamg>(p);
  };
  list.push_back({"petsc_gamg", "PETSc GAMG",
                  "PETSc CG + GAMG on the prefiltered matrix, S-filtered rigid modes; tuned: unsmoothed aggregation, threshold 0.01, "
                  "one smoothing step per level",
                  false, peer(linear::PetscAmg::gamg, "-pc_gamg_agg_nsmooths 0 -pc_gamg_threshold 0.01 -mg_levels_ksp_max_it 1")});
  list.push_back({"petsc_boomeramg", "hypre BoomerAMG",
                  "PETSc CG + hypre BoomerAMG (classical AMG) on the prefiltered matrix; tuned: PMIS coarsening, ext+i "
                  "interpolation, aggressive coarsening on the first level",
                  false,
                  peer(linear::PetscAmg::boomeramg,
                       "-pc_hypre_boomeramg_coarsen_type PMIS -pc_hypre_boomeramg_interp_type ext+i -pc_hypre_boomeramg_agg_nl 1")});
  list.push_back({"petsc_ml", "Trilinos ML",
                  "PETSc CG + Trilinos ML (smoothed aggregation) on the prefiltered matrix, S-filtered rigid modes; tuned: "
                  "threshold 0.01, one smoothing step per level, coarsest 500",
                  false, peer(linear::PetscAmg::ml, "-pc_ml_Threshold 0.01 -mg_levels_ksp_max_it 1 -pc_ml_maxCoarseSize 500")});
#endif
  return list;
}

}  // namespace weft::app::benchlin
