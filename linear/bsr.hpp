#pragma once
/// \file bsr.hpp
/// Generic fixed-block-size sparse kernels (methods/multigrid §13 "block sizes"): a block-sparse
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
#include <type_traits>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "framework/block_csr.hpp"

namespace weft::linear {

/// Loops over fewer rows than this run serially: a parallel region costs more than the
/// work, and much more on an oversubscribed machine.
inline constexpr int parallel_rows = 2048;

/// Row-major R x C block (column vectors stay column-major, as Eigen requires).
template <int R, int C>
using BlockOf = Eigen::Matrix<double, R, C, (C == 1 && R != 1) ? Eigen::ColMajor : Eigen::RowMajor>;

/// Per-vertex 3x3 filters that turn a 3x3 block matrix A into the prefiltered operator
///   Ahat = S A S + Sigma (I - S)      (methods/multigrid §7.3; linear/prefilter.hpp)
/// applied as A is read, so Ahat is never stored: block (i, j) of Ahat is (S_i A_ij) S_j
/// (the factor on a free vertex is I), plus sigma_i (I - S_i) on the diagonal. Non-owning
/// (linear::OperatorFilter owns the arrays); an empty view (slot == nullptr) filters nothing.
struct VertexFilterView {
  const int* slot = nullptr;      ///< per block row: -1 (free) or index into S and sigma
  const double* S = nullptr;      ///< 9 row-major doubles per slot: S_i
  const double* sigma = nullptr;  ///< per slot: sigma_i
  bool empty() const { return slot == nullptr; }
  Eigen::Map<const BlockOf<3, 3>> filter(int s) const { return Eigen::Map<const BlockOf<3, 3>>(S + 9 * static_cast<std::ptrdiff_t>(s)); }
  /// Block (i, j) of Ahat from block A_ij of A.
  BlockOf<3, 3> apply(int i, int j, const BlockOf<3, 3>& Aij) const {
    if (!slot) return Aij;
    const int si = slot[i], sj = slot[j];
    if (si < 0 && sj < 0) return Aij;
    BlockOf<3, 3> out = Aij;
    if (si >= 0) out = (filter(si) * out).eval();
    if (sj >= 0) out = (out * filter(sj)).eval();
    if (i == j && si >= 0) out += sigma[si] * (BlockOf<3, 3>::Identity() - filter(si));
    return out;
  }
};

/// Block k of R x C row-major blocks stored as T (double, or float for single-precision
/// storage), read as double.
template <int R, int C, class T>
inline Eigen::Matrix<double, R, C> value_block(const T* val, std::ptrdiff_t k) {
  return Eigen::Map<const Eigen::Matrix<T, R, C, Eigen::RowMajor>>(val + static_cast<std::ptrdiff_t>(R * C) * k).template cast<double>();
}

/// The same for int16 storage (fixed16 prolongators: the caller applies the scales). Through
/// float, which the compiler vectorises with the baseline instruction set: with Eigen's
/// direct cast, SA+PPCG's solve at 1M vertices took 1.10x that with float storage; through
/// float, 0.94-0.96x (same-run ratios, bench/results/table-11-1/M3-fixed16/pinned1M*).
template <int R, int C>
inline Eigen::Matrix<double, R, C> value_block(const std::int16_t* val, std::ptrdiff_t k) {
  alignas(16) float tmp[R * C];
  const std::int16_t* q = val + static_cast<std::ptrdiff_t>(R * C) * k;
  for (int e = 0; e < R * C; ++e) tmp[e] = static_cast<float>(q[e]);
  return Eigen::Map<const Eigen::Matrix<float, R, C, Eigen::RowMajor>>(tmp).template cast<double>();
}

/// Non-owning view of a BSR matrix: #rows block rows, R*C doubles per block.
///
/// A square view may be stored by one triangle (`src` non-null, see `SymBlockMatrix`): the
/// pattern (row_ptr, col) is the full one, and block k of the pattern is stored block
/// src[k] (>= 0) or the transpose of stored block ~src[k] (< 0). Code that walks the
/// pattern by k works unchanged through `block(k)`; the products below read the stored
/// triangle directly.
template <int R, int C>
struct BsrView {
  int rows = 0;  ///< block rows
  int cols = 0;  ///< block columns
  const int* row_ptr = nullptr;
  const int* col = nullptr;
  const double* val = nullptr;
  const int* src = nullptr;  ///< square views only: one-triangle storage map (nullptr: block k is stored at k)
  VertexFilterView filter{};  ///< 3x3 views only: read as the prefiltered operator (see VertexFilterView)
  /// One-triangle views only: the stored values in single precision (then val == nullptr);
  /// every read converts them to double.
  const float* valf = nullptr;

