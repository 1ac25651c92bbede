#pragma once
/// \file block_csr.hpp
/// Sparse matrices with 3x3 blocks, and the assembly plan that fills them.
///
/// The symmetric sparsity pattern is built once per topology (`AssemblyPlan::finalize`)
/// and reused for every evaluation. Element kernels write their local matrices through an
/// `ElementBuffer`: by default each element adds its blocks straight into the matrix, the
/// elements visited colour by colour so that concurrent writers never share a vertex
/// (`AssemblyMode::direct`); optionally every element keeps a private slot and a gather sums
/// them (`AssemblyMode::stored`). Either way the assembly needs no locks or atomics and is
/// bitwise deterministic whatever the number of threads.
#include <Eigen/Core>
#include <Eigen/SparseCore>
#ifdef _OPENMP
#include <omp.h>
#endif

#include <algorithm>
#include <array>
#include <memory>
#include <ranges>
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
  /// diag_value keeps each row's scale, sigma_i = tr(A_ii)/3 (the prefilter's Sigma, methods/multigrid
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

/// Classes of elements that may add into a matrix at the same time without touching the same
/// block. The elements are cut into chunks of `chunk` consecutive elements, and the chunks
/// are coloured (greedy first-fit in chunk order) so that the chunks of one colour share no
/// vertex. A writer takes a whole chunk and visits its elements in ascending order, so
/// consecutive elements of a mesh's numbering, which share vertices, hit the same matrix
/// blocks while they are in cache (element-wise colouring, chunk = 1, sweeps the whole
/// matrix once per colour with no reuse within a sweep: the refactored bending path took
/// twice as long per vertex at 6561 vertices as at 121). Deterministic, and the colours,
/// chunks and elements are visited in a fixed order, so every matrix block sums its
/// contributions in the same order whatever the number of threads. On the generated sheets
/// (20^2 to 300^2 cells, regular and irregular), chunks of 32 take 3-4 colours for triangles
/// and 5-8 for hinges; element-wise, 7-9 and 14-18.
class Colouring {
 public:
  static constexpr int default_chunk = 32;
  Colouring() = default;
  /// Element s touches the vertices ids[ptr[s] .. ptr[s+1]).
  Colouring(std::span<const int> ptr, std::span<const int> ids, int num_vertices, int chunk = default_chunk);
  /// Elements of a fixed stencil size k: element s touches ids[k s .. k s + k).
  static Colouring uniform(std::span<const int> ids, int stencil, int num_vertices, int chunk = default_chunk);
  int num_elements() const { return n_; }
  int num_colours() const { return static_cast<int>(ptr_.size()) - 1; }
  int chunk_size() const { return chunk_; }
  /// The chunks of colour c: k in [first_chunk(c), end_chunk(c)), for `chunk(k)`.
  int first_chunk(int c) const { return ptr_[c]; }
  int end_chunk(int c) const { return ptr_[c + 1]; }
  /// The elements of the k-th chunk in colour order: consecutive, ascending.
  std::ranges::iota_view<int, int> chunk(int k) const {
    const int q = chunks_[k];
    return std::views::iota(q * chunk_, std::min(n_, (q + 1) * chunk_));
  }
  /// How many elements colour c holds.
  int colour_size(int c) const {
    int s = 0;
    for (int k = first_chunk(c); k < end_chunk(c); ++k) s += static_cast<int>(chunk(k).size());
    return s;
  }

 private:
  int n_ = 0, chunk_ = 1;
  std::vector<int> chunks_, ptr_{0};  // chunk ids by colour; colour c: chunks_[ptr_[c] .. ptr_[c+1])
};

/// How element Hessians reach the matrix.
///  - `direct` (default): every element adds its blocks straight into the matrix, colour by
///    colour (no element storage: the assembly needs no memory beyond the matrix).
///  - `stored`: every element writes a private slot, and a gather sums the slots per matrix
///    block (fully parallel, but 4.75 kB per cloth vertex of element storage).
/// Both are bitwise deterministic across thread counts; they agree to round-off.
enum class AssemblyMode { direct, stored };

