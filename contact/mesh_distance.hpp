#pragma once
/// \file mesh_distance.hpp
/// `MeshDistance`: signed distance to a triangle-mesh obstacle in its body coordinates,
/// with exact derivatives where it is smooth. Used by `ObstaclePose::distance` for
/// ObstacleShape::mesh.
///
/// Closest point: a static BVH (detection::Bvh, leaf boxes exact, built once in body
/// coordinates) traversed depth first, nearer child first, pruning boxes farther than the
/// best triangle so far; the point-triangle distance is detection::point_triangle_distance.
/// The closest point c lies in the relative interior of a face, an edge or at a vertex
/// (read off the zero barycentric weights). With d = |x - c| and s the sign of
/// (x - c) . n_p, n_p the feature's angle-weighted pseudonormal (framework/obstacle_mesh.hpp):
///   face f:   phi = n_f . (x - x_f0),  grad = n_f,           Hess = 0;
///   edge e:   phi = s d,  g = s (x - c) / d,  Hess = (I - t t^T - g g^T) / phi   (t the unit edge direction:
///             the distance to the line through the edge);
///   vertex:   phi = s d,  g = s (x - c) / d,  Hess = (I - g g^T) / phi           (the distance to the point).
/// These are the exact derivatives inside each feature's Voronoi region (phi is C^1 across
/// region boundaries of a closed mesh, its Hessian jumps there). Special cases:
///  - a closest point on a flat edge or a flat interior vertex (coplanar faces: an empty
///    Voronoi region) takes the face branch of the triangle it was found on;
///  - within 1e-12 x the mesh extent of an edge or a vertex (on the surface, where d has no
///    direction): phi = s d, grad = the feature's unit pseudonormal (the mean outward
///    direction there, rather than one face's normal), Hess = 0.
///
/// Properties relied on by the strategies: phi is 1-Lipschitz for a closed mesh (it is the
/// exact signed distance); moving x by grad (delta - phi) puts it at phi = delta exactly in
/// a face region, approximately near edges and vertices.
#include <Eigen/Core>

#include "contact/detection/bvh.hpp"
#include "framework/obstacle_mesh.hpp"

namespace weft::contact {

struct Distance;

/// The closest point of a mesh to a query point, and the feature it lies in.
struct MeshClosest {
  enum class Feature { face, edge, vertex };
  double distance_squared = 0;                        ///< [m^2]
  Eigen::Vector3d closest = Eigen::Vector3d::Zero();  ///< c, body coordinates
  Feature feature = Feature::face;
  int id = -1;    ///< face, edge or vertex id
  int face = -1;  ///< the triangle c was found on
};

/// Closest-point queries and signed distance over one `ObstacleMesh` (body coordinates).
class MeshDistance {
 public:
  /// Builds the BVH over the triangles of `mesh`, which must outlive this object.
  explicit MeshDistance(const ObstacleMesh& mesh);
  /// The index of `mesh`, built on the first call (thread-safe) and owned by the mesh.
  static const MeshDistance& of(const ObstacleMesh& mesh);

  const ObstacleMesh& mesh() const { return mesh_; }
  /// Closest point of the surface to y and its feature (ties: the first triangle found).
  MeshClosest closest(const Eigen::Vector3d& y) const;
  /// Signed distance at y with its gradient and Hessian (file comment), body coordinates.
  Distance distance(const Eigen::Vector3d& y) const;

 private:
  const ObstacleMesh& mesh_;
  detection::Bvh bvh_;
};

}  // namespace weft::contact
