#include "linear/sa_amg.hpp"

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

namespace weft::linear {

namespace {

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

/// Deterministic pseudo-random number in [-1, 1) from an index (splitmix64).
double hash_uniform(std::uint64_t i) {
  std::uint64_t z = i + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

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

// ---------------------------------------------------------------------------------------
// Building blocks
// ---------------------------------------------------------------------------------------
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
void strength(const BsrView<B, B>& A, double theta, SocMeasure measure, std::vector<double>& mu,
              std::vector<std::uint8_t>& strong, const SheetEdges* sheets) {
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
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k)
      strong[k] = A.col[k] != i && ref > 0 && mu[k] > theta * ref;
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

/// Clears every flag of a block that touches a special node.
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

template <int B>
Aggregates aggregate(const BsrView<B, B>& A, const std::vector<std::uint8_t>& strong,
                     const std::vector<std::uint8_t>& special, const std::vector<int>& scan) {
  const int n = A.rows;
  WEFT_ASSERT(scan.empty() || static_cast<int>(scan.size()) == n, "scan order has {} nodes, expected {}", scan.size(), n);
  Aggregates out;
  out.node_agg.assign(n, -1);
  std::vector<int>& agg = out.node_agg;
  std::vector<int> members, member_ptr{0};  // pass-1 members, by aggregate
  // Pass 1: a free node whose strong neighbours are all free seeds an aggregate of them all.
  for (int t = 0; t < n; ++t) {
    const int i = scan.empty() ? t : scan[t];
    if (special[i] || agg[i] >= 0) continue;
    bool free = true;
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1] && free; ++k)
      if (strong[k] && agg[A.col[k]] >= 0) free = false;
    if (!free) continue;
    const int a = out.count++;
    agg[i] = a;
    members.push_back(i);
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k)
      if (strong[k]) agg[A.col[k]] = a, members.push_back(A.col[k]);
    member_ptr.push_back(static_cast<int>(members.size()));
  }
  // Pass 2: leftovers join the aggregate of a strong neighbour (one layer, original members only).
  std::vector<int> size(out.count, 0);
  for (int a = 0; a < out.count; ++a) {
    size[a] = member_ptr[a + 1] - member_ptr[a];
    for (int t = member_ptr[a]; t < member_ptr[a + 1]; ++t) {
      const int j = members[t];
      for (int k = A.row_ptr[j]; k < A.row_ptr[j + 1]; ++k) {
        const int m = A.col[k];
        if (strong[k] && agg[m] < 0 && !special[m]) agg[m] = a, ++size[a];
      }
    }
  }
  for (int i = 0; i < n; ++i)
    WEFT_ASSERT(special[i] || agg[i] >= 0, "node {} is neither special nor aggregated (strength matrix not symmetric?)", i);
  out.max_size = size.empty() ? 0 : *std::max_element(size.begin(), size.end());
  return out;
}

SheetEdges sheet_edges(const BsrView<3, 3>& A) {
  SheetEdges edges;
  for (int i = 0; i < A.rows; ++i)
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
      const int j = A.col[k];
      if (j <= i) continue;
      const Mat<3> M = A.block(i, k);
      const double f2 = M.squaredNorm();
      if (!(f2 > 0)) continue;  // a block the filters zeroed
      // ||adj M||_F^2: the cofactor rows are the cross products of M's rows.
      const Eigen::Vector3d r0 = M.row(0), r1 = M.row(1), r2 = M.row(2);
      const double adj2 = r1.cross(r2).squaredNorm() + r2.cross(r0).squaredNorm() + r0.cross(r1).squaredNorm();
      if (adj2 > rank_one_tolerance * rank_one_tolerance * f2 * f2) edges.emplace_back(i, j);  // else a spring
    }
  return edges;
}

int split_sheets(const SheetEdges& edges, Aggregates& aggs, const std::vector<int>& scan, const BsrView<3, 3>* A,
                 double bonded) {
  std::vector<int>& agg = aggs.node_agg;
  const int n = static_cast<int>(agg.size());
  UnionFind sheets(n);
  for (const auto& [i, j] : edges)
    if (agg[i] >= 0 && agg[i] == agg[j]) sheets.unite(i, j);
  if (A && bonded > 0) {
    // Sum -A_ij over the couplings between the pieces of each aggregate; keep it whole when
    // that sum is stiff in two directions (springs at several angles bond the layers).
    WEFT_ASSERT(A->rows == n, "{} rows for {} nodes", A->rows, n);
    std::vector<Mat<3>> S(aggs.count, Mat<3>::Zero());
    std::vector<int> first(aggs.count, -1);
    for (int i = 0; i < n; ++i) {
      if (agg[i] < 0) continue;
      if (first[agg[i]] < 0) first[agg[i]] = i;
      for (int k = A->row_ptr[i]; k < A->row_ptr[i + 1]; ++k) {
        const int j = A->col[k];
        if (j != i && agg[j] == agg[i] && sheets.find(i) != sheets.find(j)) S[agg[i]] -= A->block(i, k);
      }
    }
    std::vector<std::uint8_t> whole(aggs.count, 0);
    for (int a = 0; a < aggs.count; ++a) {
      if (!(S[a].squaredNorm() > 0)) continue;
      const Eigen::SelfAdjointEigenSolver<Mat<3>> es(0.5 * (S[a] + S[a].transpose()), Eigen::EigenvaluesOnly);
      const Eigen::Vector3d ev = es.eigenvalues();  // ascending
      whole[a] = ev(2) > 0 && ev(1) > bonded * ev(2);
    }
    for (int i = 0; i < n; ++i)
      if (agg[i] >= 0 && whole[agg[i]]) sheets.unite(i, first[agg[i]]);
  }
  std::vector<int> label(n, -1);
  int count = 0;
  for (int t = 0; t < n; ++t) {
    const int i = scan.empty() ? t : scan[t];
    if (agg[i] >= 0 && label[sheets.find(i)] < 0) label[sheets.find(i)] = count++;
  }
  const int before = aggs.count;
  std::vector<int> size(count, 0);
  for (int i = 0; i < n; ++i)
    if (agg[i] >= 0) agg[i] = label[sheets.find(i)], ++size[agg[i]];
  aggs.count = count;
  aggs.max_size = size.empty() ? 0 : *std::max_element(size.begin(), size.end());
  return count - before;
}

