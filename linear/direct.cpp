#include "linear/direct.hpp"

#include <fmt/format.h>

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
  A_ = nullptr;
  factorized_ = false;
  if (!analyzed_) {
    failure_ = "call analyze_pattern() before factorize()";
    return Status::invalid_input;
  }
  if (pre_.active() && pre_.context().constraints->num_vertices() != A.block_rows()) {
    failure_ = fmt::format("the constraint set has {} vertices but the matrix {} block rows",
                           pre_.context().constraints->num_vertices(), A.block_rows());
    return Status::invalid_input;
  }
  failure_ = "LDL^T factorisation failed: the matrix is numerically singular or not finite";
  const BlockCsr& M = pre_.matrix(A);  // Ahat (same pattern as A) or A itself; timed as prefiltering
  double t = 0;
  {
    ScopedTimer timer(t);
    double* dst = lower_.valuePtr();
    const double* src = M.values().data();
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
    r.status = A_ ? Status::numerical_issue : Status::invalid_input;
    r.message = failure_;
    return r;
  }
  {
    // The factor L (CSC: values, row indices, column starts), D, the two permutations,
    // the matrix copy and the value map.
    const auto& L = ldlt_.matrixL().nestedExpression();
    r.memory_bytes = static_cast<std::size_t>(L.nonZeros()) * (sizeof(double) + sizeof(int)) +
                     static_cast<std::size_t>(L.cols() + 1) * sizeof(int) +
                     static_cast<std::size_t>(ldlt_.vectorD().size()) * sizeof(double) +
                     2 * static_cast<std::size_t>(lower_.rows()) * sizeof(int) +
                     static_cast<std::size_t>(lower_.nonZeros()) * (sizeof(double) + sizeof(int)) +
                     map_.capacity() * sizeof(std::pair<int, int>);
  }
  if (b.size() != A_->rows()) {
    r.status = Status::invalid_input;
    r.message = "right-hand side of the wrong size";
    return r;
  }
  const Eigen::VectorXd& c = pre_.rhs(b);  // S (b - A z), or b itself
  {
    ScopedTimer timer(r.solve_seconds);
    x = ldlt_.solve(c);
    pre_.finish(x);  // x = z + S y
  }
  r.prefilter_seconds = pre_.take_seconds();
  if (!x.allFinite()) {
    r.status = Status::numerical_issue;
    r.message = "LDL^T solve produced non-finite values";
    return r;
  }
  const ConstraintSet* cs = pre_.active() ? pre_.context().constraints : nullptr;
  if (cs) r.constraint_violation = cs->violation(x);
  if (prm_.check_residual) {
    // ||S (b - A x)|| / ||S b|| with the unfiltered A (S = I without constraints).
    Eigen::VectorXd res;
    A_->multiply(x, res);
    res = b - res;
    double nb = b.norm();
    if (cs) {
      cs->filter(res);
      Eigen::VectorXd Sb = b;
      cs->filter(Sb);
      nb = Sb.norm();
    }
    r.relative_residual = nb > 0 ? res.norm() / nb : res.norm();
  }
  return r;
}

}  // namespace weft::linear
