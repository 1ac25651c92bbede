/// \file sa_prolongator.cpp
/// Smoothed aggregation, setup stage 3 (methods/multigrid §4.6-4.8): the rigid-body near null
/// space, the tentative prolongator by local QR, the Lanczos bound of lambda_max(D^-1 A), and
/// the smoothed prolongator P = (I - omega D^-1 A_f) Phat with its optional mode repair and
/// truncation. Next: the coarse operators A_c = P^T A P, level by level, in sa_amg.cpp.
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

namespace {

/// Deterministic pseudo-random number in [-1, 1) from an index (splitmix64).
double hash_uniform(std::uint64_t i) {
  std::uint64_t z = i + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

}  // namespace

namespace sa {

NullSpace rigid_body_modes(const Eigen::VectorXd& positions, const ConstraintSet* constraints) {
  const int n = static_cast<int>(positions.size() / 3);
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) centre += positions.segment<3>(3 * i);
  if (n > 0) centre /= n;
  NullSpace K(3 * n, 6);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p = positions.segment<3>(3 * i) - centre;
    auto Ki = K.middleRows<3>(3 * i);
    Ki.leftCols<3>().setIdentity();
    // Columns r_x, r_y, r_z (methods/multigrid §4.2): the velocity e_k x p.
    Ki.rightCols<3>() << 0, p.z(), -p.y(),  //
        -p.z(), 0, p.x(),                   //
        p.y(), -p.x(), 0;
    if (constraints && constraints->count(i) > 0) {
      const Block3 S = constraints->filter(i);
      const Eigen::Matrix<double, 3, 6> Kf = S * Ki;
      Ki = Kf;
    }
  }
  return K;
}

template <int B>
Tentative tentative_prolongator(const Aggregates& aggs, const NullSpace& K, double tolerance) {
  const int n = static_cast<int>(aggs.node_agg.size());
  const int na = aggs.count;
  WEFT_ASSERT(K.rows() == static_cast<Eigen::Index>(B) * n, "near null space has {} rows, expected {}", K.rows(), B * n);
  // Members of each aggregate in node order (counting sort).
  std::vector<int> ptr(na + 1, 0), nodes(n);
  for (int i = 0; i < n; ++i)
    if (aggs.node_agg[i] >= 0) ++ptr[aggs.node_agg[i] + 1];
  for (int a = 0; a < na; ++a) ptr[a + 1] += ptr[a];
  {
    std::vector<int> fill(ptr.begin(), ptr.end() - 1);
    for (int i = 0; i < n; ++i)
      if (aggs.node_agg[i] >= 0) nodes[fill[aggs.node_agg[i]]++] = i;
  }
  Tentative t;
  t.Q.assign(static_cast<std::size_t>(6 * B) * n, 0.0);
  t.Kc.setZero(6 * na, 6);
  t.dummy.assign(6 * na, 0);
  int deficient = 0;
#pragma omp parallel reduction(+ : deficient) if (na > parallel_rows / 8)
  {
    Eigen::Matrix<double, Eigen::Dynamic, 6> V;  // thread-local, grows only
#pragma omp for schedule(dynamic, 64)
    for (int a = 0; a < na; ++a) {
      const int size = ptr[a + 1] - ptr[a], m = B * size;
      if (V.rows() < m) V.resize(m, 6);
      auto Va = V.topRows(m);
      for (int s = 0; s < size; ++s) Va.middleRows(B * s, B) = K.middleRows(B * nodes[ptr[a] + s], B);
      double top = 0;
      for (int c = 0; c < 6; ++c) top = std::max(top, Va.col(c).norm());
      Eigen::Matrix<double, 6, 6> R = Eigen::Matrix<double, 6, 6>::Zero();
      bool dropped = false;
      // Classical Gram-Schmidt, twice (CGS2): orthogonal to round-off; columns in the span of
      // the previous ones (relative tolerance) are dropped and stay zero (methods/multigrid §4.6).
      for (int c = 0; c < 6; ++c) {
        const double original = Va.col(c).norm();
        for (int pass = 0; pass < 2; ++pass)
          for (int p = 0; p < c; ++p) {
            const double h = Va.col(p).dot(Va.col(c));
            R(p, c) += h;
            Va.col(c) -= h * Va.col(p);
          }
        const double nrm = Va.col(c).norm();
        if (nrm <= tolerance * std::max(original, top) || nrm == 0.0) {
          Va.col(c).setZero();
          t.dummy[6 * a + c] = 1;
          dropped = true;
        } else {
          Va.col(c) /= nrm;
          R(c, c) = nrm;
        }
      }
      deficient += dropped;
      for (int s = 0; s < size; ++s)
        Eigen::Map<BlockOf<B, 6>>(t.Q.data() + static_cast<std::ptrdiff_t>(6 * B) * nodes[ptr[a] + s]) =
            Va.middleRows(B * s, B);
      t.Kc.middleRows<6>(6 * a) = R;
    }
  }
  t.deficient = deficient;
  return t;
}

