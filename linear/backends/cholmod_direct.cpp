#include "linear/backends/cholmod_direct.hpp"

#include <cholmod.h>
#include <dlfcn.h>
#include <fmt/format.h>

#include <filesystem>
#include <vector>

#include "framework/timers.hpp"

namespace weft::linear {

/// CHOLMOD's workspace, the CSC lower triangle and the factor. Not copyable (CHOLMOD
/// objects), owned through a unique_ptr.
struct CholmodDirect::Impl {
  cholmod_common c{};
  cholmod_sparse* lower = nullptr;  // stype = -1: lower triangle, sorted, packed
  cholmod_factor* L = nullptr;
  cholmod_dense *X = nullptr, *Y = nullptr, *E = nullptr;  // cholmod_solve2 workspace
  std::vector<int> source;          // lower->x[p] = A.values()[source[p]]
  int failed_column = -1;           // not positive definite at this column (-1: none)
  double rcond = 0;
  bool analyzed = false, factorized = false;

  Impl() {
    cholmod_start(&c);
    c.supernodal = CHOLMOD_SUPERNODAL;  // forced: the supernodal (BLAS-3) LL^T
    c.print = 0;                        // failures are returned as Status, not printed
    c.error_handler = nullptr;
  }
  ~Impl() {
    release();
    cholmod_finish(&c);
  }
  void release() {
    cholmod_free_dense(&X, &c);
    cholmod_free_dense(&Y, &c);
    cholmod_free_dense(&E, &c);
    cholmod_free_factor(&L, &c);
    cholmod_free_sparse(&lower, &c);
    analyzed = factorized = false;
  }
};

CholmodDirect::CholmodDirect(const Params& prm) : prm_(prm), impl_(std::make_unique<Impl>()) {}
CholmodDirect::~CholmodDirect() = default;
CholmodDirect::CholmodDirect(CholmodDirect&&) noexcept = default;
CholmodDirect& CholmodDirect::operator=(CholmodDirect&&) noexcept = default;

Status CholmodDirect::analyze_pattern(const BlockCsr& A) {
  analyze_seconds_ = 0;
  Status status;
  {
    ScopedTimer timer(analyze_seconds_);
    status = analyze(A);
  }
  setup_seconds_ = analyze_seconds_;
  return status;
}

Status CholmodDirect::analyze(const BlockCsr& A) {
  Impl& s = *impl_;
  s.release();
  const int nb = A.block_rows(), n = A.rows();
  const auto& rp = A.row_ptr();
  const auto& col = A.col();
  // Column c = 3j + b of the lower triangle holds rows r = 3i + a >= c for the blocks (j, i),
  // i >= j, of block row j (the pattern is symmetric): A(r, c) = block (j, i) entry (b, a),
  // so every column is read from one contiguous block row.
  std::size_t nnz = 0;
  for (int j = 0; j < nb; ++j)
    for (int k = rp[j]; k < rp[j + 1]; ++k)
      if (col[k] > j) nnz += 9;
  nnz += 6 * static_cast<std::size_t>(nb);  // lower triangles of the diagonal blocks
  s.lower = cholmod_allocate_sparse(n, n, nnz, /*sorted=*/1, /*packed=*/1, /*stype=*/-1, CHOLMOD_REAL, &s.c);
  if (!s.lower) return Status::numerical_issue;
  auto* cp = static_cast<int*>(s.lower->p);
  auto* ri = static_cast<int*>(s.lower->i);
  s.source.resize(nnz);
  std::size_t p = 0;
  for (int j = 0; j < nb; ++j) {
    if (A.diagonal(j) < 0) return Status::invalid_input;
    for (int b = 0; b < 3; ++b) {
      const int c = 3 * j + b;
      cp[c] = static_cast<int>(p);
      for (int k = rp[j]; k < rp[j + 1]; ++k) {  // columns sorted: rows come out sorted
        const int i = col[k];
        if (i < j) continue;
        for (int a = 0; a < 3; ++a) {
          const int r = 3 * i + a;
          if (r < c) continue;
          ri[p] = r;
          s.source[p++] = 9 * k + 3 * b + a;
        }
      }
    }
  }
  cp[n] = static_cast<int>(p);
  if (p != nnz) return Status::invalid_input;
  s.L = cholmod_analyze(s.lower, &s.c);
  s.analyzed = s.L != nullptr && s.c.status >= CHOLMOD_OK;
  return s.analyzed ? Status::success : Status::numerical_issue;
}

Status CholmodDirect::factorize(const BlockCsr& A) {
  Impl& s = *impl_;
  if (!s.analyzed) return Status::invalid_input;
  s.factorized = false;
  s.failed_column = -1;
  factorize_seconds_ = 0;
  {
    ScopedTimer timer(factorize_seconds_);
    M_ = &prefilter_.matrix(A);
    if (static_cast<std::size_t>(M_->num_blocks()) * 9 != M_->values().size() || M_->rows() != static_cast<int>(s.lower->nrow))
      return Status::invalid_input;
    auto* dst = static_cast<double*>(s.lower->x);
    const double* src = M_->values().data();
    const std::size_t nnz = s.source.size();
    for (std::size_t p = 0; p < nnz; ++p) dst[p] = src[s.source[p]];
    cholmod_factorize(s.lower, s.L, &s.c);
  }
  setup_seconds_ += factorize_seconds_ + prefilter_.take_seconds();
  if (s.c.status == CHOLMOD_NOT_POSDEF) {
    s.failed_column = static_cast<int>(s.L->minor);
    return Status::numerical_issue;
  }
  if (s.c.status < CHOLMOD_OK || !s.L->is_ll) return Status::numerical_issue;
  // Positive pivots at round-off level relative to the largest: numerically singular (e.g.
  // an unpinned body without mass). Refuse, as the Eigen LDL^T policy does.
  s.rcond = cholmod_rcond(s.L, &s.c);
  if (!(s.rcond > prm_.min_rcond)) return Status::numerical_issue;
  s.factorized = true;
  return Status::success;
}

LinearReport CholmodDirect::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  Impl& s = *impl_;
  LinearReport r;
  r.solves = 1;
  r.setup_seconds = setup_seconds_;
  setup_seconds_ = 0;
  r.memory_bytes = s.c.memory_usage;
  if (!s.factorized) {
    r.status = Status::numerical_issue;
    r.indefinite = s.failed_column >= 0;
    if (s.failed_column >= 0)
      r.message = fmt::format("CHOLMOD: the matrix is not positive definite (Cholesky failed at column {}, vertex {})",
                              s.failed_column, s.failed_column / 3);
    else if (s.analyzed && s.L && s.L->is_ll)
      r.message = fmt::format("CHOLMOD: the matrix is numerically singular (rcond {:.3g} <= {:.3g})", s.rcond, prm_.min_rcond);
    else
      r.message = fmt::format("CHOLMOD: no factorisation (status {})", s.c.status);
    return r;
  }
  if (b.size() != static_cast<Eigen::Index>(s.lower->nrow)) {
    r.status = Status::invalid_input;
    r.message = fmt::format("CHOLMOD: right-hand side of size {} for a matrix of {} rows", b.size(), s.lower->nrow);
    return r;
  }
  double t_pre = 0;
  const Eigen::VectorXd* rhs = nullptr;
  {
    ScopedTimer timer(t_pre);
    rhs = &prefilter_.rhs(b);
  }
  {
    ScopedTimer timer(r.solve_seconds);
    cholmod_dense B{};  // a view of rhs: CHOLMOD only reads it
    B.nrow = B.nzmax = static_cast<std::size_t>(rhs->size());
    B.ncol = 1;
    B.d = B.nrow;
    B.x = const_cast<double*>(rhs->data());
    B.xtype = CHOLMOD_REAL;
    B.dtype = CHOLMOD_DOUBLE;
    if (!cholmod_solve2(CHOLMOD_A, s.L, &B, nullptr, &s.X, nullptr, &s.Y, &s.E, &s.c)) {
      r.status = Status::numerical_issue;
      r.message = fmt::format("CHOLMOD: solve failed (status {})", s.c.status);
      return r;
    }
    x = Eigen::Map<const Eigen::VectorXd>(static_cast<const double*>(s.X->x), rhs->size());
  }
  if (!x.allFinite()) {
    r.status = Status::numerical_issue;
    r.message = "CHOLMOD: the solve produced non-finite values";
    return r;
  }
  // The residual of the system actually factorised (Ahat y = chat with constraints): it is
  // ||S (b - A x)|| / ||S (b - A z)||, the unconstrained rows' residual of the original.
  if (prm_.check_residual && M_) {
    Eigen::VectorXd Mx;
    M_->multiply(x, Mx);
    const double nb = rhs->norm();
    r.relative_residual = nb > 0 ? (*rhs - Mx).norm() / nb : (*rhs - Mx).norm();
  }
  {
    ScopedTimer timer(t_pre);
    prefilter_.finish(x);
  }
  r.prefilter_seconds = prefilter_.take_seconds();
  if (prefilter_.active()) r.constraint_violation = prefilter_.context().constraints->violation(x);
  r.memory_bytes = s.c.memory_usage;
  return r;
}

