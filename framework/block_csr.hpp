#pragma once
/// \file block_csr.hpp
/// Sparse matrices with 3x3 blocks, and the assembly plan that fills them.
///
/// The symmetric sparsity pattern is built once per topology (`AssemblyPlan::finalize`)
/// and reused for every evaluation. Element kernels write their local matrices into an
/// `ElementBuffer`, one private slot per element (no sharing, so any number of threads
/// may write at once); `AssemblyPlan::gather` then sums, for every block of the matrix,
/// the element blocks that land on it, in a fixed order. The assembly therefore needs no
/// locks or atomics and is bitwise deterministic whatever the number of threads.
#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <span>
#include <vector>

namespace weft {

using Block3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

/// Square block-sparse matrix, #rows block rows of 3 scalar rows each. The pattern is
/// structurally symmetric and always holds the diagonal block; both (i, j) and (j, i)
/// are stored. Blocks are row-major 3x3, 9 consecutive doubles.
class BlockCsr {
 public:
  BlockCsr() = default;
  /// Pattern from per-row sorted column lists; the diagonal is added if absent.
  explicit BlockCsr(const std::vector<std::vector<int>>& columns);

  int block_rows() const { return static_cast<int>(row_ptr_.size()) - 1; }
  int rows() const { return 3 * block_rows(); }
  int num_blocks() const { return static_cast<int>(col_.size()); }
  const std::vector<int>& row_ptr() const { return row_ptr_; }
  const std::vector<int>& col() const { return col_; }
  std::vector<double>& values() { return values_; }
  const std::vector<double>& values() const { return values_; }
  /// Index of the diagonal block of row i.
  int diagonal(int i) const { return diag_[i]; }
  /// Index of block (i, j), or -1 if it is not in the pattern. O(log row length).
  int find(int i, int j) const;
  Eigen::Map<Block3> block(int k) { return Eigen::Map<Block3>(values_.data() + 9 * k); }
  Eigen::Map<const Block3> block(int k) const { return Eigen::Map<const Block3>(values_.data() + 9 * k); }

  void set_zero();
  /// y = A x (parallel over block rows).
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const;
  /// A += diag(d) with d of size rows(): adds d[3i+k] to entry (3i+k, 3i+k).
  void add_diagonal(const Eigen::VectorXd& d);
  /// A *= s.
  void scale(double s);
  /// Replace rows and columns of the marked block rows by identity * diag_value:
  /// the Dirichlet filter for pinned and scripted vertices (keeps symmetry). A negative
  /// diag_value keeps each row's scale, sigma_i = tr(A_ii)/3 (the prefilter's Sigma, spec 04
  /// §7.3: the decoupled eigenvalues then sit inside the spectrum whatever the units).
  void filter_rows(const std::vector<unsigned char>& fixed, double diag_value = 1.0);
  /// ||A - A^T||_F / ||A||_F.
  double asymmetry() const;
  /// Scalar CSC matrix with the lower triangle only (for LDL^T) or the full matrix.
  Eigen::SparseMatrix<double> to_sparse(bool lower_only = false) const;
  Eigen::MatrixXd to_dense() const;

 private:
  std::vector<int> row_ptr_{0}, col_, diag_;
  std::vector<double> values_;
};

/// Per-evaluation storage for local element Hessians. Element e of group g has a
/// k x k array of 3x3 blocks (k = stencil size), stored block-major, row-major blocks.
class ElementBuffer {
 public:
  /// Writable 3x3 block (a, b) of element e in group g.
  Eigen::Map<Block3> block(int group, int e, int a, int b);
  /// Copy a dense (3k x 3k) local matrix into element e of group g.
  template <class Derived>
  void set(int group, int e, const Eigen::MatrixBase<Derived>& local) {
    const int k = stencil_[group];
    for (int a = 0; a < k; ++a)
      for (int b = 0; b < k; ++b) block(group, e, a, b) = local.template block<3, 3>(3 * a, 3 * b);
  }
  /// Zero every local matrix of group g (for models that add, rather than set, terms).
  void zero_group(int group);
  int stencil_size(int group) const { return stencil_[group]; }

 private:
  friend class AssemblyPlan;
  std::vector<int> stencil_;        // per group
  std::vector<size_t> offset_;      // per group: first double
  std::vector<double> data_;
};

/// The map from element blocks to matrix blocks, built once per topology.
class AssemblyPlan {
 public:
  /// Register `vertex_ids.size() / stencil_size` elements; returns the group id that the
  /// model passes back to `ElementBuffer`. Only before `finalize`.
  int add_group(int stencil_size, std::span<const int> vertex_ids);
  /// Build the pattern of a #vertices x #vertices block matrix and the gather lists.
  void finalize(int num_vertices);
  bool finalized() const { return finalized_; }

  /// A matrix with the plan's pattern (values zero).
  const BlockCsr& pattern() const { return pattern_; }
  /// A buffer sized for every registered element (allocate once, reuse).
  ElementBuffer make_buffer() const;
  /// out = sum of all element blocks (out must have the plan's pattern). Parallel over
  /// matrix blocks; every matrix block sums its contributions in a fixed order.
  void gather(const ElementBuffer& buffer, BlockCsr& out) const;
  int num_groups() const { return static_cast<int>(stencil_.size()); }

 private:
  bool finalized_ = false;
  std::vector<int> stencil_;
  std::vector<std::vector<int>> ids_;
  BlockCsr pattern_;
  // For matrix block m: contributions src_[src_ptr_[m] .. src_ptr_[m+1]) are block indices
  // (in units of 9 doubles) into the element buffer's data.
  std::vector<size_t> src_ptr_, src_;
};

}  // namespace weft
