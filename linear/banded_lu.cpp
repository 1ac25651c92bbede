#include "linear/banded_lu.hpp"

#include <dlfcn.h>
#include <fmt/format.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstddef>
#include <cstdlib>

#include "framework/error.hpp"
#include "linear/lapack_info.hpp"

// LAPACK (Fortran calling convention; gfortran appends the hidden length of character
// arguments, passed explicitly for dgbtrs' TRANS).
extern "C" {
void dgbtrf_(const int* m, const int* n, const int* kl, const int* ku, double* ab, const int* ldab, int* ipiv, int* info);
void dgbtrs_(const char* trans, const int* n, const int* kl, const int* ku, const int* nrhs, const double* ab,
             const int* ldab, const int* ipiv, double* b, const int* ldb, int* info, std::size_t trans_len);
}

namespace weft::linear {

std::string lapack_library() {
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&dgbtrf_), &info) == 0 || info.dli_fname == nullptr) return "unknown";
  char resolved[PATH_MAX];
  return realpath(info.dli_fname, resolved) ? std::string(resolved) : std::string(info.dli_fname);
}

Status BandedLu::factorize(const BandMatrix& A) {
  lu_ = A;
  n_ = A.rows();
  k_ = A.bandwidth();
  ok_ = false;
  // dgbtrf writes the fill-in of U into the first k rows of every column: start from zero.
  double* ab = lu_.data();
  for (int j = 0; j < n_; ++j)
    for (int r = 0; r < k_; ++r) ab[r + static_cast<std::size_t>(j) * lu_.ldab()] = 0.0;
  for (int j = 0; j < n_; ++j)
    for (int i = std::max(0, j - k_); i <= std::min(n_ - 1, j + k_); ++i)
      if (!std::isfinite(A(i, j))) {
        message_ = fmt::format("BandedLu: entry ({}, {}) is not finite", i, j);
        return Status::invalid_input;
      }
  ipiv_.assign(static_cast<std::size_t>(n_), 0);
  if (n_ == 0) {
    ok_ = true;
    message_.clear();
    return Status::success;
  }
  const int ldab = lu_.ldab();
  int info = 0;
  dgbtrf_(&n_, &n_, &k_, &k_, ab, &ldab, ipiv_.data(), &info);
  if (info > 0) {
    message_ = fmt::format("BandedLu: the matrix is singular: U({0}, {0}) is exactly zero (pivot {0} of {1}, 0-based)",
                           info - 1, n_);
    return Status::numerical_issue;
  }
  if (info < 0) {
    message_ = fmt::format("BandedLu: dgbtrf rejected argument {}", -info);
    return Status::invalid_input;
  }
  ok_ = true;
  message_.clear();
  return Status::success;
}

void BandedLu::solve(Eigen::Ref<Eigen::MatrixXd> B) const {
  WEFT_ASSERT(ok_, "BandedLu::solve: {}", message_.empty() ? "call factorize() first" : message_);
  WEFT_ASSERT(B.rows() == n_, "BandedLu::solve: B has {} rows, expected {}", B.rows(), n_);
  if (n_ == 0 || B.cols() == 0) return;
  const char trans = 'N';
  const int nrhs = static_cast<int>(B.cols());
  const int ldab = lu_.ldab();
  const int ldb = static_cast<int>(B.outerStride());
  int info = 0;
  dgbtrs_(&trans, &n_, &k_, &k_, &nrhs, lu_.data(), &ldab, ipiv_.data(), B.data(), &ldb, &info, 1);
  WEFT_ASSERT(info == 0, "BandedLu::solve: dgbtrs returned info = {}", info);
}

}  // namespace weft::linear