  int nnz() const { return rows ? row_ptr[rows] : 0; }
  /// Whether block k of the pattern is the transpose of its stored block.
  bool transposed(std::ptrdiff_t k) const { return src && src[k] < 0; }
  /// Index of the stored block behind block k of the pattern.
  std::ptrdiff_t stored_index(std::ptrdiff_t k) const { return src ? (src[k] >= 0 ? src[k] : ~src[k]) : k; }
  /// The stored block behind block k of the pattern (transpose it when `transposed(k)`);
  /// double storage only.
  Eigen::Map<const BlockOf<R, C>> stored(std::ptrdiff_t k) const {
    return Eigen::Map<const BlockOf<R, C>>(val + static_cast<std::ptrdiff_t>(R * C) * stored_index(k));
  }
  /// Block k of the pattern: a map of the storage for rectangular views, a copy for square
  /// ones (which may be stored by one triangle, in double or single precision).
  auto block(std::ptrdiff_t k) const {
    if constexpr (R == C) {
      BlockOf<R, C> b = valf ? value_block<R, C>(valf, stored_index(k)) : value_block<R, C>(val, stored_index(k));
      if (transposed(k)) b.transposeInPlace();
      return b;
    } else {
      return stored(k);
    }
  }
  /// Block k of the pattern, in block row i, as the operator sees it: through `filter` when
  /// there is one (3x3 views), else `block(k)`.
  auto block(int i, std::ptrdiff_t k) const {
    if constexpr (R == 3 && C == 3) {
      if (!filter.empty()) return filter.apply(i, col[k], BlockOf<3, 3>(stored(k)));
    }
    return block(k);
  }
};

/// Block row i of a 6x6 view stored by one triangle in single precision, portable form of
/// `sym_row_product_single` (same expressions, same order; the reference its test compares
/// the SSE2 form with, and the form used without SSE2).
inline Eigen::Matrix<double, 6, 1> sym_row_product_single_portable(const int* row_ptr, const int* col, const int* src,
                                                                   const float* valf, int i, const double* x) {
  double acc[6] = {0, 0, 0, 0, 0, 0};
  for (int k = row_ptr[i]; k < row_ptr[i + 1]; ++k) {
    const int s = src[k];
    const double* xj = x + 6 * static_cast<std::ptrdiff_t>(col[k]);
    const float* b = valf + 36 * static_cast<std::ptrdiff_t>(s >= 0 ? s : ~s);
    auto v = [&](int r, int c) { return static_cast<double>(b[6 * r + c]); };
    if (s >= 0) {
      for (int r = 0; r < 6; ++r) {
        const double e = (v(r, 0) * xj[0] + v(r, 2) * xj[2]) + v(r, 4) * xj[4];
        const double o = (v(r, 1) * xj[1] + v(r, 3) * xj[3]) + v(r, 5) * xj[5];
        acc[r] += e + o;
      }
    } else {
      for (int r = 0; r < 6; ++r)
        for (int c = 0; c < 6; ++c) acc[c] += v(r, c) * xj[r];
    }
  }
  return Eigen::Map<const Eigen::Matrix<double, 6, 1>>(acc);
}

/// Block row i of a 6x6 view stored by one triangle in single precision (the coarse
/// operators of smoothed aggregation under `single_coarse_operators`): sum_k A_ik x_col(k),
/// products and sums in double. Eigen's product of a cast block converted and multiplied
/// one entry at a time; here each pair of block rows is read as three 4-float loads and
/// converted two entries at a time, and both the stored and the transposed blocks run two
/// lanes wide (SSE2, the x86-64 baseline). Level 1's smoothing of dropVertical at 160k took
/// 74 ms with Eigen's product and 55 ms with this one (level 2: 9.6 and 5.2 ms).
///
/// Every output entry sums its terms in a fixed order, elementwise in the lanes: a stored
/// block adds (b_r0 x_0 + b_r2 x_2 + b_r4 x_4) + (b_r1 x_1 + b_r3 x_3 + b_r5 x_5) to entry r,
/// a transposed one adds b_rc x_r to entry c for r = 0..5, block by block along the row, so
/// the result is `sym_row_product_single_portable`'s bit for bit.
inline Eigen::Matrix<double, 6, 1> sym_row_product_single(const int* row_ptr, const int* col, const int* src,
                                                          const float* valf, int i, const double* x) {
#if defined(__SSE2__)
  __m128d acc[3] = {_mm_setzero_pd(), _mm_setzero_pd(), _mm_setzero_pd()};  // entries (0,1), (2,3), (4,5)
  for (int k = row_ptr[i]; k < row_ptr[i + 1]; ++k) {
    const int s = src[k];
    const double* xj = x + 6 * static_cast<std::ptrdiff_t>(col[k]);
    const float* b = valf + 36 * static_cast<std::ptrdiff_t>(s >= 0 ? s : ~s);
    if (s >= 0) {
      const __m128d x01 = _mm_loadu_pd(xj), x23 = _mm_loadu_pd(xj + 2), x45 = _mm_loadu_pd(xj + 4);
      for (int p = 0; p < 3; ++p) {  // rows 2p and 2p + 1: floats f0..f5 and f6..f11
        const float* f = b + 12 * p;
        const __m128 q0 = _mm_loadu_ps(f), q1 = _mm_loadu_ps(f + 4), q2 = _mm_loadu_ps(f + 8);
        const __m128d e = _mm_add_pd(_mm_add_pd(_mm_mul_pd(_mm_cvtps_pd(q0), x01), _mm_mul_pd(_mm_cvtps_pd(_mm_movehl_ps(q0, q0)), x23)),
                                     _mm_mul_pd(_mm_cvtps_pd(q1), x45));
        const __m128d o = _mm_add_pd(_mm_add_pd(_mm_mul_pd(_mm_cvtps_pd(_mm_movehl_ps(q1, q1)), x01), _mm_mul_pd(_mm_cvtps_pd(q2), x23)),
                                     _mm_mul_pd(_mm_cvtps_pd(_mm_movehl_ps(q2, q2)), x45));
        // e = (row 2p's even-column sum, its odd-column sum), o the same for row 2p + 1
        acc[p] = _mm_add_pd(acc[p], _mm_add_pd(_mm_unpacklo_pd(e, o), _mm_unpackhi_pd(e, o)));
      }
    } else {
      for (int p = 0; p < 3; ++p) {
        const float* f = b + 12 * p;
        const __m128 q0 = _mm_loadu_ps(f), q1 = _mm_loadu_ps(f + 4), q2 = _mm_loadu_ps(f + 8);
        const __m128d xa = _mm_set1_pd(xj[2 * p]), xb = _mm_set1_pd(xj[2 * p + 1]);
        acc[0] = _mm_add_pd(acc[0], _mm_mul_pd(_mm_cvtps_pd(q0), xa));
        acc[1] = _mm_add_pd(acc[1], _mm_mul_pd(_mm_cvtps_pd(_mm_movehl_ps(q0, q0)), xa));
        acc[2] = _mm_add_pd(acc[2], _mm_mul_pd(_mm_cvtps_pd(q1), xa));
        acc[0] = _mm_add_pd(acc[0], _mm_mul_pd(_mm_cvtps_pd(_mm_movehl_ps(q1, q1)), xb));
        acc[1] = _mm_add_pd(acc[1], _mm_mul_pd(_mm_cvtps_pd(q2), xb));
        acc[2] = _mm_add_pd(acc[2], _mm_mul_pd(_mm_cvtps_pd(_mm_movehl_ps(q2, q2)), xb));
      }
    }
  }
  Eigen::Matrix<double, 6, 1> out;
  for (int p = 0; p < 3; ++p) _mm_storeu_pd(out.data() + 2 * p, acc[p]);
  return out;
#else
  return sym_row_product_single_portable(row_ptr, col, src, valf, i, x);
#endif
}

/// acc = sum_k A_ik x_col(k) for block row i (one-triangle storage read as stored). With
/// M > 1, x holds one C x M row-major block per block column (M vectors at once, node by
/// node, as a row-major NullSpace stores them): each block of A is read once for all M.
template <int R, int C, int M = 1>
inline BlockOf<R, M> row_product(const BsrView<R, C>& A, int i, const double* x) {
  using In = Eigen::Map<const BlockOf<C, M>>;
  using Blk = Eigen::Map<const BlockOf<R, C>>;
  constexpr std::ptrdiff_t S = R * C;
  constexpr std::ptrdiff_t X = C * M;
  BlockOf<R, M> acc = BlockOf<R, M>::Zero();
  if constexpr (R == 3 && C == 3) {
    if (!A.filter.empty()) {
      // (Ahat x)_i = S_i sum_j A_ij (S_j x_j) + sigma_i (I - S_i) x_i.
      const VertexFilterView& F = A.filter;
      for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
        const int j = A.col[k], sj = F.slot[j];
        if (sj < 0)
          acc.noalias() += Blk(A.val + S * k) * In(x + X * j);
        else
          acc.noalias() += Blk(A.val + S * k) * (F.filter(sj) * In(x + X * j));
      }
      const int si = F.slot[i];
      if (si >= 0) {
        const BlockOf<3, M> xi = In(x + X * i);
        const BlockOf<3, M> Sx = F.filter(si) * xi;
        acc = (F.filter(si) * acc + F.sigma[si] * (xi - Sx)).eval();
      }
      return acc;
    }
  }
  if constexpr (R == C) {
    if (A.src) {
      auto sum = [&](const auto* val) {  // double or single-precision storage, products in double
        using T = std::remove_cv_t<std::remove_pointer_t<decltype(val)>>;
        using BlkT = Eigen::Map<const Eigen::Matrix<T, R, C, Eigen::RowMajor>>;
        for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
          const int s = A.src[k];
          if (s >= 0)
            acc.noalias() += BlkT(val + S * s).template cast<double>() * In(x + X * A.col[k]);
          else
            acc.noalias() += BlkT(val + S * ~s).transpose().template cast<double>() * In(x + X * A.col[k]);
        }
      };
      if constexpr (R == 6 && M == 1) {
        if (A.valf) return sym_row_product_single(A.row_ptr, A.col, A.src, A.valf, i, x);
      }
      if (A.valf)
        sum(A.valf);
      else
        sum(A.val);
      return acc;
    }
  }
  for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) acc.noalias() += Blk(A.val + S * k) * In(x + X * A.col[k]);
  return acc;
}

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
  /// Remove blocks that are exactly zero (pruning before the Galerkin product, methods/multigrid §4.8).
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
    if (removed > 0) {  // resize keeps the capacity: give the pruned blocks back
      col_.shrink_to_fit();
      val_.shrink_to_fit();
    }
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

