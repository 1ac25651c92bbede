#pragma once
/// \file intersection_check.hpp
/// The independent oracle for "no cloth-cloth intersection after every step": which pairs
/// of triangles of a mesh (or of two meshes) intersect, decided exactly.
///
/// Method: a broad phase on the triangles' bounding boxes (hash_grid.hpp: a uniform hash
/// grid, not the detection code's BVH), then the exact tests of triangle_intersection.hpp
/// on every overlapping pair, in parallel. Each face's plane is prepared once
/// (Orient3dPlane), so that most pairs are settled by two to six plane sides: a triangle
/// strictly on one side of the other's plane, for pairs sharing a vertex a far edge
/// strictly on one side, for pairs sharing an edge a nonzero fold angle. Nothing is shared
/// with contact/detection: no thickness, no tolerance, no distance computation.
///
/// Cost (measured on 2 cores of a loaded machine, Release): a 40k-vertex sheet (80k faces,
/// ~600k candidate pairs, most of them neighbours) takes ~50 ms on one thread when curved,
/// ~90 ms when exactly flat in a coordinate plane (2D tests on every neighbour pair) and
/// ~115 ms when exactly flat in a tilted plane (every neighbour orientation needs the exact
/// stages); two threads nearly halve these.
///
/// What counts, for two faces of one mesh (distinct faces; vertex ids within a face distinct):
///  - no common vertex id: any common point (touching counts);
///  - one common vertex v: a common point other than v (an edge passing through the other
///    face, or the faces overlapping in a common plane around v);
///  - a common edge: a common point off that edge, which for proper triangles means
///    folded flat onto each other (coplanar, on the same side of the edge);
///  - three common vertex ids (a duplicated face): always reported.
/// Vertices with different ids but equal positions are distinct vertices that touch.
/// Faces of two different meshes have no common vertices: any common point counts.
///
/// Guarantees: the pair list is exact for the given double coordinates, sorted, and the
/// same whatever the number of OpenMP threads.
#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "contact/verify/hash_grid.hpp"

namespace weft::contact::verify {

/// Settings of a check.
struct IntersectionCheckParams {
  int max_pairs = 16;            ///< pairs listed in the report (all are counted)
  BroadPhaseParams broad_phase;  ///< grid or brute force, cell size, OpenMP threads
};

/// Outcome of a check.
struct IntersectionReport {
  std::int64_t num_pairs = 0;             ///< intersecting triangle pairs
  std::vector<std::array<int, 2>> pairs;  ///< the first max_pairs of them in lexicographic order
  std::int64_t candidates = 0;            ///< pairs with overlapping boxes, tested exactly
  std::int64_t exact_evaluations = 0;     ///< predicate calls that needed exact arithmetic
  double seconds = 0;                     ///< wall time of the check [s]
  bool intersection_free() const { return num_pairs == 0; }
};

/// Vertex positions as points: from a stacked #V*3 vector (State::x) or a #V by 3 matrix.
std::vector<Eigen::Vector3d> points_from_stacked(const Eigen::Ref<const Eigen::VectorXd>& x);
std::vector<Eigen::Vector3d> points_from_rows(const Eigen::Ref<const Eigen::MatrixX3d>& V);

/// Whether faces f and g of one mesh with vertex positions x intersect beyond what they
/// share (the rules above). Exact.
bool faces_intersect(std::span<const Eigen::Vector3d> x, const std::array<int, 3>& f, const std::array<int, 3>& g);

/// Intersecting pairs (i, j), i < j, of faces of one mesh.
/// \param x #V positions  \param faces #F by 3 vertex ids
IntersectionReport check_self_intersections(std::span<const Eigen::Vector3d> x, const Eigen::MatrixX3i& faces,
                                            const IntersectionCheckParams& prm = {});
/// The same on a stacked #V*3 position vector (State::x).
IntersectionReport check_self_intersections(const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::MatrixX3i& faces,
                                            const IntersectionCheckParams& prm = {});

/// Intersecting pairs (i, j) of face i of mesh A (e.g. the cloth) and face j of mesh B
/// (e.g. a triangle-mesh obstacle); the meshes share no vertices.
IntersectionReport check_intersections(std::span<const Eigen::Vector3d> xa, const Eigen::MatrixX3i& faces_a,
                                       std::span<const Eigen::Vector3d> xb, const Eigen::MatrixX3i& faces_b,
                                       const IntersectionCheckParams& prm = {});

}  // namespace weft::contact::verify
