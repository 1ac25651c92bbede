#include "contact/rods/rod_detection.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>
#include <tuple>

#include "contact/detection/bvh.hpp"
#include "contact/detection/distance.hpp"
#include "contact/detection/parallel.hpp"
#include "contact/rods/rod_edges.hpp"
#include "contact/rods/thick_ccd.hpp"
#include "framework/error.hpp"

namespace weft::contact::rods {

namespace detail {

void check_curves(const RodCurves& c) {
  if (c.first.empty()) {
    WEFT_ASSERT(c.x0.empty() && c.x1.empty() && c.radius.empty(), "RodCurves: {} vertices and {} radii without offsets",
                c.x0.size(), c.radius.size());
    return;
  }
  WEFT_ASSERT(c.first.front() == 0, "RodCurves::first must start with 0, not {}", c.first.front());
  WEFT_ASSERT(c.first.back() == c.num_vertices(), "RodCurves::first ends at {} for {} vertices", c.first.back(),
              c.num_vertices());
  WEFT_ASSERT(c.x1.size() == c.x0.size(), "RodCurves: x0 has {} vertices, x1 {}", c.x0.size(), c.x1.size());
  WEFT_ASSERT(static_cast<int>(c.radius.size()) == c.num_rods(), "RodCurves: {} radii for {} rods", c.radius.size(),
              c.num_rods());
  for (int r = 0; r < c.num_rods(); ++r) {
    WEFT_ASSERT(c.first[r + 1] - c.first[r] >= 2, "rod {} has {} vertices (at least 2)", r, c.first[r + 1] - c.first[r]);
    WEFT_ASSERT(c.radius[r] >= 0 && std::isfinite(c.radius[r]), "rod {} has radius {}", r, c.radius[r]);
  }
}

RodEdges::RodEdges(const RodCurves& c) {
  check_curves(c);
  for (int r = 0; r < c.num_rods(); ++r) {
    for (int i = c.first[r]; i + 1 < c.first[r + 1]; ++i) {
      v.push_back({i, i + 1});
      rod.push_back(r);
      local.push_back(i - c.first[r]);
    }
    max_radius = std::max(max_radius, c.radius[r]);
  }
}

/// The material point of contact k on side a (b: side = 1) at the start of the step.
Eigen::Vector3d contact_point(const RodCurves& c, const RodContact& k, int side) {
  const int rod = side == 0 ? k.rod_a : k.rod_b, e = c.first[rod] + (side == 0 ? k.edge_a : k.edge_b);
  const double s = side == 0 ? k.s_a : k.s_b;
  return (1 - s) * c.x0[e] + s * c.x0[e + 1];
}

/// Merges the near-duplicates of a sorted list of rod-rod contacts (file comment): deepest
/// first, a contact is dropped when it is a near-duplicate of one already kept, so every
/// dropped contact has a kept near-duplicate at most as deep (not transitive: a chain of
/// near-duplicates keeps more than one). The output stays in the sort order.
void merge_near_duplicates(const RodCurves& c, const RodDetectionParams& p, std::vector<RodContact>& cs) {
  if (p.merge_fraction <= 0 || cs.size() < 2) return;
  const int n = static_cast<int>(cs.size());
  std::vector<int> by_gap(n);
  std::iota(by_gap.begin(), by_gap.end(), 0);
  std::stable_sort(by_gap.begin(), by_gap.end(), [&](int i, int j) { return cs[i].gap < cs[j].gap; });
  std::map<std::pair<int, int>, std::vector<int>> kept;  // per pair of rods
  std::vector<char> keep(n, 0);
  for (int i : by_gap) {
    std::vector<int>& same_rods = kept[{cs[i].rod_a, cs[i].rod_b}];
    if (std::any_of(same_rods.begin(), same_rods.end(), [&](int k) { return rods::near_duplicates(c, cs[k], cs[i], p); })) continue;
    same_rods.push_back(i);
    keep[i] = 1;
  }
  std::vector<RodContact> out;
  out.reserve(n);
  for (int i = 0; i < n; ++i)
    if (keep[i]) out.push_back(cs[i]);
  cs = std::move(out);
}

}  // namespace detail

bool near_duplicates(const RodCurves& c, const RodContact& i, const RodContact& j, const RodDetectionParams& p) {
  if (p.merge_fraction <= 0 || i.kind != RodContact::Kind::rod_rod || j.kind != RodContact::Kind::rod_rod) return false;
  if (i.rod_a != j.rod_a || i.rod_b != j.rod_b || std::abs(i.edge_a - j.edge_a) > 1 || std::abs(i.edge_b - j.edge_b) > 1)
    return false;
  if (i.normal.dot(j.normal) < std::cos(p.merge_angle * std::numbers::pi / 180)) return false;
  const double reach = p.merge_fraction * (c.radius[i.rod_a] + c.radius[i.rod_b]);
  return (detail::contact_point(c, i, 0) - detail::contact_point(c, j, 0)).norm() <= reach &&
         (detail::contact_point(c, i, 1) - detail::contact_point(c, j, 1)).norm() <= reach;
}

bool contact_less(const RodContact& a, const RodContact& b) {
  return std::forward_as_tuple(a.kind, a.rod_a, a.edge_a, a.rod_b, a.edge_b, a.obstacle, a.obstacle_edge, a.s_a) <
         std::forward_as_tuple(b.kind, b.rod_a, b.edge_a, b.rod_b, b.edge_b, b.obstacle, b.obstacle_edge, b.s_a);
}

std::vector<RodContact> detect_rod_rod(const RodCurves& c, const RodDetectionParams& p) {
  RodDetectionParams::validate(p).throw_if_failed("invalid rod detection parameters:");
  const detail::RodEdges edges(c);
  if (edges.size() < 2) return {};
  const double eta = p.ccd_tolerance;

  // Broad phase: boxes inflated so that pairs within reach (r_a + r_b + proximity, plus eta
  // for the CCD) overlap; the tree leaves out pairs sharing a vertex (adjacent edges).
  detection::Bvh tree(detection::Primitives::edges(edges.v));
  const auto X0 = detail::stacked(c.x0), X1 = detail::stacked(c.x1);
  tree.build(X0, p.rod_ccd ? X1 : X0, edges.max_radius + 0.5 * p.proximity + (p.rod_ccd ? eta : 0.0));
  std::vector<detection::PrimitivePair> pairs = detection::self_pairs(tree);
  std::erase_if(pairs, [&](const detection::PrimitivePair& q) {
    const int i = q[0], j = q[1];
    if (edges.rod[i] != edges.rod[j]) return false;
    return !p.self_contact || std::abs(edges.local[i] - edges.local[j]) < p.self_skip;
  });

  // Narrow phase. Pairs come with i < j, i.e. (rod_a, edge_a) < (rod_b, edge_b).
  std::vector<RodContact> out = detection::ordered_collect<RodContact>(
      static_cast<int>(pairs.size()), [&](int k, std::vector<RodContact>& found) {
        const int i = pairs[k][0], j = pairs[k][1];
        const int ra = edges.rod[i], rb = edges.rod[j];
        const double delta = c.radius[ra] + c.radius[rb];
        const detection::Stencil s0{c.x0[edges.v[i][0]], c.x0[edges.v[i][1]], c.x0[edges.v[j][0]], c.x0[edges.v[j][1]]};
        RodContact rc;
        rc.kind = RodContact::Kind::rod_rod;
        rc.rod_a = ra;
        rc.edge_a = edges.local[i];
        rc.rod_b = rb;
        rc.edge_b = edges.local[j];
        const detection::SegmentSegment d0 = detection::segment_segment_distance(s0[0], s0[1], s0[2], s0[3]);
        const double dist0 = std::sqrt(d0.distance_squared);
        if (dist0 < delta + p.proximity) {
          // Orientation hint for (nearly) intersecting centrelines: where a comes from.
          const Eigen::Vector3d va = (1 - d0.s) * (c.x1[edges.v[i][0]] - s0[0]) + d0.s * (c.x1[edges.v[i][1]] - s0[1]);
          const Eigen::Vector3d vb = (1 - d0.t) * (c.x1[edges.v[j][0]] - s0[2]) + d0.t * (c.x1[edges.v[j][1]] - s0[3]);
          rc.s_a = d0.s;
          rc.s_b = d0.t;
          rc.normal = segment_contact_normal(s0, d0.s, d0.t, dist0, {Eigen::Vector3d(vb - va), Eigen::Vector3d::Zero()});
          rc.toi = 0;
          rc.gap = dist0 - delta;
          found.push_back(rc);
          return;
        }
        if (!p.rod_ccd) return;
        const detection::Stencil s1{c.x1[edges.v[i][0]], c.x1[edges.v[i][1]], c.x1[edges.v[j][0]], c.x1[edges.v[j][1]]};
        const ThickImpact hit = segment_segment_ccd(s0, s1, delta, eta, p.ccd_max_iterations);
        if (!hit.hit) return;
        rc.s_a = hit.s;
        rc.s_b = hit.t;
        rc.normal = hit.normal;
        rc.toi = hit.toi;
        rc.gap = hit.distance - delta;
        found.push_back(rc);
      });
  std::sort(out.begin(), out.end(), contact_less);  // already in this order; kept explicit
  detail::merge_near_duplicates(c, p, out);
  return out;
}

std::vector<RodContact> detect_rod_contacts(const RodCurves& c, const std::vector<ObstacleSpec>& obstacles, double t0,
                                            double t1, const RodDetectionParams& p) {
  std::vector<RodContact> out = detect_rod_rod(c, p);
  std::vector<RodContact> o = detect_rod_obstacles(c, obstacles, t0, t1, p);
  out.insert(out.end(), o.begin(), o.end());
  return out;
}

}  // namespace weft::contact::rods
