// Rod-obstacle contacts (rod_detection.hpp): vertex contacts by conservative advancement on
// the signed distance, segment contacts against the sharp edges of box and mesh obstacles.
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include "contact/detection/bvh.hpp"
#include "contact/detection/distance.hpp"
#include "contact/detection/parallel.hpp"
#include "contact/obstacle_penalty.hpp"
#include "contact/rods/rod_detection.hpp"
#include "contact/rods/rod_edges.hpp"
#include "contact/rods/thick_ccd.hpp"
#include "framework/obstacle_mesh.hpp"

namespace weft::contact::rods {

namespace {

using Eigen::Vector3d;
constexpr double inf = std::numeric_limits<double>::infinity();

/// An obstacle over the step [t0, t1]: its poses, and bounds for the advancement.
struct Posed {
  const ObstacleSpec* spec = nullptr;
  double t0 = 0, t1 = 0;
  ObstaclePose p0, p1;
  bool moving = false;
  double speed = 0, angular_speed = 0;           // |v|, |omega| of the scripted motion
  Vector3d rotation_centre0 = Vector3d::Zero();  // centre of rotation at t0
  // The signed distance moves by a linear translation over the step (static included):
  // its supporting planes too, which allows exact axis steps (sphere, box, plane).
  bool linear = false;
  Vector3d translation = Vector3d::Zero();  // that translation over the whole step
  double bound_radius = inf;                // mesh: every surface point within this of the centre

