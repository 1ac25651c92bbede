#include "linear/direct.hpp"

#include <algorithm>
#include <limits>

#include "framework/timers.hpp"

namespace weft::linear {

Status Direct::analyze_pattern(const BlockCsr& A) {
  double t = 0;
  {
    ScopedTimer timer(t);
    lower_ = A.to_sparse(/*lower_only=*/true);
    lower_.makeCompressed();
    // Map every lower-triangle scalar of the BlockCsr to its slot in the CSC matrix.
    map_.clear();
    const auto* outer = lower_.outerIndexPtr();
    const auto* inner = lower_.innerIndexPtr();
    for (int i = 0; i < A.block_rows(); ++i)
      for (int k = A.row_ptr()[i]; k < A.row_ptr()[i + 1]; ++k)
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) {
            const int r = 3 * i + a, c = 3 * A.col()[k] + b;
            if (r < c) continue;
            const int* first = inner + outer[c];
            const int* last = inner + outer[c + 1];
            const int* it = std::lower_bound(first, last, r);
            if (it == last || *it != r) return Status::invalid_input;
            map_.emplace_back(9 * k + 3 * a + b, static_cast<int>(it - inner));
          }
    ldlt_.analyzePattern(lower_);
  }
  setup_seconds_ = t;
  analyzed_ = ldlt_.info() == Eigen::Success;
  return analyzed_ ? Status::success : Status::numerical_issue;
}

Status Direct::factorize(const BlockCsr& A) {
  if (!analyzed_) return Status::invalid_input;
  double t = 0;
  {
    ScopedTimer timer(t);
    double* dst = lower_.valuePtr();
    const double* src = A.values().data();
    for (const auto& [s, d] : map_) dst[d] = src[s];
    ldlt_.factorize(lower_);
  }
  setup_seconds_ += t;
  A_ = &A;
  factorized_ = ldlt_.info() == Eigen::Success;
  if (factorized_) {
    const auto& D = ldlt_.vectorD();
    negative_pivots_ = static_cast<int>((D.array() < 0).count());
    // A pivot at round-off level relative to the largest means a numerically singular
    // matrix (e.g. an unpinned body without mass): refuse rather than return garbage.
    const double tiny = 1e3 * std::numeric_limits<double>::epsilon() * D.cwiseAbs().maxCoeff();
    if (!D.allFinite() || (D.array().abs() <= tiny).any()) factorized_ = false;
  }
  return factorized_ ? Status::success : Status::numerical_issue;
}

LinearReport Direct::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  LinearReport r;
  r.solves = 1;
  r.setup_seconds = setup_seconds_;
  setup_seconds_ = 0;
  r.negative_pivots = negative_pivots_;
  r.indefinite = negative_pivots_ > 0;
  if (!factorized_) {
    r.status = Status::numerical_issue;
    r.message = "LDL^T factorisation failed: the matrix is numerically singular or not finite";
    return r;
  }
  {
    ScopedTimer timer(r.solve_seconds);
    x = ldlt_.solve(b);
  }
  if (!x.allFinite()) {
    r.status = Status::numerical_issue;
    r.message = "LDL^T solve produced non-finite values";
    return r;
  }
  if (prm_.check_residual && A_) {
    Eigen::VectorXd Ax;
    A_->multiply(x, Ax);
    const double nb = b.norm();
    r.relative_residual = nb > 0 ? (b - Ax).norm() / nb : (b - Ax).norm();
  }
  return r;
}

}  // namespace weft::linear