int merge_small_aggregates(const SheetEdges& edges, Aggregates& aggs, int max_size) {
  std::vector<int>& agg = aggs.node_agg;
  std::vector<int> size(aggs.count, 0);
  for (const int a : agg)
    if (a >= 0) ++size[a];
  // One vote (small, large) per sheet coupling between a small and a large aggregate.
  std::vector<std::pair<int, int>> votes;
  for (const auto& [i, j] : edges) {
    const int a = agg[i], b = agg[j];
    if (a < 0 || b < 0 || a == b) continue;
    if (size[a] <= max_size && size[b] > max_size) votes.emplace_back(a, b);
    if (size[b] <= max_size && size[a] > max_size) votes.emplace_back(b, a);
  }
  std::sort(votes.begin(), votes.end());
  std::vector<int> target(aggs.count, -1), best(aggs.count, 0);
  for (std::size_t r = 0; r < votes.size();) {
    std::size_t e = r;
    while (e < votes.size() && votes[e] == votes[r]) ++e;
    const auto [a, b] = votes[r];
    if (static_cast<int>(e - r) > best[a]) best[a] = static_cast<int>(e - r), target[a] = b;  // ties: lowest b
    r = e;
  }
  // Targets are large, so never merged themselves: one pass renumbers.
  std::vector<int> label(aggs.count, -1);
  int count = 0;
  for (int a = 0; a < aggs.count; ++a)
    if (target[a] < 0) label[a] = count++;
  std::fill(size.begin(), size.end(), 0);
  for (int& a : agg)
    if (a >= 0) a = label[target[a] < 0 ? a : target[a]], ++size[a];
  const int merged = aggs.count - count;
  aggs.count = count;
  aggs.max_size = count == 0 ? 0 : *std::max_element(size.begin(), size.begin() + count);
  return merged;
}

