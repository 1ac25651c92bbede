#pragma once
/// \file union_find.hpp
/// Disjoint sets over the ids 0..n-1, with path halving. The smaller id of two merged
/// components becomes the root, so a component's root is its smallest id whatever the order
/// of the unions: results built from roots are deterministic.

#include <numeric>
#include <utility>
#include <vector>

namespace weft {

class UnionFind {
 public:
  explicit UnionFind(int n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  /// The root (smallest id) of i's component.
  int find(int i) {
    while (parent_[i] != i) i = parent_[i] = parent_[parent_[i]];
    return i;
  }
  void unite(int a, int b) {
    a = find(a);
    b = find(b);
    if (a == b) return;
    if (b < a) std::swap(a, b);
    parent_[b] = a;
  }

 private:
  std::vector<int> parent_;
};

}  // namespace weft