/// Symmetric B x B block matrix stored by its upper triangle (diagonal included), with the
/// full pattern kept for the algorithms that walk rows (strength, aggregation, P, Galerkin):
/// per block of the pattern 8 bytes (column, `src`), per stored block B*B doubles, or floats
/// when constructed `single` (every read converts to double). A full BlockMatrix of a coarse
/// SA operator (6x6 blocks) holds almost twice the values. The pattern must be structurally
/// symmetric with every diagonal block present.
template <int B>
class SymBlockMatrix {
 public:
  using Block = BlockOf<B, B>;
  SymBlockMatrix() = default;
  /// From a full, structurally symmetric pattern with sorted rows (values zero, in single
  /// precision when `single`).
  SymBlockMatrix(int rows, std::vector<int> row_ptr, std::vector<int> col, bool single = false)
      : rows_(rows), row_ptr_(std::move(row_ptr)), col_(std::move(col)), single_(single) {
    src_.assign(col_.size(), 0);
    int stored = 0;
    // Upper blocks numbered row by row (so a row's stored blocks are contiguous), then each
    // lower block (i, j), j < i, points at the stored (j, i): row j was numbered first.
    for (int i = 0; i < rows_; ++i)
      for (int k = row_ptr_[i]; k < row_ptr_[i + 1]; ++k)
        if (col_[k] >= i) src_[k] = stored++;
    for (int i = 0; i < rows_; ++i)
      for (int k = row_ptr_[i]; k < row_ptr_[i + 1]; ++k) {
        const int j = col_[k];
        if (j >= i) continue;
        const int kt = find(j, i);
        src_[k] = kt >= 0 ? ~src_[kt] : 0;  // kt < 0: the pattern is not symmetric (asserted by tests)
      }
    if (single_)
      valf_.assign(static_cast<std::size_t>(B * B) * stored, 0.0f);
    else
      val_.assign(static_cast<std::size_t>(B * B) * stored, 0.0);
  }