SheetEdges coarse_sheet_edges(const SheetEdges& edges, const Aggregates& aggs) {
  SheetEdges coarse;
  coarse.reserve(edges.size() / 4);
  for (const auto& [i, j] : edges) {
    const int a = aggs.node_agg[i], b = aggs.node_agg[j];
    if (a >= 0 && b >= 0 && a != b) coarse.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(coarse.begin(), coarse.end());
  coarse.erase(std::unique(coarse.begin(), coarse.end()), coarse.end());
  return coarse;
}

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
long long truncate_prolongator(BlockMatrix<B, 6>& P, double fraction, int max_blocks) {
  const int n = P.rows();
  const int* pr = P.row_ptr().data();
  long long dropped = 0;
#pragma omp parallel reduction(+ : dropped) if (n > parallel_rows)
  {
    std::vector<double> norms, order;  // one row's squared block norms, buffers reused across the rows
#pragma omp for schedule(static)
    for (int i = 0; i < n; ++i) {
      norms.clear();
      for (int k = pr[i]; k < pr[i + 1]; ++k) norms.push_back(P.block(k).squaredNorm());
      if (norms.empty()) continue;
      double cut = fraction * fraction * *std::max_element(norms.begin(), norms.end());  // compared as squares
      if (max_blocks > 0 && static_cast<int>(norms.size()) > max_blocks) {
        // The max_blocks-th largest norm: blocks below it go as well (ties stay).
        order.assign(norms.begin(), norms.end());
        std::nth_element(order.begin(), order.begin() + (max_blocks - 1), order.end(), std::greater<>());
        cut = std::max(cut, order[max_blocks - 1]);
      }
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

#define WEFT_SA_INSTANTIATE(B)                                                                                        \
  template void strength<B>(const BsrView<B, B>&, double, SocMeasure, std::vector<double>&, std::vector<std::uint8_t>&,  \
                            const SheetEdges*);                                                                       \
  template void strong_flags<B>(const BsrView<B, B>&, const std::vector<double>&, double, std::vector<std::uint8_t>&,    \
                                const SheetEdges*);                                                                   \
  template int special_nodes<B>(const BsrView<B, B>&, const std::vector<double>&, double, std::vector<std::uint8_t>&,   \
                                std::vector<std::uint8_t>&);                                                          \
  template Aggregates aggregate<B>(const BsrView<B, B>&, const std::vector<std::uint8_t>&,                            \
                                   const std::vector<std::uint8_t>&, const std::vector<int>&);                        \
  template Tentative tentative_prolongator<B>(const Aggregates&, const NullSpace&, double);                          \
  template LanczosResult lanczos<B>(const BsrView<B, B>&, const std::vector<double>&, int);                          \
  template BlockMatrix<B, 6> prolongator_pattern<B>(const BsrView<B, B>&, const std::vector<std::uint8_t>*,          \
                                                    const Aggregates&);                                               \
  template void prolongator_values<B>(const BsrView<B, B>&, const std::vector<double>&,                               \
                                      const std::vector<std::uint8_t>*, const Aggregates&, const Tentative&, double,  \
                                      BlockMatrix<B, 6>&);                                                           \
  template double preserve_modes<B>(const BsrView<B, B>&, const std::vector<double>&, const Aggregates&, double, int, \
                                    const NullSpace&, const NullSpace&, BlockMatrix<B, 6>&);                           \
  template BlockMatrix<B, 6> smooth_prolongator<B>(const BsrView<B, B>&, const std::vector<double>&,                  \
                                                   const std::vector<std::uint8_t>*, const Aggregates&, double,       \
                                                   const BlockMatrix<B, 6>&);                                            \
  template long long truncate_prolongator<B>(BlockMatrix<B, 6>&, double, int);                                               \
  template std::vector<int> restriction_chunks<B>(const BsrView<B, 6>&, int);
WEFT_SA_INSTANTIATE(3)
WEFT_SA_INSTANTIATE(6)
#undef WEFT_SA_INSTANTIATE

}  // namespace sa

// ---------------------------------------------------------------------------------------
// The hierarchy
// ---------------------------------------------------------------------------------------

namespace {

/// One level: its operator, smoother data, and the transfer to the next level.
template <int B>
struct Level {
  static constexpr int block = B;
  BsrView<B, B> external;       // the caller's matrix (fine level, reuse != frozen)
  // Galerkin result (coarse: symmetric, upper triangle stored) or private copy (fine, frozen).
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
  BlockMatrix<B, 6> P;           // pattern; its values are freed when Pf or Pq holds them
  std::vector<float> Pf;         // prolongator_storage single: P's values, B x 6 row-major blocks
  std::vector<std::int16_t> Pq;  // prolongator_storage fixed16: P = Pq diag(Pscale)
  std::vector<double> Pscale;    // one scale per coarse dof
  std::vector<int> rchunks;      // row chunks of the restriction P^T r (`restriction_chunks`)
  std::vector<std::uint8_t> dummy;  // per coarse dof
  int deficient = 0;
  bool coarsest = false;

  // implicit_prolongator (level 0): P = Z (I - omega D^-1 A_f) Phat is applied from A and
  // never stored (Z zeroes the rows of special nodes). aggs.node_agg is kept.
  bool implicit = false;
  double omega = 0;
  std::vector<float> Qf;                   // Phat: one B x 6 block per node (zero on special nodes)
  std::vector<int> agg_ptr, agg_nodes;     // the nodes of each aggregate, by increasing index
  std::vector<std::uint64_t> strong_bits;  // filtered smoothing: bit k = block k of A is strong

  // Coarsest solve.
  int direct = 0;  // 0: smoother only, 1: LLT, 2: LDLT
  Eigen::LLT<Eigen::MatrixXd> llt;
  Eigen::LDLT<Eigen::MatrixXd> ldlt;

  // Work vectors (apply is const; one apply at a time).
  // f, x: the level's right-hand side and solution (coarse levels); d: the smoother's
  // correction, also the residual restricted to the next level; res: the residual when the
  // implicit P uses d itself (level 0 only).
  mutable Eigen::VectorXd f, x, res, d;

  std::size_t memory_bytes() const {
    auto vb = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    std::size_t m = own.memory_bytes() + vb(Dinv) + vb(Dinvf) + vb(strong) + vb(filter) + vb(special) + vb(aggs.node_agg) +
                    P.memory_bytes() + vb(Pf) + vb(Pq) + vb(Pscale) + vb(rchunks) + vb(dummy);
    m += vb(Qf) + vb(agg_ptr) + vb(agg_nodes) + vb(strong_bits);
    m += sizeof(double) * (f.size() + x.size() + res.size() + d.size());
    if (direct == 1) m += sizeof(double) * llt.matrixLLT().size();
    if (direct == 2) m += sizeof(double) * (ldlt.matrixLDLT().size() + 2 * ldlt.rows());
    return m;
  }
};

}  // namespace

struct SaAmg::Impl {
  std::unique_ptr<Level<3>> fine = std::make_unique<Level<3>>();
  std::vector<Level<6>> coarse;  // reserved to max_levels: references stay valid
  bool built = false;
  int fine_rows = -1, fine_nnz = -1;
  double nnz_scalar_total = 0, rows_scalar_total = 0;
};

namespace {

/// ||D^-1 A||_inf with D the block diagonal of A as the operator reads it: an upper bound of
/// the spectral radius of D^-1 A (every induced norm bounds it), so of lambda_max(D^-1 A).
template <int B>
double inf_norm_bound(const Level<B>& L) {
  const auto A = L.A();
  const int n = A.rows;
  double g = 0;
#pragma omp parallel for schedule(static) reduction(max : g) if (n > parallel_rows)
  for (int i = 0; i < n; ++i) {
    const int kd = find_block(A, i, i);
    if (kd < 0) continue;
    const Mat<B> Dinv = Mat<B>(A.block(i, kd)).inverse();
    Eigen::Matrix<double, B, 1> row = Eigen::Matrix<double, B, 1>::Zero();
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) row += (Dinv * A.block(i, k)).cwiseAbs().rowwise().sum();
    if (row.allFinite()) g = std::max(g, row.maxCoeff());
  }
  return g;
}

}  // namespace

bool SaAmg::widen_smoothers() {
  if (!impl_->built) return false;
  bool changed = false;
  auto widen = [&](auto& L, int l) {
    if (L.coarsest && L.direct != 0) return;  // solved exactly: no smoother
    // The interval's top, chebyshev_upper * lambda, must cover lambda_max <= g.
    const double lambda = inf_norm_bound(L) / prm_.chebyshev_upper;
    if (!(lambda > L.lambda)) return;
    L.lambda = lambda;
    if (l < static_cast<int>(stats_.levels.size())) stats_.levels[l].lambda = lambda;
    ++widened_;
    changed = true;
  };
  widen(*impl_->fine, 0);
  for (std::size_t l = 0; l < impl_->coarse.size(); ++l) widen(impl_->coarse[l], static_cast<int>(l) + 1);
  return changed;
}

SaAmg::SaAmg(const Params& prm) : prm_(prm), impl_(std::make_unique<Impl>()) { validate(prm_).throw_if_failed(); }
SaAmg::~SaAmg() = default;
SaAmg::SaAmg(SaAmg&&) noexcept = default;
SaAmg& SaAmg::operator=(SaAmg&&) noexcept = default;

Checker SaAmg::validate(const Params& p) {
  Checker c("SaAmg::Params");
  c.require(p.theta > 0 && p.theta < 1, "theta", p.theta, "in (0, 1)")
      .require(p.diagonal_dominance >= 0, "diagonal_dominance", p.diagonal_dominance, ">= 0")
      .require(p.coarse_size >= 1, "coarse_size", p.coarse_size, ">= 1")
      .require(p.max_levels >= 1 && p.max_levels <= 30, "max_levels", p.max_levels, "in [1, 30]")
      .require(p.stall_ratio > 0 && p.stall_ratio <= 1, "stall_ratio", p.stall_ratio, "in (0, 1]")
      .require(p.aggregation_theta >= 0 && p.aggregation_theta < 1, "aggregation_theta", p.aggregation_theta, "in [0, 1) (0: theta)")
      .require(p.dense_limit >= 1, "dense_limit", p.dense_limit, ">= 1")
      .require(p.qr_tolerance > 0 && p.qr_tolerance < 1, "qr_tolerance", p.qr_tolerance, "in (0, 1)")
      .require(p.lanczos_steps >= 1 && p.lanczos_steps <= 100, "lanczos_steps", p.lanczos_steps, "in [1, 100]")
      .require(p.chebyshev_degree >= 1 && p.chebyshev_degree <= 10, "chebyshev_degree", p.chebyshev_degree, "in [1, 10]")
      .require(p.chebyshev_lower > 0 && p.chebyshev_lower < p.chebyshev_upper, "chebyshev_lower", p.chebyshev_lower,
               "in (0, chebyshev_upper)")
      .require(p.cycle_gamma >= 1 && p.cycle_gamma <= 4, "cycle_gamma", p.cycle_gamma, "in [1, 4]")
      .require(p.cycle_gamma_levels >= 1 && p.cycle_gamma_levels <= 30, "cycle_gamma_levels", p.cycle_gamma_levels,
               "in [1, 30]")
      .require(p.prolongator_degree >= 1 && p.prolongator_degree <= 3, "prolongator_degree", p.prolongator_degree,
               "in [1, 3]")
      .require(p.prolongator_degree_levels >= 1 && p.prolongator_degree_levels <= 30, "prolongator_degree_levels",
               p.prolongator_degree_levels, "in [1, 30]")
      .require(!p.implicit_prolongator || p.prolongator_degree == 1, "prolongator_degree", p.prolongator_degree,
               "1 when implicit_prolongator is true (the implicit P is one smoothing step)")
      .require(!p.implicit_prolongator || !p.preserve_modes, "preserve_modes", p.preserve_modes,
               "false when implicit_prolongator is true (the implicit P is applied from A and Phat)")
      .require(p.prolongator_truncation >= 0 && p.prolongator_truncation < 1, "prolongator_truncation",
               p.prolongator_truncation, "in [0, 1)")
      .require(p.prolongator_max_blocks >= 0, "prolongator_max_blocks", p.prolongator_max_blocks, ">= 0")
      .require(p.split_bonded >= 0 && p.split_bonded <= 1, "split_bonded", p.split_bonded, "in [0, 1]")
      .require(!p.sheet_strength || p.split_sheets, "sheet_strength", p.sheet_strength,
               "false unless split_sheets is true (it measures strength within the sheets)")
      .require(p.split_merge >= 0, "split_merge", p.split_merge, ">= 0")
      .require(p.split_merge == 0 || p.split_sheets, "split_merge", p.split_merge,
               "0 unless split_sheets is true (it merges within the sheets)");
  // Both ways of dropping prolongator blocks need the mode repair and fresh patterns.
  auto trims = [&](const char* key, auto value) {
    c.require(value == 0 || p.preserve_modes, key, value,
              "0 unless preserve_modes is true (it repairs the rigid modes the dropped blocks carried)")
        .require(value == 0 || p.reuse == SaReuse::none, key, value,
                 "0 unless reuse is none (the kept blocks, and so the patterns, change with the values)");
  };
  trims("prolongator_truncation", p.prolongator_truncation);
  trims("prolongator_max_blocks", p.prolongator_max_blocks);
  return c;
}

Status SaAmg::analyze_pattern(const BlockCsr& A) {
  impl_->built = false;
  impl_->fine_rows = A.block_rows();
  impl_->fine_nnz = A.num_blocks();
  return Status::success;
}

namespace {

struct BuildContext {
  const SaAmg::Params& prm;
  SaSetupTimes& times;
  std::vector<SaLevelStats>& stats;
  std::vector<Level<6>>& coarse;
};

template <int B>
void make_coarsest(Level<B>& L, const SaAmg::Params& prm) {
  L.coarsest = true;
  L.direct = 0;
  const int N = B * L.n();
  if (N > prm.dense_limit || N == 0) return;
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(N, N);
  const auto A = L.A();
  for (int i = 0; i < A.rows; ++i)
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) D.block<B, B>(B * i, B * A.col[k]) = A.block(i, k);
  L.llt.compute(D);
  if (L.llt.info() == Eigen::Success) {
    L.direct = 1;
    return;
  }
  L.llt = Eigen::LLT<Eigen::MatrixXd>();
  L.ldlt.compute(D);
  if (L.ldlt.info() == Eigen::Success) L.direct = 2;
}

/// The nearest integer to x (|x| <= 32767.5), halves away from zero: inlined, unlike
/// std::nearbyint on the baseline instruction set (45M values per setup at 1M vertices).
inline int round_to_int(double x) { return static_cast<int>(x + std::copysign(0.5, x)); }

/// Rounds P's values to the storage the cycle will read them from (ValueStorage); fixed16
/// also fills L.Pq and the per-column scales L.Pscale (the double values, kept for the
/// Galerkin product, are then exactly Pq diag(Pscale)). Applied before the Galerkin product;
/// T is P's transpose index.
template <int B>
void round_to_storage(Level<B>& L, const TransposeIndex& T, ValueStorage storage) {
  std::vector<double>& v = L.P.values();
  if (storage != ValueStorage::fixed16) {
    L.Pscale = {};
    L.Pq = {};
  }
  if (storage == ValueStorage::single_precision) {
    for (double& x : v) x = static_cast<double>(static_cast<float>(x));
    return;
  }
  if (storage != ValueStorage::fixed16) return;
  const int rows = L.P.rows();
  const int* rp = L.P.row_ptr().data();
  const int* col = L.P.col().data();
  std::vector<double>& s = L.Pscale;
  const int cols = L.P.cols();
  s.assign(static_cast<std::size_t>(6) * cols, 0.0);
  // Parallel over block columns through T.
#pragma omp parallel for schedule(static) if (cols > parallel_rows)
  for (int J = 0; J < cols; ++J)
    for (int t = T.ptr[J]; t < T.ptr[J + 1]; ++t)
      for (int e = 0; e < B * 6; ++e) {  // the largest |entry| of each column
        double& m = s[6 * J + e % 6];
        m = std::max(m, std::abs(v[static_cast<std::size_t>(B * 6) * T.blk[t] + e]));
      }
  for (double& m : s) m /= 32767.0;
  L.Pq.resize(v.size());
#pragma omp parallel for schedule(static) if (rows > parallel_rows)
  for (int i = 0; i < rows; ++i)
    for (int k = rp[i]; k < rp[i + 1]; ++k)
      for (int e = 0; e < B * 6; ++e) {
        const std::size_t at = static_cast<std::size_t>(B * 6) * k + e;
        const double m = s[6 * col[k] + e % 6];
        const int q = m > 0 ? round_to_int(v[at] / m) : 0;
        L.Pq[at] = static_cast<std::int16_t>(q);
        v[at] = q * m;
      }
}

/// The smoother's block inverses in the precision the cycle reads (single_block_inverses),
/// or none on the fine level (fine_inverses_on_the_fly): called once the setup of the level
/// no longer needs them in double.
template <int B>
void keep_inverses(Level<B>& L, const SaAmg::Params& prm) {
  if (B == 3 && prm.fine_inverses_on_the_fly) {
    std::vector<double>().swap(L.Dinv);
    std::vector<float>().swap(L.Dinvf);
  } else if (prm.single_block_inverses) {
    L.Dinvf.assign(L.Dinv.begin(), L.Dinv.end());
    std::vector<double>().swap(L.Dinv);
  } else {
    std::vector<float>().swap(L.Dinvf);
  }
}

double bound_of(const sa::LanczosResult& r, LambdaBound b) {
  switch (b) {
    case LambdaBound::ritz_factor: return 1.1 * r.ritz;
    case LambdaBound::ritz: return r.ritz;
    case LambdaBound::ritz_residual:
    default: return r.ritz + r.residual;
  }
}

/// The threshold aggregation follows (aggregation_theta, or theta when it is 0).
double aggregation_threshold(const SaAmg::Params& prm) { return prm.aggregation_theta > 0 ? prm.aggregation_theta : prm.theta; }

/// Build (or refresh, with `reuse`) level `index` (0 = fine) and recursively the levels below.
template <int B>
Status build_level(BuildContext& ctx, Level<B>& L, int index, NullSpace K, bool reuse, sa::SheetEdges sheets = {},
                   std::vector<int> scan = {}) {
  const auto& prm = ctx.prm;
  auto& T = ctx.times;
  const auto A = L.A();
  const int n = A.rows;
  SaLevelStats st;
  st.rows = n;
  st.block_size = B;
  st.nnz_blocks = A.nnz();
  {
    ScopedTimer t(T.other);
    const int bad = invert_block_diagonal<B>(A, L.Dinv);
    if (bad > 0 && index == 0) return Status::numerical_issue;
  }
  {
    ScopedTimer t(T.lanczos);
    const sa::LanczosResult lr = sa::lanczos<B>(A, L.Dinv, prm.lanczos_steps);
    L.ritz = lr.ritz;
    L.lambda = bound_of(lr, prm.lambda_bound);
  }
  st.ritz = L.ritz;
  st.lambda = L.lambda;
  if (!(L.lambda > 0) || !std::isfinite(L.lambda)) return Status::numerical_issue;

  const bool last = index + 1 >= prm.max_levels || n <= prm.coarse_size;
  std::vector<int> next_scan;  // the next level's scan order (`AggregateOrder::rcm`)
  if (!reuse) {
    L.coarsest = false;
    if (!last) {
      std::vector<double> mu;
      if constexpr (B == 3)
        if (prm.split_sheets) {
          ScopedTimer t(T.aggregation);
          sheets = sa::sheet_edges(A);
        }
      {
        ScopedTimer t(T.strength);
        sa::strength<B>(A, aggregation_threshold(prm), prm.strength, mu, L.strong, prm.sheet_strength ? &sheets : nullptr);
        L.num_special = sa::special_nodes<B>(A, mu, prm.diagonal_dominance, L.strong, L.special);
      }
      {
        ScopedTimer t(T.aggregation);
        L.aggs = sa::aggregate<B>(A, L.strong, L.special, scan);
        if (prm.split_sheets) {
          if constexpr (B == 3)
            L.sheet_splits = sa::split_sheets(sheets, L.aggs, scan, &A, prm.split_bonded);
          else
            L.sheet_splits = sa::split_sheets(sheets, L.aggs, scan);
          if (prm.split_merge > 0) L.sheet_merges = sa::merge_small_aggregates(sheets, L.aggs, prm.split_merge);
        }
        // The next level visits its nodes in their natural order (see `sa::aggregate`).
        if (prm.aggregate_order != AggregateOrder::natural) {
          next_scan = sa::order_aggregates<B>(A, L.aggs, prm.aggregate_order);
          L.reordered = !next_scan.empty();
        }
        if (prm.split_sheets) sheets = sa::coarse_sheet_edges(sheets, L.aggs);
      }
      if (prm.filtered_smoothing && prm.theta != aggregation_threshold(prm)) {
        // The smoothing filter's own threshold; blocks touching a special node stay
        // weak as in L.strong.
        ScopedTimer t(T.strength);
        sa::strong_flags<B>(A, mu, prm.theta, L.filter);
        sa::weaken_special<B>(A, L.special, L.filter);
      } else {
        L.filter = {};
      }
    }
    if (last || L.aggs.count == 0 || L.aggs.count > prm.stall_ratio * n) {
      ScopedTimer t(T.other);
      L.strong = {};
      L.filter = {};
      L.special = {};
      L.aggs = {};
      L.P.clear();
      L.Pf = {};
      L.Pq = {};
      L.Pscale = {};
      make_coarsest(L, prm);
      keep_inverses(L, prm);
      ctx.stats.push_back(st);
      return Status::success;
    }
  } else if (L.coarsest) {
    ScopedTimer t(T.other);
    make_coarsest(L, prm);
    keep_inverses(L, prm);
    ctx.stats.push_back(st);
    return Status::success;
  }
  st.special = L.num_special;
  st.aggregates = L.aggs.count;
  st.max_aggregate = L.aggs.max_size;
  st.sheet_splits = L.sheet_splits;
  st.sheet_merges = L.sheet_merges;
  st.reordered = L.reordered;

  sa::Tentative tent;
  {
    ScopedTimer t(T.qr);
    tent = sa::tentative_prolongator<B>(L.aggs, K, prm.qr_tolerance);
    if (!prm.preserve_modes) K = NullSpace();  // not needed below: free it before the Galerkin product
  }
  L.dummy = tent.dummy;
  L.deficient = tent.deficient;
  st.deficient = tent.deficient;
  const std::vector<std::uint8_t>* strong =
      !prm.filtered_smoothing ? nullptr : (L.filter.empty() ? &L.strong : &L.filter);
  const double omega = 4.0 / (3.0 * L.lambda);
  L.implicit = prm.implicit_prolongator && index == 0;
  const int degree = index < prm.prolongator_degree_levels ? prm.prolongator_degree : 1;
  // P's transpose index, for the fixed16 scales and the Galerkin product only (the cycle
  // restricts by P's rows): built for each setup, freed after the Galerkin product.
  TransposeIndex PT;
  {
    ScopedTimer t(T.smoothing);
    // An implicit P is formed here for the Galerkin product and freed after it.
    // A wider P (degree > 1) is formed from the one-step pattern each time.
    if (!reuse || L.P.rows() == 0 || degree > 1) L.P = sa::prolongator_pattern<B>(A, strong, L.aggs);
    L.P.values().resize(static_cast<std::size_t>(B * 6) * L.P.nnz());  // reallocated if a compact storage freed it
    sa::prolongator_values<B>(A, L.Dinv, strong, L.aggs, tent, omega, L.P);
    for (int d = 1; d < degree; ++d) L.P = sa::smooth_prolongator<B>(A, L.Dinv, strong, L.aggs, omega, L.P);
    if (prm.prolongator_truncation > 0 || prm.prolongator_max_blocks > 0)
      st.truncated = sa::truncate_prolongator<B>(L.P, prm.prolongator_truncation, prm.prolongator_max_blocks);
    if (prm.preserve_modes) {
      if (strong || st.truncated > 0)  // the filter, or the dropped blocks, moved P Kc
        st.mode_correction = sa::preserve_modes<B>(A, L.Dinv, L.aggs, omega, degree, K, tent.Kc, L.P);
      K = NullSpace();
    }
    if (!reuse && prm.reuse == SaReuse::none) L.P.prune_zero_blocks();
    PT.build(L.P.view());
    if (!L.implicit)  // rounded before the Galerkin product: A_c = P^T A P for the stored P
      round_to_storage(L, PT, prm.prolongator_storage);
  }
  st.nnz_p = L.P.nnz();
  if (L.implicit) {
    ScopedTimer t(T.other);
    L.omega = omega;
    L.Qf.assign(tent.Q.begin(), tent.Q.end());
    const std::vector<int>& agg = L.aggs.node_agg;
    L.agg_ptr.assign(L.aggs.count + 1, 0);
    for (int i = 0; i < n; ++i)
      if (agg[i] >= 0) ++L.agg_ptr[agg[i] + 1];
    for (int J = 0; J < L.aggs.count; ++J) L.agg_ptr[J + 1] += L.agg_ptr[J];
    L.agg_nodes.assign(L.agg_ptr.back(), 0);
    std::vector<int> fill(L.agg_ptr.begin(), L.agg_ptr.end() - 1);
    for (int i = 0; i < n; ++i)
      if (agg[i] >= 0) L.agg_nodes[fill[agg[i]]++] = i;
    L.strong_bits.assign(strong ? (static_cast<std::size_t>(A.nnz()) + 63) / 64 : 0, 0);
    if (strong)
      for (int k = 0; k < A.nnz(); ++k)
        if ((*strong)[k]) L.strong_bits[k >> 6] |= std::uint64_t{1} << (k & 63);
  } else {
    L.Qf = {};
    L.agg_ptr = {};
    L.agg_nodes = {};
    L.strong_bits = {};
  }
  tent.Q = {};
  keep_inverses(L, prm);

  const int nc = L.aggs.count;
  if (!reuse) {
    ctx.coarse.emplace_back();
  }
  Level<6>& C = ctx.coarse[index];
  {
    ScopedTimer t(T.galerkin);
    if (!reuse) {
      C.own = Galerkin<B, 6>::symbolic(A, L.P.view(), PT, prm.single_coarse_operators);
    }
    Galerkin<B, 6>::numeric(A, L.P.view(), PT, C.own);  // exactly symmetric
    PT = {};  // freed before the levels below are built
    // Dummy coarse dofs (dropped QR columns) have zero rows and columns: give them the mean
    // diagonal so A_c stays SPD; they are decoupled from everything else.
    double sum = 0;
    long count = 0;
    for (int I = 0; I < nc; ++I) {
      const auto D = C.own.stored_value(C.own.diagonal_index(I));
      for (int c = 0; c < 6; ++c)
        if (!L.dummy[6 * I + c]) sum += D(c, c), ++count;
    }
    const double mean = count > 0 ? sum / count : 1.0;
    for (int I = 0; I < nc; ++I) {
      bool any = false;
      for (int c = 0; c < 6; ++c) any = any || L.dummy[6 * I + c];
      if (!any) continue;
      const int s = C.own.diagonal_index(I);
      auto D = C.own.stored_value(s);
      for (int c = 0; c < 6; ++c)
        if (L.dummy[6 * I + c]) D(c, c) = mean;
      C.own.store(s, D);
    }
  }
  L.Pf = {};
  if (L.implicit) {  // the cycle applies P from A, Qf and the aggregates
    L.P.clear();
    L.Pq = {};
    L.Pscale = {};
  } else if (prm.prolongator_storage == ValueStorage::single_precision) {  // the cycle reads P from here on
    L.Pf.assign(L.P.values().begin(), L.P.values().end());
    std::vector<double>().swap(L.P.values());
  } else if (prm.prolongator_storage == ValueStorage::fixed16) {  // Pq holds it (round_to_storage)
    std::vector<double>().swap(L.P.values());
  }
  // The cycle restricts by P's rows (`restrict_rows`), with no transpose index (8 bytes per
  // block of P).
  L.rchunks = L.implicit ? std::vector<int>{} : sa::restriction_chunks<B>(L.P.view());
  st.restriction_chunks = std::max(0, static_cast<int>(L.rchunks.size()) - 1);
  if (prm.reuse == SaReuse::none) {
    // Nothing reads the coarsening structure again before the next setup rebuilds it: give
    // it back now (only `aggregates` refreshes values on the kept structure).
    std::vector<std::uint8_t>().swap(L.strong);
    std::vector<std::uint8_t>().swap(L.filter);
    std::vector<std::uint8_t>().swap(L.special);
    if (!L.implicit) std::vector<int>().swap(L.aggs.node_agg);
    std::vector<std::uint8_t>().swap(L.dummy);
  }
  L.coarsest = false;
  ctx.stats.push_back(st);
  // Work vectors of the coarse level.
  C.f.resize(6 * nc);
  C.x.resize(6 * nc);
  C.d.resize(6 * nc);
  return build_level<6>(ctx, C, index + 1, std::move(tent.Kc), reuse, std::move(sheets), std::move(next_scan));
}

}  // namespace

Status SaAmg::setup(const BlockCsr& A, const SolveContext& ctx) { return setup(A, ctx, VertexFilterView{}); }

Status SaAmg::setup(const BlockCsr& A, const SolveContext& ctx, const VertexFilterView& filter) {
  Impl& I = *impl_;
  stats_.message.clear();
  if (!ctx.positions) {
    stats_.message = "SaAmg needs the vertex positions for the rotation modes: set SolveContext::positions";
    return Status::invalid_input;
  }
  const int n = A.block_rows();
  if (ctx.positions->size() != 3 * n) {
    stats_.message = fmt::format("SaAmg: positions have {} entries, the matrix {} rows", ctx.positions->size(), 3 * n);
    return Status::invalid_input;
  }
  if (ctx.constraints && ctx.constraints->num_vertices() != n && !ctx.constraints->empty()) {
    stats_.message = fmt::format("SaAmg: constraint set has {} vertices, the matrix {}", ctx.constraints->num_vertices(), n);
    return Status::invalid_input;
  }
  const bool same_pattern = I.built && I.fine_rows == n && I.fine_nnz == A.num_blocks();
  const bool reuse = same_pattern && prm_.reuse != SaReuse::none;
  stats_.reused = reuse;
  if (reuse && prm_.reuse == SaReuse::frozen) return Status::success;

  SaSetupTimes times;
  double total = 0;
  Status status;
  {
    ScopedTimer t(total);
    if (!reuse) {
      I.coarse.clear();
      I.coarse.reserve(prm_.max_levels);
      I.fine = std::make_unique<Level<3>>();
    }
    Level<3>& F = *I.fine;
    if (prm_.reuse == SaReuse::frozen) {
      F.own = BlockMatrix<3, 3>(n, n, A.row_ptr(), A.col());
      F.own.values() = A.values();
      if (!filter.empty()) {  // the copy holds Ahat itself: the filters need not outlive setup
        BsrView<3, 3> v = bsr_view(A);
        v.filter = filter;
        for (int i = 0; i < n; ++i)
          for (int k = A.row_ptr()[i]; k < A.row_ptr()[i + 1]; ++k) F.own.block(k) = v.block(i, k);
      }
      F.uses_external = false;
    } else {
      F.external = bsr_view(A);
      F.external.filter = filter;
      F.uses_external = true;
    }
    F.res.resize(prm_.implicit_prolongator ? 3 * n : 0);  // the implicit P's residual vector
    Eigen::VectorXd().swap(F.d);  // allocated by the first apply that brings no work vector
    NullSpace K;
    {
      ScopedTimer tk(times.other);
      K = sa::rigid_body_modes(*ctx.positions, ctx.constraints && !ctx.constraints->empty() ? ctx.constraints : nullptr);
    }
    stats_.levels.clear();
    BuildContext bc{prm_, times, stats_.levels, I.coarse};
    status = build_level<3>(bc, F, 0, std::move(K), reuse);
  }
  times.total = total;
  stats_.times = times;
  I.fine_rows = n;
  I.fine_nnz = A.num_blocks();
  if (status != Status::success) {
    I.built = false;
    if (stats_.message.empty()) stats_.message = "SaAmg setup failed: a diagonal block is singular or lambda is not finite";
    return status;
  }
  I.built = true;
  const int L = levels();
  stats_.coarse_direct = (L == 1 ? I.fine->direct : I.coarse[L - 2].direct) != 0;
  return Status::success;
}

int SaAmg::levels() const {
  if (!impl_->built) return 0;
  return 1 + static_cast<int>(impl_->coarse.size());
}

// ---------------------------------------------------------------------------------------
// The cycle
// ---------------------------------------------------------------------------------------

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
/// (prolongator_storage: double, float, or int16 with one scale per column).
template <int B, class F>
void with_prolongator_values(const Level<B>& L, F&& f) {
  if (!L.Pq.empty())
    f(L.Pq.data(), L.Pscale.data());
  else if (!L.Pf.empty())
    f(L.Pf.data(), static_cast<const double*>(nullptr));
  else
    f(L.P.values().data(), static_cast<const double*>(nullptr));
}

/// Row i of A_f w (transpose: of A_f^T w), A_f the matrix P was smoothed with: A, with the
/// weak blocks lumped into the diagonal when the level keeps strong flags. A_f's off-diagonal
/// blocks are symmetric, its lumped diagonal blocks are not: A_f^T's diagonal block i is the
/// diagonal block of A plus sum over weak j of A_ij^T. Read through the vertex filters of a
/// prefiltered fine level as the setup read it.
template <int B>
Vec<B> smoothing_row(const Level<B>& L, const BsrView<B, B>& A, int i, const double* w, bool transpose) {
  using In = Eigen::Map<const Vec<B>>;
  const std::uint64_t* bits = L.strong_bits.empty() ? nullptr : L.strong_bits.data();
  auto kept = [&](int k, int j) { return j == i || !bits || ((bits[k >> 6] >> (k & 63)) & 1u); };
  Vec<B> acc = Vec<B>::Zero();
  if constexpr (B == 3) {
    if (!A.src && !A.valf) {  // the fine level: 3x3 blocks in double, maybe filtered
      const VertexFilterView& F = A.filter;
      const int si = F.empty() ? -1 : F.slot[i];
      Vec<3> lumped_t = Vec<3>::Zero();  // transpose: sum over weak j of Ahat_ij^T w_i = S_j A_ij^T S_i w_i
      const Vec<3> Swi = si >= 0 ? Vec<3>(F.filter(si) * In(w + 3 * i)) : Vec<3>(In(w + 3 * i));
      for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
        const int j = A.col[k], sj = F.empty() ? -1 : F.slot[j];
        const Eigen::Map<const BlockOf<3, 3>> Aij(A.val + 9 * static_cast<std::ptrdiff_t>(k));
        if (transpose && !kept(k, j)) {
          const Vec<3> v = Aij.transpose() * Swi;
          lumped_t += sj >= 0 ? Vec<3>(F.filter(sj) * v) : v;
          continue;
        }
        const In y(w + 3 * (kept(k, j) ? j : i));
        if (sj < 0)
          acc.noalias() += Aij * y;
        else
          acc.noalias() += Aij * (F.filter(sj) * y);
      }
      if (si >= 0) {
        const Vec<3> wi = In(w + 3 * i);
        acc = (F.filter(si) * acc + F.sigma[si] * (wi - F.filter(si) * wi)).eval();
      }
      return acc + lumped_t;
    }
  }
  for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
    const int j = A.col[k];
    if (kept(k, j))
      acc.noalias() += A.block(i, k) * In(w + B * j);
    else if (transpose)
      acc.noalias() += A.block(i, k).transpose() * In(w + B * i);
    else
      acc.noalias() += A.block(i, k) * In(w + B * i);
  }
  return acc;
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

