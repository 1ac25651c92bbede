#pragma once
/// \file obj_io.hpp
/// Wavefront OBJ: reading through tinyobjloader (vertex order preserved as in the file,
/// polygons triangulated), and writing frames.
#include <Eigen/Core>

#include <string>

#include "framework/mesh_generators.hpp"

namespace weft {

/// Read a triangle mesh, with its texture coordinates (`vt`, per face corner) when the file
/// has them. Throws ConfigError naming the file for a missing or malformed file, or one
/// without faces.
MeshData read_obj(const std::string& path);

/// Coordinates are meters: a vertex beyond this distance from the origin is a unit or file
/// error (and would overflow the squared lengths and areas of the geometry checks).
inline constexpr double max_coordinate = 1e6;
/// "" when every coordinate of V is finite and within max_coordinate; else what is wrong,
/// naming the first bad vertex (0-based).
std::string check_extent(const Eigen::MatrixX3d& V);

/// Write vertices (#V*3 stacked) and faces. Writes to `path` + ".tmp" and renames, so a
/// file is either complete or absent.
void write_obj(const std::string& path, const Eigen::VectorXd& x, const Eigen::MatrixX3i& F,
               const std::string& comment = {});

}  // namespace weft
