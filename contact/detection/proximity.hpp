#pragma once
/// \file proximity.hpp
/// Proximity queries (methods/integration-and-contact §11.1): the vertex-triangle (VF) and edge-edge (EE) pairs of
/// triangle meshes whose distance is at most a thickness, with the weights of the closest
/// points and a unit normal.
///
/// Pairs. VF: a vertex p and a triangle not containing it; EE: two edges without a
/// shared vertex. Vertex-vertex and vertex-edge proximity appear as VF or EE pairs whose
/// closest point lies on the boundary (the weights say where). Side A is the vertex (VF)
/// or the first edge (EE); side B the triangle or the second edge. Every pair within the
/// thickness is reported (the broad phase is conservative: boxes are inflated by half the
/// thickness each), so a vertex near an edge shared by two triangles yields both VF pairs.
/// `ProximityOptions::edge_edge_interior_only` drops the EE pairs whose closest point is
/// an endpoint of either edge: for a closed set of triangles those are also found as VF
/// pairs of the endpoint (Bridson et al. 2002 do the same).
///
/// Weights: gamma such that g = sum_j gamma_j x_j = p^a - p^b (methods/integration-and-contact §11.1), so
/// VF gamma = (1, -w0, -w1, -w2) with w the barycentric coordinates of the closest point,
/// EE gamma = (1 - s, s, -(1 - t), -t) with s, t the parameters of the closest points.
///
/// Normal, from B to A: n = (p^a - p^b) / |p^a - p^b| when the distance exceeds 1e-8 times
/// the size of the pair (the triangle's longest edge, or the longer edge), so C = n . g - thickness is the
/// distance minus the thickness. For smaller distances (nearly intersecting primitives)
/// that direction is rounding noise, and the geometric normal is used instead: the face
/// normal (VF) or the normalised cross product of the two edges (EE), with the sign that
/// makes n . (p^a - p^b) >= 0; when the gap is exactly zero the face normal keeps the
/// triangle's orientation and the EE normal the sign that makes its largest component
/// positive. Degenerate geometry (collapsed triangle, parallel edges) falls back to a fixed
/// perpendicular of the longest edge. The normal is thus a deterministic function of the
/// pair's positions. The detection has no memory: orienting by the previous step, as methods/integration-and-contact
/// §11.1 suggests for the near-zero case, is left to the caller.
///
/// Order: VF pairs, then EE pairs (`mesh_proximity`: its three lists in the order given
/// there), each sorted by the primitive id of A, then of B. The output does not depend on
/// the number of OpenMP threads (the narrow phase filters fixed chunks, parallel.hpp).
#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "contact/detection/bvh.hpp"

namespace weft {
class TriangleMesh;
}

namespace weft::contact::detection {

/// Kind of a contact pair.
enum class PairKind : std::uint8_t {
  vertex_triangle,  ///< A is a vertex, B a triangle
  edge_edge,        ///< A and B are edges
};

/// Closest-point data of one pair.
struct Proximity {
  double distance = 0;                               ///< |p^a - p^b| [m]
  std::array<double, 4> gamma{};                     ///< stencil weights (see the file comment)
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit, from B to A
};

/// One pair within the thickness.
struct ProximityPair {
  PairKind kind = PairKind::vertex_triangle;
  int body_a = 0, body_b = 0;  ///< mesh whose vertex ids A and B use (0 and 1 in two-mesh queries)
  int a = -1, b = -1;          ///< primitive ids: vertex or edge (A), triangle or edge (B)
  std::array<int, 4> v{};      ///< stencil vertex ids: VF (p, t0, t1, t2), EE (a0, a1, b0, b1)
  Proximity geometry;          ///< distance, weights, normal
};

/// Options of the proximity queries.
struct ProximityOptions {
  bool edge_edge_interior_only = false;  ///< drop EE pairs closest at an edge endpoint (see above)
};

/// Vertex p against triangle (a, b, c): the closest-point data if the distance is <= thickness.
std::optional<Proximity> vertex_triangle_proximity(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                                   const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                                   double thickness);

/// Edge (a0, a1) against edge (b0, b1): the closest-point data if the distance is <= thickness.
std::optional<Proximity> edge_edge_proximity(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1,
                                             const Eigen::Vector3d& b0, const Eigen::Vector3d& b1,
                                             double thickness, const ProximityOptions& opt = {});

/// Narrow phase over VF candidates (vertex id of A, triangle id of B), in candidate order.
/// \param xa, xb stacked positions of bodies A and B (the same vector for self contact).
std::vector<ProximityPair> vertex_triangle_narrow(const std::vector<PrimitivePair>& candidates,
                                                  const Eigen::Ref<const Eigen::VectorXd>& xa, int body_a,
                                                  const Eigen::Ref<const Eigen::VectorXd>& xb,
                                                  const Eigen::MatrixX3i& faces_b, int body_b, double thickness);

/// Narrow phase over EE candidates (edge id of A, edge id of B), in candidate order.
std::vector<ProximityPair> edge_edge_narrow(const std::vector<PrimitivePair>& candidates,
                                            const Eigen::Ref<const Eigen::VectorXd>& xa,
                                            const std::vector<std::array<int, 2>>& edges_a, int body_a,
                                            const Eigen::Ref<const Eigen::VectorXd>& xb,
                                            const std::vector<std::array<int, 2>>& edges_b, int body_b,
                                            double thickness, const ProximityOptions& opt = {});

/// The edges of a triangle list, each (i, j) with i < j, sorted and unique. For a
/// `TriangleMesh` use its own `edges()` (same convention; it also rejects non-manifold
/// input, which obstacle meshes may be).
std::vector<std::array<int, 2>> unique_edges(const Eigen::MatrixX3i& faces);

/// Self proximity of one mesh at positions x (stacked #V*3): VF pairs then EE pairs.
/// Builds its BVHs on every call; per-step use goes through `CollisionDetector`.
std::vector<ProximityPair> self_proximity(const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::MatrixX3i& faces,
                                          const std::vector<std::array<int, 2>>& edges, double thickness,
                                          const ProximityOptions& opt = {});
/// Self proximity of a `TriangleMesh` (its faces and edges) at positions x.
std::vector<ProximityPair> self_proximity(const Eigen::Ref<const Eigen::VectorXd>& x, const TriangleMesh& mesh,
                                          double thickness, const ProximityOptions& opt = {});

/// Proximity between mesh 0 (e.g. cloth; positions xa) and mesh 1 (e.g. an obstacle;
/// positions xb): vertices of 0 against triangles of 1, then vertices of 1 against
/// triangles of 0, then edges of 0 against edges of 1. `body_a` and `body_b` of each pair
/// say which mesh the vertex ids of its side A and side B refer to.
std::vector<ProximityPair> mesh_proximity(const Eigen::Ref<const Eigen::VectorXd>& xa, const Eigen::MatrixX3i& faces_a,
                                          const std::vector<std::array<int, 2>>& edges_a,
                                          const Eigen::Ref<const Eigen::VectorXd>& xb, const Eigen::MatrixX3i& faces_b,
                                          const std::vector<std::array<int, 2>>& edges_b, double thickness,
                                          const ProximityOptions& opt = {});

}  // namespace weft::contact::detection
