#include "framework/block_csr.hpp"

#include <algorithm>

#include "framework/error.hpp"

namespace weft {

BlockCsr::BlockCsr(const std::vector<std::vector<int>>& columns) {
  const int n = static_cast<int>(columns.size());
  row_ptr_.assign(n + 1, 0);
  diag_.assign(n, -1);
  for (int i = 0; i < n; ++i) {
    std::vector<int> c = columns[i];
    c.push_back(i);
    std::sort(c.begin(), c.end());
    c.erase(std::unique(c.begin(), c.end()), c.end());
    for (int j : c) {
      WEFT_ASSERT(j >= 0 && j < n, "column {} out of range", j);
      if (j == i) diag_[i] = static_cast<int>(col_.size());
      col_.push_back(j);
    }
    row_ptr_[i + 1] = static_cast<int>(col_.size());
  }
  values_.assign(9 * col_.size(), 0.0);
}

int BlockCsr::find(int i, int j) const {
  const auto first = col_.begin() + row_ptr_[i], last = col_.begin() + row_ptr_[i + 1];
  const auto it = std::lower_bound(first, last, j);
  return (it != last && *it == j) ? static_cast<int>(it - col_.begin()) : -1;
}

void BlockCsr::set_zero() { std::fill(values_.begin(), values_.end(), 0.0); }

void BlockCsr::multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  WEFT_ASSERT(x.size() == rows(), "size mismatch {} vs {}", x.size(), rows());
  y.resize(rows());
  const int n = block_rows();
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3d acc = Eigen::Vector3d::Zero();
    for (int k = row_ptr_[i]; k < row_ptr_[i + 1]; ++k) acc.noalias() += block(k) * x.segment<3>(3 * col_[k]);
    y.segment<3>(3 * i) = acc;
  }
}

void BlockCsr::add_diagonal(const Eigen::VectorXd& d) {
  for (int i = 0; i < block_rows(); ++i)
    for (int k = 0; k < 3; ++k) block(diag_[i])(k, k) += d[3 * i + k];
}

void BlockCsr::scale(double s) {
  for (double& v : values_) v *= s;
}

void BlockCsr::filter_rows(const std::vector<unsigned char>& fixed, double diag_value) {
  const int n = block_rows();
  for (int i = 0; i < n; ++i)
    for (int k = row_ptr_[i]; k < row_ptr_[i + 1]; ++k)
      if ((fixed[i] || fixed[col_[k]]) && !(diag_value < 0 && k == diag_[i])) block(k).setZero();
  for (int i = 0; i < n; ++i)
    if (fixed[i]) block(diag_[i]) = (diag_value < 0 ? block(diag_[i]).trace() / 3.0 : diag_value) * Block3::Identity();
}

double BlockCsr::asymmetry() const {
  double num = 0, den = 0;
  for (int i = 0; i < block_rows(); ++i)
    for (int k = row_ptr_[i]; k < row_ptr_[i + 1]; ++k) {
      const int kt = find(col_[k], i);
      const Block3 t = kt < 0 ? Block3::Zero() : Block3(block(kt).transpose());
      num += (block(k) - t).squaredNorm();
      den += block(k).squaredNorm();
    }
  return den > 0 ? std::sqrt(num / den) : 0.0;
}

Eigen::SparseMatrix<double> BlockCsr::to_sparse(bool lower_only) const {
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(9 * col_.size());
  for (int i = 0; i < block_rows(); ++i)
    for (int k = row_ptr_[i]; k < row_ptr_[i + 1]; ++k)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
          const int r = 3 * i + a, c = 3 * col_[k] + b;
          if (!lower_only || r >= c) t.emplace_back(r, c, block(k)(a, b));
        }
  Eigen::SparseMatrix<double> m(rows(), rows());
  m.setFromTriplets(t.begin(), t.end());
  return m;
}

Eigen::MatrixXd BlockCsr::to_dense() const {
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(rows(), rows());
  for (int i = 0; i < block_rows(); ++i)
    for (int k = row_ptr_[i]; k < row_ptr_[i + 1]; ++k) d.block<3, 3>(3 * i, 3 * col_[k]) += block(k);
  return d;
}

