#pragma once
/// \file bsr.hpp
/// Generic fixed-block-size sparse kernels (spec 04 §13 "block sizes"): a block-sparse
/// matrix of R x C row-major blocks in BSR layout, block SpMV, transpose SpMV through a
/// cached transpose index, the Galerkin triple product P^T A P with a cached symbolic
/// phase, and block-diagonal inversion. Written once for every block shape the smoothed
/// aggregation hierarchy uses (3x3, 3x6, 6x6).
///
/// Every parallel loop runs over rows (or coarse rows) that are computed independently,
/// each summing its terms in a fixed order: results are bitwise identical for any number
/// of OpenMP threads.
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/LU>

#include <algorithm>
#include <cstddef>
#include <vector>

#include "framework/block_csr.hpp"

namespace weft::linear {

/// Loops over fewer rows than this run serially: a parallel region costs more than the
/// work, and much more on an oversubscribed machine.
inline constexpr int parallel_rows = 2048;

/// Row-major R x C block (column vectors stay column-major, as Eigen requires).
template <int R, int C>
using BlockOf = Eigen::Matrix<double, R, C, (C == 1 && R != 1) ? Eigen::ColMajor : Eigen::RowMajor>;

/// Non-owning view of a BSR matrix: #rows block rows, R*C doubles per block.
template <int R, int C>
struct BsrView {
  int rows = 0;  ///< block rows
  int cols = 0;  ///< block columns
  const int* row_ptr = nullptr;
  const int* col = nullptr;
  const double* val = nullptr;

  int nnz() const { return rows ? row_ptr[rows] : 0; }
  Eigen::Map<const BlockOf<R, C>> block(std::ptrdiff_t k) const {
    return Eigen::Map<const BlockOf<R, C>>(val + static_cast<std::ptrdiff_t>(R * C) * k);
  }
};

/// The 3x3 BlockCsr seen as a BSR matrix.
inline BsrView<3, 3> bsr_view(const BlockCsr& A) {
  return {A.block_rows(), A.block_rows(), A.row_ptr().data(), A.col().data(), A.values().data()};
}

/// Owning BSR matrix of R x C row-major blocks; rows of a block row sorted by column.
template <int R, int C>
class BlockMatrix {
 public:
  using Block = BlockOf<R, C>;
  BlockMatrix() = default;
  /// Pattern from a row pointer and column list (values zero).
  BlockMatrix(int rows, int cols, std::vector<int> row_ptr, std::vector<int> col)
      : rows_(rows), cols_(cols), row_ptr_(std::move(row_ptr)), col_(std::move(col)) {
    val_.assign(static_cast<std::size_t>(R * C) * col_.size(), 0.0);
  }