/// fc = P^T r. Implicit P: P^T = Phat^T (I - omega A_f^T D^-1) Z, with w as work vector.
template <int B>
void restrict_to(const Level<B>& L, const double* r, double* fc, double* w) {
  if (!L.implicit) {
    with_prolongator_values(L, [&](const auto* p, const double* s) { restrict_rows(L.P.view(), L.rchunks, p, r, fc, s); });
    return;
  }
  const auto A = L.A();
  const int n = A.rows, nc = static_cast<int>(L.agg_ptr.size()) - 1;
  const int* agg = L.aggs.node_agg.data();
  with_inverses(L, [&](const auto* Dinv) {
#pragma omp parallel for schedule(static) if (n > parallel_rows)
    for (int i = 0; i < n; ++i)
      Eigen::Map<Vec<B>>(w + B * i) =
          agg[i] >= 0 ? inverse_times(A, Dinv, i, Vec<B>(Eigen::Map<const Vec<B>>(r + B * i))) : Vec<B>::Zero();
  });
#pragma omp parallel for schedule(static) if (nc > parallel_rows / 8)
  for (int J = 0; J < nc; ++J) {
    Vec<6> acc = Vec<6>::Zero();
    for (int t = L.agg_ptr[J]; t < L.agg_ptr[J + 1]; ++t) {
      const int i = L.agg_nodes[t];
      const Vec<B> v = Eigen::Map<const Vec<B>>(r + B * i) - L.omega * smoothing_row(L, A, i, w, /*transpose=*/true);
      acc.noalias() += value_block<B, 6>(L.Qf.data(), i).transpose() * v;
    }
    Eigen::Map<Vec<6>>(fc + 6 * J) = acc;
  }
}

