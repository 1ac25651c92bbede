/// \file sa_cycle.cpp
/// Smoothed aggregation, the cycle (methods/multigrid §5): Chebyshev smoothing on D^-1 A, the
/// restriction P^T r in row chunks, the coarse correction (V-cycle, or cycle_gamma cycles on
/// the first coarse levels) and the coarsest solve; and the read-only views of the hierarchy
/// (level matrices, prolongators, statistics).
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numeric>
#include <type_traits>
#include <utility>

#include "framework/error.hpp"
#include "framework/timers.hpp"
#include "framework/union_find.hpp"
#include "linear/sa_amg.hpp"
#include "linear/sa_internal.hpp"

namespace weft::linear {

namespace sa {

template <int B>
std::vector<int> restriction_chunks(const BsrView<B, 6>& P, int min_rows) {
  const int n = P.rows;
  std::vector<int> first(P.cols, n), last(P.cols, -1);
  for (int i = 0; i < n; ++i)
    for (int k = P.row_ptr[i]; k < P.row_ptr[i + 1]; ++k) {
      first[P.col[k]] = std::min(first[P.col[k]], i);
      last[P.col[k]] = std::max(last[P.col[k]], i);
    }
  std::vector<int> reach(n, -1);  // reach[r] = max last(J) over first(J) <= r
  for (int J = 0; J < P.cols; ++J)
    if (first[J] < n) reach[first[J]] = std::max(reach[first[J]], last[J]);
  for (int r = 1; r < n; ++r) reach[r] = std::max(reach[r], reach[r - 1]);
  std::vector<int> b{0};
  while (b.back() < n) {
    const int bk = b.back();
    const int next = std::max(bk + min_rows, bk > 0 ? reach[bk - 1] + 1 : 0);
    b.push_back(std::min(next, n));
  }
  return b;
}

#define WEFT_SA_INSTANTIATE(B)                                                \
  template std::vector<int> restriction_chunks<B>(const BsrView<B, 6>&, int);
WEFT_SA_INSTANTIATE(3)
WEFT_SA_INSTANTIATE(6)
#undef WEFT_SA_INSTANTIATE

}  // namespace sa

namespace {

/// f(the smoother's block inverses), in double or (single_block_inverses) float, or a null
/// double pointer when the level keeps none (fine_inverses_on_the_fly).
template <int B, class F>
void with_inverses(const Level<B>& L, F&& f) {
  if (!L.Dinvf.empty())
    f(L.Dinvf.data());
  else if (!L.Dinv.empty())
    f(L.Dinv.data());
  else
    f(static_cast<const double*>(nullptr));
}

/// D_i^-1 r with D_i the diagonal block of row i as the operator reads it (through the
/// filters): by the adjugate when Sylvester's criterion shows D_i SPD (one division, no
/// square root), else by LU, zero if singular or absent (as `invert_block_diagonal`).
inline Vec<3> solve_diagonal(const BsrView<3, 3>& A, int i, const Vec<3>& r) {
  const int kd = find_block(A, i, i);
  if (kd < 0) return Vec<3>::Zero();
  const Mat<3> D = A.block(i, kd);
  const double c00 = D(1, 1) * D(2, 2) - D(1, 2) * D(2, 1), c01 = D(1, 2) * D(2, 0) - D(1, 0) * D(2, 2),
               c02 = D(1, 0) * D(2, 1) - D(1, 1) * D(2, 0);
  const double det = D(0, 0) * c00 + D(0, 1) * c01 + D(0, 2) * c02;
  if (D(0, 0) > 0 && D(0, 0) * D(1, 1) - D(0, 1) * D(1, 0) > 0 && det > 0) {
    Mat<3> adj;  // adj = cof^T
    adj << c00, D(0, 2) * D(2, 1) - D(0, 1) * D(2, 2), D(0, 1) * D(1, 2) - D(0, 2) * D(1, 1),  //
        c01, D(0, 0) * D(2, 2) - D(0, 2) * D(2, 0), D(0, 2) * D(1, 0) - D(0, 0) * D(1, 2),     //
        c02, D(0, 1) * D(2, 0) - D(0, 0) * D(2, 1), D(0, 0) * D(1, 1) - D(0, 1) * D(1, 0);
    return (adj * r) / det;
  }
  Eigen::FullPivLU<Mat<3>> lu(D);
  return lu.isInvertible() ? Vec<3>(lu.solve(r)) : Vec<3>::Zero();
}

/// D_i^-1 v from the stored inverses, or (Dinv == nullptr: the fine level under
/// fine_inverses_on_the_fly) by `solve_diagonal`. Coarse levels always keep theirs.
template <int B, class T>
Vec<B> inverse_times(const BsrView<B, B>& A, const T* Dinv, int i, const Vec<B>& v) {
  if constexpr (B == 3) {
    if (!Dinv) return solve_diagonal(A, i, v);
  }
  return value_block<B, B>(Dinv, i) * v;
}

/// One Chebyshev step fused with its residual, row by row: d = c1 d + c2 Dinv (f - A x)
/// (x == nullptr: x = 0, d's old value is not read when c1 == 0). Reads x whole and writes
/// only d, so the level needs one work vector and no residual vector. Parallel over rows.
template <int B, class T>
void chebyshev_step(const BsrView<B, B>& A, const T* Dinv, const double* f, const double* x, double c1, double c2,
                    double* d) {
  const int n = A.rows;
#pragma omp parallel for schedule(static) if (n > parallel_rows)
  for (int i = 0; i < n; ++i) {
    Vec<B> r = Eigen::Map<const Vec<B>>(f + B * i);
    if (x) r -= row_product(A, i, x);
    Eigen::Map<Vec<B>> di(d + B * i);
    const Vec<B> z = inverse_times(A, Dinv, i, r);
    if (c1 == 0.0)
      di.noalias() = c2 * z;
    else
      di = c1 * di + c2 * z;
  }
}

/// x += d, or x = d when `assign`. Parallel over rows.
template <int B>
void add_correction(int n, const double* d, double* x, bool assign) {
#pragma omp parallel for schedule(static) if (n > parallel_rows)
  for (int i = 0; i < n; ++i) {
    const Eigen::Map<const Vec<B>> di(d + B * i);
    Eigen::Map<Vec<B>> xi(x + B * i);
    if (assign)
      xi = di;
    else
      xi += di;
  }
}

/// Chebyshev iteration (methods/multigrid §5.2) on D^-1 A over [lower, upper] * lambda:
/// x <- x + p-correction; with `zero_guess` x is overwritten (x = p-smoothing of 0). Each
/// step forms its residual f - A x from x itself (not by the update r -= A d), so the only
/// work vector is the correction d (the level's work vector, see `work_of`).
template <int B>
void chebyshev(const Level<B>& L, const SaAmg::Params& prm, const double* f, double* x, bool zero_guess, double* d) {
  const auto A = L.A();
  const int n = A.rows;
  const double a = prm.chebyshev_lower * L.lambda, b = prm.chebyshev_upper * L.lambda;
  const double theta = 0.5 * (a + b), delta = 0.5 * (b - a), sigma = theta / delta;
  auto run = [&](const auto* Dinv) {
    double rho = 1.0 / sigma;
    chebyshev_step<B>(A, Dinv, f, zero_guess ? nullptr : x, 0.0, 1.0 / theta, d);
    add_correction<B>(n, d, x, /*assign=*/zero_guess);
    for (int j = 2; j <= prm.chebyshev_degree; ++j) {
      const double rho_new = 1.0 / (2.0 * sigma - rho);
      chebyshev_step<B>(A, Dinv, f, x, rho_new * rho, 2.0 * rho_new / delta, d);
      add_correction<B>(n, d, x, false);
      rho = rho_new;
    }
  };
  with_inverses(L, run);
}

template <int B>
void coarsest_solve(const Level<B>& L, const SaAmg::Params& prm, const double* f, double* x, double* d) {
  const int N = B * L.n();
  if (L.direct == 0) {  // smoother only: B = A^-1 - G A^-1 G^T, still SPD (Appendix A)
    chebyshev(L, prm, f, x, true, d);
    chebyshev(L, prm, f, x, false, d);
    return;
  }
  Eigen::Map<Eigen::VectorXd> xv(x, N);
  xv = Eigen::Map<const Eigen::VectorXd>(f, N);
  if (L.direct == 1)
    L.llt.solveInPlace(xv);
  else
    xv = L.ldlt.solve(xv);
}

/// f(values of P, column scales or nullptr): P's values as the cycle reads them
/// (prolongator_storage: double, or int16 with one scale per column).
template <int B, class F>
void with_prolongator_values(const Level<B>& L, F&& f) {
  if (!L.Pq.empty())
    f(L.Pq.data(), L.Pscale.data());
  else
    f(L.P.values().data(), static_cast<const double*>(nullptr));
}

/// fc = (P diag(s))^T r by P's rows: each row i adds P_iJ^T r_i to fc_J. The even chunks of
/// `sa::restriction_chunks` scatter in parallel, then the odd ones, so every fc_J sums its terms
/// in one fixed order whatever the thread count, with no transpose index of P.
template <int R, class V>
void restrict_rows(const BsrView<R, 6>& P, const std::vector<int>& chunks, const V* val, const double* r, double* fc,
                   const double* scale) {
  const int m = 6 * P.cols, count = static_cast<int>(chunks.size()) - 1;
#pragma omp parallel if (P.rows > parallel_rows)
  {
#pragma omp for schedule(static)
    for (int j = 0; j < m; ++j) fc[j] = 0.0;
    for (int parity = 0; parity < 2; ++parity) {
#pragma omp for schedule(dynamic, 1)
      for (int c = parity; c < count; c += 2)
        for (int i = chunks[c]; i < chunks[c + 1]; ++i) {
          const Eigen::Map<const Vec<R>> ri(r + R * i);
          for (int k = P.row_ptr[i]; k < P.row_ptr[i + 1]; ++k)
            Eigen::Map<Vec<6>>(fc + 6 * P.col[k]).noalias() += value_block<R, 6>(val, k).transpose() * ri;
        }
    }
    if (scale) {
#pragma omp for schedule(static)
      for (int j = 0; j < m; ++j) fc[j] *= scale[j];
    }
  }
}

/// fc = P^T r.
template <int B>
void restrict_to(const Level<B>& L, const double* r, double* fc) {
  with_prolongator_values(L, [&](const auto* p, const double* s) { restrict_rows(L.P.view(), L.rchunks, p, r, fc, s); });
}

/// x += P xc.
template <int B>
void prolong_add(const Level<B>& L, const double* xc, double* x) {
  with_prolongator_values(L, [&](const auto* p, const double* s) { multiply_add(L.P.view(), p, xc, x, s); });
}

/// One cycle on level L: x = B_L f from a zero guess, or (zero_guess false, L not the
/// coarsest) x += B_L (f - A_L x) from the x given, the same linear map applied to the
/// residual. d is L's work vector (`work_of`, or on the fine level one lent by the caller).
template <int B>
void cycle(const Level<B>& L, const std::vector<Level<6>>& coarse, int index, const SaAmg::Params& prm,
           const double* f, double* x, double* d, bool zero_guess = true) {
  if (L.coarsest) {
    coarsest_solve(L, prm, f, x, d);
    return;
  }
  const Level<6>& C = coarse[index];
  const auto A = L.A();
  chebyshev(L, prm, f, x, zero_guess, d);  // pre-smoothing (G*)
  // The residual goes to the smoother's work vector, free until the post-smoothing.
  residual(A, f, x, d);
  restrict_to(L, d, C.f.data());
  cycle(C, coarse, index + 1, prm, C.f.data(), C.x.data(), C.d.data());
  // mu-cycle on the first cycle_gamma_levels coarse levels: x_c += V_c (f_c - A_c x_c), so the
  // correction is (I - (I - V_c A_c)^gamma) A_c^-1 f_c, symmetric in A_c (methods/multigrid §2.4). The
  // cycle from the current x_c applies that update in place: no residual or correction vector.
  if (!C.coarsest && index + 1 <= prm.cycle_gamma_levels)
    for (int r = 1; r < prm.cycle_gamma; ++r)
      cycle(C, coarse, index + 1, prm, C.f.data(), C.x.data(), C.d.data(), /*zero_guess=*/false);
  prolong_add(L, C.x.data(), x);
  chebyshev(L, prm, f, x, /*zero_guess=*/false, d);  // post-smoothing (G), same polynomial
}

/// The level's own work vector. The fine level allocates it on first use only: PCG lends
/// its own idle vector instead (`SaAmg::apply(r, z, work)`).
template <int B>
double* work_of(const Level<B>& L) {
  if (L.d.size() != B * L.n()) L.d.resize(B * L.n());
  return L.d.data();
}

}  // namespace

void SaAmg::apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  WEFT_ASSERT(impl_->built, "SaAmg::apply before a successful setup");
  apply(r, z, impl_->fine->d);
}