  int rows() const { return rows_; }  ///< block rows
  int cols() const { return cols_; }  ///< block columns
  int nnz() const { return static_cast<int>(col_.size()); }  ///< stored blocks
  const std::vector<int>& row_ptr() const { return row_ptr_; }
  const std::vector<int>& col() const { return col_; }
  std::vector<double>& values() { return val_; }
  const std::vector<double>& values() const { return val_; }
  Eigen::Map<Block> block(std::ptrdiff_t k) { return Eigen::Map<Block>(val_.data() + R * C * k); }
  Eigen::Map<const Block> block(std::ptrdiff_t k) const { return Eigen::Map<const Block>(val_.data() + R * C * k); }
  BsrView<R, C> view() const { return {rows_, cols_, row_ptr_.data(), col_.data(), val_.data()}; }
  /// Index of block (i, j) or -1. O(log row length).
  int find(int i, int j) const {
    const auto first = col_.begin() + row_ptr_[i], last = col_.begin() + row_ptr_[i + 1];
    const auto it = std::lower_bound(first, last, j);
    return (it != last && *it == j) ? static_cast<int>(it - col_.begin()) : -1;
  }
  /// Bytes of the arrays (capacity, not size: what the allocator holds).
  std::size_t memory_bytes() const {
    return row_ptr_.capacity() * sizeof(int) + col_.capacity() * sizeof(int) + val_.capacity() * sizeof(double);
  }
  /// Remove blocks that are exactly zero (pruning before the Galerkin product, spec 04 §4.8).
  /// Returns the number removed.
  int prune_zero_blocks() {
    int out = 0, removed = 0;
    for (int i = 0; i < rows_; ++i) {
      const int first = row_ptr_[i], last = row_ptr_[i + 1];
      row_ptr_[i] = out;
      for (int k = first; k < last; ++k) {
        if (block(k).isZero(0.0)) {
          ++removed;
          continue;
        }
        if (out != k) {
          col_[out] = col_[k];
          block(out) = block(k);
        }
        ++out;
      }
    }
    row_ptr_[rows_] = out;
    col_.resize(out);
    val_.resize(static_cast<std::size_t>(R * C) * out);
    return removed;
  }
  Eigen::MatrixXd to_dense() const {
    Eigen::MatrixXd D = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(R) * rows_, static_cast<Eigen::Index>(C) * cols_);
    for (int i = 0; i < rows_; ++i)
      for (int k = row_ptr_[i]; k < row_ptr_[i + 1]; ++k) D.template block<R, C>(R * i, C * col_[k]) += block(k);
    return D;
  }
  void clear() { *this = BlockMatrix(); }

 private:
  int rows_ = 0, cols_ = 0;
  std::vector<int> row_ptr_{0}, col_;
  std::vector<double> val_;
};

/// y = A x (y sized R * rows). Parallel over block rows.
template <int R, int C>
void spmv(const BsrView<R, C>& A, const double* x, double* y) {
#pragma omp parallel for schedule(static) if (A.rows > parallel_rows)
  for (int i = 0; i < A.rows; ++i) {
    Eigen::Matrix<double, R, 1> acc = Eigen::Matrix<double, R, 1>::Zero();
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k)
      acc.noalias() += A.block(k) * Eigen::Map<const Eigen::Matrix<double, C, 1>>(x + C * A.col[k]);
    Eigen::Map<Eigen::Matrix<double, R, 1>>(y + R * i) = acc;
  }
}

/// r = f - A x. Parallel over block rows.
template <int R, int C>
void residual(const BsrView<R, C>& A, const double* f, const double* x, double* r) {
#pragma omp parallel for schedule(static) if (A.rows > parallel_rows)
  for (int i = 0; i < A.rows; ++i) {
    Eigen::Matrix<double, R, 1> acc = Eigen::Map<const Eigen::Matrix<double, R, 1>>(f + R * i);
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k)
      acc.noalias() -= A.block(k) * Eigen::Map<const Eigen::Matrix<double, C, 1>>(x + C * A.col[k]);
    Eigen::Map<Eigen::Matrix<double, R, 1>>(r + R * i) = acc;
  }
}

/// y += A x. Parallel over block rows (x and y must not alias).
template <int R, int C>
void multiply_add(const BsrView<R, C>& A, const double* x, double* y) {
#pragma omp parallel for schedule(static) if (A.rows > parallel_rows)
  for (int i = 0; i < A.rows; ++i) {
    Eigen::Matrix<double, R, 1> acc = Eigen::Map<const Eigen::Matrix<double, R, 1>>(y + R * i);
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k)
      acc.noalias() += A.block(k) * Eigen::Map<const Eigen::Matrix<double, C, 1>>(x + C * A.col[k]);
    Eigen::Map<Eigen::Matrix<double, R, 1>>(y + R * i) = acc;
  }
}

/// Column-wise listing of a BSR pattern: for block column j, the blocks
/// (row[t], blk[t]) for t in [ptr[j], ptr[j+1]), by increasing row. Built once per
/// pattern; gives a deterministic parallel A^T x and the Galerkin product.
struct TransposeIndex {
  std::vector<int> ptr{0}, row, blk;