template <int B>
LanczosResult lanczos(const BsrView<B, B>& A, const std::vector<double>& Dinv, int steps) {
  const int n = A.rows, N = B * n;
  LanczosResult out;
  if (n == 0) return out;
  auto apply_Dinv = [&](const Eigen::VectorXd& x, Eigen::VectorXd& y) {
    y.resize(N);
#pragma omp parallel for schedule(static) if (n > parallel_rows)
    for (int i = 0; i < n; ++i)
      y.segment<B>(B * i) = Eigen::Map<const BlockOf<B, B>>(Dinv.data() + static_cast<std::ptrdiff_t>(B * B) * i) *
                            x.segment<B>(B * i);
  };
  // Lanczos in the D inner product, keeping v = D q alongside q (no products with D).
  Eigen::VectorXd v(N), q, v_prev = Eigen::VectorXd::Zero(N), q_prev = Eigen::VectorXd::Zero(N), w, u, s;
  for (int k = 0; k < N; ++k) v[k] = hash_uniform(k);
  apply_Dinv(v, q);
  double nrm = std::sqrt(std::max(0.0, q.dot(v)));
  if (!(nrm > 0)) return out;
  q /= nrm;
  v /= nrm;
  std::vector<double> alpha, beta;
  double beta_prev = 0;
  for (int j = 0; j < steps; ++j) {
    w.resize(N);
    spmv(A, q.data(), w.data());
    const double a = q.dot(w);
    alpha.push_back(a);
    u = w - a * v - beta_prev * v_prev;  // D w~
    apply_Dinv(w, s);
    s -= a * q + beta_prev * q_prev;     // w~ = D^-1 A q - a q - beta q_prev
    const double b2 = s.dot(u);
    const double b = std::sqrt(std::max(0.0, b2));
    beta.push_back(b);
    if (!(b > 1e-12 * std::abs(a))) break;
    q_prev.swap(q);
    v_prev.swap(v);
    q = s / b;
    v = u / b;
    beta_prev = b;
  }
  const int m = static_cast<int>(alpha.size());
  Eigen::MatrixXd T = Eigen::MatrixXd::Zero(m, m);
  for (int j = 0; j < m; ++j) {
    T(j, j) = alpha[j];
    if (j + 1 < m) T(j, j + 1) = T(j + 1, j) = beta[j];
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(T);
  const int top = m - 1;  // eigenvalues ascending
  out.ritz = es.eigenvalues()[top];
  out.residual = std::abs(beta[m - 1] * es.eigenvectors()(m - 1, top));
  out.steps = m;
  return out;
}

/// A block pattern built row by row in two parallel passes (count, then fill):
/// row_columns(i, mark, cols) lists row i's sorted columns, with `mark` (one int per column,
/// initially -1, private to the thread) free for deduplication.
template <class RowColumns>
std::pair<std::vector<int>, std::vector<int>> build_pattern(int n, int ncols, RowColumns&& row_columns) {
  std::vector<int> ptr(n + 1, 0);
#pragma omp parallel if (n > parallel_rows)
  {
    std::vector<int> mark(ncols, -1), cols;
#pragma omp for schedule(static)
    for (int i = 0; i < n; ++i) {
      row_columns(i, mark, cols);
      ptr[i + 1] = static_cast<int>(cols.size());
    }
  }
  for (int i = 0; i < n; ++i) ptr[i + 1] += ptr[i];
  std::vector<int> col(ptr[n]);
#pragma omp parallel if (n > parallel_rows)
  {
    std::vector<int> mark(ncols, -1), cols;
#pragma omp for schedule(static)
    for (int i = 0; i < n; ++i) {
      row_columns(i, mark, cols);
      std::copy(cols.begin(), cols.end(), col.begin() + ptr[i]);
    }
  }
  return {std::move(ptr), std::move(col)};
}

template <int B>
BlockMatrix<B, 6> prolongator_pattern(const BsrView<B, B>& A, const std::vector<std::uint8_t>* strong,
                                      const Aggregates& aggs) {
  const std::vector<int>& agg = aggs.node_agg;
  auto [ptr, col] = build_pattern(A.rows, aggs.count, [&](int i, std::vector<int>& mark, std::vector<int>& cols) {
    cols.clear();
    if (agg[i] < 0) return;
    mark[agg[i]] = i, cols.push_back(agg[i]);
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
      const int j = A.col[k];
      if (j == i || agg[j] < 0 || (strong && !(*strong)[k])) continue;
      if (mark[agg[j]] != i) mark[agg[j]] = i, cols.push_back(agg[j]);
    }
    std::sort(cols.begin(), cols.end());
  });
  return BlockMatrix<B, 6>(A.rows, aggs.count, std::move(ptr), std::move(col));
}