double CholmodDirect::factor_nonzeros() const {
  const cholmod_factor* L = impl_->L;
  if (!L) return 0;
  return L->is_super ? static_cast<double>(L->xsize) : impl_->c.lnz;
}
double CholmodDirect::factor_flops() const { return impl_->c.fl; }
std::size_t CholmodDirect::peak_memory_bytes() const { return impl_->c.memory_usage; }

std::string CholmodDirect::ordering() const {
  if (!impl_->L) return "none";
  switch (impl_->L->ordering) {
    case CHOLMOD_NATURAL: return "natural";
    case CHOLMOD_GIVEN: return "given";
    case CHOLMOD_AMD: return "amd";
    case CHOLMOD_METIS: return "metis";
    case CHOLMOD_NESDIS: return "nesdis";
    case CHOLMOD_COLAMD: return "colamd";
    default: return fmt::format("ordering {}", impl_->L->ordering);
  }
}

std::string CholmodDirect::blas_library() {
  void* sym = dlsym(RTLD_DEFAULT, "dgemm_");
  Dl_info info{};
  if (!sym || !dladdr(sym, &info) || !info.dli_fname) return "unknown";
  std::error_code ec;
  const auto real = std::filesystem::canonical(info.dli_fname, ec);  // follows Debian's alternatives
  return ec ? std::string(info.dli_fname) : real.string();
}

}  // namespace weft::linear
