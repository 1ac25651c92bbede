#pragma once
/// \file band_matrix.hpp
/// `BandMatrix`: a square n x n matrix with lower and upper half-bandwidth k, stored in the
/// LAPACK general band layout that `dgbtrf` factorises in place (with the k extra rows its
/// fill-in needs). The Hessian of one discrete elastic rod (4V - 1 interleaved DoFs) has
/// k = 10 (methods/rod-contact §13, V-03).
///
/// Storage: column major, ldab = 3k + 1 rows per column, A(i, j) at ab[(2k + i - j) + j ldab]
/// for |i - j| <= k; rows 0..k-1 of each column are LAPACK's workspace for the U fill-in and
/// are kept zero here.
#include <Eigen/Core>

#include <algorithm>
#include <cstdlib>
#include <vector>

#include "framework/error.hpp"

namespace weft {

/// Square band matrix with equal lower and upper half-bandwidth k, LAPACK band layout.
class BandMatrix {
 public:
  BandMatrix() = default;
  /// Zero n x n matrix of half-bandwidth k.
  BandMatrix(int n, int k) : n_(n), k_(k), ab_(static_cast<size_t>(3 * k + 1) * std::max(n, 0), 0.0) {
    WEFT_ASSERT(n >= 0 && k >= 0, "BandMatrix({}, {}): n and k must be >= 0", n, k);
  }

  int rows() const { return n_; }
  int cols() const { return n_; }
  int bandwidth() const { return k_; }
  /// Leading dimension of the band storage: 3k + 1.
  int ldab() const { return 3 * k_ + 1; }

  /// Entry (i, j); requires |i - j| <= k.
  double& operator()(int i, int j) {
    WEFT_ASSERT(in_band(i, j), "BandMatrix: entry ({}, {}) outside the band (n = {}, k = {})", i, j, n_, k_);
    return ab_[index(i, j)];
  }
  /// Entry (i, j); 0 outside the band.
  double operator()(int i, int j) const { return in_band(i, j) ? ab_[index(i, j)] : 0.0; }
  /// True if (i, j) is a valid index inside the band.
  bool in_band(int i, int j) const { return i >= 0 && j >= 0 && i < n_ && j < n_ && std::abs(i - j) <= k_; }

  void setZero() { std::fill(ab_.begin(), ab_.end(), 0.0); }

  /// The n x n dense matrix (zeros outside the band).
  Eigen::MatrixXd dense() const {
    Eigen::MatrixXd D = Eigen::MatrixXd::Zero(n_, n_);
    for (int j = 0; j < n_; ++j)
      for (int i = std::max(0, j - k_); i <= std::min(n_ - 1, j + k_); ++i) D(i, j) = ab_[index(i, j)];
    return D;
  }

  /// y = A x (y is resized).
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
    WEFT_ASSERT(x.size() == n_, "BandMatrix::multiply: x has {} entries, expected {}", x.size(), n_);
    y.setZero(n_);
    for (int j = 0; j < n_; ++j) {
      const double xj = x[j];
      const double* col = ab_.data() + static_cast<size_t>(j) * ldab() + 2 * k_ - j;
      for (int i = std::max(0, j - k_); i <= std::min(n_ - 1, j + k_); ++i) y[i] += col[i] * xj;
    }
  }

  /// Band storage, ldab() x rows(), column major.
  const double* data() const { return ab_.data(); }
  double* data() { return ab_.data(); }

 private:
  size_t index(int i, int j) const { return static_cast<size_t>(2 * k_ + i - j) + static_cast<size_t>(j) * ldab(); }

  int n_ = 0, k_ = 0;
  std::vector<double> ab_;
};

}  // namespace weft
