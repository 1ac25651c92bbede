#pragma once
/// \file triangle_mesh.hpp
/// A consistently oriented triangle 2-manifold (with boundary) and the adjacency the
/// energy models need: edges, hinges (interior edges with their four vertices) and
/// vertex neighbourhoods. Built once per topology.
#include <Eigen/Core>

#include <array>
#include <vector>

namespace weft {

/// Stencil of one interior edge, labelled as in methods/shells §6.1: triangle T = (x0, x1, x2)
/// counter-clockwise, triangle T~ = (x3, x2, x1); the hinge edge is x1 -> x2 as traversed
/// by T; x0 and x3 are the wing vertices.
struct Hinge {
  std::array<int, 4> v;     ///< vertex ids x0, x1, x2, x3
  std::array<int, 2> face;  ///< face ids of T and T~
  int edge;                 ///< edge id
};

class TriangleMesh {
 public:
  TriangleMesh() = default;
  /// \param rest #V by 3 rest positions [m]
  /// \param faces #F by 3 vertex ids, counter-clockwise about the intended normal
  /// \throws ConfigError for out-of-range ids, degenerate (repeated-vertex) faces,
  ///         non-manifold edges or inconsistent orientation.
  TriangleMesh(Eigen::MatrixX3d rest, Eigen::MatrixX3i faces);

  int num_vertices() const { return static_cast<int>(rest_.rows()); }
  int num_faces() const { return static_cast<int>(faces_.rows()); }
  int num_edges() const { return static_cast<int>(edges_.size()); }
  int num_hinges() const { return static_cast<int>(hinges_.size()); }

  const Eigen::MatrixX3d& rest() const { return rest_; }   ///< #V by 3
  const Eigen::MatrixX3i& faces() const { return faces_; } ///< #F by 3
  /// Edge e joins edges()[e][0] < edges()[e][1] (the global orientation: low id to high id).
  const std::vector<std::array<int, 2>>& edges() const { return edges_; }
  /// The one or two faces of edge e; [1] is -1 on the boundary.
  const std::vector<std::array<int, 2>>& edge_faces() const { return edge_faces_; }
  /// face_edges()[f][i] is the edge opposite local vertex i of face f.
  const std::vector<std::array<int, 3>>& face_edges() const { return face_edges_; }
  const std::vector<Hinge>& hinges() const { return hinges_; }
  /// Neighbours of vertex i: neighbours(i) over [vertex_offsets()[i], vertex_offsets()[i+1]).
  const std::vector<int>& vertex_offsets() const { return vertex_offsets_; }
  const std::vector<int>& vertex_neighbours() const { return vertex_neighbours_; }
  bool is_boundary_edge(int e) const { return edge_faces_[e][1] < 0; }
  /// Number of boundary edges.
  int num_boundary_edges() const;
  /// Number of connected components (by shared edges).
  int num_components() const;
  /// Total rest area [m^2].
  double rest_area() const;

 private:
  Eigen::MatrixX3d rest_;
  Eigen::MatrixX3i faces_;
  std::vector<std::array<int, 2>> edges_;
  std::vector<std::array<int, 2>> edge_faces_;
  std::vector<std::array<int, 3>> face_edges_;
  std::vector<Hinge> hinges_;
  std::vector<int> vertex_offsets_, vertex_neighbours_;
};

}  // namespace weft