  int rows() const { return rows_; }
  int cols() const { return rows_; }
  int nnz() const { return static_cast<int>(col_.size()); }  ///< blocks of the full pattern
  int stored_blocks() const { return static_cast<int>((single_ ? valf_.size() : val_.size()) / (B * B)); }
  bool single() const { return single_; }
  /// Index of the stored block of (i, i).
  int diagonal_index(int i) const { return src_[find(i, i)]; }
  /// Stored block s, in double, for either precision.
  Block stored_value(std::ptrdiff_t s) const { return single_ ? value_block<B, B>(valf_.data(), s) : value_block<B, B>(val_.data(), s); }
  /// Write stored block s (rounded to float in single precision).
  void store(std::ptrdiff_t s, const Block& b) {
    if (single_)
      Eigen::Map<Eigen::Matrix<float, B, B, Eigen::RowMajor>>(valf_.data() + B * B * s) = b.template cast<float>();
    else
      Eigen::Map<Block>(val_.data() + B * B * s) = b;
  }
  const std::vector<int>& row_ptr() const { return row_ptr_; }
  const std::vector<int>& col() const { return col_; }
  /// Per block of the pattern: stored index (>= 0, upper) or ~stored index of its transpose.
  const std::vector<int>& src() const { return src_; }
  std::vector<double>& values() { return val_; }
  const std::vector<double>& values() const { return val_; }
  /// Stored block s (upper triangle); double storage only.
  Eigen::Map<Block> stored(std::ptrdiff_t s) { return Eigen::Map<Block>(val_.data() + B * B * s); }
  BsrView<B, B> view() const {
    BsrView<B, B> v{rows_, rows_, row_ptr_.data(), col_.data(), single_ ? nullptr : val_.data(), src_.data()};
    if (single_) v.valf = valf_.data();
    return v;
  }
  /// Index of block (i, j) of the pattern or -1. O(log row length).
  int find(int i, int j) const {
    const auto first = col_.begin() + row_ptr_[i], last = col_.begin() + row_ptr_[i + 1];
    const auto it = std::lower_bound(first, last, j);
    return (it != last && *it == j) ? static_cast<int>(it - col_.begin()) : -1;
  }
  /// The diagonal block of row i (stored; every row holds it); double storage only.
  Eigen::Map<Block> diagonal(int i) { return stored(diagonal_index(i)); }
  std::size_t memory_bytes() const {
    return (row_ptr_.capacity() + col_.capacity() + src_.capacity()) * sizeof(int) + val_.capacity() * sizeof(double) +
           valf_.capacity() * sizeof(float);
  }
  Eigen::MatrixXd to_dense() const {
    Eigen::MatrixXd D = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(B) * rows_, static_cast<Eigen::Index>(B) * rows_);
    const auto v = view();
    for (int i = 0; i < rows_; ++i)
      for (int k = row_ptr_[i]; k < row_ptr_[i + 1]; ++k) D.template block<B, B>(B * i, B * col_[k]) = v.block(k);
    return D;
  }
  void clear() { *this = SymBlockMatrix(); }

 private:
  int rows_ = 0;
  std::vector<int> row_ptr_{0}, col_, src_;
  std::vector<double> val_;
  std::vector<float> valf_;
  bool single_ = false;
};

