#include "linear/backends/petsc_gamg.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <petscksp.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "framework/error.hpp"
#include "framework/timers.hpp"

namespace weft::linear {

namespace {

/// PETSc (and MPI) for the whole process: initialised on first use unless someone else
/// already did, finalised at exit if we initialised it. Options come from PETSC_OPTIONS.
class PetscRuntime {
 public:
  static bool ensure() {
    static PetscRuntime runtime;
    return runtime.ok_;
  }
  ~PetscRuntime() {
    PetscBool finalized = PETSC_FALSE;
    PetscFinalized(&finalized);
    if (owner_ && !finalized) PetscFinalize();
  }

 private:
  PetscRuntime() {
    PetscBool initialized = PETSC_FALSE;
    PetscInitialized(&initialized);
    if (!initialized) {
      owner_ = PetscInitializeNoArguments() == 0;
      ok_ = owner_;
    } else {
      ok_ = true;
    }
  }
  bool owner_ = false, ok_ = false;
};

bool petsc_alive() {
  PetscBool finalized = PETSC_FALSE;
  PetscFinalized(&finalized);
  return !finalized;
}

/// "-a 1 -b" -> {"-weft_a", "1", "-weft_b"}: a solver's options under the prefix of its KSP,
/// split at whitespace (a negative number is a value, an option already prefixed stays).
std::vector<std::string> prefixed_options(const std::string& options) {
  std::vector<std::string> tokens;
  std::size_t i = 0;
  while ((i = options.find_first_not_of(" \t\n\r", i)) != std::string::npos) {
    const std::size_t end = std::min(options.find_first_of(" \t\n\r", i), options.size());
    const std::string token = options.substr(i, end - i);
    const bool name = token.size() > 1 && token[0] == '-' && !std::isdigit(static_cast<unsigned char>(token[1])) && token[1] != '.';
    tokens.push_back(name && token.rfind("-weft_", 0) != 0 ? "-weft_" + token.substr(1) : token);
    i = end;
  }
  return tokens;
}

/// Collects the first PETSc error of a sequence of calls.
struct Check {
  PetscErrorCode code = 0;  // 0: no error (PETSc 3.18 has no PETSC_SUCCESS)
  const char* where = "";
  bool operator()(PetscErrorCode c, const char* call) {
    if (code == 0 && c != 0) code = c, where = call;
    return code == 0;
  }
  explicit operator bool() const { return code == 0; }
};
#define WEFT_PETSC(check, call) check(call, #call)

}  // namespace

struct PetscGamg::Impl {
  MPI_Comm comm = MPI_COMM_NULL;
  int rank = 0, size = 1;
  int first = 0, last = 0;  // owned block rows [first, last)
  Mat A = nullptr;
  Vec x = nullptr, b = nullptr, x_all = nullptr;
  VecScatter to_all = nullptr;
  KSP ksp = nullptr;
  bool analyzed = false, factorized = false;
  std::string error;

