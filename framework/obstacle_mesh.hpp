#pragma once
/// \file obstacle_mesh.hpp
/// `ObstacleMesh`: the immutable surface of a triangle-mesh obstacle, in body coordinates,
/// with the topology and the angle-weighted pseudonormals its signed distance needs
/// (Baerentzen & Aanaes 2005, "Signed distance computation using the angle weighted
/// pseudonormal", IEEE TVCG 11(3)). Loaded once per scene and shared (read-only) by every
/// copy of the scene's `ObstacleSpec`; the distance itself is computed in contact/
/// (`contact::MeshDistance`, over a BVH of contact/detection).
///
/// Pseudonormals (unnormalised sums are enough for a sign; they are stored normalised):
///   face f:    n_f = (x1 - x0) x (x2 - x0) / |..|  (faces counter-clockwise seen from outside);
///   edge e:    n_e = n_f1 + n_f2 (n_f1 on a boundary edge);
///   vertex v:  n_v = sum over the faces at v of alpha_f(v) n_f, alpha_f(v) the face's angle at v.
/// For the closest point c of x on the surface and the pseudonormal n of the feature (face,
/// edge or vertex) c lies in, sign(phi(x)) = sign((x - c) . n) on a closed, consistently
/// oriented 2-manifold (Baerentzen & Aanaes, Theorem 1).
///
/// Open meshes (boundary edges present) use the same rule. Their "inside" is the side the
/// face normals point away from, and is meaningful only near the surface: beyond a boundary
/// edge, on the extension of the mesh, phi jumps from +d to -d.
#include <Eigen/Core>

#include <array>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace weft {

namespace contact {
class MeshDistance;
}

/// Surface of a triangle-mesh obstacle in body coordinates (scaled, not posed).
struct ObstacleMesh {
  Eigen::MatrixX3d V;  ///< #V by 3 vertices [m]
  Eigen::MatrixX3i F;  ///< #F by 3 faces, counter-clockwise seen from outside
  std::vector<std::array<int, 2>> edges;       ///< #E (i, j), i < j
  std::vector<std::array<int, 2>> edge_faces;  ///< #E adjacent faces; the second is -1 on a boundary edge
  Eigen::MatrixX3i face_edges;                 ///< #F by 3: edge opposite local vertex k
  Eigen::MatrixX3d face_normals;    ///< #F by 3 unit normals
  Eigen::MatrixX3d edge_normals;    ///< #E by 3 unit pseudonormals
  Eigen::MatrixX3d vertex_normals;  ///< #V by 3 unit angle-weighted pseudonormals (zero for unused vertices)
  /// #E: 1 when the edge's two faces are coplanar (up to rounding): its Voronoi region is
  /// empty, so points that find it closest are treated as on a face.
  std::vector<unsigned char> flat_edge;
  /// #V: 1 when every face at the vertex is coplanar with the others (same reason).
  std::vector<unsigned char> flat_vertex;
  int boundary_edges = 0;  ///< edges with one face; 0 for a closed mesh
  double extent = 0;       ///< [m] diagonal of the bounding box (a length scale for tolerances)
  std::string source;      ///< the file it was read from ("" if built in code)

  bool closed() const { return boundary_edges == 0; }

  /// The closest-point index of contact/ (built there on first use: the framework does not
  /// depend on contact/). Use `contact::MeshDistance::of(mesh)`, not these members.
  mutable std::once_flag index_once;
  mutable std::shared_ptr<const contact::MeshDistance> index;
};

/// Build an obstacle mesh from vertices and faces: exact duplicate vertices are welded, then
/// the surface is checked and its topology and pseudonormals computed. \throws ConfigError
/// listing (up to 10 of each kind) non-finite vertices, faces with an index out of range,
/// zero-area faces, edges shared by more than two faces, neighbouring faces of opposite
/// orientation, and a closed mesh whose faces point inwards (negative enclosed volume).
/// Violations read "<what>: ..." with `what` naming the input (e.g. the key and file).
std::shared_ptr<const ObstacleMesh> make_obstacle_mesh(Eigen::MatrixX3d V, Eigen::MatrixX3i F, const std::string& what);

/// Read an OBJ (polygons triangulated) and scale its vertices about the OBJ origin by
/// `scale`, then `make_obstacle_mesh`. \throws ConfigError for a missing or malformed file, a
/// file without triangles, or any check of `make_obstacle_mesh`.
std::shared_ptr<const ObstacleMesh> load_obstacle_mesh(const std::string& path, double scale, const std::string& what);

}  // namespace weft