  template <int R, int C>
  void build(const BsrView<R, C>& A) {
    ptr.assign(A.cols + 1, 0);
    const int nnz = A.nnz();
    row.resize(nnz);
    blk.resize(nnz);
    for (int k = 0; k < nnz; ++k) ++ptr[A.col[k] + 1];
    for (int j = 0; j < A.cols; ++j) ptr[j + 1] += ptr[j];
    std::vector<int> fill(ptr.begin(), ptr.end() - 1);
    for (int i = 0; i < A.rows; ++i)
      for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
        const int t = fill[A.col[k]]++;
        row[t] = i;
        blk[t] = k;
      }
  }
  std::size_t memory_bytes() const { return (ptr.capacity() + row.capacity() + blk.capacity()) * sizeof(int); }
};

/// y = A^T x (y sized C * cols) through the transpose index T of A. Parallel over columns.
template <int R, int C>
void spmv_transpose(const BsrView<R, C>& A, const TransposeIndex& T, const double* x, double* y) {
#pragma omp parallel for schedule(static) if (A.cols > parallel_rows)
  for (int j = 0; j < A.cols; ++j) {
    Eigen::Matrix<double, C, 1> acc = Eigen::Matrix<double, C, 1>::Zero();
    for (int t = T.ptr[j]; t < T.ptr[j + 1]; ++t)
      acc.noalias() += A.block(T.blk[t]).transpose() * Eigen::Map<const Eigen::Matrix<double, R, 1>>(x + R * T.row[t]);
    Eigen::Map<Eigen::Matrix<double, C, 1>>(y + C * j) = acc;
  }
}

/// Index of the diagonal block of every block row (-1 if absent).
template <int B>
std::vector<int> diagonal_positions(const BsrView<B, B>& A) {
  std::vector<int> d(A.rows, -1);
  for (int i = 0; i < A.rows; ++i)
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k)
      if (A.col[k] == i) d[i] = k;
  return d;
}

/// Dinv_i = A_ii^-1 for every block row (#rows blocks of B x B doubles, row-major), by
/// Cholesky; blocks that are not SPD fall back to LU and are counted in the return value.
/// A missing or singular diagonal block gives a zero inverse (also counted).
template <int B>
int invert_block_diagonal(const BsrView<B, B>& A, std::vector<double>& Dinv) {
  using Block = BlockOf<B, B>;
  Dinv.resize(static_cast<std::size_t>(B * B) * A.rows);
  int bad = 0;
#pragma omp parallel for schedule(static) reduction(+ : bad) if (A.rows > parallel_rows)
  for (int i = 0; i < A.rows; ++i) {
    Eigen::Map<Block> out(Dinv.data() + static_cast<std::ptrdiff_t>(B * B) * i);
    int kd = -1;
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k)
      if (A.col[k] == i) kd = k;
    if (kd < 0) {
      out.setZero();
      ++bad;
      continue;
    }
    const Eigen::Matrix<double, B, B> D = A.block(kd);
    Eigen::LLT<Eigen::Matrix<double, B, B>> llt(D);
    if (llt.info() == Eigen::Success) {
      out = llt.solve(Eigen::Matrix<double, B, B>::Identity());
    } else {
      ++bad;
      Eigen::FullPivLU<Eigen::Matrix<double, B, B>> lu(D);
      if (lu.isInvertible())
        out = lu.inverse();
      else
        out.setZero();
    }
  }
  return bad;
}