  void release() {
    if (!petsc_alive()) return;  // PETSc is gone (static destruction order): leak rather than crash
    if (ksp) KSPDestroy(&ksp);
    if (to_all) VecScatterDestroy(&to_all);
    if (x_all) VecDestroy(&x_all);
    if (x) VecDestroy(&x);
    if (b) VecDestroy(&b);
    if (A) MatDestroy(&A);
    analyzed = factorized = false;
  }
  ~Impl() { release(); }
};

PetscGamg::PetscGamg(const Params& prm) : prm_(prm), impl_(std::make_unique<Impl>()) {
  if (!PetscRuntime::ensure()) throw ConfigError("PetscGamg: PetscInitialize failed");
  impl_->comm = prm_.single_process ? PETSC_COMM_SELF : PETSC_COMM_WORLD;
  MPI_Comm_rank(impl_->comm, &impl_->rank);
  MPI_Comm_size(impl_->comm, &impl_->size);
}
PetscGamg::~PetscGamg() = default;
PetscGamg::PetscGamg(PetscGamg&&) noexcept = default;
PetscGamg& PetscGamg::operator=(PetscGamg&&) noexcept = default;

int PetscGamg::rank() const { return impl_->rank; }
int PetscGamg::ranks() const { return impl_->size; }

Status PetscGamg::analyze_pattern(const BlockCsr& A) {
  Impl& s = *impl_;
  s.release();
  double t = 0;
  Check ok;
  {
    ScopedTimer timer(t);
    const int nb = A.block_rows();
    s.first = static_cast<int>(static_cast<long long>(nb) * s.rank / s.size);
    s.last = static_cast<int>(static_cast<long long>(nb) * (s.rank + 1) / s.size);
    const int nloc = s.last - s.first;
    // Exact preallocation: blocks per owned row inside / outside the diagonal part.
    std::vector<PetscInt> d_nnz(nloc, 0), o_nnz(nloc, 0);
    for (int i = s.first; i < s.last; ++i)
      for (int k = A.row_ptr()[i]; k < A.row_ptr()[i + 1]; ++k) {
        const int j = A.col()[k];
        (j >= s.first && j < s.last ? d_nnz : o_nnz)[i - s.first]++;
      }
    WEFT_PETSC(ok, MatCreate(s.comm, &s.A));
    WEFT_PETSC(ok, MatSetSizes(s.A, 3 * nloc, 3 * nloc, 3 * nb, 3 * nb));
    // AIJ with block size 3 (SeqAIJ / MPIAIJ with inodes of 3 rows): PETSc 3.18's GAMG has
    // no graph construction for BAIJ ("No method creategraph for Mat of type seqbaij").
    // Blocks are still preallocated and inserted as 3x3 blocks.
    WEFT_PETSC(ok, MatSetType(s.A, MATAIJ));
    WEFT_PETSC(ok, MatSetBlockSize(s.A, 3));
    WEFT_PETSC(ok, MatXAIJSetPreallocation(s.A, 3, d_nnz.data(), o_nnz.data(), nullptr, nullptr));
    WEFT_PETSC(ok, MatSetOption(s.A, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_TRUE));
    WEFT_PETSC(ok, MatSetOption(s.A, MAT_SYMMETRIC, PETSC_TRUE));
    WEFT_PETSC(ok, MatSetOption(s.A, MAT_SYMMETRY_ETERNAL, PETSC_TRUE));
    WEFT_PETSC(ok, MatSetOption(s.A, MAT_SPD, PETSC_TRUE));  // lets GAMG estimate eigenvalues with CG
    WEFT_PETSC(ok, MatSetOption(s.A, MAT_SPD_ETERNAL, PETSC_TRUE));
    WEFT_PETSC(ok, MatCreateVecs(s.A, &s.x, &s.b));
    WEFT_PETSC(ok, VecScatterCreateToAll(s.x, &s.to_all, &s.x_all));

    WEFT_PETSC(ok, KSPCreate(s.comm, &s.ksp));
    WEFT_PETSC(ok, KSPSetOptionsPrefix(s.ksp, "weft_"));
    WEFT_PETSC(ok, KSPSetType(s.ksp, KSPCG));
    WEFT_PETSC(ok, KSPSetNormType(s.ksp, KSP_NORM_NATURAL));
    WEFT_PETSC(ok, KSPSetTolerances(s.ksp, prm_.tolerance, 0.0, PETSC_DEFAULT, prm_.max_iterations));
    WEFT_PETSC(ok, KSPSetInitialGuessNonzero(s.ksp, PETSC_FALSE));
    WEFT_PETSC(ok, KSPSetResidualHistory(s.ksp, nullptr, PETSC_DECIDE, PETSC_TRUE));
    PC pc = nullptr;
    WEFT_PETSC(ok, KSPGetPC(s.ksp, &pc));
    switch (prm_.amg) {
      case PetscAmg::gamg:
        WEFT_PETSC(ok, PCSetType(pc, PCGAMG));
        WEFT_PETSC(ok, PCGAMGSetType(pc, PCGAMGAGG));  // smoothed aggregation
        WEFT_PETSC(ok, PCGAMGSetNSmooths(pc, prm_.gamg_smooths));
        WEFT_PETSC(ok, PCGAMGSetAggressiveLevels(pc, prm_.aggressive_levels));
        WEFT_PETSC(ok, PCGAMGSetCoarseEqLim(pc, prm_.coarse_equations));
        WEFT_PETSC(ok, PCGAMGSetReuseInterpolation(pc, prm_.reuse_interpolation ? PETSC_TRUE : PETSC_FALSE));
        break;
      case PetscAmg::boomeramg:
        WEFT_PETSC(ok, PCSetType(pc, PCHYPRE));
        WEFT_PETSC(ok, PCHYPRESetType(pc, "boomeramg"));
        break;
      case PetscAmg::ml:
        WEFT_PETSC(ok, PCSetType(pc, PCML));
        break;
    }
  }
  setup_seconds_ = t;
  s.analyzed = static_cast<bool>(ok);
  if (!ok) s.error = fmt::format("PETSc error {} in {}", static_cast<int>(ok.code), ok.where);
  return s.analyzed ? Status::success : Status::numerical_issue;
}

/// theta * mean over rows of max_j s_ij, with PETSc's collapsed, scaled block strengths.
static double mapped_threshold(const BlockCsr& M, double theta) {
  const int nb = M.block_rows();
  std::vector<double> g(M.num_blocks());
  for (int k = 0; k < M.num_blocks(); ++k) g[k] = M.block(k).cwiseAbs().sum();
  double sum = 0;
  int rows = 0;
  for (int i = 0; i < nb; ++i) {
    double best = 0;
    const double gii = g[M.diagonal(i)];
    for (int k = M.row_ptr()[i]; k < M.row_ptr()[i + 1]; ++k) {
      const int j = M.col()[k];
      if (j == i) continue;
      const double gjj = g[M.diagonal(j)];
      if (gii > 0 && gjj > 0) best = std::max(best, g[k] / std::sqrt(gii * gjj));
    }
    if (best > 0) sum += best, ++rows;
  }
  return rows ? theta * sum / rows : 0.0;
}

Status PetscGamg::factorize(const BlockCsr& A) {
  Impl& s = *impl_;
  if (!s.analyzed) return Status::invalid_input;
  s.factorized = false;
  Check ok;
  const BlockCsr& M = prefilter_.matrix(A);
  M_ = &M;
  const int nb = M.block_rows();
  {
    PetscInt N = 0;
    MatGetSize(s.A, &N, nullptr);
    if (N != 3 * nb) return Status::invalid_input;
  }
  assembly_seconds_ = 0;
  {
    ScopedTimer timer(assembly_seconds_);
    // Values of the owned block rows (the pattern is kept: zero, then insert).
    WEFT_PETSC(ok, MatZeroEntries(s.A));
    for (int i = s.first; i < s.last && ok; ++i) {
      const PetscInt row = i;
      for (int k = M.row_ptr()[i]; k < M.row_ptr()[i + 1]; ++k) {
        const PetscInt c = M.col()[k];
        if (!WEFT_PETSC(ok, MatSetValuesBlocked(s.A, 1, &row, 1, &c, M.values().data() + 9 * k, INSERT_VALUES))) break;
      }
    }
    WEFT_PETSC(ok, MatAssemblyBegin(s.A, MAT_FINAL_ASSEMBLY));
    WEFT_PETSC(ok, MatAssemblyEnd(s.A, MAT_FINAL_ASSEMBLY));

    // Near-null space: rigid-body modes at the centred positions, K <- S K, orthonormalised.
    const SolveContext& ctx = prefilter_.context();
    const Eigen::VectorXd* pos = ctx.positions;
    const bool rotations = pos && pos->size() == 3 * nb;
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    if (rotations) {
      for (int i = 0; i < nb; ++i) centre += pos->segment<3>(3 * i);
      centre /= std::max(nb, 1);
    }
    const int nmodes = rotations ? 6 : 3;
    std::array<Vec, 6> modes{};
    for (int m = 0; m < nmodes && ok; ++m) {
      WEFT_PETSC(ok, VecDuplicate(s.x, &modes[m]));
      PetscScalar* v = nullptr;
      if (!WEFT_PETSC(ok, VecGetArray(modes[m], &v))) break;
      for (int i = s.first; i < s.last; ++i) {
        Eigen::Vector3d k = Eigen::Vector3d::Zero();
        if (m < 3) {
          k[m] = 1;
        } else {
          const Eigen::Vector3d p = pos->segment<3>(3 * i) - centre;
          const Eigen::Vector3d axis = Eigen::Vector3d::Unit(m - 3);
          k = axis.cross(p);  // r_x = (0, -z, y), r_y = (z, 0, -x), r_z = (-y, x, 0)
        }
        if (prefilter_.active() && ctx.constraints->count(i) > 0) k = ctx.constraints->filter(i) * k;
        for (int a = 0; a < 3; ++a) v[3 * (i - s.first) + a] = k[a];
      }
      WEFT_PETSC(ok, VecRestoreArray(modes[m], &v));
    }
    // Modified Gram-Schmidt, twice; a mode that vanishes (all of its vertices constrained)
    // is dropped.
    int kept = 0;
    for (int m = 0; m < nmodes && ok; ++m) {
      PetscReal norm0 = 0, norm = 0;
      WEFT_PETSC(ok, VecNorm(modes[m], NORM_2, &norm0));
      for (int pass = 0; pass < 2 && ok; ++pass)
        for (int q = 0; q < kept; ++q) {
          PetscScalar d = 0;
          WEFT_PETSC(ok, VecDot(modes[m], modes[q], &d));
          WEFT_PETSC(ok, VecAXPY(modes[m], -d, modes[q]));
        }
      WEFT_PETSC(ok, VecNorm(modes[m], NORM_2, &norm));
      if (!(norm > 1e-10 * norm0) || norm0 == 0) {
        VecDestroy(&modes[m]);
        continue;
      }
      WEFT_PETSC(ok, VecScale(modes[m], 1.0 / norm));
      std::swap(modes[kept++], modes[m]);
    }
    MatNullSpace nsp = nullptr;
    if (ok && kept > 0) {
      WEFT_PETSC(ok, MatNullSpaceCreate(s.comm, PETSC_FALSE, kept, modes.data(), &nsp));
      WEFT_PETSC(ok, MatSetNearNullSpace(s.A, nsp));
      if (nsp) MatNullSpaceDestroy(&nsp);
    }
    for (Vec& v : modes)
      if (v) VecDestroy(&v);
  }
  threshold_used_ = prm_.threshold >= 0 ? prm_.threshold : mapped_threshold(M, prm_.theta);
  pc_setup_seconds_ = 0;
  {
    ScopedTimer timer(pc_setup_seconds_);
    PC pc = nullptr;
    // Derived from theta: the fine level only, then 0 (keep every connection), as an
    // absolute threshold does not carry over to the coarse operators (see the header).
    // Set after KSPSetFromOptions, which rewrites every level from the first one, unless
    // PETSC_OPTIONS gives -weft_pc_gamg_threshold.
    PetscReal th[2] = {threshold_used_, 0.0};
    PetscBool given = PETSC_FALSE;
    WEFT_PETSC(ok, KSPGetPC(s.ksp, &pc));
    WEFT_PETSC(ok, KSPSetOperators(s.ksp, s.A, s.A));
    // This solver's own options, then PETSC_OPTIONS="-weft_..." on top (read by KSPSetFromOptions).
    if (prm_.amg == PetscAmg::ml) WEFT_PETSC(ok, PetscOptionsSetValue(nullptr, "-weft_pc_ml_nullspace", "user"));
    const std::vector<std::string> own = prefixed_options(prm_.options);
    WEFT_PETSC(ok, PetscOptionsInsertString(nullptr, fmt::format("{}", fmt::join(own, " ")).c_str()));
    if (const char* env = std::getenv("PETSC_OPTIONS")) WEFT_PETSC(ok, PetscOptionsInsertString(nullptr, env));
    WEFT_PETSC(ok, KSPSetFromOptions(s.ksp));
    if (prm_.amg == PetscAmg::gamg) {
      WEFT_PETSC(ok, PetscOptionsHasName(nullptr, "weft_", "-pc_gamg_threshold", &given));
      if (!given) WEFT_PETSC(ok, PCGAMGSetThreshold(pc, th, prm_.threshold >= 0 ? 1 : 2));
    }
    WEFT_PETSC(ok, KSPSetUp(s.ksp));  // PCSetUp: the hierarchy; the levels' smoothers read their options here
    // Taken out again once the levels have read them: the next solver in this process reads only its own.
    for (const std::string& token : own)
      if (token.rfind("-weft_", 0) == 0) WEFT_PETSC(ok, PetscOptionsClearValue(nullptr, token.c_str()));
    if (prm_.amg == PetscAmg::ml) WEFT_PETSC(ok, PetscOptionsClearValue(nullptr, "-weft_pc_ml_nullspace"));
    if (const char* env = std::getenv("PETSC_OPTIONS")) WEFT_PETSC(ok, PetscOptionsInsertString(nullptr, env));
  }
  setup_seconds_ += assembly_seconds_ + pc_setup_seconds_ + prefilter_.take_seconds();
  s.factorized = static_cast<bool>(ok);
  if (!ok) s.error = fmt::format("PETSc error {} in {}", static_cast<int>(ok.code), ok.where);
  return s.factorized ? Status::success : Status::numerical_issue;
}

LinearReport PetscGamg::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  Impl& s = *impl_;
  LinearReport r;
  r.solves = 1;
  r.setup_seconds = setup_seconds_;
  setup_seconds_ = 0;
  if (!s.factorized) {
    r.status = Status::numerical_issue;
    r.message = s.error.empty() ? "PetscGamg: solve before a successful factorize" : s.error;
    return r;
  }
  if (!M_ || b.size() != M_->rows()) {
    r.status = Status::invalid_input;
    r.message = fmt::format("PetscGamg: right-hand side of size {} for a matrix of {} rows", b.size(), M_ ? M_->rows() : 0);
    return r;
  }
  const Eigen::VectorXd& rhs = prefilter_.rhs(b);
  Check ok;
  KSPConvergedReason reason = KSP_CONVERGED_ITERATING;
  PetscInt its = 0;
  {
    ScopedTimer timer(r.solve_seconds);
    PetscScalar* v = nullptr;
    WEFT_PETSC(ok, VecGetArray(s.b, &v));
    if (ok) std::copy(rhs.data() + 3 * s.first, rhs.data() + 3 * s.last, v);
    WEFT_PETSC(ok, VecRestoreArray(s.b, &v));
    WEFT_PETSC(ok, KSPSolve(s.ksp, s.b, s.x));
    WEFT_PETSC(ok, KSPGetConvergedReason(s.ksp, &reason));
    WEFT_PETSC(ok, KSPGetIterationNumber(s.ksp, &its));
    // Gather the solution to every rank.
    WEFT_PETSC(ok, VecScatterBegin(s.to_all, s.x, s.x_all, INSERT_VALUES, SCATTER_FORWARD));
    WEFT_PETSC(ok, VecScatterEnd(s.to_all, s.x, s.x_all, INSERT_VALUES, SCATTER_FORWARD));
    const PetscScalar* xa = nullptr;
    WEFT_PETSC(ok, VecGetArrayRead(s.x_all, &xa));
    if (ok) x = Eigen::Map<const Eigen::VectorXd>(xa, rhs.size());
    WEFT_PETSC(ok, VecRestoreArrayRead(s.x_all, &xa));
  }
  if (!ok) {
    r.status = Status::numerical_issue;
    r.message = fmt::format("PETSc error {} in {}", static_cast<int>(ok.code), ok.where);
    return r;
  }
  r.iterations = static_cast<int>(its);
  const PetscReal* hist = nullptr;
  PetscInt nh = 0;
  KSPGetResidualHistory(s.ksp, &hist, &nh);
  if (nh > 0 && hist[0] > 0)
    for (PetscInt i = 0; i < nh; ++i) r.residual_history.push_back(hist[i] / hist[0]);
  if (r.iterations > 0 && !r.residual_history.empty() && r.residual_history.back() > 0)
    r.convergence_rate = std::pow(r.residual_history.back(), 1.0 / r.iterations);
  PC pc = nullptr;
  KSPGetPC(s.ksp, &pc);
  if (prm_.amg != PetscAmg::boomeramg) {  // GAMG and ML are PCMG; hypre keeps its hierarchy to itself
    PetscInt levels = 0;
    PCMGGetLevels(pc, &levels);
    r.levels = static_cast<int>(levels);
    PetscReal grid_complexity = 0, op_complexity = 0;
    if (PCMGGetGridComplexity(pc, &grid_complexity, &op_complexity) == 0) r.operator_complexity = op_complexity;
  }
  if (reason > 0) {
    r.status = Status::success;
  } else if (reason == KSP_DIVERGED_ITS) {
    r.status = Status::no_convergence;
    r.message = fmt::format("PETSc CG: no convergence in {} iterations", r.iterations);
  } else {
    r.status = Status::numerical_issue;
    r.indefinite = reason == KSP_DIVERGED_INDEFINITE_MAT || reason == KSP_DIVERGED_INDEFINITE_PC;
    r.message = fmt::format("PETSc CG diverged: {}", KSPConvergedReasons[reason]);
  }
  if (!x.allFinite()) {
    r.status = Status::numerical_issue;
    r.message = "PETSc CG produced non-finite values";
    return r;
  }
  if (prm_.check_residual) {  // of the system solved (Ahat y = chat), replicated on every rank
    Eigen::VectorXd Mx;
    M_->multiply(x, Mx);
    const double nr = rhs.norm();
    r.relative_residual = nr > 0 ? (rhs - Mx).norm() / nr : (rhs - Mx).norm();
  }
  prefilter_.finish(x);
  r.prefilter_seconds = prefilter_.take_seconds();
  if (prefilter_.active()) r.constraint_violation = prefilter_.context().constraints->violation(x);
  return r;
}

}  // namespace weft::linear
