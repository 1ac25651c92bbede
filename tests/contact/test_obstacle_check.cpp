// The obstacle referee (contact/verify/obstacle_check.hpp): a cloth triangle that passes
// through a sphere, a box edge or a mesh obstacle with its three vertices outside is found
// (a vertex-only check misses each of these), with its depth; the same triangle moved clear
// is not; a vertex below a plane is.
#include <doctest/doctest.h>

#include <Eigen/Core>

#include "contact/verify/obstacle_check.hpp"
#include "framework/obstacle_mesh.hpp"
#include "framework/scene.hpp"

using namespace weft;
using Eigen::Vector3d;

namespace {

// One big triangle in the plane z = z0, centred on the z axis (circumradius 1 m).
Eigen::VectorXd triangle(double z0) {
  Eigen::VectorXd x(9);
  x << 1, 0, z0, -0.5, 0.866, z0, -0.5, -0.866, z0;
  return x;
}
Eigen::MatrixX3i one_face() {
  Eigen::MatrixX3i F(1, 3);
  F << 0, 1, 2;
  return F;
}

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("obstacle check: triangles crossing a sphere or a box or a mesh with their vertices outside are found") {
    ObstacleSpec sphere;
    sphere.shape = ObstacleShape::sphere;
    sphere.name = "ball";
    sphere.center = Vector3d(0, 0, -0.1);
    sphere.radius = 0.2;
    ObstacleSpec box;
    box.shape = ObstacleShape::box;
    box.name = "block";
    box.center = Vector3d(0, 0, -0.1);
    box.half_extents = Vector3d(0.2, 0.2, 0.2);
    // The same block as a triangle mesh (8 vertices, 12 faces, counter-clockwise from outside).
    ObstacleSpec mesh = box;
    mesh.shape = ObstacleShape::mesh;
    mesh.name = "mesh block";
    mesh.center = Vector3d(0, 0, -0.1);
    {
      Eigen::MatrixX3d V(8, 3);
      for (int k = 0; k < 8; ++k) V.row(k) << ((k & 1) ? 0.2 : -0.2), ((k & 2) ? 0.2 : -0.2), ((k & 4) ? 0.2 : -0.2);
      Eigen::MatrixX3i F(12, 3);
      F << 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4, 2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6;
      mesh.mesh = make_obstacle_mesh(V, F, "test block");
    }
    for (const ObstacleSpec& o : {sphere, box, mesh}) {
      CAPTURE(o.name);
      // Through the top at z = 0: vertices at 1 m from the axis, far outside.
      const auto r = contact::verify::check_obstacles(triangle(0.0), one_face(), {o}, 0.0);
      CHECK(r.crossing_triangles == 1);
      CHECK(r.deepest_obstacle == (o.shape == ObstacleShape::sphere ? o.name : ""));
      if (o.shape == ObstacleShape::sphere) CHECK(r.deepest == doctest::Approx(0.1));  // R - distance of the centre
      // Clear above it.
      const auto clear = contact::verify::check_obstacles(triangle(0.2), one_face(), {o}, 0.0);
      CHECK(clear.crossing_triangles == 0);
      CHECK(clear.deepest == 0);
    }
    // A vertex inside a mesh block: its depth.
    Eigen::VectorXd x = triangle(0.2);
    x.segment<3>(0) = Vector3d(0.05, 0, 0.05);  // 0.05 below the top face at z = 0.1
    const auto inside = contact::verify::check_obstacles(x, one_face(), {mesh}, 0.0);
    CHECK(inside.crossing_triangles == 1);
    CHECK(inside.deepest == doctest::Approx(0.05));
    CHECK(inside.deepest_obstacle == "mesh block");
    // Planes: a vertex below.
    ObstacleSpec plane;
    plane.shape = ObstacleShape::plane;
    plane.name = "floor";
    plane.center = Vector3d(0, 0, 0.1);
    const auto below = contact::verify::check_obstacles(triangle(0.0), one_face(), {plane}, 0.0);
    CHECK(below.crossing_triangles == 1);
    CHECK(below.deepest == doctest::Approx(0.1));
    CHECK(contact::verify::check_obstacles(triangle(0.2), one_face(), {plane}, 0.0).crossing_triangles == 0);
  }
}
