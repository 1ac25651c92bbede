#pragma once
/// \file obstacle_check.hpp
/// The referee for "no cloth crossing an obstacle": which cloth triangles cross an
/// obstacle's surface or lie partly inside it, and how deep the cloth goes, for every
/// obstacle kind of a scene (framework/scene.hpp) posed at a time t.
///
/// A vertex-only test misses a triangle that passes through an obstacle with its three
/// vertices outside (a sphere or a box edge poking through a coarse triangle); this check
/// does not:
///  - triangle meshes and boxes (as their 12 triangles): the exact triangle-triangle test
///    of intersection_check.hpp between the cloth and the posed surface, plus the
///    vertices inside (signed distance < 0: a triangle wholly inside crosses nothing);
///  - spheres: a cloth triangle whose distance to the centre is below the radius
///    (closest point of the triangle, framework/distance.hpp);
///  - planes (half-spaces): a triangle with a vertex below (the half-space is convex).
/// Depth: spheres R - dist(centre, triangle), so a triangle pierced with its vertices
/// outside counts too; planes, boxes and meshes the deepest vertex (-signed distance).
#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace weft {
struct ObstacleSpec;
}

namespace weft::contact::verify {

/// Outcome of an obstacle check.
struct ObstacleCheckReport {
  std::int64_t crossing_triangles = 0;  ///< cloth triangles crossing or inside an obstacle (each counted once per obstacle)
  double deepest = 0;                   ///< [m] >= 0: the deepest point of the cloth inside an obstacle (0: none)
  std::string deepest_obstacle;         ///< its name ("" when none)
};

/// Cloth positions x (stacked #V*3) with faces against `obstacles` posed at time t.
/// \throws ConfigError for a mesh obstacle without its geometry.
ObstacleCheckReport check_obstacles(const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::MatrixX3i& faces,
                                    const std::vector<ObstacleSpec>& obstacles, double t);

}  // namespace weft::contact::verify
