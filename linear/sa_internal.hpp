#pragma once
/// \file sa_internal.hpp
/// Internal to the translation units of `SaAmg` (linear/sa_*.cpp, linear/sa_amg.cpp): the block
/// aliases, the block lookup, and one level of the hierarchy as the setup builds it and the
/// cycle reads it. Not installed for users; include linear/sa_amg.hpp.
#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <type_traits>
#include <vector>

#include "linear/bsr.hpp"
#include "linear/sa_amg.hpp"

namespace weft::linear::sa_impl {

template <int B>
using Mat = Eigen::Matrix<double, B, B>;
template <int B>
using Vec = Eigen::Matrix<double, B, 1>;

/// Index of block (i, j) of a view, -1 if absent.
template <int R, int C>
int find_block(const BsrView<R, C>& A, int i, int j) {
  const int* first = A.col + A.row_ptr[i];
  const int* last = A.col + A.row_ptr[i + 1];
  const int* it = std::lower_bound(first, last, j);
  return (it != last && *it == j) ? static_cast<int>(it - A.col) : -1;
}

/// One level: its operator, smoother data, and the transfer to the next level.
template <int B>
struct Level {
  static constexpr int block = B;
  BsrView<B, B> external;       // the caller's matrix (fine level, reuse none or aggregates)
  // Galerkin result (coarse: symmetric, upper triangle stored) or private copy (fine, frozen or step).
  std::conditional_t<(B == 6), SymBlockMatrix<6>, BlockMatrix<B, B>> own;
  bool uses_external = false;
  BsrView<B, B> A() const { return uses_external ? external : own.view(); }
  int n() const { return uses_external ? external.rows : own.rows(); }

  std::vector<double> Dinv;     // n blocks B x B (setup; freed when Dinvf holds them)
  std::vector<float> Dinvf;     // single_block_inverses: the smoother's copy
  // Neither (after the setup): the smoother solves with A's diagonal blocks (fine level,
  // fine_inverses_on_the_fly).
  double ritz = 0, lambda = 0;

  // Coarsening structure (kept under reuse = aggregates).
  std::vector<std::uint8_t> strong, special;
  std::vector<std::uint8_t> filter;  // theta != aggregation_theta: the smoothing filter's strong flags
  sa::Aggregates aggs;
  int num_special = 0;
  int sheet_splits = 0;  // aggregates added by split_sheets
  int sheet_merges = 0;  // aggregates removed by split_merge
  bool reordered = false;  // aggregates renumbered (aggregate_order)
  BlockMatrix<B, 6> P;           // pattern; its values are freed when Pq holds them
  std::vector<int> kept_ptr, kept_col;  // a truncated P's pattern, kept for reuse = aggregates
  std::vector<std::int16_t> Pq;  // prolongator_storage fixed16: P = Pq diag(Pscale)
  std::vector<double> Pscale;    // one scale per coarse dof
  std::vector<int> rchunks;      // row chunks of the restriction P^T r (`restriction_chunks`)
  std::vector<std::uint8_t> dummy;  // per coarse dof
  int deficient = 0;
  bool coarsest = false;

  // Coarsest solve.
  int direct = 0;  // 0: smoother only, 1: LLT, 2: LDLT
  Eigen::LLT<Eigen::MatrixXd> llt;
  Eigen::LDLT<Eigen::MatrixXd> ldlt;

  // Work vectors (apply is const; one apply at a time).
  // f, x: the level's right-hand side and solution (coarse levels); d: the smoother's
  // correction, also the residual restricted to the next level.
  mutable Eigen::VectorXd f, x, d;

  std::size_t memory_bytes() const {
    auto vb = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    std::size_t m = own.memory_bytes() + vb(Dinv) + vb(Dinvf) + vb(strong) + vb(filter) + vb(special) + vb(aggs.node_agg) +
                    P.memory_bytes() + vb(kept_ptr) + vb(kept_col) + vb(Pq) + vb(Pscale) + vb(rchunks) + vb(dummy);
    m += sizeof(double) * (f.size() + x.size() + d.size());
    if (direct == 1) m += sizeof(double) * llt.matrixLLT().size();
    if (direct == 2) m += sizeof(double) * (ldlt.matrixLDLT().size() + 2 * ldlt.rows());
    return m;
  }
};

}  // namespace weft::linear::sa_impl

namespace weft::linear {

// The SA translation units use these unqualified.
using sa_impl::find_block;
using sa_impl::Level;
template <int B>
using Mat = sa_impl::Mat<B>;
template <int B>
using Vec = sa_impl::Vec<B>;

struct SaAmg::Impl {
  std::unique_ptr<Level<3>> fine = std::make_unique<Level<3>>();
  std::vector<Level<6>> coarse;  // reserved to max_levels: references stay valid
  bool built = false;
  int fine_rows = -1, fine_nnz = -1;
  std::uint64_t fine_pattern = 0;  // fingerprint of the fine matrix's pattern (reuse needs the same one)
  double nnz_scalar_total = 0, rows_scalar_total = 0;
};

}  // namespace weft::linear
