#pragma once
/// \file mesh_generators.hpp
/// Sheets generated at a given resolution: rectangles (regular or irregular
/// tessellation) and the L-shaped re-entrant sheet of thesis ch. 11.
#include <Eigen/Core>

#include <array>
#include <vector>

#include "framework/scene.hpp"

namespace weft {

struct MeshData {
  Eigen::MatrixX3d V;  ///< #V by 3
  Eigen::MatrixX3i F;  ///< #F by 3, counter-clockwise about +w (the plane normal)
  /// #UV by 2 texture coordinates (u, v); empty when the mesh has none. Generated sheets
  /// use their (u, v) plane coordinates, so texture directions are sheet directions.
  Eigen::MatrixX2d UV;
  /// #F by 3 indices into UV per face corner (OBJ `f v/vt`), -1 for a corner without one;
  /// empty when UV is empty.
  Eigen::MatrixX3i FUV;

  bool has_uv() const { return UV.rows() > 0 && FUV.rows() == F.rows(); }
};

/// Per face, the unit 3D direction in which the texture direction (cos angle, sin angle)
/// runs on the rest triangle: J (cos angle, sin angle) / |..|, where J = [x1 - x0, x2 - x0]
/// [t1 - t0, t2 - t0]^-1 (3 by 2) is the face's affine texture-to-rest map. For angle = 0 it
/// is the tangent of the lines of constant v (the direction of increasing u). It lies in
/// the face's plane. \returns #F directions. \throws ConfigError listing faces without
/// texture coordinates or with a zero-area texture triangle (at most 10, then a count).
std::vector<Eigen::Vector3d> texture_directions(const MeshData& m, double angle);

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
