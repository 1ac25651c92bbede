/// \file sa_strength.cpp
/// Smoothed aggregation, setup stage 1 (methods/multigrid §4.3-4.4): the strength of each
/// coupling, mu_ij = rho(A_ii^-1/2 A_ij A_jj^-1/2), the strong flags mu_ij > theta max_k mu_ik
/// (symmetrised) and the special nodes that get no coarse dofs. Next: sa_aggregation.cpp.
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

/// Symmetric inverse square root of an SPD block (eigenvalues below 1e-14 of the largest
/// are treated as zero: the direction gets no weight).
template <int B>
Mat<B> inverse_sqrt(const Mat<B>& D) {
  Eigen::SelfAdjointEigenSolver<Mat<B>> es;
  if constexpr (B == 3)
    es.computeDirect(D);
  else
    es.compute(D);
  Vec<B> s = es.eigenvalues();
  const double top = s.cwiseAbs().maxCoeff();
  for (int k = 0; k < B; ++k) s[k] = s[k] > 1e-14 * top && s[k] > 0 ? 1.0 / std::sqrt(s[k]) : 0.0;
  return es.eigenvectors() * s.asDiagonal() * es.eigenvectors().transpose();
}

template <int B>
double measure_block(const Mat<B>& M, SocMeasure measure) {
  switch (measure) {
    case SocMeasure::frobenius: return M.norm();
    case SocMeasure::two_norm: {
      const Mat<B> G = M.transpose() * M;
      Eigen::SelfAdjointEigenSolver<Mat<B>> es;
      if constexpr (B == 3)
        es.computeDirect(G, Eigen::EigenvaluesOnly);
      else
        es.compute(G, Eigen::EigenvaluesOnly);
      return std::sqrt(std::max(0.0, es.eigenvalues().maxCoeff()));
    }
    case SocMeasure::spectral:
    default:
      if constexpr (B == 3) {
        return sa::spectral_radius3(M);
      } else {
        // Gelfand's formula rho(M) = lim ||M^k||^(1/k) with k = 64 (six squarings, rescaled
        // against overflow): an upper estimate within a factor (sqrt(B) cond(V))^(1/64),
        // ~1.5% for near-normal blocks, at 1/20 of the cost of a Hessenberg QR eigensolve.
        Mat<B> X = M;
        double log_scale = 0;  // log of the factor divided out of X, accumulated for M^(2^s)
        for (int s = 0; s < 6; ++s) {
          const double nrm = X.norm();
          if (!(nrm > 0)) return 0.0;
          X /= nrm;
          log_scale = 2.0 * (log_scale + std::log(nrm));
          X = (X * X).eval();
        }
        const double nrm = X.norm();
        if (!(nrm > 0)) return 0.0;
        return std::exp((log_scale + std::log(nrm)) / 64.0);
      }
  }
}

}  // namespace

namespace sa {

double spectral_radius3(const Eigen::Matrix3d& M) {
  // Characteristic polynomial l^3 + a l^2 + b l + c.
  const double a = -M.trace();
  const double b = M(0, 0) * M(1, 1) - M(0, 1) * M(1, 0) + M(0, 0) * M(2, 2) - M(0, 2) * M(2, 0) + M(1, 1) * M(2, 2) -
                   M(1, 2) * M(2, 1);
  const double c = -M.determinant();
  // Depressed cubic t^3 + p t + q with l = t - a/3.
  const double shift = -a / 3.0;
  const double p = b - a * a / 3.0;
  const double q = 2.0 * a * a * a / 27.0 - a * b / 3.0 + c;
  const double disc = 0.25 * q * q + p * p * p / 27.0;
  const double scale = std::max(1.0, std::abs(a) * std::abs(a) + std::abs(b));
  if (disc <= 1e-14 * scale * scale * scale) {  // three real roots (up to round-off)
    if (p >= 0) return std::abs(shift + std::cbrt(-q));  // p ~ 0: triple root
    const double r = 2.0 * std::sqrt(-p / 3.0);
    const double arg = std::clamp(3.0 * q / (p * r), -1.0, 1.0);  // cos(3 phi)
    const double phi = std::acos(arg) / 3.0;
    double rho = 0;
    for (int k = 0; k < 3; ++k) rho = std::max(rho, std::abs(shift + r * std::cos(phi - 2.0 * M_PI * k / 3.0)));
    return rho;
  }
  const double sq = std::sqrt(disc);
  const double t = std::cbrt(-0.5 * q + sq) + std::cbrt(-0.5 * q - sq);
  const double l1 = t + shift;
  // Remaining quadratic l^2 + (a + l1) l + (b + l1 (a + l1)): complex pair of modulus sqrt(const).
  const double m2 = b + l1 * (a + l1);
  return std::max(std::abs(l1), std::sqrt(std::max(0.0, m2)));
}

template <int B>
double measure(const Eigen::Matrix<double, B, B>& M, SocMeasure m) {
  return measure_block<B>(M, m);
}
template double measure<3>(const Eigen::Matrix<double, 3, 3>&, SocMeasure);
template double measure<6>(const Eigen::Matrix<double, 6, 6>&, SocMeasure);

template <int B>
void strength(const BsrView<B, B>& A, double theta, SocMeasure measure, std::vector<double>& mu, std::vector<std::uint8_t>& strong,
              const SheetEdges* sheets) {
  const int n = A.rows, nnz = A.nnz();
  mu.assign(nnz, 0.0);
  std::vector<double> Dis(static_cast<std::size_t>(B * B) * n);
#pragma omp parallel for schedule(static) if (n > parallel_rows)
  for (int i = 0; i < n; ++i) {
    const int kd = find_block(A, i, i);
    Eigen::Map<Mat<B>> out(Dis.data() + static_cast<std::ptrdiff_t>(B * B) * i);
    if (kd < 0)
      out.setZero();
    else
      out = inverse_sqrt<B>(Mat<B>(A.block(i, kd)));
  }
  // mu_ij = mu_ji: compute once for j > i, write both blocks (row i alone writes them).
#pragma omp parallel for schedule(dynamic, 256) if (n > parallel_rows / 4)
  for (int i = 0; i < n; ++i) {
    const Eigen::Map<const Mat<B>> Di(Dis.data() + static_cast<std::ptrdiff_t>(B * B) * i);
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
      const int j = A.col[k];
      if (j <= i) continue;
      const Eigen::Map<const Mat<B>> Dj(Dis.data() + static_cast<std::ptrdiff_t>(B * B) * j);
      const Mat<B> M = Di * Mat<B>(A.block(i, k)) * Dj;
      const double m = measure_block<B>(M, measure);
      mu[k] = m;
      const int kt = find_block(A, j, i);
      if (kt >= 0) mu[kt] = m;
    }
  }
  strong_flags<B>(A, mu, theta, strong, sheets);
}

