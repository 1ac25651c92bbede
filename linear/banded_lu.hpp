#pragma once
/// \file banded_lu.hpp
/// `BandedLu`: LU factorisation with partial pivoting of a `BandMatrix` (LAPACK dgbtrf /
/// dgbtrs), for the banded rod Hessians and compliances of methods/rod-contact §10.3 (Algorithm 4) and
/// V-03. Works for indefinite nonsingular matrices; a singular matrix (an exactly zero pivot)
/// is a returned `Status::numerical_issue` whose `message()` names the pivot.
#include <Eigen/Core>

#include <string>
#include <vector>

#include "framework/band_matrix.hpp"
#include "framework/status.hpp"

namespace weft::linear {

/// Banded LU with partial pivoting (LAPACK general band routines).
class BandedLu {
 public:
  BandedLu() = default;
  /// Copies A and factorises it (dgbtrf). On failure solve() must not be called; `message()`
  /// says why (a singular matrix names its zero pivot).
  Status factorize(const BandMatrix& A);
  /// B <- A^-1 B in place, every column a right-hand side (dgbtrs). Requires a successful factorize().
  void solve(Eigen::Ref<Eigen::MatrixXd> B) const;
  /// n of the factorised matrix (0 before factorize()).
  int size() const { return n_; }
  /// True after a successful factorize().
  bool factorized() const { return ok_; }
  /// Why the last factorize() failed ("" on success).
  const std::string& message() const { return message_; }

 private:
  int n_ = 0, k_ = 0;
  BandMatrix lu_;
  std::vector<int> ipiv_;
  bool ok_ = false;
  std::string message_ = "call factorize() before solve()";
};

}  // namespace weft::linear
