#pragma once
/// \file block_jacobi.hpp
/// `BlockJacobi`: the 3x3 block-diagonal preconditioner of Diag-PCG (methods/multigrid §0, §7.2),
///   B = blockdiag(A_11, ..., A_nn)^{-1},
/// each block inverted through its Cholesky factor and symmetrised, so B = B^T > 0 exactly
/// when every diagonal block is positive definite. Built from A for MPCG and from the
/// prefiltered Ahat for PPCG (where it inverts the projected blocks S_i A_ii S_i +
/// sigma_i (I - S_i), methods/multigrid §7.5).
#include <Eigen/Core>

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/constraints.hpp"
#include "framework/params.hpp"
#include "framework/status.hpp"
#include "linear/bsr.hpp"
#include "linear/preconditioner.hpp"

namespace weft::linear {

class BlockJacobi {
 public:
  static constexpr std::string_view name = "diag";
  /// No parameters: the preconditioner is fully determined by A.
  struct Params {
    template <class V>
    void visit(V&) {}
  };

  explicit BlockJacobi(const Params& = {}) {}
  /// Sizes the storage: #rows/3 inverse blocks.
  Status analyze_pattern(const BlockCsr& A);
  /// Inverts every diagonal block of A. A block that is not positive definite (or not
  /// finite) gives Status::numerical_issue, and `message()` names its block row. The
  /// context is not used (the blocks of Ahat already carry the constraints).
  Status setup(const BlockCsr& A, const SolveContext& ctx = {});
  /// The same for the prefiltered operator read through F (Ahat on the fly): inverts
  /// S_i A_ii S_i + sigma_i (I - S_i) without a copy of Ahat.
  Status setup(const BlockCsr& A, const SolveContext& ctx, const VertexFilterView& F);
  /// z = B r (z is resized to r's size; no allocation when it already has it).
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const;
  PreconditionerInfo info() const;
  /// Why the last setup failed ("" after a successful one).
  const std::string& message() const { return message_; }
  /// The inverse blocks, 9 row-major doubles per block row (the Krylov loops fuse their
  /// application with the vector updates).
  const std::vector<double>& inverse_blocks() const { return inv_; }

 private:
  std::vector<double> inv_;
  std::string message_;
};

static_assert(Preconditioner<BlockJacobi>);

}  // namespace weft::linear