template <int B>
void strong_flags(const BsrView<B, B>& A, const std::vector<double>& mu, double theta, std::vector<std::uint8_t>& strong,
                  const SheetEdges* sheets) {
  const int n = A.rows;
  strong.assign(A.nnz(), 0);
  WEFT_ASSERT(!sheets || std::is_sorted(sheets->begin(), sheets->end()), "sheet edges must be sorted");
  auto in_sheet = [&](int i, int j) {
    return std::binary_search(sheets->begin(), sheets->end(), std::make_pair(std::min(i, j), std::max(i, j)));
  };
#pragma omp parallel for schedule(static) if (n > parallel_rows)
  for (int i = 0; i < n; ++i) {
    double top = 0, top_sheet = 0;
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
      top = std::max(top, mu[k]);
      if (sheets && A.col[k] != i && mu[k] > top_sheet && in_sheet(i, A.col[k])) top_sheet = mu[k];
    }
    const double ref = top_sheet > 0 ? top_sheet : top;
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) strong[k] = A.col[k] != i && ref > 0 && mu[k] > theta * ref;
  }
  // Symmetrise: strong if strong in either row (methods/multigrid §4.3).
#pragma omp parallel for schedule(static) if (n > parallel_rows)
  for (int i = 0; i < n; ++i)
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
      const int j = A.col[k];
      if (j <= i) continue;
      const int kt = find_block(A, j, i);
      const std::uint8_t s = strong[k] | (kt >= 0 ? strong[kt] : 0);
      strong[k] = s;
      if (kt >= 0) strong[kt] = s;
    }
}

template <int B>
void weaken_special(const BsrView<B, B>& A, const std::vector<std::uint8_t>& special, std::vector<std::uint8_t>& flags) {
  const int n = A.rows;
#pragma omp parallel for schedule(static) if (n > parallel_rows)
  for (int i = 0; i < n; ++i)
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k)
      if (flags[k] && (special[i] || special[A.col[k]])) flags[k] = 0;
}

template <int B>
int special_nodes(const BsrView<B, B>& A, const std::vector<double>& mu, double tau_dd, std::vector<std::uint8_t>& strong,
                  std::vector<std::uint8_t>& special) {
  const int n = A.rows;
  special.assign(n, 0);
#pragma omp parallel for schedule(static) if (n > parallel_rows)
  for (int i = 0; i < n; ++i) {
    double sum = 0;
    bool any = false;
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
      sum += mu[k];
      any = any || strong[k];
    }
    special[i] = !any || sum < tau_dd;
  }
  // A special node is nobody's strong neighbour; a node that thereby loses its last strong
  // neighbour becomes special too (else pass 1 would make it a singleton aggregate).
  for (bool changed = true; changed;) {
    changed = false;
    weaken_special<B>(A, special, strong);
    for (int i = 0; i < n; ++i) {
      if (special[i]) continue;
      bool any = false;
      for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1] && !any; ++k) any = strong[k];
      if (!any) special[i] = 1, changed = true;
    }
  }
  return static_cast<int>(std::count(special.begin(), special.end(), 1));
}

#define WEFT_SA_INSTANTIATE(B)                                                                                                              \
  template void strength<B>(const BsrView<B, B>&, double, SocMeasure, std::vector<double>&, std::vector<std::uint8_t>&, const SheetEdges*); \
  template void strong_flags<B>(const BsrView<B, B>&, const std::vector<double>&, double, std::vector<std::uint8_t>&, const SheetEdges*);   \
  template void weaken_special<B>(const BsrView<B, B>&, const std::vector<std::uint8_t>&, std::vector<std::uint8_t>&);                      \
  template int special_nodes<B>(const BsrView<B, B>&, const std::vector<double>&, double, std::vector<std::uint8_t>&,                       \
    std::vector<std::uint8_t>&);
WEFT_SA_INSTANTIATE(3)
WEFT_SA_INSTANTIATE(6)
#undef WEFT_SA_INSTANTIATE

}  // namespace sa

}  // namespace weft::linear
