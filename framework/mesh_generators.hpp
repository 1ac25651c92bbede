#pragma once
/// \file mesh_generators.hpp
/// Sheets generated at a given resolution: rectangles (regular or irregular
/// tessellation) and the L-shaped re-entrant sheet of thesis ch. 11.
#include <Eigen/Core>

#include <array>

#include "framework/scene.hpp"

namespace weft {

struct MeshData {
  Eigen::MatrixX3d V;  ///< #V by 3
  Eigen::MatrixX3i F;  ///< #F by 3, counter-clockwise about +w (the plane normal)
};

/// Rectangle of `size` (u, v extents) with resolution[0] x resolution[1] vertices, centred
/// at the origin of the (u, v) plane, w = 0. Regular: every quad split along the same
/// diagonal. Irregular: interior vertices jittered by up to 30% of the spacing and each
/// quad split along a random diagonal (fixed `seed`, same vertex count).
MeshData make_rectangle(const Eigen::Vector2d& size, std::array<int, 2> resolution, Tessellation t, int seed);

/// L-shaped sheet: the rectangle without its (+u, +v) quadrant; the re-entrant corner is
/// at the origin. Requires odd resolutions so the cut falls on grid lines.
MeshData make_l_shape(const Eigen::Vector2d& size, std::array<int, 2> resolution, Tessellation t, int seed);

/// Map (u, v, w) to 3D for a sheet in `plane`, then translate by `center`.
void place_sheet(MeshData& m, SheetPlane plane, const Eigen::Vector3d& center);

}  // namespace weft
