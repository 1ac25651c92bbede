/// \file sa_aggregation.cpp
/// Smoothed aggregation, setup stage 2 (methods/multigrid §4.5): the greedy aggregation of the
/// strong couplings, and the optional split of aggregates into sheets (with the merge of
/// small pieces) for layers joined by springs. The numbering of the aggregates is in
/// sa_ordering.cpp. Next: sa_prolongator.cpp.
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

#define WEFT_SA_INSTANTIATE(B)                                                                                               \
  template Aggregates aggregate<B>(const BsrView<B, B>&, const std::vector<std::uint8_t>&, const std::vector<std::uint8_t>&, \
    const std::vector<int>&);
WEFT_SA_INSTANTIATE(3)
WEFT_SA_INSTANTIATE(6)
#undef WEFT_SA_INSTANTIATE

}  // namespace sa

}  // namespace weft::linear
