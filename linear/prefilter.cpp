#include "linear/prefilter.hpp"

#include "framework/error.hpp"
#include "framework/timers.hpp"

namespace weft::linear {

void prefilter_matrix(const BlockCsr& A, const ConstraintSet& c, BlockCsr& Ahat) {
  WEFT_ASSERT(Ahat.num_blocks() == A.num_blocks() && Ahat.block_rows() == A.block_rows(), "{}",
              "prefilter_matrix: Ahat must have A's pattern");
  WEFT_ASSERT(c.num_vertices() == A.block_rows(), "constraint set of {} vertices for a matrix of {}", c.num_vertices(),
              A.block_rows());
  const int n = A.block_rows();
  const auto& rp = A.row_ptr();
  const auto& col = A.col();
#pragma omp parallel for schedule(static) if (n >= 2048)
  for (int i = 0; i < n; ++i) {
    const bool ci = c.count(i) > 0;
    const Block3 Si = ci ? c.filter(i) : Block3::Identity();
    for (int k = rp[i]; k < rp[i + 1]; ++k) {
      const int j = col[k];
      const bool cj = c.count(j) > 0;
      if (!ci && !cj) {
        Ahat.block(k) = A.block(k);
      } else if (!cj) {
        Ahat.block(k) = Si * A.block(k);
      } else {
        const Block3 Sj = c.filter(j);
        Ahat.block(k) = (ci ? Block3(Si * A.block(k)) : Block3(A.block(k))) * Sj;
      }
      if (j == i && ci) {
        const double sigma = A.block(k).trace() / 3.0;
        Ahat.block(k) += sigma * (Block3::Identity() - Si);
      }
    }
  }
}

void prefilter_rhs(const BlockCsr& A, const ConstraintSet& c, const Eigen::VectorXd& b, Eigen::VectorXd& chat) {
  A.multiply(c.target(), chat);
  chat = b - chat;
  c.filter(chat);
}

void unfilter_solution(const ConstraintSet& c, const Eigen::VectorXd& y, Eigen::VectorXd& x) {
  if (&x != &y) x = y;
  c.filter(x);
  x += c.target();
}

bool already_prefiltered(const BlockCsr& A, const ConstraintSet& c) {
  if (c.num_vertices() != A.block_rows()) return false;
  const auto& rp = A.row_ptr();
  const auto& col = A.col();
  for (int i = 0; i < A.block_rows(); ++i) {
    if (c.count(i) == 0) continue;
    if (c.count(i) != 3) return false;  // a partial filter S_i != 0 changes the couplings
    for (int k = rp[i]; k < rp[i + 1]; ++k) {
      const int j = col[k];
      if (j == i) {
        const Block3 D = A.block(k);
        if (!(D(0, 0) == D(1, 1) && D(1, 1) == D(2, 2)) || !(D - D(0, 0) * Block3::Identity()).isZero(0.0)) return false;
      } else if (!A.block(k).isZero(0.0) || !A.block(A.find(j, i)).isZero(0.0)) {
        return false;
      }
    }
  }
  return true;
}

void OperatorFilter::build(const BlockCsr& A, const ConstraintSet& c) {
  clear();
  if (c.empty() || already_prefiltered(A, c)) return;
  WEFT_ASSERT(c.num_vertices() == A.block_rows(), "constraint set of {} vertices for a matrix of {}", c.num_vertices(),
              A.block_rows());
  const int n = A.block_rows();
  slot_.assign(n, -1);
  for (int i = 0; i < n; ++i) {
    if (c.count(i) == 0) continue;
    slot_[i] = static_cast<int>(sigma_.size());
    // The same S_i and sigma_i as prefilter_matrix: the blocks read are bitwise the stored ones.
    const Block3 Si = c.filter(i);
    for (int r = 0; r < 3; ++r)
      for (int q = 0; q < 3; ++q) S_.push_back(Si(r, q));
    sigma_.push_back(A.block(A.diagonal(i)).trace() / 3.0);
  }
}

void OperatorFilter::clear() {
  std::vector<int>().swap(slot_);
  std::vector<double>().swap(S_);
  std::vector<double>().swap(sigma_);
}

const OperatorFilter& PrefilteredSystem::filter(const BlockCsr& A) {
  A_ = &A;
  Ahat_ = BlockCsr();
  if (!active()) {
    filter_.clear();
    return filter_;
  }
  ScopedTimer t(seconds_);
  filter_.build(A, *ctx_.constraints);
  return filter_;
}

const BlockCsr& PrefilteredSystem::matrix(const BlockCsr& A) {
  A_ = &A;
  filter_.clear();
  if (!active()) return A;
  ScopedTimer t(seconds_);
  if (already_prefiltered(A, *ctx_.constraints)) {
    Ahat_ = BlockCsr();  // Ahat == A exactly: no copy
    return A;
  }
  if (Ahat_.num_blocks() != A.num_blocks() || Ahat_.block_rows() != A.block_rows() || Ahat_.col() != A.col())
    Ahat_ = A;  // new pattern: copy it once
  prefilter_matrix(A, *ctx_.constraints, Ahat_);
  return Ahat_;
}

const Eigen::VectorXd& PrefilteredSystem::rhs(const Eigen::VectorXd& b) { return active() ? rhs(b, chat_) : b; }

const Eigen::VectorXd& PrefilteredSystem::rhs(const Eigen::VectorXd& b, Eigen::VectorXd& out) {
  WEFT_ASSERT(active() && A_ != nullptr, "{}", "PrefilteredSystem::rhs(b, out) without constraints or before matrix");
  ScopedTimer t(seconds_);
  prefilter_rhs(*A_, *ctx_.constraints, b, out);
  return out;
}

void PrefilteredSystem::finish(Eigen::VectorXd& y) const {
  if (active()) unfilter_solution(*ctx_.constraints, y, y);
}

double PrefilteredSystem::take_seconds() {
  const double s = seconds_;
  seconds_ = 0;
  return s;
}

}  // namespace weft::linear