/// x += P xc. Implicit P: P = Z (I - omega D^-1 A_f) Phat, with t as work vector.
template <int B>
void prolong_add(const Level<B>& L, const double* xc, double* x, double* t) {
  if (!L.implicit) {
    with_prolongator_values(L, [&](const auto* p, const double* s) { multiply_add(L.P.view(), p, xc, x, s); });
    return;
  }
  const auto A = L.A();
  const int n = A.rows;
  const int* agg = L.aggs.node_agg.data();
#pragma omp parallel for schedule(static) if (n > parallel_rows)
  for (int i = 0; i < n; ++i)
    Eigen::Map<Vec<B>>(t + B * i) =
        agg[i] >= 0 ? Vec<B>(value_block<B, 6>(L.Qf.data(), i) * Eigen::Map<const Vec<6>>(xc + 6 * agg[i])) : Vec<B>::Zero();
  with_inverses(L, [&](const auto* Dinv) {
#pragma omp parallel for schedule(static) if (n > parallel_rows)
    for (int i = 0; i < n; ++i) {
      if (agg[i] < 0) continue;
      Eigen::Map<Vec<B>>(x + B * i) +=
          Eigen::Map<const Vec<B>>(t + B * i) - L.omega * inverse_times(A, Dinv, i, smoothing_row(L, A, i, t, false));
    }
  });
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
  // The residual goes to the smoother's work vector, free until the post-smoothing (an
  // implicit P needs that one for itself and has its own residual vector).
  double* r = L.implicit ? L.res.data() : d;
  residual(A, f, x, r);
  restrict_to(L, r, C.f.data(), d);
  cycle(C, coarse, index + 1, prm, C.f.data(), C.x.data(), C.d.data());
  // mu-cycle on the first cycle_gamma_levels coarse levels: x_c += V_c (f_c - A_c x_c), so the
  // correction is (I - (I - V_c A_c)^gamma) A_c^-1 f_c, symmetric in A_c (methods/multigrid §2.4). The
  // cycle from the current x_c applies that update in place: no residual or correction vector.
  if (!C.coarsest && index + 1 <= prm.cycle_gamma_levels)
    for (int r = 1; r < prm.cycle_gamma; ++r)
      cycle(C, coarse, index + 1, prm, C.f.data(), C.x.data(), C.d.data(), /*zero_guess=*/false);
  prolong_add(L, C.x.data(), x, d);
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
  cycle(*I.fine, I.coarse, 0, prm_, r.data(), z.data(), work.data());
}

