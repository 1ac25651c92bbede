#pragma once
/// \file rod_verify.hpp
/// Independent brute-force checks of rod configurations, for tests and the penetration
/// measurements of methods/rod-contact V-09: no BVH, no CCD, nothing shared with rod_detection.hpp
/// beyond the basic distance functions (detection::segment_segment_distance and the
/// obstacles' signed distance `ObstaclePose::distance`). O(#E^2) and O(#V #obstacles):
/// meant for small scenes.
#include <Eigen/Core>

#include <vector>

#include "framework/scene.hpp"

namespace weft::contact::rods {

/// Number of rod edge pairs whose centreline distance is below r_a + r_b - tolerance, over
/// every pair of edges of different rods and every pair of edges of one rod at least
/// `self_skip` edges apart (>= 1; adjacent edges share a vertex and always touch).
/// \param x #V stacked positions, rod after rod; first #rods+1 vertex offsets; radius #rods [m].
int count_rod_overlaps(const std::vector<Eigen::Vector3d>& x, const std::vector<int>& first,
                       const std::vector<double>& radius, double tolerance, int self_skip);

/// Number of (point, obstacle) pairs with the point deeper than `tolerance` inside the
/// obstacle inflated by its rod's radius (signed distance < r - tolerance), the obstacles
/// posed at time t. The points are the vertices, plus `samples_per_edge` equally spaced
/// interior points of every edge (0: vertices only), which shows an obstacle edge passing
/// between two vertices.
int count_obstacle_penetrations(const std::vector<Eigen::Vector3d>& x, const std::vector<int>& first,
                                const std::vector<double>& radius, const std::vector<ObstacleSpec>& obstacles, double t,
                                double tolerance, int samples_per_edge = 0);

}  // namespace weft::contact::rods
