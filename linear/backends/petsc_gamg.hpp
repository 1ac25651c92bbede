#pragma once
/// \file petsc_gamg.hpp
/// `PetscGamg`: PETSc's CG preconditioned by PCGAMG smoothed aggregation, the distributed
/// baseline of methods/multigrid §13 ("Distributed back end (PETSc)") and §14, or (`amg`) by
/// hypre's BoomerAMG or Trilinos' ML through PETSc, the peers `weft bench linear` compares.
/// Optional: compiled only with -DWEFT_WITH_PETSC=ON.
///
/// - The system is prefiltered first (linear/prefilter.hpp), so GAMG sees the same SPD
///   Ahat = S A S + Sigma (I - S) as PPCG, stored as an MPI matrix with block size 3. It is
///   AIJ with block size 3 (3x3 blocks preallocated and inserted with MatSetValuesBlocked),
///   not BAIJ: PETSc 3.18's GAMG cannot build its graph from a BAIJ matrix.
/// - Near-null space: the 6 rigid-body modes at `SolveContext::positions` (centred), filtered
///   (K <- S K) and orthonormalised (modified Gram-Schmidt, twice), attached explicitly with
///   MatNullSpaceCreate + MatSetNearNullSpace. Without positions: the 3 translations only.
/// - CG with the natural norm ||r||_{M^-1} (KSP_NORM_NATURAL, the thesis criterion, methods/multigrid
///   §8), relative tolerance 1e-5 and zero initial guess (x's value on entry is ignored).
///   Smoothers are PETSc's defaults (Chebyshev / Jacobi).
/// - Strength threshold: the thesis keeps a connection when mu_ij > theta * max_k mu_ik
///   (row-relative, theta = 0.48). PETSc 3.18 collapses each 3x3 block to a scalar
///   g_ij = sum |a_ij| (block entries), scales it symmetrically, s_ij = g_ij / sqrt(g_ii g_jj),
///   and drops s_ij < threshold (absolute). With `threshold < 0` the class maps theta onto
///   PETSc's threshold as theta * mean_i(max_j s_ij), computed on Ahat; the two rules agree
///   exactly when every row has the same strongest connection (uniform meshes). This mapped
///   value applies to the fine level only; coarse levels use 0 (keep every nonzero, PETSc's
///   default): an absolute threshold does not carry over to the Galerkin operators, and
///   applying it on every level gave operator complexity 4.6 and 8 levels (setup 20x slower)
///   on a 10k-vertex cloth. `threshold >= 0` sets PETSc's threshold on every level instead.
///
/// Multi-rank: every rank holds the same (replicated) BlockCsr, right-hand side and context,
/// and calls every member collectively. Rank r owns a contiguous range of block rows and
/// inserts only those into the MPI matrix; the solution is gathered to every rank.
/// PETSc (and MPI, if nobody has) is initialised on first use and finalised at exit, so the
/// class also works in a plain single-process run without mpirun. PETSC_OPTIONS with the
/// prefix "weft_" (e.g. "-weft_ksp_view") reaches the solver for ablations; `options` sets
/// PETSc options of this solver (written without the prefix) before each setup.
///
/// The peers: BoomerAMG (PCHYPRE) is classical AMG on the scalar matrix, or nodal with
/// `-pc_hypre_boomeramg_nodal_coarsen`; it takes the rigid modes as interpolation vectors
/// with `-pc_hypre_boomeramg_vec_interp_variant`. ML (PCML) is smoothed aggregation with the
/// rigid modes as its near null space (`-pc_ml_nullspace user`, set here).
#include <Eigen/Core>

#include <array>
#include <memory>
#include <string>
#include <string_view>

#include "framework/block_csr.hpp"
#include "framework/concepts.hpp"
#include "framework/constraints.hpp"
#include "framework/params.hpp"
#include "linear/prefilter.hpp"

