#include "framework/block_csr.hpp"

#include <algorithm>
#include <bit>
#include <cstdint>

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
#pragma omp parallel for schedule(static) if (n >= 1024)
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

Colouring::Colouring(std::span<const int> ptr, std::span<const int> ids, int num_vertices, int chunk) {
  WEFT_ASSERT(chunk >= 1, "chunk size {} must be positive", chunk);
  const int n = static_cast<int>(ptr.size()) - 1;
  const int nq = (n + chunk - 1) / chunk;  // chunk q holds elements [q chunk, min(n, (q + 1) chunk))
  auto first = [&](int q) { return ptr[static_cast<size_t>(q) * chunk]; };
  auto last = [&](int q) { return ptr[std::min(n, (q + 1) * chunk)]; };
  // used[v * words + w]: bit b set when vertex v already belongs to a chunk of colour
  // 64 w + b. The word count grows if some vertex needs more than 64 colours.
  int words = 1;
  std::vector<std::uint64_t> used(num_vertices, 0);
  std::vector<int> colour(nq);
  int num_colours = 0;
  for (int q = 0; q < nq; ++q) {
    int c = -1;
    for (int w = 0; c < 0; ++w) {
      if (w == words) {  // every colour so far is taken around this chunk: widen
        std::vector<std::uint64_t> wider(static_cast<size_t>(num_vertices) * (words + 1), 0);
        for (int v = 0; v < num_vertices; ++v)
          std::copy_n(used.begin() + static_cast<size_t>(v) * words, words, wider.begin() + static_cast<size_t>(v) * (words + 1));
        used.swap(wider);
        ++words;
      }
      std::uint64_t taken = 0;
      for (int i = first(q); i < last(q); ++i) taken |= used[static_cast<size_t>(ids[i]) * words + w];
      if (~taken) c = 64 * w + std::countr_one(taken);
    }
    for (int i = first(q); i < last(q); ++i) used[static_cast<size_t>(ids[i]) * words + c / 64] |= std::uint64_t{1} << (c % 64);
    colour[q] = c;
    num_colours = std::max(num_colours, c + 1);
  }
  // Chunks by colour, ascending within a colour.
  n_ = n;
  chunk_ = chunk;
  ptr_.assign(num_colours + 1, 0);
  for (int q = 0; q < nq; ++q) ++ptr_[colour[q] + 1];
  for (int c = 0; c < num_colours; ++c) ptr_[c + 1] += ptr_[c];
  chunks_.resize(nq);
  std::vector<int> fill(ptr_.begin(), ptr_.end() - 1);
  for (int q = 0; q < nq; ++q) chunks_[fill[colour[q]]++] = q;
}

Colouring Colouring::uniform(std::span<const int> ids, int stencil, int num_vertices, int chunk) {
  std::vector<int> ptr(ids.size() / stencil + 1);
  for (size_t s = 0; s < ptr.size(); ++s) ptr[s] = static_cast<int>(s) * stencil;
  return Colouring(ptr, ids, num_vertices, chunk);
}

ElementBuffer::Slot::Slot(ElementBuffer& buf, int group, int e) : buf_(buf) {
  const detail::PlanMaps& m = *buf.maps_;
  k_ = m.stencil[group];
  first_ = m.first_block[group] + static_cast<size_t>(e) * k_ * k_;
  if (buf.mode_ == AssemblyMode::stored) {
    data_ = buf.data_.data() + 9 * first_;
  } else {
    WEFT_ASSERT(k_ <= max_stencil, "stencil {} exceeds ElementBuffer::max_stencil", k_);
    WEFT_ASSERT(buf.target_, "{}", "ElementBuffer: write outside start() / finish()");
    data_ = local_.data();
    std::fill_n(data_, 9 * k_ * k_, 0.0);
  }
}

ElementBuffer::Slot::~Slot() {
  if (buf_.mode_ != AssemblyMode::direct) return;
  const int* dst = buf_.maps_->destination.data() + first_;
  double* values = buf_.target_->values().data();
  for (int q = 0; q < k_ * k_; ++q) {
    double* out = values + 9 * static_cast<size_t>(dst[q]);
    const double* in = data_ + 9 * q;
    for (int r = 0; r < 9; ++r) out[r] += in[r];
  }
}

void ElementBuffer::start(BlockCsr& out) {
  WEFT_ASSERT(maps_, "{}", "ElementBuffer: not made by AssemblyPlan::make_buffer");
  WEFT_ASSERT(out.num_blocks() == maps_->num_blocks, "{}", "matrix does not have the plan's pattern");
  target_ = &out;
  if (mode_ == AssemblyMode::direct) out.set_zero();
}

void ElementBuffer::finish() {
  WEFT_ASSERT(target_, "{}", "ElementBuffer::finish without start");
  if (mode_ == AssemblyMode::stored) gather_into(*target_);
  target_ = nullptr;
}