/// y = A x (y sized R * rows). Parallel over block rows.
template <int R, int C>
void spmv(const BsrView<R, C>& A, const double* x, double* y) {
#pragma omp parallel for schedule(static) if (A.rows > parallel_rows)
  for (int i = 0; i < A.rows; ++i) Eigen::Map<Eigen::Matrix<double, R, 1>>(y + R * i) = row_product(A, i, x);
}

/// r = f - A x. Parallel over block rows.
template <int R, int C>
void residual(const BsrView<R, C>& A, const double* f, const double* x, double* r) {
#pragma omp parallel for schedule(static) if (A.rows > parallel_rows)
  for (int i = 0; i < A.rows; ++i)
    Eigen::Map<Eigen::Matrix<double, R, 1>>(r + R * i) = Eigen::Map<const Eigen::Matrix<double, R, 1>>(f + R * i) - row_product(A, i, x);
}

/// y += A diag(s) x for a rectangular pattern (no one-triangle storage, no filter) whose
/// values are `val` (T: double, float or int16; products in double), with one scale per
/// column (`col_scale`, C * cols entries) or none (nullptr). Parallel over block rows.
template <int R, int C, class T>
void multiply_add(const BsrView<R, C>& A, const T* val, const double* x, double* y, const double* col_scale = nullptr) {
  using VecC = Eigen::Matrix<double, C, 1>;
#pragma omp parallel for schedule(static) if (A.rows > parallel_rows)
  for (int i = 0; i < A.rows; ++i) {
    Eigen::Matrix<double, R, 1> acc = Eigen::Matrix<double, R, 1>::Zero();
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
      const Eigen::Map<const VecC> xj(x + C * A.col[k]);
      if (col_scale)
        acc.noalias() += value_block<R, C>(val, k) * xj.cwiseProduct(Eigen::Map<const VecC>(col_scale + C * A.col[k]));
      else
        acc.noalias() += value_block<R, C>(val, k) * xj;
    }
    Eigen::Map<Eigen::Matrix<double, R, 1>>(y + R * i) += acc;
  }
}