namespace weft::linear {

/// The AMG preconditioner of PETSc's CG.
enum class PetscAmg { gamg, boomeramg, ml };
inline constexpr std::array<std::string_view, 3> petsc_amg_names = {"gamg", "boomeramg", "ml"};

class PetscGamg {
 public:
  static constexpr std::string_view name = "petsc_gamg";
  /// Checkpoints: the matrix structure is rebuilt the same; kept prolongators are not (resume_caveat).
  static constexpr bool stateless = true;
  struct Params {
    double tolerance = 1e-5;      ///< ||r_i||_{M^-1} / ||r_0||_{M^-1} (methods/multigrid §8)
    int max_iterations = 1000;
    double theta = 0.48;          ///< thesis strength threshold, mapped onto PETSc's (see the file comment)
    double threshold = 0;         ///< PETSc's -pc_gamg_threshold on every level (0: PETSc's default, the
                                  ///< fastest on cloth: 2.8 s vs 7.0 s set-up + solve at 90k vertices);
                                  ///< < 0: mapped from theta on the fine level
    int aggressive_levels = 0;    ///< PETSc's square-graph coarsening levels (its default 1; SA: 0)
    int coarse_equations = 50;    ///< stop coarsening below this many equations
    bool reuse_interpolation = false;  ///< keep GAMG's prolongators across factorize calls (thesis: rebuild)
    bool single_process = false;  ///< solve on this process alone (PETSC_COMM_SELF), even under mpirun
    bool check_residual = true;   ///< report the true relative residual (one product with Ahat)
    PetscAmg amg = PetscAmg::gamg;  ///< the preconditioner (theta, threshold, aggressive_levels, coarse_equations: GAMG's)
    int gamg_smooths = 1;         ///< GAMG's prolongator smoothing steps (-pc_gamg_agg_nsmooths)
    std::string options;          ///< PETSc options of this solver, e.g. "-pc_hypre_boomeramg_strong_threshold 0.5"
    template <class V>
    void visit(V& v) {
      v.choice("amg", amg, petsc_amg_names, "the preconditioner: PETSc GAMG, hypre BoomerAMG or Trilinos ML");
      v.field("tolerance", tolerance, {Unit::none, Range::open(0, 1), "relative tolerance in the preconditioner's norm"});
      v.field("max_iterations", max_iterations, {Unit::none, Range::ge(1), "CG iteration limit"});
      v.field("theta", theta, {Unit::none, Range::closed_open(0, 1), "thesis strength threshold (row-relative)"});
      v.field("threshold", threshold, {Unit::none, Range::any(), "PETSc GAMG drop threshold; < 0: derived from theta"});
      v.field("aggressive_levels", aggressive_levels, {Unit::none, Range::ge(0), "levels coarsened with the squared graph"});
      v.field("coarse_equations", coarse_equations, {Unit::none, Range::ge(1), "coarsest level size limit"});
      v.field("reuse_interpolation", reuse_interpolation, {Unit::none, Range::any(), "reuse GAMG prolongators across factorize"});
      v.field("single_process", single_process, {Unit::none, Range::any(), "solve on PETSC_COMM_SELF"});
      v.field("check_residual", check_residual, {Unit::none, Range::any(), "report the true relative residual of each solve"});
      v.field("gamg_smooths", gamg_smooths, {Unit::none, Range::closed(0, 4), "GAMG prolongator smoothing steps"});
      v.field("options", options, {Unit::none, Range::any(), "PETSc options of this solver (without the weft_ prefix), set before each setup"});
    }
  };

  explicit PetscGamg(const Params& prm);
  ~PetscGamg();
  PetscGamg(PetscGamg&&) noexcept;
  PetscGamg& operator=(PetscGamg&&) noexcept;

  void set_context(const SolveContext& ctx) { prefilter_.set_context(ctx); }
  Status analyze_pattern(const BlockCsr& A);
  Status factorize(const BlockCsr& A);
  LinearReport solve(const Eigen::VectorXd& b, Eigen::VectorXd& x);

  int rank() const;       ///< this process's rank in the solver's communicator
  int ranks() const;      ///< the communicator's size
  double pc_setup_seconds() const { return pc_setup_seconds_; }  ///< last PCSetUp
  double assembly_seconds() const { return assembly_seconds_; }  ///< last matrix and near-null-space fill
  double threshold_used() const { return threshold_used_; }      ///< PETSc threshold of the last setup
  std::string resume_caveat() const {
    return prm_.reuse_interpolation ? "linear.reuse_interpolation: GAMG's prolongators are rebuilt at the first solve after a restore" : "";
  }

 private:
  struct Impl;  // PETSc's headers stay out of this one
  Params prm_;
  std::unique_ptr<Impl> impl_;
  PrefilteredSystem prefilter_;
  const BlockCsr* M_ = nullptr;
  double setup_seconds_ = 0, pc_setup_seconds_ = 0, assembly_seconds_ = 0, threshold_used_ = 0;
};

static_assert(LinearSolver<PetscGamg>);
static_assert(HasSolveContext<PetscGamg>);

}  // namespace weft::linear
