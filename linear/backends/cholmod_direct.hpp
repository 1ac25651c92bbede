#pragma once
/// \file cholmod_direct.hpp
/// `CholmodDirect`: supernodal sparse Cholesky LL^T by CHOLMOD (SuiteSparse), the open
/// stand-in for the thesis's PARDISO (methods/multigrid §10.6, §13 "Direct policies"). Optional:
/// compiled only with -DWEFT_WITH_CHOLMOD=ON. CHOLMOD's Supernodal module is GPL-2+, so a
/// binary linking this class is GPL-bound.
///
/// - `analyze_pattern`: the lower triangle of the scalar matrix in CSC form, the map from
///   BlockCsr values to its slots, and `cholmod_analyze` (fill-reducing ordering, supernodes).
/// - `factorize`: values copied through the map (no triplets), `cholmod_factorize`.
///   With a `SolveContext` the constrained system is prefiltered first (linear/prefilter.hpp):
///   CHOLMOD factors Ahat = S A S + Sigma (I - S), of A's pattern, so the analysis survives
///   changes of the constraint set.
/// - A matrix that is not positive definite (or numerically singular: rcond of L below
///   `Params::min_rcond`) gives `Status::numerical_issue` and a message naming the column,
///   never a garbage solution.
/// CHOLMOD's speed depends on the BLAS it is linked with at run time (Debian: the libblas.so.3
/// alternative; reference BLAS unless OpenBLAS is installed), see `blas_library()`.
#include <Eigen/Core>

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>

#include "framework/block_csr.hpp"
#include "framework/concepts.hpp"
#include "framework/constraints.hpp"
#include "framework/params.hpp"
#include "linear/prefilter.hpp"

namespace weft::linear {

class CholmodDirect {
 public:
  static constexpr std::string_view name = "cholmod";
  /// Checkpoints: the symbolic analysis is redone the same from the same pattern.
  static constexpr bool stateless = true;
  struct Params {
    bool check_residual = true;  ///< report the true relative residual of each solve (one extra product)
    double min_rcond = 2.2e-13;  ///< below this (min L_jj / max L_jj)^2 the matrix counts as singular
    template <class V>
    void visit(V& v) {
      v.field("check_residual", check_residual, {Unit::none, Range::any(), "report the true relative residual of each solve"});
      v.field("min_rcond", min_rcond, {Unit::none, Range::closed_open(0, 1),
                                       "reciprocal condition estimate (min/max pivot of LDL^T) below which the matrix is singular"});
    }
  };

  explicit CholmodDirect(const Params& prm);
  ~CholmodDirect();
  CholmodDirect(CholmodDirect&&) noexcept;
  CholmodDirect& operator=(CholmodDirect&&) noexcept;

  /// Constraints and positions of the next `factorize` (prefiltering; positions unused).
  void set_context(const SolveContext& ctx) { prefilter_.set_context(ctx); }
  Status analyze_pattern(const BlockCsr& A);
  Status factorize(const BlockCsr& A);
  /// x = A^{-1} b (or the constrained solution); x's value on entry is ignored.
  LinearReport solve(const Eigen::VectorXd& b, Eigen::VectorXd& x);

  // Statistics of the last analysis / factorisation (for benchmarks).
  double analyze_seconds() const { return analyze_seconds_; }
  double factorize_seconds() const { return factorize_seconds_; }
  double factor_nonzeros() const;      ///< nnz(L) including supernodal padding
  double factor_flops() const;         ///< flop count of the factorisation (from the analysis)
  std::size_t peak_memory_bytes() const;  ///< CHOLMOD's peak memory usage so far
  std::string ordering() const;        ///< the fill-reducing ordering the analysis chose
  /// The shared library that provides BLAS to this process (e.g. ".../blas/libblas.so.3"
  /// for reference BLAS or ".../openblas-pthread/libblas.so.3").
  static std::string blas_library();

 private:
  struct Impl;  // CHOLMOD's headers stay out of this one
  Status analyze(const BlockCsr& A);
  Params prm_;
  std::unique_ptr<Impl> impl_;
  PrefilteredSystem prefilter_;
  const BlockCsr* M_ = nullptr;  // the matrix factorised (A or Ahat)
  double analyze_seconds_ = 0, factorize_seconds_ = 0, setup_seconds_ = 0;
};

static_assert(LinearSolver<CholmodDirect>);
static_assert(HasSolveContext<CholmodDirect>);

}  // namespace weft::linear
