#include "contact/verify/obstacle_check.hpp"

#include <algorithm>
#include <vector>

#include "contact/box_mesh.hpp"
#include "contact/obstacle_penalty.hpp"
#include "contact/verify/intersection_check.hpp"
#include "framework/distance.hpp"
#include "framework/obstacle_mesh.hpp"
#include "framework/scene.hpp"

namespace weft::contact::verify {

using Eigen::Vector3d;

ObstacleCheckReport check_obstacles(const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::MatrixX3i& faces,
                                    const std::vector<ObstacleSpec>& obstacles, double t) {
  ObstacleCheckReport rep;
  const int nv = static_cast<int>(x.size() / 3), nf = static_cast<int>(faces.rows());
  const auto at = [&](int i) { return Vector3d(x.segment<3>(3 * i)); };
  std::vector<Vector3d> points;
  for (const ObstacleSpec& o : obstacles) {
    const ObstaclePose pose = ObstaclePose::at(o, t);
    std::vector<unsigned char> crossing(nf, 0);
    double deepest = 0;
    if (o.shape == ObstacleShape::sphere) {
      for (int f = 0; f < nf; ++f) {
        const double d = std::sqrt(point_triangle_distance(pose.center, at(faces(f, 0)), at(faces(f, 1)), at(faces(f, 2))).distance_squared);
        if (d < pose.radius) {
          crossing[f] = 1;
          deepest = std::max(deepest, pose.radius - d);
        }
      }
    } else {
      // Vertices inside (every shape but the sphere: its depth is the triangles').
      std::vector<double> phi(nv);
      for (int i = 0; i < nv; ++i) {
        phi[i] = pose.distance(at(i)).phi;
        if (phi[i] < 0) deepest = std::max(deepest, -phi[i]);
      }
      for (int f = 0; f < nf; ++f)
        if (phi[faces(f, 0)] < 0 || phi[faces(f, 1)] < 0 || phi[faces(f, 2)] < 0) crossing[f] = 1;
      if (o.shape == ObstacleShape::box || o.shape == ObstacleShape::mesh) {
        // The posed surface, then the exact triangle-triangle test.
        Eigen::MatrixX3d V;
        Eigen::MatrixX3i F;
        if (o.shape == ObstacleShape::mesh) {
          V = o.mesh->V;
          F = o.mesh->F;
        } else {
          box_mesh(o.half_extents, V, F);
        }
        std::vector<Vector3d> posed(V.rows());
        for (int i = 0; i < V.rows(); ++i) posed[i] = pose.rotation * V.row(i).transpose() + pose.center;
        points.resize(nv);
        for (int i = 0; i < nv; ++i) points[i] = at(i);
        IntersectionCheckParams prm;
        prm.max_pairs = 1 << 30;  // every pair listed: the crossing triangles
        const IntersectionReport r = check_intersections(points, faces, posed, F, prm);
        for (const auto& p : r.pairs) crossing[p[0]] = 1;
      }
    }
    rep.crossing_triangles += std::count(crossing.begin(), crossing.end(), 1);
    if (deepest > rep.deepest) {
      rep.deepest = deepest;
      rep.deepest_obstacle = o.name;
    }
  }
  return rep;
}

}  // namespace weft::contact::verify