/// Galerkin triple product Ac = P^T A P (A: n x n blocks of B x B, P: n x nc blocks of
/// B x C, Ac: nc x nc blocks of C x C), fused row by row: coarse row I first forms the
/// row I of P^T A, T_j = sum_{i in col I of P} P_iI^T A_ij, then Ac_IJ = sum_j T_j P_jJ.
/// No intermediate A P is stored. `symbolic` builds (and caches in the caller) Ac's
/// pattern; `numeric` fills values for a pattern from `symbolic` with the same patterns
/// of A and P. Both are parallel over coarse rows and deterministic.
template <int B, int C>
struct Galerkin {
  /// Pattern of Ac (sorted rows; every row holds its diagonal).
  static BlockMatrix<C, C> symbolic(const BsrView<B, B>& A, const BsrView<B, C>& P, const TransposeIndex& PT) {
    const int nc = P.cols;
    std::vector<std::vector<int>> rows(nc);
#pragma omp parallel if (nc > parallel_rows / 8)
    {
      std::vector<int> mark_f(A.rows, -1), mark_c(nc, -1), fine, coarse;
#pragma omp for schedule(dynamic, 64)
      for (int I = 0; I < nc; ++I) {
        fine.clear();
        coarse.clear();
        for (int t = PT.ptr[I]; t < PT.ptr[I + 1]; ++t) {
          const int i = PT.row[t];
          for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k)
            if (mark_f[A.col[k]] != I) mark_f[A.col[k]] = I, fine.push_back(A.col[k]);
        }
        mark_c[I] = I;
        coarse.push_back(I);
        for (int j : fine)
          for (int k = P.row_ptr[j]; k < P.row_ptr[j + 1]; ++k)
            if (mark_c[P.col[k]] != I) mark_c[P.col[k]] = I, coarse.push_back(P.col[k]);
        std::sort(coarse.begin(), coarse.end());
        rows[I] = coarse;
      }
    }
    std::vector<int> ptr(nc + 1, 0), col;
    for (int I = 0; I < nc; ++I) ptr[I + 1] = ptr[I] + static_cast<int>(rows[I].size());
    col.reserve(ptr[nc]);
    for (auto& r : rows) {
      col.insert(col.end(), r.begin(), r.end());
      std::vector<int>().swap(r);
    }
    return BlockMatrix<C, C>(nc, nc, std::move(ptr), std::move(col));
  }

  /// Ac's values (Ac from `symbolic` for these patterns of A and P).
  static void numeric(const BsrView<B, B>& A, const BsrView<B, C>& P, const TransposeIndex& PT, BlockMatrix<C, C>& Ac) {
    using TBlock = Eigen::Matrix<double, C, B>;
    const int nc = P.cols;
    double* out_values = Ac.values().data();
    const int* ac_ptr = Ac.row_ptr().data();
    const int* ac_col = Ac.col().data();
#pragma omp parallel if (nc > parallel_rows / 8)
    {
      std::vector<int> slot(A.rows, -1), pos(nc, -1), fine;
      std::vector<TBlock, Eigen::aligned_allocator<TBlock>> T;
#pragma omp for schedule(dynamic, 64)
      for (int I = 0; I < nc; ++I) {
        fine.clear();
        // Row I of P^T A, in the order the fine columns are first met (fixed).
        for (int t = PT.ptr[I]; t < PT.ptr[I + 1]; ++t) {
          const int i = PT.row[t];
          const Eigen::Matrix<double, C, B> PiT = P.block(PT.blk[t]).transpose();
          for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
            const int j = A.col[k];
            if (slot[j] < 0) {
              slot[j] = static_cast<int>(fine.size());
              fine.push_back(j);
              if (T.size() < fine.size()) T.resize(fine.size());
              T[slot[j]].setZero();
            }
            T[slot[j]].noalias() += PiT * A.block(k);
          }
        }
        for (int k = ac_ptr[I]; k < ac_ptr[I + 1]; ++k) pos[ac_col[k]] = k;
        for (int k = ac_ptr[I]; k < ac_ptr[I + 1]; ++k)
          Eigen::Map<BlockOf<C, C>>(out_values + static_cast<std::ptrdiff_t>(C * C) * k).setZero();
        for (std::size_t s = 0; s < fine.size(); ++s) {
          const int j = fine[s];
          for (int k = P.row_ptr[j]; k < P.row_ptr[j + 1]; ++k)
            Eigen::Map<BlockOf<C, C>>(out_values + static_cast<std::ptrdiff_t>(C * C) * pos[P.col[k]]).noalias() +=
                T[s] * P.block(k);
          slot[j] = -1;
        }
      }
    }
  }
};

}  // namespace weft::linear