class AssemblyPlan;

namespace detail {
/// The immutable part of a finalised plan, shared by the plan and its buffers (so a buffer
/// stays valid when the plan that made it moves).
struct PlanMaps {
  int num_blocks = 0;                 // of the pattern
  std::vector<int> stencil;           // per group
  std::vector<size_t> first_block;    // per group: index of its first element block
  std::vector<int> destination;       // per element block: index of the matrix block
  std::vector<Colouring> colouring;   // per group
  // Stored mode: for matrix block m, element blocks src[src_ptr[m] .. src_ptr[m+1]).
  std::vector<size_t> src_ptr, src;
};
}  // namespace detail

/// Where models write their local element Hessians during one assembly:
///
///     buf.start(A);                                 // A has the plan's pattern
///     buf.for_each(group, [&](int e) { buf.set(group, e, local(e)); });
///     buf.finish();                                 // A = sum of element matrices
///
/// Element e of group g has a k x k array of 3x3 blocks (k = its stencil size), block-major,
/// row-major blocks. Writes must go through `for_each` (colour by colour in direct mode):
/// two elements sharing a vertex are never written at the same time. An element that is not
/// written contributes nothing in direct mode and keeps its last value in stored mode
/// (`zero_group` clears a group for models that skip elements).
class ElementBuffer {
 public:
  static constexpr int max_stencil = 6;
  /// The local matrix of one element. In direct mode it lives on the stack and is added to
  /// the matrix when the slot goes out of scope; in stored mode it is the element's storage.
  class Slot {
   public:
    Slot(const Slot&) = delete;
    Slot& operator=(const Slot&) = delete;
    ~Slot();
    /// Block (a, b): 9 doubles, row-major.
    Eigen::Map<Block3> block(int a, int b) { return Eigen::Map<Block3>(data_ + 9 * (a * k_ + b)); }
    /// The k*k blocks, contiguous and block-major.
    double* data() { return data_; }
    int stencil_size() const { return k_; }

   private:
    friend class ElementBuffer;
    Slot(ElementBuffer& buf, int group, int e);
    ElementBuffer& buf_;
    size_t first_;  // index of the element's first block
    int k_;
    double* data_;
    std::array<double, 9 * max_stencil * max_stencil> local_;  // direct mode only
  };

  ElementBuffer() = default;
  AssemblyMode mode() const { return mode_; }
  /// Begin an assembly into `out`, which must have the plan's pattern (direct mode zeroes it).
  void start(BlockCsr& out);
  /// End it: stored mode sums the element slots into the matrix given to `start`.
  void finish();

  Slot slot(int group, int e) { return Slot(*this, group, e); }
  /// Copy a dense (3k x 3k) local matrix into element e of group g.
  template <class Derived>
  void set(int group, int e, const Eigen::MatrixBase<Derived>& local) {
    Slot s = slot(group, e);
    for (int a = 0; a < s.k_; ++a)
      for (int b = 0; b < s.k_; ++b) s.block(a, b) = local.template block<3, 3>(3 * a, 3 * b);
  }
  /// Stored mode: writable block (a, b) of element e in group g (direct mode has no storage).
  Eigen::Map<Block3> block(int group, int e, int a, int b);
  /// Zero every local matrix of group g (stored mode; nothing to do in direct mode).
  void zero_group(int group);
  int stencil_size(int group) const { return maps_->stencil[group]; }
  /// The plan's colouring of group g (chunks of one colour share no vertex).
  const Colouring& colouring(int group) const { return maps_->colouring[group]; }

