#pragma once
/// \file rod_edges.hpp
/// Internal to the rod detection: the edges of stacked rod centrelines as BVH primitives,
/// and the input checks shared by rod_detection.cpp and rod_obstacle_detection.cpp.
#include <Eigen/Core>

#include <array>
#include <vector>

#include "contact/rods/rod_detection.hpp"

namespace weft::contact::rods::detail {

/// Every rod edge: global id e = first[r] - r + k for edge k of rod r.
struct RodEdges {
  std::vector<std::array<int, 2>> v;  ///< #E vertex ids (i, i + 1)
  std::vector<int> rod, local;        ///< #E rod and edge index within the rod
  double max_radius = 0;              ///< [m]
  explicit RodEdges(const RodCurves& c);
  int size() const { return static_cast<int>(v.size()); }
};

/// Stacked #V*3 view of a position list (Eigen::Vector3d is three packed doubles).
inline Eigen::Map<const Eigen::VectorXd> stacked(const std::vector<Eigen::Vector3d>& x) {
  static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double));
  return {x.empty() ? nullptr : x[0].data(), 3 * static_cast<Eigen::Index>(x.size())};
}

/// WEFT_ASSERT on the consistency of the curves (sizes, offsets, radii).
void check_curves(const RodCurves& c);

/// (edge, s) of local vertex k of a rod with n vertices: (k, 0), or (n - 2, 1) for the last.
inline std::array<double, 2> vertex_on_edge(int k, int n) {
  return k < n - 1 ? std::array<double, 2>{double(k), 0.0} : std::array<double, 2>{double(n - 2), 1.0};
}

}  // namespace weft::contact::rods::detail
