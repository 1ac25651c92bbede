#pragma once
/// \file box_mesh.hpp
/// The surface of a box obstacle as 12 triangles in body coordinates (corner k has x, y, z
/// of sign bit 0, 1, 2 of k; faces counter-clockwise seen from outside), for the code that
/// treats boxes as triangle meshes: barrier contact and the obstacle referee.
#include <Eigen/Core>

namespace weft::contact {

/// Vertices (8 x 3) and faces (12 x 3) of the box [-h, h].
void box_mesh(const Eigen::Vector3d& half_extents, Eigen::MatrixX3d& V, Eigen::MatrixX3i& F);

}  // namespace weft::contact