/// Row i of one damped Jacobi step with A_f (A with its weak blocks lumped into the diagonal;
/// strong == nullptr: A itself): calls off(j, W), W = omega D_i^-1 A_ij, for each strong
/// off-diagonal block and returns G = I - omega D_i^-1 (A_f)_ii.
template <int B, class Off>
Mat<B> jacobi_row(const BsrView<B, B>& A, const std::vector<double>& Dinv, const std::vector<std::uint8_t>* strong, int i,
                  double omega, Off&& off) {
  const Eigen::Map<const BlockOf<B, B>> Di(Dinv.data() + static_cast<std::ptrdiff_t>(B * B) * i);
  Mat<B> Aii = Mat<B>::Zero();
  for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
    const int j = A.col[k];
    if (j == i || (strong && !(*strong)[k]))
      Aii += A.block(i, k);  // the diagonal, and weak blocks lumped into it
    else
      off(j, Mat<B>(omega * Di * A.block(i, k)));
  }
  return Mat<B>::Identity() - omega * Di * Aii;
}

template <int B>
void prolongator_values(const BsrView<B, B>& A, const std::vector<double>& Dinv, const std::vector<std::uint8_t>* strong,
                        const Aggregates& aggs, const Tentative& t, double omega, BlockMatrix<B, 6>& P) {
  const int n = A.rows;
  const std::vector<int>& agg = aggs.node_agg;
  const int* pr = P.row_ptr().data();
  const int* pc = P.col().data();
  auto Q = [&](int j) { return Eigen::Map<const BlockOf<B, 6>>(t.Q.data() + static_cast<std::ptrdiff_t>(6 * B) * j); };
  auto slot = [&](int i, int c) {
    const int* it = std::lower_bound(pc + pr[i], pc + pr[i + 1], c);
    WEFT_ASSERT(it != pc + pr[i + 1] && *it == c, "prolongator pattern lacks block ({}, {})", i, c);
    return static_cast<int>(it - pc);
  };
#pragma omp parallel for schedule(static) if (n > parallel_rows)
  for (int i = 0; i < n; ++i) {
    for (int k = pr[i]; k < pr[i + 1]; ++k) P.block(k).setZero();
    if (agg[i] < 0) continue;
    const Mat<B> G = jacobi_row(A, Dinv, strong, i, omega, [&](int j, const Mat<B>& W) {
      if (agg[j] >= 0) P.block(slot(i, agg[j])).noalias() -= W * Q(j);
    });
    P.block(slot(i, agg[i])).noalias() += G * Q(i);
  }
}