Eigen::Map<Block3> ElementBuffer::block(int group, int e, int a, int b) {
  const int k = stencil_[group];
  return Eigen::Map<Block3>(data_.data() + offset_[group] + 9 * (static_cast<size_t>(e) * k * k + a * k + b));
}

void ElementBuffer::zero_group(int group) {
  const size_t end = group + 1 < static_cast<int>(offset_.size()) ? offset_[group + 1] : data_.size();
  std::fill(data_.begin() + offset_[group], data_.begin() + end, 0.0);
}

int AssemblyPlan::add_group(int stencil_size, std::span<const int> vertex_ids) {
  WEFT_ASSERT(!finalized_, "{}", "add_group after finalize: rebuild the plan for a new topology");
  WEFT_ASSERT(stencil_size > 0 && vertex_ids.size() % stencil_size == 0, "bad stencil {}", stencil_size);
  stencil_.push_back(stencil_size);
  ids_.emplace_back(vertex_ids.begin(), vertex_ids.end());
  return static_cast<int>(stencil_.size()) - 1;
}

void AssemblyPlan::finalize(int num_vertices) {
  std::vector<std::vector<int>> cols(num_vertices);
  for (size_t g = 0; g < ids_.size(); ++g) {
    const int k = stencil_[g];
    for (size_t e = 0; e < ids_[g].size() / k; ++e)
      for (int a = 0; a < k; ++a)
        for (int b = 0; b < k; ++b) {
          const int i = ids_[g][e * k + a], j = ids_[g][e * k + b];
          WEFT_ASSERT(i >= 0 && i < num_vertices && j >= 0 && j < num_vertices, "vertex id {} or {} out of range", i, j);
          cols[i].push_back(j);
        }
  }
  pattern_ = BlockCsr(cols);

  // Gather lists: counting sort of (matrix block, buffer block) pairs by matrix block,
  // visiting elements in registration order, so each sum has a fixed order.
  std::vector<std::pair<int, size_t>> pairs;
  size_t base = 0;
  for (size_t g = 0; g < ids_.size(); ++g) {
    const int k = stencil_[g];
    const size_t ne = ids_[g].size() / k;
    for (size_t e = 0; e < ne; ++e)
      for (int a = 0; a < k; ++a)
        for (int b = 0; b < k; ++b)
          pairs.emplace_back(pattern_.find(ids_[g][e * k + a], ids_[g][e * k + b]), base + e * k * k + a * k + b);
    base += ne * k * k;
  }
  src_ptr_.assign(pattern_.num_blocks() + 1, 0);
  for (const auto& p : pairs) ++src_ptr_[p.first + 1];
  for (size_t m = 0; m + 1 < src_ptr_.size(); ++m) src_ptr_[m + 1] += src_ptr_[m];
  src_.resize(pairs.size());
  std::vector<size_t> fill(src_ptr_.begin(), src_ptr_.end() - 1);
  for (const auto& p : pairs) src_[fill[p.first]++] = p.second;
  finalized_ = true;
}

ElementBuffer AssemblyPlan::make_buffer() const {
  WEFT_ASSERT(finalized_, "{}", "call finalize() before make_buffer()");
  ElementBuffer b;
  b.stencil_ = stencil_;
  size_t off = 0;
  for (size_t g = 0; g < ids_.size(); ++g) {
    b.offset_.push_back(off);
    off += 9 * ids_[g].size() * stencil_[g];  // (#elements * k) * k blocks of 9
  }
  b.data_.assign(off, 0.0);
  return b;
}

void AssemblyPlan::gather(const ElementBuffer& buffer, BlockCsr& out) const {
  WEFT_ASSERT(out.num_blocks() == pattern_.num_blocks(), "{}", "matrix does not have the plan's pattern");
  const int nb = pattern_.num_blocks();
  const double* src = buffer.data_.data();
  double* dst = out.values().data();
#pragma omp parallel for schedule(static)
  for (int m = 0; m < nb; ++m) {
    double acc[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    for (size_t s = src_ptr_[m]; s < src_ptr_[m + 1]; ++s) {
      const double* blk = src + 9 * src_[s];
      for (int q = 0; q < 9; ++q) acc[q] += blk[q];
    }
    for (int q = 0; q < 9; ++q) dst[9 * m + q] = acc[q];
  }
}

}  // namespace weft