  /// Call f(e) for every element of `c`: in parallel, and in direct mode one colour at a
  /// time, each chunk of the colour by one writer in element order, so that no two
  /// concurrent writers share a vertex.
  template <class F>
  void for_each(const Colouring& c, F&& f) const {
    if (mode_ == AssemblyMode::stored) {
      parallel_range(c.num_elements(), [&f](int e) { f(e); });
      return;
    }
    for (int k = 0; k < c.num_colours(); ++k) {
      const int q0 = c.first_chunk(k), nq = c.end_chunk(k) - q0;
      auto chunk = [&f, &c, q0](int q) {
        for (int e : c.chunk(q0 + q)) f(e);
      };
      if (nq > 1 && nq * c.chunk_size() >= 256)
        parallel_range(nq, chunk, 1);
      else
        for (int q = 0; q < nq; ++q) chunk(q);
    }
  }
  /// Every element of group g, each writing its own slot.
  template <class F>
  void for_each(int group, F&& f) const {
    for_each(colouring(group), std::forward<F>(f));
  }

 private:
  friend class AssemblyPlan;
  void gather_into(BlockCsr& out) const;
  /// g(i) for i in [0, n): in parallel when worth a team (n >= min_n; small ranges, or a
  /// caller already inside a parallel region, run inline and never touch the OpenMP runtime).
  template <class G>
  static void parallel_range(int n, G&& g, int min_n = 256) {
#ifdef _OPENMP
    if (n >= min_n && omp_get_max_threads() > 1 && !omp_in_parallel()) {
#pragma omp parallel for schedule(static)
      for (int i = 0; i < n; ++i) g(i);
      return;
    }
#endif
    for (int i = 0; i < n; ++i) g(i);
  }
  AssemblyMode mode_ = AssemblyMode::direct;
  std::shared_ptr<const detail::PlanMaps> maps_;
  BlockCsr* target_ = nullptr;
  std::vector<double> data_;  // stored mode: every element block
};

/// The map from element blocks to matrix blocks, built once per topology.
class AssemblyPlan {
 public:
  /// Register `vertex_ids.size() / stencil_size` elements; returns the group id that the
  /// model passes back to `ElementBuffer`. Only before `finalize`.
  int add_group(int stencil_size, std::span<const int> vertex_ids);
  /// Replace the elements of group g (same stencil size), e.g. the contact pairs of a new
  /// step; the plan must be finalised again (and its buffers and matrices remade) before
  /// the next assembly. Other groups keep their elements and ids.
  void replace_group(int group, std::span<const int> vertex_ids);
  /// Build the pattern of a #vertices x #vertices block matrix, the element-to-matrix map
  /// and a colouring of each group.
  void finalize(int num_vertices);
  bool finalized() const { return finalized_; }
  int num_vertices() const { return pattern_.block_rows(); }

  /// A new matrix with the plan's pattern, values zero.
  BlockCsr pattern() const {
    BlockCsr m = pattern_;
    m.values().assign(9 * static_cast<size_t>(m.num_blocks()), 0.0);
    return m;
  }
  /// The pattern alone (row pointers and columns; `values()` is empty): the plan keeps no
  /// matrix-sized array of its own.
  const BlockCsr& structure() const { return pattern_; }
  /// A buffer for this plan (allocate once, reuse). Stored mode allocates every element's
  /// slot and the gather lists on first use.
  ElementBuffer make_buffer(AssemblyMode mode = AssemblyMode::direct);
  /// Stored mode: out = sum of all element blocks (out must have the plan's pattern).
  /// Parallel over matrix blocks; every matrix block sums its contributions in a fixed order.
  void gather(const ElementBuffer& buffer, BlockCsr& out) const;
  int num_groups() const { return static_cast<int>(stencil_.size()); }

 private:
  bool finalized_ = false;
  std::vector<int> stencil_;
  std::vector<std::vector<int>> ids_;
  BlockCsr pattern_;
  std::shared_ptr<detail::PlanMaps> maps_;
};

}  // namespace weft