void SaAmg::smooth(int l, const Eigen::VectorXd& f, Eigen::VectorXd& x) const {
  const Impl& I = *impl_;
  WEFT_ASSERT(l >= 0 && l < levels(), "level {} out of range", l);
  if (l == 0) {
    WEFT_ASSERT(x.size() == f.size() && f.size() == 3 * I.fine->n(), "size mismatch");
    chebyshev(*I.fine, prm_, f.data(), x.data(), false, work_of(*I.fine));
  } else {
    const Level<6>& C = I.coarse[l - 1];
    WEFT_ASSERT(x.size() == f.size() && f.size() == 6 * C.n(), "size mismatch");
    chebyshev(C, prm_, f.data(), x.data(), false, work_of(C));
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
    if (L.implicit || !L.Pq.empty()) {  // column by column, through the cycle's own application of P
      const int n = L.n(), nc = L.implicit ? static_cast<int>(L.agg_ptr.size()) - 1 : L.P.cols();
      constexpr int B = std::remove_cvref_t<decltype(L)>::block;
      Eigen::MatrixXd D = Eigen::MatrixXd::Zero(B * n, 6 * nc);
      Eigen::VectorXd ec = Eigen::VectorXd::Zero(6 * nc), x(B * n);
      for (int c = 0; c < 6 * nc; ++c) {
        ec[c] = 1;
        x.setZero();
        prolong_add(L, ec.data(), x.data(), work_of(L));
        D.col(c) = x;
        ec[c] = 0;
      }
      return D;
    }
    if (L.Pf.empty()) return L.P.to_dense();
    auto P = L.P;  // the pattern, with the float values in double (a diagnostic: a copy is fine)
    P.values().assign(L.Pf.begin(), L.Pf.end());
    return P.to_dense();
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
