#include "linear/block_jacobi.hpp"

#include <Eigen/Cholesky>

#include <fmt/format.h>

namespace weft::linear {

Status BlockJacobi::analyze_pattern(const BlockCsr& A) {
  inv_.assign(9 * static_cast<std::size_t>(A.block_rows()), 0.0);
  message_.clear();
  return Status::success;
}

Status BlockJacobi::setup(const BlockCsr& A, const SolveContext& ctx) { return setup(A, ctx, VertexFilterView{}); }

Status BlockJacobi::setup(const BlockCsr& A, const SolveContext& /*ctx*/, const VertexFilterView& F) {
  const int n = A.block_rows();
  if (inv_.size() != 9 * static_cast<std::size_t>(n)) inv_.assign(9 * static_cast<std::size_t>(n), 0.0);
  message_.clear();
  int bad = n;  // smallest failing row (deterministic whatever the thread count)
#pragma omp parallel for schedule(static) reduction(min : bad) if (n >= 4096)
  for (int i = 0; i < n; ++i) {
    const Eigen::Matrix3d D = F.apply(i, i, A.block(A.diagonal(i)));
    Eigen::Map<Block3> out(inv_.data() + 9 * static_cast<std::size_t>(i));
    // Eigen's LLT only rejects non-positive pivots; also reject non-finite input.
    const Eigen::LLT<Eigen::Matrix3d> llt(D);
    if (!D.allFinite() || llt.info() != Eigen::Success) {
      out.setZero();
      bad = std::min(bad, i);
      continue;
    }
    const Eigen::Matrix3d X = llt.solve(Eigen::Matrix3d::Identity());
    out = 0.5 * (X + X.transpose());  // exactly symmetric: B = B^T
  }
  if (bad < n) {
    message_ = fmt::format(
        "block-Jacobi: the diagonal block of block row {} (vertex {}) is not positive definite or not finite, so the "
        "matrix is not positive definite; project the element Hessians or shift the matrix",
        bad, bad);
    return Status::numerical_issue;
  }
  return Status::success;
}

void BlockJacobi::apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  const int n = static_cast<int>(r.size() / 3);
  z.resize(r.size());
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (int i = 0; i < n; ++i)
    z.segment<3>(3 * i).noalias() = Eigen::Map<const Block3>(inv_.data() + 9 * static_cast<std::size_t>(i)) * r.segment<3>(3 * i);
}

PreconditionerInfo BlockJacobi::info() const {
  PreconditionerInfo p;
  p.memory_bytes = inv_.capacity() * sizeof(double);
  p.levels = 0;
  p.operator_complexity = 0;
  p.grid_complexity = 0;
  return p;
}

}  // namespace weft::linear