  Posed(const ObstacleSpec& o, double a, double b) : spec(&o), t0(a), t1(b), p0(ObstaclePose::at(o, a)), p1(ObstaclePose::at(o, b)) {
    const Motion& m = o.motion;
    moving = !(m.is_static() || m.end <= t0 || m.start >= t1 || t1 <= t0);
    linear = !moving;
    if (moving) {
      speed = m.velocity.norm();
      angular_speed = m.angular_velocity.norm();
      rotation_centre0 = m.center + m.velocity * (std::clamp(t0, m.start, std::max(m.start, m.end)) - m.start);
      // Linear over the whole step when the motion window covers it and nothing rotates,
      // or only a sphere spins about an axis through its centre (its distance ignores that).
      const bool window = m.start <= t0 && m.end >= t1;
      const bool spin_only = o.shape == ObstacleShape::sphere && (o.center - m.center).cross(m.angular_velocity).norm() == 0;
      if (window && (m.angular_velocity.isZero() || spin_only)) {
        linear = true;
        translation = m.velocity * (t1 - t0);
      }
    }
    if (o.shape == ObstacleShape::mesh) bound_radius = o.mesh->V.rowwise().norm().maxCoeff();
  }
  ObstaclePose at(double s) const { return moving ? ObstaclePose::at(*spec, t0 + s * (t1 - t0)) : p0; }
  bool convex() const { return spec->shape != ObstacleShape::mesh; }
  /// Bound on |d/ds| of the body coordinates of a point moving from x0 by dx over the step.
  double rate_bound(const Vector3d& x0, const Vector3d& dx) const {
    double L = dx.norm();
    if (moving) {
      const double dt = t1 - t0;
      L += dt * (speed + angular_speed * ((x0 - rotation_centre0).norm() + dx.norm() + speed * dt));
    }
    return L;
  }
  /// Scripted motion over the step of the material point at body coordinates y.
  Vector3d displacement(const Vector3d& y) const { return (p1.center + p1.rotation * y) - (p0.center + p0.rotation * y); }
};

/// A contact of a vertex: fraction s of the step, pose, position and distance there.
struct VertexHit {
  double s = 0;
  ObstaclePose pose;
  Distance d;
  Vector3d x;
};

/// Start test of a vertex with radius r at x0 (phi - r < proximity, or within eta). Fills
/// `hit` with the start (s = 0) unless a mesh's bounding sphere rules the contact out.
bool start_hit(const Posed& o, const Vector3d& x0, double r, const RodDetectionParams& p, VertexHit& hit) {
  if (o.bound_radius < inf) {  // |x - c| - R <= phi outside the bounding sphere
    const double lb = (x0 - o.p0.center).norm() - o.bound_radius - r;
    if (lb >= p.proximity && lb > p.ccd_tolerance) return false;
  }
  hit.s = 0;
  hit.pose = o.p0;
  hit.x = x0;
  hit.d = o.p0.distance(x0);
  const double g = hit.d.phi - r;
  return g < p.proximity || g <= p.ccd_tolerance;
}

/// The pose and distance at fraction s of the step of a vertex moving x0 -> x1.
VertexHit hit_at(const Posed& o, const Vector3d& x0, const Vector3d& x1, double s) {
  VertexHit h;
  h.s = s;
  h.pose = o.at(s);
  h.x = x0 + s * (x1 - x0);
  h.d = h.pose.distance(h.x);
  return h;
}

/// CCD of a vertex against an analytic obstacle (file comment of rod_detection.hpp),
/// after a failed start test.
bool analytic_hit(const Posed& o, const Vector3d& x0, const Vector3d& x1, double r, const RodDetectionParams& p,
                  VertexHit& hit) {
  const double eta = p.ccd_tolerance;
  const Vector3d dx = x1 - x0;
  const double L = o.rate_bound(x0, dx);
  if (!(L > 0)) return false;
  double g = hit.d.phi - r;  // from start_hit
  const double g1 = o.p1.distance(x1).phi - r;
  if (0.5 * (g + g1 - L) > 0.5 * eta) return false;
  const Vector3d rel = dx - o.translation;  // motion relative to the distance field when `linear`
  for (int it = 1;; ++it) {
    double step = (g - 0.5 * eta) / L;
    if (o.linear && o.convex()) {
      // phi >= n . (y - c) for the supporting plane at the closest point c (convex shape),
      // a plane that moves with the translation.
      const Vector3d n = hit.d.grad, c = hit.x - hit.d.phi * n;
      const double h = n.dot(hit.x - c) - r, rate = n.dot(rel);
      if (h >= 0.5 * eta) step = std::max(step, rate < 0 ? (h - 0.5 * eta) / -rate : inf);
    }
    const double s = hit.s + step;
    if (!(s <= 1)) return false;
    hit = hit_at(o, x0, x1, s);
    g = hit.d.phi - r;
    if (g <= eta || it >= p.ccd_max_iterations) return true;
  }
}

/// Earliest time at which each vertex comes within its radius of a mesh obstacle's
/// triangles (thick point-triangle CCD, triangles moving linearly between their poses at
/// t0 and t1), or -1. The broad phase pairs vertex paths with posed triangles.
std::vector<double> mesh_first_touch(const Posed& o, const RodCurves& c, const std::vector<int>& vertex_rod,
                                     const detection::Bvh& vertex_tree, const RodDetectionParams& p) {
  const ObstacleMesh& m = *o.spec->mesh;
  const int nv = static_cast<int>(m.V.rows());
  Eigen::VectorXd w0(3 * nv), w1(3 * nv);
  for (int j = 0; j < nv; ++j) {
    w0.segment<3>(3 * j) = o.p0.center + o.p0.rotation * m.V.row(j).transpose();
    w1.segment<3>(3 * j) = o.p1.center + o.p1.rotation * m.V.row(j).transpose();
  }
  detection::Bvh tri_tree(detection::Primitives::triangles(m.F));
  tri_tree.build(w0, w1, 0.0);
  const std::vector<detection::PrimitivePair> pairs = detection::cross_pairs(vertex_tree, tri_tree, false);
  std::vector<int> starts;  // pairs are sorted by vertex: one group per vertex
  for (int k = 0; k < static_cast<int>(pairs.size()); ++k)
    if (k == 0 || pairs[k][0] != pairs[k - 1][0]) starts.push_back(k);
  starts.push_back(static_cast<int>(pairs.size()));
  const std::vector<std::pair<int, double>> hits = detection::ordered_collect<std::pair<int, double>>(
      static_cast<int>(starts.size()) - 1, [&](int g, std::vector<std::pair<int, double>>& found) {
        const int i = pairs[starts[g]][0];
        const double r = c.radius[vertex_rod[i]];
        double best = inf;
        for (int k = starts[g]; k < starts[g + 1]; ++k) {
          const int f = pairs[k][1];
          detection::Stencil s0{c.x0[i], w0.segment<3>(3 * m.F(f, 0)), w0.segment<3>(3 * m.F(f, 1)), w0.segment<3>(3 * m.F(f, 2))};
          detection::Stencil s1{c.x1[i], w1.segment<3>(3 * m.F(f, 0)), w1.segment<3>(3 * m.F(f, 1)), w1.segment<3>(3 * m.F(f, 2))};
          if (r > 0) {
            const ThickImpact h = point_triangle_ccd(s0, s1, r, p.ccd_tolerance, p.ccd_max_iterations);
            if (h.hit) best = std::min(best, h.toi);
          } else {
            const detection::Impact h = detection::vertex_triangle_ccd(s0, s1, p.ccd_tolerance, {.max_iterations = p.ccd_max_iterations});
            if (h.hit) best = std::min(best, h.toi);
          }
        }
        if (best < inf) found.emplace_back(i, best);
      });
  std::vector<double> toi(c.num_vertices(), -1.0);
  for (const auto& [i, t] : hits) toi[i] = t;
  return toi;
}

/// The sharp edges of a box or mesh obstacle in body coordinates (rod_detection.hpp).
struct SharpEdges {
  std::vector<std::array<Vector3d, 2>> y;  // endpoints
  std::vector<Vector3d> pseudonormal;      // unit, outward
  std::vector<int> id;                     // RodContact::obstacle_edge
  std::vector<unsigned char> boundary;     // an open mesh's rim: no inside to check against
};

SharpEdges sharp_edges(const ObstacleSpec& o) {
  SharpEdges e;
  if (o.shape == ObstacleShape::box) {
    const Vector3d h = o.half_extents;
    for (int k = 0; k < 3; ++k) {
      const int i = (k + 1) % 3, j = (k + 2) % 3;
      for (int m = 0; m < 4; ++m) {
        const double si = (m & 1) ? 1.0 : -1.0, sj = (m & 2) ? 1.0 : -1.0;
        Vector3d a = Vector3d::Zero();
        a[i] = si * h[i];
        a[j] = sj * h[j];
        Vector3d b = a;
        a[k] = -h[k];
        b[k] = h[k];
        Vector3d n = Vector3d::Zero();
        n[i] = si;
        n[j] = sj;
        e.y.push_back({a, b});
        e.pseudonormal.push_back(n.normalized());
        e.id.push_back(4 * k + m);
        e.boundary.push_back(0);
      }
    }
  } else if (o.shape == ObstacleShape::mesh) {
    const ObstacleMesh& m = *o.mesh;
    for (size_t k = 0; k < m.edges.size(); ++k) {
      if (m.flat_edge[k]) continue;
      const auto [i, j] = m.edges[k];
      const auto [f1, f2] = m.edge_faces[k];
      const bool rim = f2 < 0;
      if (!rim) {
        // Convex iff the far vertex of the second face lies below the first face's plane.
        int far = -1;
        for (int c = 0; c < 3; ++c)
          if (m.F(f2, c) != i && m.F(f2, c) != j) far = m.F(f2, c);
        if (far < 0 || m.face_normals.row(f1).dot(m.V.row(far) - m.V.row(i)) >= 0) continue;
      }
      e.y.push_back({m.V.row(i).transpose(), m.V.row(j).transpose()});
      e.pseudonormal.push_back(m.edge_normals.row(k).transpose());
      e.id.push_back(static_cast<int>(k));
      e.boundary.push_back(rim ? 1 : 0);
    }
  }
  return e;
}

}  // namespace

std::vector<RodContact> detect_rod_obstacles(const RodCurves& c, const std::vector<ObstacleSpec>& obstacles, double t0,
                                             double t1, const RodDetectionParams& p) {
  RodDetectionParams::validate(p).throw_if_failed("invalid rod detection parameters:");
  detail::check_curves(c);
  if (obstacles.empty() || c.num_vertices() == 0) return {};
  std::vector<Posed> posed;
  posed.reserve(obstacles.size());
  for (const ObstacleSpec& o : obstacles) posed.emplace_back(o, t0, t1);  // throws for a mesh without geometry
  const int num_obstacles = static_cast<int>(posed.size());

  // Rod of each vertex.
  std::vector<int> vertex_rod(c.num_vertices());
  for (int r = 0; r < c.num_rods(); ++r)
    for (int i = c.first[r]; i < c.first[r + 1]; ++i) vertex_rod[i] = r;

  // 1. Vertex contacts, one per (vertex, obstacle). Mesh obstacles: CCD on the triangles first.
  std::vector<std::vector<double>> mesh_toi(num_obstacles);
  {
    std::optional<detection::Bvh> vertex_tree;
    for (int k = 0; k < num_obstacles; ++k) {
      if (obstacles[k].shape != ObstacleShape::mesh) continue;
      if (!vertex_tree) {
        double max_radius = 0;
        for (double r : c.radius) max_radius = std::max(max_radius, r);
        vertex_tree.emplace(detection::Primitives::vertices(c.num_vertices()));
        vertex_tree->build(detail::stacked(c.x0), detail::stacked(c.x1), max_radius + p.proximity + p.ccd_tolerance);
      }
      mesh_toi[k] = mesh_first_touch(posed[k], c, vertex_rod, *vertex_tree, p);
    }
  }
  std::vector<RodContact> out =
      detection::ordered_collect<RodContact>(c.num_vertices(), [&](int i, std::vector<RodContact>& found) {
        const int r = vertex_rod[i];
        for (int k = 0; k < num_obstacles; ++k) {
          const Posed& o = posed[k];
          VertexHit h;
          bool hit = start_hit(o, c.x0[i], c.radius[r], p, h);
          if (!hit && !mesh_toi[k].empty()) {
            hit = mesh_toi[k][i] >= 0;
            if (hit) h = hit_at(o, c.x0[i], c.x1[i], mesh_toi[k][i]);
          } else if (!hit) {
            hit = analytic_hit(o, c.x0[i], c.x1[i], c.radius[r], p, h);  // h: the start, from start_hit
          }
          if (!hit) continue;
          RodContact rc;
          rc.kind = RodContact::Kind::rod_obstacle;
          rc.rod_a = r;
          const auto [edge, s] = detail::vertex_on_edge(i - c.first[r], c.first[r + 1] - c.first[r]);
          rc.edge_a = static_cast<int>(edge);
          rc.s_a = s;
          rc.obstacle = k;
          rc.normal = h.d.grad;
          const Vector3d surface = h.x - h.d.phi * h.d.grad;
          rc.obstacle_displacement = o.displacement(h.pose.rotation.transpose() * (surface - h.pose.center));
          rc.toi = h.s;
          rc.gap = h.d.phi - c.radius[r];
          found.push_back(rc);
        }
      });
  std::vector<std::pair<int, int>> touched;  // (vertex, obstacle) of the vertex contacts, sorted
  for (const RodContact& rc : out) touched.emplace_back(c.first[rc.rod_a] + rc.edge_a + (rc.s_a == 1 ? 1 : 0), rc.obstacle);
  std::sort(touched.begin(), touched.end());

  // 2. Segment contacts against the sharp edges of boxes and meshes.
  std::vector<SharpEdges> sharp(num_obstacles);
  bool any_edges = false;
  for (int k = 0; k < num_obstacles; ++k) {
    sharp[k] = sharp_edges(obstacles[k]);
    any_edges = any_edges || !sharp[k].y.empty();
  }
  if (any_edges) {
    const detail::RodEdges edges(c);
    const double eta = p.ccd_tolerance;
    detection::Bvh rod_tree(detection::Primitives::edges(edges.v));
    rod_tree.build(detail::stacked(c.x0), detail::stacked(c.x1), edges.max_radius + p.proximity + eta);
    for (int k = 0; k < num_obstacles; ++k) {
      const SharpEdges& se = sharp[k];
      const int n = static_cast<int>(se.y.size());
      if (n == 0) continue;
      const Posed& o = posed[k];
      // Endpoints posed at t0 and t1 (the narrow phase moves them linearly in between).
      Eigen::VectorXd w0(6 * n), w1(6 * n);
      std::vector<std::array<int, 2>> ev(n);
      for (int e = 0; e < n; ++e) {
        for (int m = 0; m < 2; ++m) {
          w0.segment<3>(6 * e + 3 * m) = o.p0.center + o.p0.rotation * se.y[e][m];
          w1.segment<3>(6 * e + 3 * m) = o.p1.center + o.p1.rotation * se.y[e][m];
        }
        ev[e] = {2 * e, 2 * e + 1};
      }
      detection::Bvh edge_tree(detection::Primitives::edges(ev));
      edge_tree.build(w0, w1, 0.0);
      const std::vector<detection::PrimitivePair> pairs = detection::cross_pairs(rod_tree, edge_tree, false);
      std::vector<RodContact> seg = detection::ordered_collect<RodContact>(
          static_cast<int>(pairs.size()), [&](int q, std::vector<RodContact>& found) {
            const int re = pairs[q][0], e = pairs[q][1];
            const int r = edges.rod[re];
            const double rad = c.radius[r];
            const detection::Stencil s0{c.x0[edges.v[re][0]], c.x0[edges.v[re][1]], w0.segment<3>(6 * e),
                                        w0.segment<3>(6 * e + 3)};
            const detection::Stencil s1{c.x1[edges.v[re][0]], c.x1[edges.v[re][1]], w1.segment<3>(6 * e),
                                        w1.segment<3>(6 * e + 3)};
            const detection::SegmentSegment d0 = detection::segment_segment_distance(s0[0], s0[1], s0[2], s0[3]);
            double toi = 0, sa = d0.s, sb = d0.t, dist = std::sqrt(d0.distance_squared);
            if (!(dist - rad < p.proximity)) {
              const ThickImpact hit = segment_segment_ccd(s0, s1, rad, eta, p.ccd_max_iterations);
              if (!hit.hit) return;
              toi = hit.toi;
              sa = hit.s;
              sb = hit.t;
              dist = hit.distance;
            }
            if (sa == 0 || sa == 1) {
              const int v = edges.v[re][sa == 0 ? 0 : 1];
              if (std::binary_search(touched.begin(), touched.end(), std::make_pair(v, k))) return;
            }
            RodContact rc;
            rc.kind = RodContact::Kind::rod_obstacle;
            rc.rod_a = r;
            rc.edge_a = edges.local[re];
            rc.s_a = sa;
            rc.obstacle = k;
            rc.obstacle_edge = se.id[e];
            // Normal at toi: closest points' difference, else the outward pseudonormal.
            const ObstaclePose pose = o.at(toi);
            const Vector3d pa = (1 - sa) * (s0[0] + toi * (s1[0] - s0[0])) + sa * (s0[1] + toi * (s1[1] - s0[1]));
            const Vector3d pb = (1 - sb) * (s0[2] + toi * (s1[2] - s0[2])) + sb * (s0[3] + toi * (s1[3] - s0[3]));
            const Vector3d pseudo = pose.rotation * se.pseudonormal[e];
            const double scale = std::max((s0[1] - s0[0]).norm(), (s0[3] - s0[2]).norm());
            const Vector3d gap = pa - pb;
            rc.normal = gap.norm() > 1e-8 * scale && gap.norm() > 0 ? Vector3d(gap.normalized()) : pseudo;
            if (!se.boundary[e] && rc.normal.dot(pseudo) < 0) rc.normal = pseudo;
            rc.obstacle_displacement = o.displacement((1 - sb) * se.y[e][0] + sb * se.y[e][1]);
            rc.toi = toi;
            rc.gap = dist - rad;
            found.push_back(rc);
          });
      out.insert(out.end(), seg.begin(), seg.end());
    }
  }
  std::sort(out.begin(), out.end(), contact_less);
  return out;
}

}  // namespace weft::contact::rods