/// Column-wise listing of a BSR pattern: for block column j, the blocks
/// (row[t], blk[t]) for t in [ptr[j], ptr[j+1]), by increasing row. Built once per
/// pattern for the Galerkin product (deterministic and parallel over coarse rows).
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
    const Eigen::Matrix<double, B, B> D = A.block(i, kd);
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
  /// Pattern of Ac (sorted rows; every row holds its diagonal; structurally symmetric),
  /// stored by its upper triangle, in single precision when `single`.
  static SymBlockMatrix<C> symbolic(const BsrView<B, B>& A, const BsrView<B, C>& P, const TransposeIndex& PT,
                                    bool single = false) {
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
    return SymBlockMatrix<C>(nc, std::move(ptr), std::move(col), single);
  }

  /// Ac's values (Ac from `symbolic` for these patterns of A and P, in the precision Ac
  /// stores). Only the upper blocks (J >= I) are formed, each in double and rounded once when
  /// stored, and the diagonal blocks are symmetrised (their (a, b) and (b, a) entries come
  /// from different sums), so Ac is exactly symmetric.
  static void numeric(const BsrView<B, B>& A, const BsrView<B, C>& P, const TransposeIndex& PT, SymBlockMatrix<C>& Ac) {
    using TBlock = Eigen::Matrix<double, C, B>;
    using CBlock = BlockOf<C, C>;
    const int nc = P.cols;
    const int* ac_ptr = Ac.row_ptr().data();
    const int* ac_col = Ac.col().data();
    const int* ac_src = Ac.src().data();
#pragma omp parallel if (nc > parallel_rows / 8)
    {
      std::vector<int> slot(A.rows, -1), pos(nc, -1), fine;
      std::vector<TBlock, Eigen::aligned_allocator<TBlock>> T;
      std::vector<CBlock, Eigen::aligned_allocator<CBlock>> out;  // row I's stored blocks, in order
#pragma omp for schedule(dynamic, 64)
      for (int I = 0; I < nc; ++I) {
        fine.clear();
        // Row I of P^T A, in the order the fine columns are first met (fixed).
        for (int t = PT.ptr[I]; t < PT.ptr[I + 1]; ++t) {
          const int i = PT.row[t];
          const Eigen::Matrix<double, C, B> PiT = P.stored(PT.blk[t]).transpose();
          for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
            const int j = A.col[k];
            if (slot[j] < 0) {
              slot[j] = static_cast<int>(fine.size());
              fine.push_back(j);
              if (T.size() < fine.size()) T.resize(fine.size());
              T[slot[j]].setZero();
            }
            T[slot[j]].noalias() += PiT * A.block(i, k);
          }
        }
        // Stored (upper) blocks of row I, numbered consecutively from its diagonal block;
        // the lower ones are the transposes of other rows'.
        int first = -1, count = 0;
        for (int k = ac_ptr[I]; k < ac_ptr[I + 1]; ++k) {
          if (ac_src[k] < 0) {
            pos[ac_col[k]] = -1;
            continue;
          }
          if (first < 0) first = ac_src[k];
          pos[ac_col[k]] = ac_src[k] - first;
          ++count;
        }
        if (static_cast<int>(out.size()) < count) out.resize(count);
        for (int t = 0; t < count; ++t) out[t].setZero();
        for (std::size_t s = 0; s < fine.size(); ++s) {
          const int j = fine[s];
          for (int k = P.row_ptr[j]; k < P.row_ptr[j + 1]; ++k) {
            const int dst = pos[P.col[k]];
            if (dst >= 0) out[dst].noalias() += T[s] * P.stored(k);
          }
          slot[j] = -1;
        }
        out[0] = (0.5 * (out[0] + out[0].transpose())).eval();  // the diagonal block (col I) comes first
        for (int t = 0; t < count; ++t) Ac.store(first + t, out[t]);
      }
    }
  }
};

}  // namespace weft::linear
