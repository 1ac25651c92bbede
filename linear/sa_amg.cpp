/// \file sa_amg.cpp
/// Smoothed aggregation, setup stage 4 (methods/multigrid §4.9-4.10): the hierarchy. Each level
/// runs the stages of sa_strength.cpp, sa_aggregation.cpp and sa_prolongator.cpp, forms its
/// coarse operator A_c = P^T A P (linear/bsr.hpp's Galerkin product) and recurses; the
/// coarsest is factorised densely. Also the parameters' validation and the smoother widening
/// after an indefinite cycle. The cycle that applies the hierarchy: sa_cycle.cpp.
#include "linear/sa_amg.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <numeric>
#include <string>
#include <type_traits>
#include <utility>

#include "framework/error.hpp"
#include "framework/params_json.hpp"
#include "framework/timers.hpp"
#include "framework/union_find.hpp"
#include "linear/sa_internal.hpp"

namespace weft::linear {

namespace {

/// Reuse modes that refresh the values on a kept structure (and so keep a truncated P's pattern).
constexpr bool refreshes_values(SaReuse r) { return r == SaReuse::aggregates || r == SaReuse::step; }
/// Reuse modes whose hierarchy outlives the caller's values: the fine level holds its own copy.
/// (`step` reads the caller's current matrix on the fine level: see SaReuse::step.)
constexpr bool owns_fine_copy(SaReuse r) { return r == SaReuse::frozen; }

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
    const double lambda = inf_norm_bound(L) / active_.chebyshev_upper;
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

SaAmg::SaAmg(const Params& prm) : prm_(prm), active_(prm), impl_(std::make_unique<Impl>()) { validate(prm_).throw_if_failed(); }
SaAmg::~SaAmg() = default;
SaAmg::SaAmg(SaAmg&&) noexcept = default;
SaAmg& SaAmg::operator=(SaAmg&&) noexcept = default;

SaAmg::Params SaAmg::Params::of(SaPreset p) {
  Params q;
  q.preset = p;
  switch (p) {
    case SaPreset::thesis:
      q.reuse = SaReuse::none;
      break;
    case SaPreset::large:
      // bench/results/table-11-1/MERGE.md: every Table 11.1 target met, 10k-1M vertices.
      q.aggregation_theta = 0.25;
      q.cycle_gamma = 2;
      q.cycle_gamma_levels = 2;
      q.preserve_modes = true;
      q.split_sheets = true;
      q.sheet_strength = true;
      q.split_bonded = 0.01;
      q.prolongator_degree = 2;
      q.prolongator_degree_levels = 1;
      q.prolongator_truncation = 0.05;
      q.split_merge = 3;
      break;
    case SaPreset::automatic:
      break;
  }
  return q;
}

SaAmg::Params SaAmg::Params::resolved(int rows) const {
  if (preset != SaPreset::automatic || rows < large_from) return *this;
  // The settings that differ from auto's, as keys, read over large's.
  const auto keys = [](Params p) {
    Json j;
    JsonWriter w(j);
    p.visit(w);
    return j;
  };
  const Json mine = keys(*this), base = keys(of(SaPreset::automatic));
  Json changed = Json::object();
  for (auto it = mine.begin(); it != mine.end(); ++it) {
    const bool named = std::find(given.begin(), given.end(), it.key()) != given.end();
    if (it.key() != "preset" && (named || base.at(it.key()) != it.value())) changed[it.key()] = it.value();
  }
  Params out = of(SaPreset::large);
  std::vector<std::string> errors;
  JsonReader r(changed, "", errors);
  out.visit(r);
  return out;  // written by the same visit: nothing to report
}

Checker SaAmg::validate(const Params& p) {
  Checker c("SaAmg::Params");
  c.require(p.large_from >= 1, "large_from", p.large_from, ">= 1");
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
      .require(p.prolongator_truncation >= 0 && p.prolongator_truncation < 1, "prolongator_truncation",
               p.prolongator_truncation, "in [0, 1)")
      .require(p.split_bonded >= 0 && p.split_bonded <= 1, "split_bonded", p.split_bonded, "in [0, 1]")
      .require(!p.sheet_strength || p.split_sheets, "sheet_strength", p.sheet_strength,
               "false unless split_sheets is true (it measures strength within the sheets)")
      .require(p.split_merge >= 0, "split_merge", p.split_merge, ">= 0")
      .require(p.split_merge == 0 || p.split_sheets, "split_merge", p.split_merge,
               "0 unless split_sheets is true (it merges within the sheets)")
      .require(p.prolongator_truncation == 0 || p.preserve_modes, "prolongator_truncation", p.prolongator_truncation,
               "0 unless preserve_modes is true (it repairs the rigid modes the dropped blocks carried)");
  // Under auto the large settings must hold too, with the keys given beside it.
  if (p.preset == SaPreset::automatic) {
    const Checker large = validate(p.resolved(std::numeric_limits<int>::max()));
    for (const std::string& v : large.violations())
      if (std::find(c.violations().begin(), c.violations().end(), v) == c.violations().end())
        c.fail(fmt::format("from large_from = {} fine rows (preset auto takes the large settings): {}", p.large_from, v));
  }
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

/// Stages 1-2 on level L: strength and special nodes (sa_strength.cpp), then the aggregates,
/// split into sheets and numbered (sa_aggregation.cpp, sa_ordering.cpp). `sheets` enters as
/// the level's sheet couplings (coarse levels) and leaves as the next level's. Returns the
/// next level's scan order (empty: natural).
template <int B>
std::vector<int> coarsen(BuildContext& ctx, Level<B>& L, sa::SheetEdges& sheets, const std::vector<int>& scan) {
  const auto& prm = ctx.prm;
  auto& T = ctx.times;
  const auto A = L.A();
  std::vector<int> next_scan;
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
  if (prm.theta != aggregation_threshold(prm)) {
    // The smoothing filter's own threshold; blocks touching a special node stay
    // weak as in L.strong.
    ScopedTimer t(T.strength);
    sa::strong_flags<B>(A, mu, prm.theta, L.filter);
    sa::weaken_special<B>(A, L.special, L.filter);
  } else {
    L.filter = {};
  }
  return next_scan;
}

/// Restricts P to the pattern (ptr, col), a subset of P's: the truncation of the first setup
/// under reuse, so that the coarse operators keep their patterns. Returns the blocks dropped.
template <int B>
long long restrict_prolongator(BlockMatrix<B, 6>& P, const std::vector<int>& ptr, const std::vector<int>& col) {
  BlockMatrix<B, 6> R(P.rows(), P.cols(), ptr, col);
  for (int i = 0; i < P.rows(); ++i)
    for (int k = ptr[i]; k < ptr[i + 1]; ++k)
      if (const int m = P.find(i, col[k]); m >= 0) R.block(k) = P.block(m);
  const long long dropped = static_cast<long long>(P.nnz()) - R.nnz();
  P = std::move(R);
  return dropped;
}

/// Stage 4, the coarse operator A_c = P^T A P of level L into C (the symbolic product unless
/// `reuse` keeps C's pattern); dummy coarse dofs (dropped QR columns) have zero rows and
/// columns and get the mean diagonal, so that A_c stays SPD with them decoupled.
template <int B>
void coarse_operator(const Level<B>& L, const TransposeIndex& PT, bool reuse, bool single, Level<6>& C) {
  const auto A = L.A();
  const int nc = L.aggs.count;
  if (!reuse) C.own = Galerkin<B, 6>::symbolic(A, L.P.view(), PT, single);
  Galerkin<B, 6>::numeric(A, L.P.view(), PT, C.own);  // exactly symmetric
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

/// After the Galerkin product: keeps P in the storage the cycle reads, its restriction chunks, and (reuse = none) frees the coarsening structure,
/// which nothing reads again before the next setup rebuilds it. Returns the chunk count.
template <int B>
int keep_for_cycle(Level<B>& L, const SaAmg::Params& prm) {
  if (prm.prolongator_storage == ValueStorage::fixed16)  // Pq holds it (round_to_storage)
    std::vector<double>().swap(L.P.values());
  // The cycle restricts by P's rows (`restrict_rows`), with no transpose index (8 bytes per
  // block of P).
  L.rchunks = sa::restriction_chunks<B>(L.P.view());
  if (prm.reuse == SaReuse::none) {
    // Only `aggregates` and `step` refresh values on the kept structure.
    std::vector<std::uint8_t>().swap(L.strong);
    std::vector<std::uint8_t>().swap(L.filter);
    std::vector<std::uint8_t>().swap(L.special);
    std::vector<int>().swap(L.aggs.node_agg);
    std::vector<std::uint8_t>().swap(L.dummy);
  }
  return std::max(0, static_cast<int>(L.rchunks.size()) - 1);
}

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
    if (!last) next_scan = coarsen(ctx, L, sheets, scan);
    if (last || L.aggs.count == 0 || L.aggs.count > prm.stall_ratio * n) {
      ScopedTimer t(T.other);
      L.strong = {};
      L.filter = {};
      L.special = {};
      L.aggs = {};
      L.P.clear();
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
  // The prolongator is smoothed with A_f, the strong blocks (weak ones lumped into the diagonal).
  const std::vector<std::uint8_t>* strong = L.filter.empty() ? &L.strong : &L.filter;
  const double omega = 4.0 / (3.0 * L.lambda);
  const int degree = index < prm.prolongator_degree_levels ? prm.prolongator_degree : 1;
  // P's transpose index, for the fixed16 scales and the Galerkin product only (the cycle
  // restricts by P's rows): built for each setup, freed after the Galerkin product.
  TransposeIndex PT;
  {
    ScopedTimer t(T.smoothing);
    // A wider P (degree > 1) is formed from the one-step pattern each time.
    // A truncated P is formed whole and restricted to its first setup's pattern under reuse.
    const bool truncating = prm.prolongator_truncation > 0;
    if (!reuse || L.P.rows() == 0 || degree > 1 || truncating) L.P = sa::prolongator_pattern<B>(A, strong, L.aggs);
    L.P.values().resize(static_cast<std::size_t>(B * 6) * L.P.nnz());  // reallocated if a compact storage freed it
    sa::prolongator_values<B>(A, L.Dinv, strong, L.aggs, tent, omega, L.P);
    for (int d = 1; d < degree; ++d) L.P = sa::smooth_prolongator<B>(A, L.Dinv, strong, L.aggs, omega, L.P);
    if (truncating && reuse) {
      st.truncated = restrict_prolongator<B>(L.P, L.kept_ptr, L.kept_col);
    } else if (truncating) {
      st.truncated = sa::truncate_prolongator<B>(L.P, prm.prolongator_truncation);
      if (refreshes_values(prm.reuse)) {
        L.kept_ptr = L.P.row_ptr();
        L.kept_col = L.P.col();
      }
    }
    if (prm.preserve_modes) {
      // The filter, and any dropped blocks, moved P Kc.
      st.mode_correction = sa::preserve_modes<B>(A, L.Dinv, L.aggs, omega, degree, K, tent.Kc, L.P);
      K = NullSpace();
    }
    if (!reuse && prm.reuse == SaReuse::none) L.P.prune_zero_blocks();
    PT.build(L.P.view());
    round_to_storage(L, PT, prm.prolongator_storage);  // before the Galerkin product: A_c = P^T A P for the stored P
  }
  st.nnz_p = L.P.nnz();
  tent.Q = {};
  keep_inverses(L, prm);

  const int nc = L.aggs.count;
  if (!reuse) {
    ctx.coarse.emplace_back();
  }
  Level<6>& C = ctx.coarse[index];
  {
    ScopedTimer t(T.galerkin);
    coarse_operator(L, PT, reuse, prm.single_coarse_operators, C);
    PT = {};  // freed before the levels below are built
  }
  st.restriction_chunks = keep_for_cycle(L, prm);
  L.coarsest = false;
  ctx.stats.push_back(st);
  // Work vectors of the coarse level.
  C.f.resize(6 * nc);
  C.x.resize(6 * nc);
  C.d.resize(6 * nc);
  return build_level<6>(ctx, C, index + 1, std::move(tent.Kc), reuse, std::move(sheets), std::move(next_scan));
}

/// FNV-1a over the row pointers and column indices.
std::uint64_t pattern_fingerprint(const BlockCsr& A) {
  std::uint64_t h = 1469598103934665603ull;
  const auto mix = [&h](int v) {
    h ^= static_cast<std::uint32_t>(v);
    h *= 1099511628211ull;
  };
  for (int v : A.row_ptr()) mix(v);
  for (int v : A.col()) mix(v);
  return h;
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
  // Reuse needs the very pattern the structure was built on: contact pairs that come and go
  // can leave the block count unchanged while moving blocks.
  const std::uint64_t pattern = pattern_fingerprint(A);
  const bool same_pattern = I.built && I.fine_rows == n && I.fine_nnz == A.num_blocks() && I.fine_pattern == pattern;
  const bool reuse = same_pattern && active_.reuse != SaReuse::none;
  stats_.reused = reuse;
  const bool keeps_all = active_.reuse == SaReuse::frozen || (active_.reuse == SaReuse::step && !step_begun_);
  if (reuse && keeps_all) {
    stats_.times = {};  // nothing was set up
    if (!owns_fine_copy(active_.reuse)) {
      // `step`: the fine level smooths with the current matrix, the coarse levels stay.
      I.fine->external = bsr_view(A);
      I.fine->external.filter = filter;
    }
    kept_ = true;
    return Status::success;
  }
  kept_ = false;
  if (!reuse) active_ = prm_.resolved(n);  // kept with the structure it built

  SaSetupTimes times;
  double total = 0;
  Status status;
  {
    ScopedTimer t(total);
    if (!reuse) {
      I.coarse.clear();
      I.coarse.reserve(active_.max_levels);
      I.fine = std::make_unique<Level<3>>();
    }
    Level<3>& F = *I.fine;
    if (owns_fine_copy(active_.reuse)) {
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
    Eigen::VectorXd().swap(F.d);  // allocated by the first apply that brings no work vector
    NullSpace K;
    {
      ScopedTimer tk(times.other);
      K = sa::rigid_body_modes(*ctx.positions, ctx.constraints && !ctx.constraints->empty() ? ctx.constraints : nullptr);
    }
    stats_.levels.clear();
    BuildContext bc{active_, times, stats_.levels, I.coarse};
    status = build_level<3>(bc, F, 0, std::move(K), reuse);
  }
  times.total = total;
  stats_.times = times;
  I.fine_rows = n;
  I.fine_nnz = A.num_blocks();
  I.fine_pattern = pattern;
  if (status != Status::success) {
    I.built = false;
    if (stats_.message.empty()) stats_.message = "SaAmg setup failed: a diagonal block is singular or lambda is not finite";
    return status;
  }
  I.built = true;
  step_begun_ = false;
  ++refreshes_;
  const int L = levels();
  stats_.coarse_direct = (L == 1 ? I.fine->direct : I.coarse[L - 2].direct) != 0;
  return Status::success;
}

int SaAmg::levels() const {
  if (!impl_->built) return 0;
  return 1 + static_cast<int>(impl_->coarse.size());
}

}  // namespace weft::linear
