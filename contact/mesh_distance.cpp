#include "contact/mesh_distance.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "contact/detection/distance.hpp"
#include "contact/obstacle_penalty.hpp"
#include "framework/error.hpp"

namespace weft::contact {

namespace {

using Eigen::Vector3d;

// Barycentric weights below this count as zero when reading off the feature: a point found
// on an edge a rounding error away from its end point is at the vertex (the sign must come
// from the vertex pseudonormal there).
constexpr double zero_weight = 1e-12;
// Distances below this fraction of the mesh extent are on the surface.
constexpr double on_surface = 1e-12;

double box_distance_squared(const detection::Aabb& b, const Vector3d& y) {
  const Vector3d below = (b.lo - y).cwiseMax(0.0), above = (y - b.hi).cwiseMax(0.0);
  return (below + above).squaredNorm();
}

Eigen::VectorXd stacked(const Eigen::MatrixX3d& V) {
  Eigen::VectorXd x(3 * V.rows());
  for (Eigen::Index i = 0; i < V.rows(); ++i) x.segment<3>(3 * i) = V.row(i).transpose();
  return x;
}

}  // namespace

MeshDistance::MeshDistance(const ObstacleMesh& mesh)
    : mesh_(mesh), bvh_(detection::Primitives::triangles(mesh.F), detection::BvhParams{.leaf_size = 4}) {
  const Eigen::VectorXd x = stacked(mesh.V);
  bvh_.build(x, x, 0.0);  // exact boxes: the pruning below is exact
}

const MeshDistance& MeshDistance::of(const ObstacleMesh& mesh) {
  std::call_once(mesh.index_once, [&] { mesh.index = std::make_shared<const MeshDistance>(mesh); });
  return *mesh.index;
}

MeshClosest MeshDistance::closest(const Vector3d& y) const {
  const auto& nodes = bvh_.nodes();
  const auto& order = bvh_.order();
  const auto& boxes = bvh_.leaf_boxes();
  const auto& V = mesh_.V;
  const auto& F = mesh_.F;
  MeshClosest best;
  best.distance_squared = std::numeric_limits<double>::infinity();
  Vector3d weights = Vector3d::Zero();
  // Depth-first, nearer child first. The median split keeps the depth near log2(#F / 4),
  // and the stack holds at most one pending sibling per level.
  int stack[128];
  int top = 0;
  if (!nodes.empty()) stack[top++] = 0;
  while (top > 0) {
    const auto& node = nodes[stack[--top]];
    if (box_distance_squared(node.box, y) >= best.distance_squared) continue;
    if (node.leaf()) {
      for (int k = node.first; k < node.first + node.count; ++k) {
        if (box_distance_squared(boxes[k], y) >= best.distance_squared) continue;
        const int f = order[k];
        const detection::PointTriangle pt =
            detection::point_triangle_distance(y, V.row(F(f, 0)).transpose(), V.row(F(f, 1)).transpose(), V.row(F(f, 2)).transpose());
        if (pt.distance_squared < best.distance_squared) {
          best.distance_squared = pt.distance_squared;
          best.closest = pt.closest;
          best.face = f;
          weights = pt.weights;
        }
      }
      continue;
    }
    const double dl = box_distance_squared(nodes[node.left].box, y), dr = box_distance_squared(nodes[node.right].box, y);
    WEFT_ASSERT(top + 2 <= 128, "{}", "MeshDistance: BVH deeper than the traversal stack");
    if (dl <= dr) {
      stack[top++] = node.right;
      stack[top++] = node.left;
    } else {
      stack[top++] = node.left;
      stack[top++] = node.right;
    }
  }
  WEFT_ASSERT(best.face >= 0, "{}", "MeshDistance: no triangle found (empty mesh?)");
  int zeros = 0, nonzero = 0, zero = 0;
  for (int k = 0; k < 3; ++k) {
    if (weights[k] <= zero_weight) ++zeros, zero = k;
    else nonzero = k;
  }
  if (zeros == 0) {
    best.feature = MeshClosest::Feature::face;
    best.id = best.face;
  } else if (zeros == 1) {
    best.feature = MeshClosest::Feature::edge;
    best.id = mesh_.face_edges(best.face, zero);
  } else {
    best.feature = MeshClosest::Feature::vertex;
    best.id = F(best.face, nonzero);
  }
  return best;
}

Distance MeshDistance::distance(const Vector3d& y) const {
  const MeshClosest q = closest(y);
  const ObstacleMesh& m = mesh_;
  const Vector3d nf = m.face_normals.row(q.face).transpose();
  Distance out;
  const bool edge = q.feature == MeshClosest::Feature::edge, vertex = q.feature == MeshClosest::Feature::vertex;
  const bool flat = (edge && m.flat_edge[q.id]) || (vertex && m.flat_vertex[q.id]);
  if ((!edge && !vertex) || flat) {
    // Face region: the signed distance to the face's plane (exact, and the same on both sides).
    out.phi = nf.dot(y - m.V.row(m.F(q.face, 0)).transpose());
    out.grad = nf;
    return out;
  }
  const Vector3d r = y - q.closest;
  const double d = std::sqrt(q.distance_squared);
  const Vector3d np = edge ? Vector3d(m.edge_normals.row(q.id).transpose()) : Vector3d(m.vertex_normals.row(q.id).transpose());
  const double s = r.dot(np) < 0 ? -1.0 : 1.0;  // Baerentzen & Aanaes, Theorem 1
  out.phi = s * d;
  if (d <= on_surface * m.extent) {
    out.grad = np;  // on the surface: the feature's pseudonormal, the mean outward direction there
    return out;
  }
  out.grad = (s / d) * r;
  Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - out.grad * out.grad.transpose();
  if (edge) {
    const auto& e = m.edges[q.id];
    const Vector3d t = (m.V.row(e[1]) - m.V.row(e[0])).normalized().transpose();
    P -= t * t.transpose();
  }
  out.hess = P / out.phi;
  return out;
}

}  // namespace weft::contact
