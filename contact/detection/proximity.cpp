#include "contact/detection/proximity.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "contact/detection/distance.hpp"
#include "contact/detection/parallel.hpp"
#include "framework/error.hpp"
#include "framework/triangle_mesh.hpp"

namespace weft::contact::detection {

namespace {
using Eigen::Vector3d;

// Below this fraction of the pair's size the gap direction is dominated by rounding.
constexpr double tiny_gap = 1e-8;

// A fixed unit vector perpendicular to u (+z for u = 0).
Vector3d any_perpendicular(const Vector3d& u) {
  if (u.squaredNorm() == 0) return Vector3d::UnitZ();
  int axis = 0;
  u.cwiseAbs().minCoeff(&axis);
  return u.cross(Vector3d::Unit(axis)).normalized();
}

// Orient n so that n . gap >= 0; for a zero gap use the fallback orientation `keep`
// (true: keep n as is) or make the largest component positive.
Vector3d orient(Vector3d n, const Vector3d& gap, bool keep) {
  const double s = n.dot(gap);
  if (s < 0) return -n;
  if (s > 0 || keep) return n;
  int axis = 0;
  n.cwiseAbs().maxCoeff(&axis);
  return n[axis] < 0 ? Vector3d(-n) : n;
}

Vector3d segment(const Eigen::Ref<const Eigen::VectorXd>& x, int i) { return x.segment<3>(3 * i); }
}  // namespace

std::optional<Proximity> vertex_triangle_proximity(const Vector3d& p, const Vector3d& a, const Vector3d& b,
                                                   const Vector3d& c, double thickness) {
  const PointTriangle r = point_triangle_distance(p, a, b, c);
  if (!(r.distance_squared <= thickness * thickness)) return std::nullopt;
  Proximity out;
  out.distance = std::sqrt(r.distance_squared);
  out.gamma = {1, -r.weights[0], -r.weights[1], -r.weights[2]};
  const Vector3d gap = p - r.closest;
  const Vector3d e[3] = {b - a, c - b, a - c};
  int longest = 0;
  for (int k = 1; k < 3; ++k)
    if (e[k].squaredNorm() > e[longest].squaredNorm()) longest = k;
  const double size = e[longest].norm();
  if (out.distance > tiny_gap * size) {
    out.normal = gap / out.distance;
  } else {
    const Vector3d n = e[0].cross(c - a);
    if (n.norm() > tiny_gap * size * size)
      out.normal = orient(n.normalized(), gap, true);
    else
      out.normal = orient(any_perpendicular(e[longest]), gap, true);
  }
  return out;
}

std::optional<Proximity> edge_edge_proximity(const Vector3d& a0, const Vector3d& a1, const Vector3d& b0,
                                             const Vector3d& b1, double thickness, const ProximityOptions& opt) {
  const SegmentSegment r = segment_segment_distance(a0, a1, b0, b1);
  if (!(r.distance_squared <= thickness * thickness)) return std::nullopt;
  if (opt.edge_edge_interior_only && (r.s <= 0 || r.s >= 1 || r.t <= 0 || r.t >= 1)) return std::nullopt;
  Proximity out;
  out.distance = std::sqrt(r.distance_squared);
  out.gamma = {1 - r.s, r.s, -(1 - r.t), -r.t};
  const Vector3d gap = r.closest_a - r.closest_b;
  const Vector3d da = a1 - a0, db = b1 - b0;
  const double la = da.norm(), lb = db.norm();
  if (out.distance > tiny_gap * std::max(la, lb)) {
    out.normal = gap / out.distance;
  } else {
    const Vector3d n = da.cross(db);
    if (n.norm() > tiny_gap * la * lb && n.norm() > 0)
      out.normal = orient(n.normalized(), gap, false);
    else
      out.normal = orient(any_perpendicular(la >= lb ? da : db), gap, false);
  }
  return out;
}

std::vector<ProximityPair> vertex_triangle_narrow(const std::vector<PrimitivePair>& candidates,
                                                  const Eigen::Ref<const Eigen::VectorXd>& xa, int body_a,
                                                  const Eigen::Ref<const Eigen::VectorXd>& xb,
                                                  const Eigen::MatrixX3i& faces_b, int body_b, double thickness) {
  return ordered_collect<ProximityPair>(static_cast<int>(candidates.size()), [&](int i, auto& out) {
    const int v = candidates[i][0], f = candidates[i][1];
    const int t0 = faces_b(f, 0), t1 = faces_b(f, 1), t2 = faces_b(f, 2);
    const auto g = vertex_triangle_proximity(segment(xa, v), segment(xb, t0), segment(xb, t1), segment(xb, t2), thickness);
    if (g) out.push_back({PairKind::vertex_triangle, body_a, body_b, v, f, {v, t0, t1, t2}, *g});
  });
}

std::vector<ProximityPair> edge_edge_narrow(const std::vector<PrimitivePair>& candidates,
                                            const Eigen::Ref<const Eigen::VectorXd>& xa,
                                            const std::vector<std::array<int, 2>>& edges_a, int body_a,
                                            const Eigen::Ref<const Eigen::VectorXd>& xb,
                                            const std::vector<std::array<int, 2>>& edges_b, int body_b,
                                            double thickness, const ProximityOptions& opt) {
  return ordered_collect<ProximityPair>(static_cast<int>(candidates.size()), [&](int i, auto& out) {
    const auto& ea = edges_a[candidates[i][0]];
    const auto& eb = edges_b[candidates[i][1]];
    const auto g = edge_edge_proximity(segment(xa, ea[0]), segment(xa, ea[1]), segment(xb, eb[0]), segment(xb, eb[1]),
                                       thickness, opt);
    if (g)
      out.push_back({PairKind::edge_edge, body_a, body_b, candidates[i][0], candidates[i][1],
                     {ea[0], ea[1], eb[0], eb[1]}, *g});
  });
}

std::vector<std::array<int, 2>> unique_edges(const Eigen::MatrixX3i& faces) {
  std::vector<std::array<int, 2>> e;
  e.reserve(3 * faces.rows());
  for (Eigen::Index f = 0; f < faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int i = faces(f, k), j = faces(f, (k + 1) % 3);
      e.push_back({std::min(i, j), std::max(i, j)});
    }
  std::sort(e.begin(), e.end());
  e.erase(std::unique(e.begin(), e.end()), e.end());
  return e;
}

std::vector<ProximityPair> self_proximity(const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::MatrixX3i& faces,
                                          const std::vector<std::array<int, 2>>& edges, double thickness,
                                          const ProximityOptions& opt) {
  WEFT_ASSERT(thickness >= 0, "thickness {} must be >= 0", thickness);
  const int n = static_cast<int>(x.size() / 3);
  Bvh vertices(Primitives::vertices(n)), triangles(Primitives::triangles(faces)), edge_tree(Primitives::edges(edges));
  for (Bvh* t : {&vertices, &triangles, &edge_tree}) t->build(x, x, 0.5 * thickness);
  auto out = vertex_triangle_narrow(cross_pairs(vertices, triangles, true), x, 0, x, faces, 0, thickness);
  auto ee = edge_edge_narrow(self_pairs(edge_tree), x, edges, 0, x, edges, 0, thickness, opt);
  out.insert(out.end(), ee.begin(), ee.end());
  return out;
}

std::vector<ProximityPair> self_proximity(const Eigen::Ref<const Eigen::VectorXd>& x, const TriangleMesh& mesh,
                                          double thickness, const ProximityOptions& opt) {
  return self_proximity(x, mesh.faces(), mesh.edges(), thickness, opt);
}

std::vector<ProximityPair> mesh_proximity(const Eigen::Ref<const Eigen::VectorXd>& xa, const Eigen::MatrixX3i& faces_a,
                                          const std::vector<std::array<int, 2>>& edges_a,
                                          const Eigen::Ref<const Eigen::VectorXd>& xb, const Eigen::MatrixX3i& faces_b,
                                          const std::vector<std::array<int, 2>>& edges_b, double thickness,
                                          const ProximityOptions& opt) {
  WEFT_ASSERT(thickness >= 0, "thickness {} must be >= 0", thickness);
  const double r = 0.5 * thickness;
  Bvh va(Primitives::vertices(static_cast<int>(xa.size() / 3))), ta(Primitives::triangles(faces_a)),
      ea(Primitives::edges(edges_a));
  Bvh vb(Primitives::vertices(static_cast<int>(xb.size() / 3))), tb(Primitives::triangles(faces_b)),
      eb(Primitives::edges(edges_b));
  for (Bvh* t : {&va, &ta, &ea}) t->build(xa, xa, r);
  for (Bvh* t : {&vb, &tb, &eb}) t->build(xb, xb, r);
  auto out = vertex_triangle_narrow(cross_pairs(va, tb, false), xa, 0, xb, faces_b, 1, thickness);
  auto ba = vertex_triangle_narrow(cross_pairs(vb, ta, false), xb, 1, xa, faces_a, 0, thickness);
  auto ee = edge_edge_narrow(cross_pairs(ea, eb, false), xa, edges_a, 0, xb, edges_b, 1, thickness, opt);
  out.insert(out.end(), ba.begin(), ba.end());
  out.insert(out.end(), ee.begin(), ee.end());
  return out;
}

}  // namespace weft::contact::detection