void ElementBuffer::gather_into(BlockCsr& out) const {
  const detail::PlanMaps& m = *maps_;
  const int nb = out.num_blocks();
  WEFT_ASSERT(mode_ == AssemblyMode::stored, "{}", "gather needs a stored-mode buffer");
  WEFT_ASSERT(nb == m.num_blocks, "{}", "matrix does not have the plan's pattern");
  const double* src = data_.data();
  double* dst = out.values().data();
  parallel_range(nb, [&](int b) {
    double acc[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    for (size_t s = m.src_ptr[b]; s < m.src_ptr[b + 1]; ++s) {
      const double* blk = src + 9 * m.src[s];
      for (int q = 0; q < 9; ++q) acc[q] += blk[q];
    }
    for (int q = 0; q < 9; ++q) dst[9 * static_cast<size_t>(b) + q] = acc[q];
  });
}

Eigen::Map<Block3> ElementBuffer::block(int group, int e, int a, int b) {
  WEFT_ASSERT(mode_ == AssemblyMode::stored, "{}", "ElementBuffer::block needs stored mode: use slot()");
  const int k = maps_->stencil[group];
  return Eigen::Map<Block3>(data_.data() + 9 * (maps_->first_block[group] + static_cast<size_t>(e) * k * k + a * k + b));
}

void ElementBuffer::zero_group(int group) {
  if (mode_ == AssemblyMode::direct) return;
  const size_t begin = 9 * maps_->first_block[group];
  const size_t end = group + 1 < static_cast<int>(maps_->first_block.size()) ? 9 * maps_->first_block[group + 1] : data_.size();
  std::fill(data_.begin() + begin, data_.begin() + end, 0.0);
}

int AssemblyPlan::add_group(int stencil_size, std::span<const int> vertex_ids) {
  WEFT_ASSERT(!finalized_, "{}", "add_group after finalize: rebuild the plan for a new topology");
  WEFT_ASSERT(stencil_size > 0 && vertex_ids.size() % stencil_size == 0, "bad stencil {}", stencil_size);
  stencil_.push_back(stencil_size);
  ids_.emplace_back(vertex_ids.begin(), vertex_ids.end());
  return static_cast<int>(stencil_.size()) - 1;
}

void AssemblyPlan::replace_group(int group, std::span<const int> vertex_ids) {
  WEFT_ASSERT(group >= 0 && group < num_groups(), "no group {}", group);
  WEFT_ASSERT(vertex_ids.size() % stencil_[group] == 0, "{} ids for stencil size {}", vertex_ids.size(), stencil_[group]);
  ids_[group].assign(vertex_ids.begin(), vertex_ids.end());
  finalized_ = false;
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
  pattern_.values() = {};  // the structure only (pattern() hands out matrices)
  cols = {};

  auto maps = std::make_shared<detail::PlanMaps>();
  maps->stencil = stencil_;
  maps->num_blocks = pattern_.num_blocks();
  size_t blocks = 0;
  for (size_t g = 0; g < ids_.size(); ++g) {
    maps->first_block.push_back(blocks);
    blocks += ids_[g].size() * stencil_[g];  // (#elements * k) * k
  }
  maps->destination.resize(blocks);
  for (size_t g = 0; g < ids_.size(); ++g) {
    const int k = stencil_[g];
    const size_t ne = ids_[g].size() / k;
    int* dst = maps->destination.data() + maps->first_block[g];
#pragma omp parallel for schedule(static) if (ne >= 1024)
    for (size_t e = 0; e < ne; ++e)
      for (int a = 0; a < k; ++a)
        for (int b = 0; b < k; ++b) dst[e * k * k + a * k + b] = pattern_.find(ids_[g][e * k + a], ids_[g][e * k + b]);
    maps->colouring.push_back(Colouring::uniform(ids_[g], k, num_vertices));
  }
  maps_ = std::move(maps);
  finalized_ = true;
}

ElementBuffer AssemblyPlan::make_buffer(AssemblyMode mode) {
  WEFT_ASSERT(finalized_, "{}", "call finalize() before make_buffer()");
  if (mode == AssemblyMode::stored && maps_->src_ptr.empty()) {
    // Gather lists: counting sort of the element blocks by matrix block, in element order,
    // so that each sum has a fixed order.
    const std::vector<int>& dst = maps_->destination;
    maps_->src_ptr.assign(pattern_.num_blocks() + 1, 0);
    for (int d : dst) ++maps_->src_ptr[d + 1];
    for (size_t m = 0; m + 1 < maps_->src_ptr.size(); ++m) maps_->src_ptr[m + 1] += maps_->src_ptr[m];
    maps_->src.resize(dst.size());
    std::vector<size_t> fill(maps_->src_ptr.begin(), maps_->src_ptr.end() - 1);
    for (size_t q = 0; q < dst.size(); ++q) maps_->src[fill[dst[q]]++] = q;
  }
  ElementBuffer b;
  b.mode_ = mode;
  b.maps_ = maps_;
  if (mode == AssemblyMode::stored) b.data_.assign(9 * maps_->destination.size(), 0.0);
  return b;
}

void AssemblyPlan::gather(const ElementBuffer& buffer, BlockCsr& out) const {
  buffer.gather_into(out);
}

}  // namespace weft
