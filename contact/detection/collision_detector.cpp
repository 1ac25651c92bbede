#include "contact/detection/collision_detector.hpp"

#include <algorithm>
#include <cmath>

#include "contact/detection/parallel.hpp"
#include "framework/error.hpp"
#include "framework/timers.hpp"
#include "framework/triangle_mesh.hpp"

namespace weft::contact::detection {

namespace {
Eigen::Vector3d vertex(const Eigen::Ref<const Eigen::VectorXd>& x, int i) { return x.segment<3>(3 * i); }
}  // namespace

CollisionDetector::CollisionDetector(const TriangleMesh& cloth, const Params& prm)
    : CollisionDetector(cloth.num_vertices(), cloth.faces(), cloth.edges(), prm) {}

CollisionDetector::CollisionDetector(int num_vertices, const Eigen::MatrixX3i& faces,
                                     std::vector<std::array<int, 2>> edges, const Params& prm)
    : prm_(prm) {
  Params::validate(prm_).throw_if_failed();
  add_body(num_vertices, faces, std::move(edges));
}

void CollisionDetector::add_body(int num_vertices, const Eigen::MatrixX3i& faces,
                                 std::vector<std::array<int, 2>> edges) {
  WEFT_ASSERT(faces.size() == 0 || (faces.minCoeff() >= 0 && faces.maxCoeff() < num_vertices),
              "face vertex ids must lie in [0, {})", num_vertices);
  Body b;
  b.num_vertices = num_vertices;
  b.faces = faces;
  b.edges = std::move(edges);
  b.vertex_tree = Bvh(Primitives::vertices(num_vertices), prm_.bvh);
  b.edge_tree = Bvh(Primitives::edges(b.edges), prm_.bvh);
  b.triangle_tree = Bvh(Primitives::triangles(b.faces), prm_.bvh);
  bodies_.push_back(std::move(b));
  candidates_valid_ = false;
}

int CollisionDetector::add_obstacle(const Eigen::MatrixX3i& faces, int num_vertices) {
  add_body(num_vertices, faces, unique_edges(faces));
  return num_bodies() - 1;
}

void CollisionDetector::set_obstacle_positions(int body, const Eigen::Ref<const Eigen::VectorXd>& x0,
                                               const Eigen::Ref<const Eigen::VectorXd>& x1) {
  WEFT_ASSERT(body >= 1 && body < num_bodies(), "obstacle body id {} not in [1, {})", body, num_bodies());
  Body& b = bodies_[body];
  WEFT_ASSERT(x0.size() == 3 * b.num_vertices && x1.size() == 3 * b.num_vertices,
              "obstacle {} has {} vertices: positions must have {} entries", body, b.num_vertices, 3 * b.num_vertices);
  if (b.x0.size() == x0.size() && b.x0 == x0 && b.x1 == x1) return;  // unchanged: keep the trees
  b.x0 = x0;
  b.x1 = x1;
  b.dirty = true;
}

void CollisionDetector::update(const Eigen::Ref<const Eigen::VectorXd>& x0, const Eigen::Ref<const Eigen::VectorXd>& x1) {
  ScopedTimer timer(stats_.seconds_update);
  WEFT_ASSERT(x0.size() == 3 * bodies_[0].num_vertices && x1.size() == x0.size(),
              "cloth positions must have 3 * {} entries", bodies_[0].num_vertices);
  ++stats_.updates;
  candidates_valid_ = false;
  double worst = 1;
  for (int k = 0; k < num_bodies(); ++k) {
    Body& b = bodies_[k];
    const bool cloth = k == 0;
    if (!cloth && !b.dirty) continue;
    WEFT_ASSERT(cloth || b.x0.size() == 3 * b.num_vertices, "obstacle {}: call set_obstacle_positions() first", k);
    for (Bvh* t : {&b.vertex_tree, &b.edge_tree, &b.triangle_tree}) {
      const bool had_tree = t->built();
      const bool rebuilt = cloth ? t->update(x0, x1, prm_.margin) : t->update(b.x0, b.x1, prm_.margin);
      stats_.refits += had_tree ? 1 : 0;
      stats_.rebuilds += rebuilt ? 1 : 0;
      worst = std::max(worst, t->quality());
    }
    b.dirty = false;
  }
  stats_.quality = worst;
}

void CollisionDetector::check_on_trajectory(const Eigen::Ref<const Eigen::VectorXd>& x, const char* what) const {
  const Bvh& tree = bodies_[0].vertex_tree;
  WEFT_ASSERT(tree.built(), "{}", "CollisionDetector: call update(x0, x1) before a query");
  const double m = prm_.margin;
  int outside = -1;
  for (int i = 0; i < bodies_[0].num_vertices && outside < 0; ++i) {
    const Aabb& b = tree.primitive_box(i);
    for (int k = 0; k < 3; ++k) {
      const double xi = x[3 * i + k], tol = 1e-12 * (std::abs(xi) + m);
      if (xi < b.lo[k] + m - tol || xi > b.hi[k] - m + tol) outside = i;
    }
  }
  WEFT_ASSERT(outside < 0,
              "{}: cloth vertex {} is not on the trajectory of the last update(x0, x1); call update() with the "
              "step's positions first",
              what, outside);
}

const std::vector<CollisionDetector::Candidates>& CollisionDetector::broad_phase() {
  WEFT_ASSERT(bodies_[0].vertex_tree.built(), "{}", "CollisionDetector: call update(x0, x1) before a query");
  if (candidates_valid_) return candidates_;
  ScopedTimer timer(stats_.seconds_broad);
  std::vector<Candidates>& out = candidates_;
  out.clear();
  const Body& cloth = bodies_[0];
  if (prm_.self_contact) {
    out.push_back({PairKind::vertex_triangle, 0, 0, cross_pairs(cloth.vertex_tree, cloth.triangle_tree, true)});
    out.push_back({PairKind::edge_edge, 0, 0, self_pairs(cloth.edge_tree)});
  }
  for (int k = 1; k < num_bodies(); ++k) {
    const Body& o = bodies_[k];
    out.push_back({PairKind::vertex_triangle, 0, k, cross_pairs(cloth.vertex_tree, o.triangle_tree, false)});
    out.push_back({PairKind::vertex_triangle, k, 0, cross_pairs(o.vertex_tree, cloth.triangle_tree, false)});
    out.push_back({PairKind::edge_edge, 0, k, cross_pairs(cloth.edge_tree, o.edge_tree, false)});
  }
  candidates_valid_ = true;
  return out;
}

std::vector<ProximityPair> CollisionDetector::proximity(const Eigen::Ref<const Eigen::VectorXd>& x, double thickness,
                                                        double obstacle_time) {
  WEFT_ASSERT(thickness >= 0 && thickness <= 2 * prm_.margin * (1 + 1e-12),
              "proximity thickness {} must be in [0, 2 margin = {}]: raise CollisionDetectorParams::margin", thickness,
              2 * prm_.margin);
  WEFT_ASSERT(x.size() == 3 * bodies_[0].num_vertices, "cloth positions must have 3 * {} entries",
              bodies_[0].num_vertices);
  check_on_trajectory(x, "proximity(x)");
  const auto& candidates = broad_phase();
  ScopedTimer timer(stats_.seconds_narrow);
  // Obstacle positions at obstacle_time.
  std::vector<Eigen::VectorXd> xb(num_bodies());
  for (int k = 1; k < num_bodies(); ++k)
    xb[k] = obstacle_time == 0 ? bodies_[k].x0
                                : Eigen::VectorXd((1 - obstacle_time) * bodies_[k].x0 + obstacle_time * bodies_[k].x1);
  auto pos = [&](int body) -> Eigen::Ref<const Eigen::VectorXd> {
    return body == 0 ? x : Eigen::Ref<const Eigen::VectorXd>(xb[body]);
  };
  std::vector<ProximityPair> out;
  for (const Candidates& c : candidates) {
    stats_.proximity_candidates += static_cast<long long>(c.pairs.size());
    const Body& ba = bodies_[c.body_a];
    const Body& bb = bodies_[c.body_b];
    auto found = c.kind == PairKind::vertex_triangle
                     ? vertex_triangle_narrow(c.pairs, pos(c.body_a), c.body_a, pos(c.body_b), bb.faces, c.body_b, thickness)
                     : edge_edge_narrow(c.pairs, pos(c.body_a), ba.edges, c.body_a, pos(c.body_b), bb.edges, c.body_b,
                                        thickness, prm_.proximity);
    out.insert(out.end(), found.begin(), found.end());
  }
  stats_.proximity_pairs += static_cast<long long>(out.size());
  return out;
}

std::vector<CcdPair> CollisionDetector::ccd(const Eigen::Ref<const Eigen::VectorXd>& x0,
                                            const Eigen::Ref<const Eigen::VectorXd>& x1, double eta) {
  WEFT_ASSERT(eta > 0 && eta <= 2 * prm_.margin * (1 + 1e-12),
              "CCD eta {} must be in (0, 2 margin = {}]: raise CollisionDetectorParams::margin", eta, 2 * prm_.margin);
  WEFT_ASSERT(x0.size() == 3 * bodies_[0].num_vertices && x1.size() == x0.size(),
              "cloth positions must have 3 * {} entries", bodies_[0].num_vertices);
  check_on_trajectory(x0, "ccd(x0, x1)");
  check_on_trajectory(x1, "ccd(x0, x1)");
  const auto& candidates = broad_phase();
  ScopedTimer timer(stats_.seconds_narrow);
  auto start = [&](int body) -> Eigen::Ref<const Eigen::VectorXd> {
    return body == 0 ? x0 : Eigen::Ref<const Eigen::VectorXd>(bodies_[body].x0);
  };
  auto end = [&](int body) -> Eigen::Ref<const Eigen::VectorXd> {
    return body == 0 ? x1 : Eigen::Ref<const Eigen::VectorXd>(bodies_[body].x1);
  };
  std::vector<CcdPair> out;
  long long iterations = 0;
  for (const Candidates& c : candidates) {
    stats_.ccd_candidates += static_cast<long long>(c.pairs.size());
    const Body& ba = bodies_[c.body_a];
    const Body& bb = bodies_[c.body_b];
    const auto xa0 = start(c.body_a), xa1 = end(c.body_a), xb0 = start(c.body_b), xb1 = end(c.body_b);
    const bool vf = c.kind == PairKind::vertex_triangle;
    auto found = ordered_collect<CcdPair>(static_cast<int>(c.pairs.size()), [&](int i, auto& hits) {
      const int a = c.pairs[i][0], b = c.pairs[i][1];
      std::array<int, 4> v;
      if (vf)
        v = {a, bb.faces(b, 0), bb.faces(b, 1), bb.faces(b, 2)};
      else
        v = {ba.edges[a][0], ba.edges[a][1], bb.edges[b][0], bb.edges[b][1]};
      const int na = vf ? 1 : 2;  // stencil entries on side A
      Stencil s0, s1;
      for (int j = 0; j < 4; ++j) {
        s0[j] = vertex(j < na ? xa0 : xb0, v[j]);
        s1[j] = vertex(j < na ? xa1 : xb1, v[j]);
      }
      const Impact imp = vf ? vertex_triangle_ccd(s0, s1, eta, prm_.ccd) : edge_edge_ccd(s0, s1, eta, prm_.ccd);
#pragma omp atomic
      iterations += imp.iterations;
      if (imp.hit) hits.push_back({c.kind, c.body_a, c.body_b, a, b, v, imp});
    });
    for (const CcdPair& p : found) stats_.ccd_conservative += p.impact.conservative ? 1 : 0;
    out.insert(out.end(), found.begin(), found.end());
  }
  stats_.ccd_hits += static_cast<long long>(out.size());
  stats_.ccd_iterations += iterations;
  return out;
}

}  // namespace weft::contact::detection
