#include "contact/rods/rod_verify.hpp"

#include <cmath>

#include "contact/detection/distance.hpp"
#include "contact/obstacle_penalty.hpp"
#include "framework/error.hpp"

namespace weft::contact::rods {

int count_rod_overlaps(const std::vector<Eigen::Vector3d>& x, const std::vector<int>& first,
                       const std::vector<double>& radius, double tolerance, int self_skip) {
  WEFT_ASSERT(!first.empty() && first.back() == static_cast<int>(x.size()) && radius.size() + 1 == first.size(),
              "inconsistent rods: {} vertices, {} offsets, {} radii", x.size(), first.size(), radius.size());
  const int R = static_cast<int>(radius.size());
  int count = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : count) if (R > 1)
  for (int ra = 0; ra < R; ++ra)
    for (int i = first[ra]; i + 1 < first[ra + 1]; ++i)
      for (int rb = ra; rb < R; ++rb)
        for (int j = rb == ra ? i + self_skip : first[rb]; j + 1 < first[rb + 1]; ++j) {
          const double reach = radius[ra] + radius[rb] - tolerance;
          if (reach <= 0) continue;
          const double d2 = detection::segment_segment_distance(x[i], x[i + 1], x[j], x[j + 1]).distance_squared;
          count += d2 < reach * reach;
        }
  return count;
}

int count_obstacle_penetrations(const std::vector<Eigen::Vector3d>& x, const std::vector<int>& first,
                                const std::vector<double>& radius, const std::vector<ObstacleSpec>& obstacles, double t,
                                double tolerance, int samples_per_edge) {
  WEFT_ASSERT(!first.empty() && first.back() == static_cast<int>(x.size()) && radius.size() + 1 == first.size(),
              "inconsistent rods: {} vertices, {} offsets, {} radii", x.size(), first.size(), radius.size());
  std::vector<ObstaclePose> poses;
  for (const ObstacleSpec& o : obstacles) poses.push_back(ObstaclePose::at(o, t));
  const int R = static_cast<int>(radius.size());
  int count = 0;
  for (int r = 0; r < R; ++r)
    for (int i = first[r]; i < first[r + 1]; ++i) {
      const int samples = i + 1 < first[r + 1] ? samples_per_edge : 0;
      for (int k = 0; k <= samples; ++k) {
        const double s = double(k) / (samples + 1);
        const Eigen::Vector3d p = k == 0 ? x[i] : Eigen::Vector3d((1 - s) * x[i] + s * x[i + 1]);
        for (const ObstaclePose& pose : poses) count += pose.distance(p).phi < radius[r] - tolerance;
      }
    }
  return count;
}

}  // namespace weft::contact::rods
