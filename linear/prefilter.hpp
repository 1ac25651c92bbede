#pragma once
/// \file prefilter.hpp
/// Prefiltering of methods/multigrid §7.3-7.4: the constrained problem
///   min ||S (b - A x)||  s.t.  (I - S) x = (I - S) z
/// becomes the SPD system of A's size and block pattern
///   (S A S + Sigma (I - S)) y = S (b - A z),   x = z + S y,
/// with Sigma_i = tr(A_ii)/3 per vertex (so the constrained directions' eigenvalues sit
/// inside A's spectrum whatever the units; methods/multigrid §7.3 [ours]). Any SPD solver (PCG with
/// any preconditioner, direct, PETSc) then solves the constrained problem exactly.
#include <Eigen/Core>

#include <cstddef>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/constraints.hpp"
#include "linear/bsr.hpp"

namespace weft::linear {

/// Ahat = S A S + Sigma (I - S). `Ahat` must have A's pattern (copy A once per pattern).
void prefilter_matrix(const BlockCsr& A, const ConstraintSet& c, BlockCsr& Ahat);
/// True when Ahat would equal A exactly, so no copy is needed: every constrained vertex is
/// fully fixed and A already decouples it (zero off-diagonal blocks in its row and column,
/// a diagonal block sigma I), as `BlockCsr::filter_rows(fixed, -1)` leaves it. O(constrained
/// vertices x row length).
bool already_prefiltered(const BlockCsr& A, const ConstraintSet& c);
/// chat = S (b - A z).
void prefilter_rhs(const BlockCsr& A, const ConstraintSet& c, const Eigen::VectorXd& b, Eigen::VectorXd& chat);
/// x = z + S y (the final projection makes the constraints hold to round-off); x may be y.
void unfilter_solution(const ConstraintSet& c, const Eigen::VectorXd& y, Eigen::VectorXd& x);

/// What it takes to apply Ahat = S A S + Sigma (I - S) on the fly from A, without storing
/// it: per constrained vertex its filter S_i and sigma_i = tr(A_ii)/3 (84 bytes, against
/// A's 76 bytes per block for a copy). Block (i, j) of Ahat is read as (S_i A_ij) S_j (+
/// sigma_i (I - S_i) on the diagonal), exactly the block `prefilter_matrix` stores.
class OperatorFilter {
 public:
  /// From A's diagonal and the constraints. Nothing to filter (empty) without constraints
  /// or when A is already prefiltered (`already_prefiltered`).
  void build(const BlockCsr& A, const ConstraintSet& c);
  void clear();
  bool empty() const { return slot_.empty(); }
  /// The view the kernels read (empty view when `empty()`).
  VertexFilterView view() const {
    if (empty()) return {};
    return {slot_.data(), S_.data(), sigma_.data()};
  }
  std::size_t bytes() const {
    return slot_.capacity() * sizeof(int) + (S_.capacity() + sigma_.capacity()) * sizeof(double);
  }

 private:
  std::vector<int> slot_;        // per vertex: -1 or index into S_, sigma_
  std::vector<double> S_, sigma_;
};

/// The three steps above for a solver that takes a `SolveContext`: with no (or an empty)
/// constraint set everything passes through untouched and costs nothing.
class PrefilteredSystem {
 public:
  void set_context(const SolveContext& ctx) { ctx_ = ctx; }
  const SolveContext& context() const { return ctx_; }
  bool active() const { return ctx_.constraints && !ctx_.constraints->empty(); }
  /// The matrix to factorise or precondition: A itself (no constraints, or A already
  /// prefiltered: see `already_prefiltered`), or Ahat (a copy of A's size).
  const BlockCsr& matrix(const BlockCsr& A);
  /// The right-hand side to solve with: b itself, or chat.
  const Eigen::VectorXd& rhs(const Eigen::VectorXd& b);
  /// chat written to `out`, which is returned; only when `active()`. Nothing is kept.
  const Eigen::VectorXd& rhs(const Eigen::VectorXd& b, Eigen::VectorXd& out);
  /// In place: y -> x = z + S y (nothing without constraints; no copy of y).
  void finish(Eigen::VectorXd& y) const;
  /// The matrix handed to the last `matrix` or `filter` call (the unfiltered A).
  const BlockCsr* original() const { return A_; }
  /// Instead of `matrix`: prefilters on the fly. Builds the filters that read A as Ahat
  /// (empty without constraints or when A is already prefiltered); no copy of A is made and
  /// any kept copy is released.
  const OperatorFilter& filter(const BlockCsr& A);
  /// Bytes owned: the copy Ahat (none when A was already prefiltered or is filtered on the
  /// fly), the on-the-fly filters and the prefiltered rhs.
  std::size_t bytes() const {
    return sizeof(double) * (Ahat_.values().capacity() + static_cast<std::size_t>(chat_.size())) +
           sizeof(int) * (Ahat_.col().capacity() + Ahat_.row_ptr().capacity()) + filter_.bytes();
  }
  /// Seconds spent prefiltering since the last call (and reset).
  double take_seconds();

 private:
  SolveContext ctx_;
  const BlockCsr* A_ = nullptr;
  BlockCsr Ahat_;
  OperatorFilter filter_;
  Eigen::VectorXd chat_;
  double seconds_ = 0;
};

}  // namespace weft::linear