void SaAmg::apply(const Eigen::VectorXd& r, Eigen::VectorXd& z, Eigen::VectorXd& work) const {
  const Impl& I = *impl_;
  WEFT_ASSERT(I.built, "SaAmg::apply before a successful setup");
  WEFT_ASSERT(r.size() == 3 * I.fine->n(), "SaAmg::apply: r has {} entries, expected {}", r.size(), 3 * I.fine->n());
  z.resize(r.size());
  if (r.size() == 0) return;
  work.resize(r.size());  // keeps the storage when the size is unchanged
  cycle(*I.fine, I.coarse, 0, active_, r.data(), z.data(), work.data());
}

void SaAmg::smooth(int l, const Eigen::VectorXd& f, Eigen::VectorXd& x) const {
  const Impl& I = *impl_;
  WEFT_ASSERT(l >= 0 && l < levels(), "level {} out of range", l);
  if (l == 0) {
    WEFT_ASSERT(x.size() == f.size() && f.size() == 3 * I.fine->n(), "size mismatch");
    chebyshev(*I.fine, active_, f.data(), x.data(), false, work_of(*I.fine));
  } else {
    const Level<6>& C = I.coarse[l - 1];
    WEFT_ASSERT(x.size() == f.size() && f.size() == 6 * C.n(), "size mismatch");
    chebyshev(C, active_, f.data(), x.data(), false, work_of(C));
  }
}