template <int B>
BlockMatrix<B, 6> smooth_prolongator(const BsrView<B, B>& A, const std::vector<double>& Dinv,
                                     const std::vector<std::uint8_t>* strong, const Aggregates& aggs, double omega,
                                     const BlockMatrix<B, 6>& P) {
  const int n = A.rows, nc = P.cols();
  const std::vector<int>& agg = aggs.node_agg;
  const int* pr = P.row_ptr().data();
  const int* pc = P.col().data();
  // Row i of the result has the columns of P's rows i and j over A_f's off-diagonal blocks
  // (i, j); zero rows stay zero (Z).
  auto [ptr, col] = build_pattern(n, nc, [&](int i, std::vector<int>& mark, std::vector<int>& cols) {
    cols.clear();
    if (agg[i] < 0) return;
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
      const int j = A.col[k];
      if (j != i && strong && !(*strong)[k]) continue;
      for (int q = pr[j]; q < pr[j + 1]; ++q)
        if (mark[pc[q]] != i) mark[pc[q]] = i, cols.push_back(pc[q]);
    }
    std::sort(cols.begin(), cols.end());
  });
  BlockMatrix<B, 6> out(n, nc, std::move(ptr), std::move(col));  // values zero
  const int* orp = out.row_ptr().data();
  const int* oc = out.col().data();
#pragma omp parallel if (n > parallel_rows)
  {
    std::vector<int> where(nc);  // column -> its block in the current row
#pragma omp for schedule(static)
    for (int i = 0; i < n; ++i) {
      if (agg[i] < 0) continue;
      for (int k = orp[i]; k < orp[i + 1]; ++k) where[oc[k]] = k;
      const Mat<B> G = jacobi_row(A, Dinv, strong, i, omega, [&](int j, const Mat<B>& W) {
        for (int q = pr[j]; q < pr[j + 1]; ++q) out.block(where[pc[q]]).noalias() -= W * P.block(q);
      });
      for (int q = pr[i]; q < pr[i + 1]; ++q) out.block(where[pc[q]]).noalias() += G * P.block(q);
    }
  }
  return out;
}

template <int B>
double preserve_modes(const BsrView<B, B>& A, const std::vector<double>& Dinv, const Aggregates& aggs, double omega,
                      int degree, const NullSpace& K, const NullSpace& Kc, BlockMatrix<B, 6>& P) {
  // Node by node (row-major, as K): `row_product` reads each block of A once for the six
  // modes, as the cycle reads it (through the prefilter, or from one-triangle
  // single-precision storage). Two buffers, swapped between the steps.
  using Tall = Eigen::Matrix<double, B, 6>;
  using Node = Eigen::Map<BlockOf<B, 6>>;
  constexpr std::ptrdiff_t S = B * 6;
  const int n = A.rows;
  const std::vector<int>& agg = aggs.node_agg;
  // The target: (Z (I - omega D^-1 A))^degree Z K, Z zeroing the rows outside every aggregate.
  NullSpace T = K, next(K.rows(), 6);
  for (int i = 0; i < n; ++i)
    if (agg[i] < 0) Node(T.data() + S * i).setZero();
  for (int d = 0; d < degree; ++d) {
#pragma omp parallel for schedule(static) if (n > parallel_rows)
    for (int i = 0; i < n; ++i) {
      Node out(next.data() + S * i);
      if (agg[i] < 0) {
        out.setZero();
        continue;
      }
      const Eigen::Map<const BlockOf<B, B>> Di(Dinv.data() + static_cast<std::ptrdiff_t>(B * B) * i);
      out = Node(T.data() + S * i) - omega * Di * row_product<B, B, 6>(A, i, T.data());
    }
    T.swap(next);
  }
  next = NullSpace();
  const int* pr = P.row_ptr().data();
  const int* pc = P.col().data();
  const int nc = P.cols();
  std::vector<Mat<6>> RtR(nc);  // each coarse node's Kc_J^T Kc_J, shared by the rows holding J
#pragma omp parallel for schedule(static) if (nc > parallel_rows)
  for (int J = 0; J < nc; ++J) RtR[J].noalias() = Kc.middleRows<6>(6 * J).transpose() * Kc.middleRows<6>(6 * J);
  double worst = 0;
#pragma omp parallel for schedule(static) reduction(max : worst) if (n > parallel_rows)
  for (int i = 0; i < n; ++i) {
    if (pr[i] == pr[i + 1]) continue;
    Tall y = Tall::Zero();
    Mat<6> G = Mat<6>::Zero();
    for (int k = pr[i]; k < pr[i + 1]; ++k) {
      y.noalias() += P.block(k) * Kc.middleRows<6>(6 * pc[k]);
      G += RtR[pc[k]];
    }
    const Tall target = Node(T.data() + S * i);
    const Tall X = target - y;
    // X G^+: by Cholesky, or by the eigenvalues of G when it is (nearly) singular, as when
    // the row's aggregates dropped a column.
    Tall XG;
    const Eigen::LLT<Mat<6>> llt(G);
    const double dmin = llt.matrixLLT().diagonal().minCoeff(), dmax = llt.matrixLLT().diagonal().maxCoeff();
    if (llt.info() == Eigen::Success && dmin > 1e-6 * dmax) {
      XG = llt.solve(X.transpose()).transpose();
    } else {
      Eigen::SelfAdjointEigenSolver<Mat<6>> es(G);
      const Eigen::Matrix<double, 6, 1> ev = es.eigenvalues();
      const double cut = 1e-12 * ev.maxCoeff();
      Eigen::Matrix<double, 6, 1> inv;
      for (int c = 0; c < 6; ++c) inv[c] = ev[c] > cut ? 1.0 / ev[c] : 0.0;
      XG = X * es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose();
    }
    for (int k = pr[i]; k < pr[i + 1]; ++k) P.block(k).noalias() += XG * Kc.middleRows<6>(6 * pc[k]).transpose();
    const double t = target.norm();
    if (t > 0) worst = std::max(worst, X.norm() / t);
  }
  return worst;
}

