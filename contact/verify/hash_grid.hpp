#pragma once
/// \file hash_grid.hpp
/// Broad phase of the intersection check: the pairs of closed axis-aligned boxes that
/// overlap, found with a uniform hash grid (deliberately not the BVH of the detection
/// code, so that the check shares no structure with what it checks).
///
/// Guarantee: every overlapping pair is listed, exactly once. Boxes are the exact
/// min/max of their triangle's coordinates, overlap is tested with closed comparisons,
/// and a coordinate's cell is floor((x - origin) / h) clamped, a monotone function of x:
/// a point common to two boxes lies in a cell both boxes cover. A pair met in several
/// common cells is kept only in the cell of the lower corner of the boxes' intersection,
/// max(lo_i, lo_j) per axis: a common cell c is that one iff on every axis c equals the
/// lower cell of one of the two boxes, a per-entry 3-bit mask.
///
/// Method: each box is entered in every cell it covers (cells of twice the mean box size
/// by default); entries are bucketed by cell with a counting sort (the cells themselves
/// when the grid's bounding block has at most 4 cells per entry, else a multiplicative
/// hash of the packed cell), so each bucket lists its boxes in index order, and the
/// pairs of each bucket that share a cell are tested. A box covering more than 64 cells
/// is not entered; it is tested against every other box instead, so a few huge
/// triangles (a floor, a wall) do not flood the grid. Nothing depends on the number of
/// threads or on scheduling.
#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

namespace weft::contact::verify {

/// Closed axis-aligned box.
struct Box {
  Eigen::Vector3d lo, hi;
  bool overlaps(const Box& o) const {
    return lo[0] <= o.hi[0] && o.lo[0] <= hi[0] && lo[1] <= o.hi[1] && o.lo[1] <= hi[1] && lo[2] <= o.hi[2] &&
           o.lo[2] <= hi[2];
  }
  /// The smallest box holding a, b and c (exact: minima and maxima, no arithmetic).
  static Box of(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
    return {a.cwiseMin(b).cwiseMin(c), a.cwiseMax(b).cwiseMax(c)};
  }
};

/// How candidate pairs are found.
enum class BroadPhase {
  hash_grid,    ///< uniform hash grid (the default)
  brute_force,  ///< every pair of boxes: O(n^2), a reference for tests
};

/// Broad-phase settings.
struct BroadPhaseParams {
  BroadPhase method = BroadPhase::hash_grid;
  double cell_size = 0;  ///< [m] grid cell edge; <= 0: twice the mean largest extent of the boxes
  int threads = 0;       ///< OpenMP threads; 0: the OpenMP default
};

/// The grid over a list of boxes. Boxes [0, split) and [split, n) may form two sets
/// whose pairs alone are wanted (split < 0: one set, all pairs).
class HashGrid {
 public:
  /// Builds the grid; `boxes` must outlive it. \param cell_size <= 0: automatic.
  HashGrid(std::span<const Box> boxes, double cell_size, int split = -1, int threads = 1);

  /// Buckets to pass to for_each_pair_in_bucket, and boxes too large for the grid.
  int num_buckets() const { return num_buckets_; }
  int num_big() const { return static_cast<int>(big_.size()); }

  /// f(i, j), i < j, for each wanted overlapping pair whose lowest common cell is in
  /// bucket b. Buckets can be visited concurrently; together they list every such pair
  /// between grid boxes once.
  template <class F>
  void for_each_pair_in_bucket(int b, F&& f) const {
    const int end = start_[b + 1];
    for (int p = start_[b]; p < end; ++p)
      for (int q = p + 1; q < end; ++q) {
        if (key_[p] != key_[q] || (mask_[p] | mask_[q]) != 7) continue;  // other cell, or not the lowest
        const int i = box_[p], j = box_[q];                              // i < j: buckets are in box order
        if (wanted(i, j) && boxes_[i].overlaps(boxes_[j])) f(i, j);
      }
  }
  /// f(i, j), i < j, for each wanted overlapping pair of big box t (0 <= t < num_big())
  /// with any other box; a pair of two big boxes is listed once.
  template <class F>
  void for_each_pair_of_big(int t, F&& f) const {
    const int i = big_[t], n = static_cast<int>(boxes_.size());
    for (int j = 0; j < n; ++j) {
      if (j == i || (is_big_[j] && j < i)) continue;
      const int a = std::min(i, j), b = std::max(i, j);
      if (wanted(a, b) && boxes_[a].overlaps(boxes_[b])) f(a, b);
    }
  }
  /// Whether pair (i, j), i < j, is wanted (both sets, or one from each).
  bool wanted(int i, int j) const { return split_ < 0 || (i < split_ && j >= split_); }

 private:
  std::span<const Box> boxes_;
  int split_ = -1;
  int num_buckets_ = 0;
  std::vector<int> start_;                // bucket b holds entries [start_[b], start_[b+1])
  std::unique_ptr<std::uint64_t[]> key_;  // packed cell of each entry
  std::unique_ptr<int[]> box_;            // box of each entry
  std::unique_ptr<std::uint8_t[]> mask_;  // bit k: the entry's cell is its box's lowest on axis k
  std::vector<int> big_;
  std::vector<unsigned char> is_big_;
};

/// Pairs (i, j), i < j, of overlapping boxes, each listed once, sorted.
std::vector<std::array<int, 2>> overlapping_pairs(std::span<const Box> boxes, const BroadPhaseParams& prm = {});

}  // namespace weft::contact::verify
