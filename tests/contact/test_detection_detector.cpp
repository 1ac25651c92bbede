// CollisionDetector: its proximity and CCD lists equal brute force over every admissible
// pair (cloth self contact and cloth against a rigid obstacle), whatever the rebuild
// history and the number of threads; statistics add up; bad parameters are refused.
#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <tuple>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "contact/detection/collision_detector.hpp"
#include "contact/detection/distance.hpp"
#include "framework/mesh_generators.hpp"
#include "tests/support/contact_fixtures.hpp"
#include "framework/triangle_mesh.hpp"

using namespace weft;
using namespace weft::contact::detection;
using weft::support::crumpled_sheet;
using weft::support::displaced;
using weft::support::Sheet;
using Eigen::Vector3d;

namespace {



Vector3d at(const Eigen::VectorXd& x, int i) { return x.segment<3>(3 * i); }

bool same(const ProximityPair& a, const ProximityPair& b) {
  return a.kind == b.kind && a.body_a == b.body_a && a.body_b == b.body_b && a.a == b.a && a.b == b.b && a.v == b.v &&
         a.geometry.distance == b.geometry.distance && a.geometry.gamma == b.geometry.gamma &&
         a.geometry.normal == b.geometry.normal;
}

bool same(const CcdPair& a, const CcdPair& b) {
  return a.kind == b.kind && a.body_a == b.body_a && a.body_b == b.body_b && a.a == b.a && a.b == b.b && a.v == b.v &&
         a.impact.toi == b.impact.toi && a.impact.distance == b.impact.distance && a.impact.gamma == b.impact.gamma &&
         a.impact.normal == b.impact.normal && a.impact.conservative == b.impact.conservative;
}

template <class T>
bool same(const std::vector<T>& a, const std::vector<T>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (!same(a[i], b[i])) return false;
  return true;
}

using Key = std::tuple<int, int, int, int, int>;  // kind, body_a, body_b, a, b

// CCD over every admissible pair between body A (vertices/edges) and body B (triangles/edges).
void brute_ccd(const Eigen::VectorXd& xa0, const Eigen::VectorXd& xa1, const std::vector<std::array<int, 2>>& ea,
               int body_a, const Eigen::VectorXd& xb0, const Eigen::VectorXd& xb1, const Eigen::MatrixX3i& fb,
               const std::vector<std::array<int, 2>>& eb, int body_b, double eta, bool self, bool vf_only,
               std::vector<Key>& out) {
  for (int v = 0; v < xa0.size() / 3; ++v)
    for (int f = 0; f < fb.rows(); ++f) {
      if (self && (fb(f, 0) == v || fb(f, 1) == v || fb(f, 2) == v)) continue;
      const Stencil s0{at(xa0, v), at(xb0, fb(f, 0)), at(xb0, fb(f, 1)), at(xb0, fb(f, 2))};
      const Stencil s1{at(xa1, v), at(xb1, fb(f, 0)), at(xb1, fb(f, 1)), at(xb1, fb(f, 2))};
      if (vertex_triangle_ccd(s0, s1, eta).hit) out.emplace_back(0, body_a, body_b, v, f);
    }
  if (vf_only) return;
  for (size_t i = 0; i < ea.size(); ++i)
    for (size_t j = self ? i + 1 : 0; j < eb.size(); ++j) {
      if (self && (ea[i][0] == eb[j][0] || ea[i][0] == eb[j][1] || ea[i][1] == eb[j][0] || ea[i][1] == eb[j][1]))
        continue;
      const Stencil s0{at(xa0, ea[i][0]), at(xa0, ea[i][1]), at(xb0, eb[j][0]), at(xb0, eb[j][1])};
      const Stencil s1{at(xa1, ea[i][0]), at(xa1, ea[i][1]), at(xb1, eb[j][0]), at(xb1, eb[j][1])};
      if (edge_edge_ccd(s0, s1, eta).hit) out.emplace_back(1, body_a, body_b, int(i), int(j));
    }
}

std::vector<Key> keys(const std::vector<CcdPair>& pairs) {
  std::vector<Key> k;
  for (const auto& p : pairs) k.emplace_back(static_cast<int>(p.kind), p.body_a, p.body_b, p.a, p.b);
  return k;
}

// A flat square "table" of 2 x 2 quads at height z, as a rigid obstacle.
void table(double z, Eigen::MatrixX3i& F, Eigen::VectorXd& x) {
  F.resize(8, 3);
  x.resize(27);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) x.segment<3>(3 * (3 * i + j)) = Vector3d(-0.4 + 0.4 * j, -0.4 + 0.4 * i, z);
  int f = 0;
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) {
      const int v = 3 * i + j;
      F.row(f++) << v, v + 1, v + 4;
      F.row(f++) << v, v + 4, v + 3;
    }
}

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("detection detector: proximity and ccd equal brute force for cloth self contact") {
    const Sheet s = crumpled_sheet(15, 0.15, 0.6, 1);
    const TriangleMesh mesh(s.V, s.F);
    const Eigen::VectorXd x0 = s.x, x1 = displaced(s.x, 0.06, 2);
    CollisionDetector det(mesh, {.margin = 0.02});
    det.update(x0, x1);
    // Proximity at x0: the same list as the one-shot query.
    const auto prox = det.proximity(x0, 0.03);
    CHECK(same(prox, self_proximity(x0, mesh, 0.03)));
    CHECK(prox.size() > 50);
    // CCD over the step: the same hits as CCD over all pairs.
    const double eta = 1e-6;
    const auto hits = det.ccd(x0, x1, eta);
    std::vector<Key> expected;
    brute_ccd(x0, x1, mesh.edges(), 0, x0, x1, mesh.faces(), mesh.edges(), 0, eta, true, false, expected);
    CHECK(keys(hits) == expected);
    CHECK(hits.size() > 20);
    int vf = 0;
    for (const auto& h : hits) {
      vf += h.kind == PairKind::vertex_triangle;
      CHECK(h.impact.distance <= eta);
    }
    CHECK(vf > 5);
    CHECK(static_cast<int>(hits.size()) - vf > 5);
    // Statistics.
    const DetectionStats& st = det.stats();
    CHECK(st.updates == 1);
    CHECK(st.rebuilds == 3);
    CHECK(st.refits == 0);
    CHECK(st.proximity_pairs == static_cast<long long>(prox.size()));
    CHECK(st.proximity_candidates >= st.proximity_pairs);
    CHECK(st.ccd_hits == static_cast<long long>(hits.size()));
    CHECK(st.ccd_candidates > st.ccd_hits);
    CHECK(st.ccd_iterations >= st.ccd_hits);
    CHECK(st.ccd_conservative == 0);
    CHECK(st.seconds() > 0);
    det.update(x1, displaced(x1, 0.01, 3));
    CHECK(det.stats().refits == 3);
    det.reset_stats();
    CHECK(det.stats().updates == 0);
  }

  TEST_CASE("detection detector: cloth against a rigid obstacle equals brute force") {
    // A wavy sheet dropping through a moving table.
    const Sheet s = crumpled_sheet(12, 0.05, 0.2, 5);
    const auto edges = unique_edges(s.F);
    Eigen::MatrixX3i tf;
    Eigen::VectorXd t0, t1;
    table(-0.1, tf, t0);
    table(-0.05, tf, t1);  // the table rises during the step, the sheet (|z| < 0.07) falls through it
    Eigen::VectorXd x0 = s.x, x1 = s.x;
    for (Eigen::Index i = 2; i < x1.size(); i += 3) x1[i] -= 0.2;
    CollisionDetector det(static_cast<int>(s.x.size() / 3), s.F, edges, {.margin = 0.01, .self_contact = false});
    const int body = det.add_obstacle(tf, 9);
    CHECK(body == 1);
    det.set_obstacle_positions(body, t0, t1);
    det.update(x0, x1);
    const double eta = 1e-6;
    const auto hits = det.ccd(x0, x1, eta);
    std::vector<Key> expected, obstacle_vertices, ee;
    const auto tedges = unique_edges(tf);
    brute_ccd(x0, x1, edges, 0, t0, t1, tf, tedges, 1, eta, false, true, expected);
    brute_ccd(t0, t1, tedges, 1, x0, x1, s.F, edges, 0, eta, false, true, obstacle_vertices);
    brute_ccd(x0, x1, edges, 0, t0, t1, tf, tedges, 1, eta, false, false, ee);
    ee.erase(ee.begin(), ee.begin() + static_cast<long>(expected.size()));  // keep its EE part
    expected.insert(expected.end(), obstacle_vertices.begin(), obstacle_vertices.end());
    expected.insert(expected.end(), ee.begin(), ee.end());
    CHECK(keys(hits) == expected);
    CHECK(obstacle_vertices.size() >= 1);  // the table's interior vertex passes through the sheet
    // Every sheet vertex above the table's interior crosses it.
    int over = 0;
    for (int i = 0; i < s.x.size() / 3; ++i) over += std::abs(s.x[3 * i]) < 0.39 && std::abs(s.x[3 * i + 1]) < 0.39;
    int vertex_hits = 0;
    for (const auto& h : hits) vertex_hits += h.kind == PairKind::vertex_triangle && h.body_a == 0;
    CHECK(vertex_hits >= over);
    // Normals of cloth-vertex hits point up from the table towards the vertex coming down.
    for (const auto& h : hits)
      if (h.kind == PairKind::vertex_triangle && h.body_a == 0) CHECK(h.impact.normal.z() > 0.99);
    // Proximity in the middle of the step, where the sheet passes the table.
    const Eigen::VectorXd x_mid = 0.5 * (x0 + x1), t_mid = 0.5 * (t0 + t1);
    const auto prox = det.proximity(x_mid, 0.02, 0.5);
    CHECK(prox.size() > 20);
    CHECK(same(prox, mesh_proximity(x_mid, s.F, edges, t_mid, tf, tedges, 0.02)));
    // An unchanged obstacle is not refitted again.
    det.set_obstacle_positions(body, t0, t1);
    det.update(x0, x1);
    CHECK(det.stats().refits == 3);  // the cloth's three trees only
  }

  TEST_CASE("detection detector: results do not depend on threads or on rebuilds") {
    const Sheet s = crumpled_sheet(30, 0.15, 0.6, 7);
    const auto edges = unique_edges(s.F);
    const int n = static_cast<int>(s.x.size() / 3);
    const Eigen::VectorXd a0 = s.x, a1 = displaced(a0, 0.01, 8), b1 = displaced(a1, 0.01, 9);
    auto run = [&](bool history, double factor) {
      CollisionDetector det(n, s.F, edges, {.margin = 0.01, .bvh = {.leaf_size = 4, .rebuild_factor = factor}});
      if (history) det.update(a0, a1);  // refit from another configuration's tree
      det.update(a1, b1);
      return std::make_pair(det.proximity(a1, 0.02), det.ccd(a1, b1, 1e-6));
    };
#ifdef _OPENMP
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    const auto one = run(false, 2.0);
    omp_set_num_threads(2);
    const auto two = run(false, 2.0);
    const auto refit = run(true, 1e9);
    omp_set_num_threads(threads);
#else
    const auto one = run(false, 2.0), two = run(false, 2.0), refit = run(true, 1e9);
#endif
    CHECK(one.first.size() > 100);
    CHECK(one.second.size() > 10);
    CHECK(same(one.first, two.first));
    CHECK(same(one.second, two.second));
    CHECK(same(one.first, refit.first));
    CHECK(same(one.second, refit.second));
  }

  TEST_CASE("detection detector: invalid parameters and queries are refused") {
    const Sheet s = crumpled_sheet(5, 0.0, 0.0, 0);
    const auto edges = unique_edges(s.F);
    const int n = static_cast<int>(s.x.size() / 3);
    CHECK_THROWS_AS(CollisionDetector(n, s.F, edges, {.margin = 0}), ConfigError);
    CHECK_THROWS_WITH(CollisionDetector(n, s.F, edges, {.bvh = {.leaf_size = 0}}), doctest::Contains("leaf_size"));
    CollisionDetector det(n, s.F, edges, {.margin = 1e-3});
    CHECK_THROWS_AS(det.proximity(s.x, 1e-3), InvariantError);  // no update yet
    det.update(s.x, s.x);
    CHECK_THROWS_WITH(det.proximity(s.x, 3e-3), doctest::Contains("margin"));
    CHECK_THROWS_AS(det.ccd(s.x, s.x, 0.0), InvariantError);
    CHECK(det.proximity(s.x, 2e-3).empty());  // a flat regular sheet: no non-adjacent pair within 2 mm
    // Positions off the last update's trajectory would miss pairs: refused.
    Eigen::VectorXd moved = s.x;
    moved[7] += 1e-6;
    CHECK_THROWS_WITH(det.proximity(moved, 1e-3), doctest::Contains("trajectory"));
    CHECK_THROWS_AS(det.ccd(s.x, moved, 1e-6), InvariantError);
  }
}

TEST_SUITE("contact") {
  TEST_CASE("detection detector: a crumpled sheet's refits and proximity and CCD need no conservative fallback") {
    const Sheet s = crumpled_sheet(40, 0.05, 0.4, 11);
    const auto edges = unique_edges(s.F);
    const int n = static_cast<int>(s.x.size() / 3);
    const Eigen::VectorXd x0 = s.x, x1 = displaced(s.x, 2e-3, 12), x2 = displaced(x1, 2e-3, 13);
    CollisionDetector det(n, s.F, edges, {.margin = 1e-3});
    det.update(x0, x1);
    det.reset_stats();
    det.update(x1, x2);
    const auto prox = det.proximity(x1, 2e-3);
    const auto hits = det.ccd(x1, x2, 1e-6);
    const DetectionStats& st = det.stats();
    CHECK(st.proximity_candidates > 0);  // the crumpled layers come within reach of each other
    CHECK(st.ccd_candidates > 0);
    CHECK(st.ccd_conservative == 0);
    CHECK(prox.size() <= static_cast<size_t>(st.proximity_candidates));  // pairs come from candidates
    CHECK(hits.size() <= static_cast<size_t>(st.ccd_candidates));
  }
}