Eigen::MatrixXd SaAmg::level_matrix(int l) const {
  WEFT_ASSERT(l >= 0 && l < levels(), "level {} out of range", l);
  auto dense = [](const auto& A, auto bs) {
    constexpr int B = decltype(bs)::value;
    Eigen::MatrixXd D = Eigen::MatrixXd::Zero(B * A.rows, B * A.cols);
    for (int i = 0; i < A.rows; ++i)
      for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) D.block<B, B>(B * i, B * A.col[k]) = A.block(i, k);
    return D;
  };
  if (l == 0) return dense(impl_->fine->A(), std::integral_constant<int, 3>());
  return dense(impl_->coarse[l - 1].A(), std::integral_constant<int, 6>());
}

Eigen::MatrixXd SaAmg::prolongator(int l) const {
  WEFT_ASSERT(l >= 0 && l + 1 < levels(), "level {} has no prolongator", l);
  auto dense = [](const auto& L) {
    if (!L.Pq.empty()) {  // column by column, through the cycle's own application of P
      const int n = L.n(), nc = L.P.cols();
      constexpr int B = std::remove_cvref_t<decltype(L)>::block;
      Eigen::MatrixXd D = Eigen::MatrixXd::Zero(B * n, 6 * nc);
      Eigen::VectorXd ec = Eigen::VectorXd::Zero(6 * nc), x(B * n);
      for (int c = 0; c < 6 * nc; ++c) {
        ec[c] = 1;
        x.setZero();
        prolong_add(L, ec.data(), x.data());
        D.col(c) = x;
        ec[c] = 0;
      }
      return D;
    }
    return L.P.to_dense();
  };
  if (l == 0) return dense(*impl_->fine);
  return dense(impl_->coarse[l - 1]);
}


PreconditionerInfo SaAmg::info() const {
  PreconditionerInfo out;
  if (!impl_->built) return out;
  out.memory_bytes = impl_->fine->memory_bytes();
  for (const auto& C : impl_->coarse) out.memory_bytes += C.memory_bytes();
  out.levels = levels();
  double nnz0 = 0, rows0 = 0, nnz = 0, rows = 0;
  for (const auto& s : stats_.levels) {
    const double b = s.block_size;
    if (nnz0 == 0) nnz0 = b * b * s.nnz_blocks, rows0 = b * s.rows;
    nnz += b * b * s.nnz_blocks;
    rows += b * s.rows;
  }
  out.operator_complexity = nnz0 > 0 ? nnz / nnz0 : 0;
  out.grid_complexity = rows0 > 0 ? rows / rows0 : 0;
  return out;
}

}  // namespace weft::linear