template <int B>
long long truncate_prolongator(BlockMatrix<B, 6>& P, double fraction) {
  const int n = P.rows();
  const int* pr = P.row_ptr().data();
  long long dropped = 0;
#pragma omp parallel reduction(+ : dropped) if (n > parallel_rows)
  {
    std::vector<double> norms;  // one row's squared block norms, reused across the rows
#pragma omp for schedule(static)
    for (int i = 0; i < n; ++i) {
      norms.clear();
      for (int k = pr[i]; k < pr[i + 1]; ++k) norms.push_back(P.block(k).squaredNorm());
      if (norms.empty()) continue;
      const double cut = fraction * fraction * *std::max_element(norms.begin(), norms.end());  // compared as squares
      for (int k = pr[i]; k < pr[i + 1]; ++k)
        if (norms[k - pr[i]] < cut) {
          P.block(k).setZero();
          ++dropped;
        }
    }
  }
  if (dropped > 0) P.prune_zero_blocks();
  return dropped;
}

#define WEFT_SA_INSTANTIATE(B)                                                                                                               \
  template Tentative tentative_prolongator<B>(const Aggregates&, const NullSpace&, double);                                                  \
  template LanczosResult lanczos<B>(const BsrView<B, B>&, const std::vector<double>&, int);                                                  \
  template BlockMatrix<B, 6> prolongator_pattern<B>(const BsrView<B, B>&, const std::vector<std::uint8_t>*, const Aggregates&);              \
  template void prolongator_values<B>(const BsrView<B, B>&, const std::vector<double>&, const std::vector<std::uint8_t>*, const Aggregates&, \
    const Tentative&, double, BlockMatrix<B, 6>&);                                                                                           \
  template double preserve_modes<B>(const BsrView<B, B>&, const std::vector<double>&, const Aggregates&, double, int, const NullSpace&,      \
    const NullSpace&, BlockMatrix<B, 6>&);                                                                                                   \
  template BlockMatrix<B, 6> smooth_prolongator<B>(const BsrView<B, B>&, const std::vector<double>&, const std::vector<std::uint8_t>*,       \
    const Aggregates&, double, const BlockMatrix<B, 6>&);                                                                                    \
  template long long truncate_prolongator<B>(BlockMatrix<B, 6>&, double);
WEFT_SA_INSTANTIATE(3)
WEFT_SA_INSTANTIATE(6)
#undef WEFT_SA_INSTANTIATE

}  // namespace sa

}  // namespace weft::linear
