// Proximity queries: the self and two-mesh queries return exactly the pairs an O(n^2)
// loop over all admissible vertex-triangle and edge-edge pairs finds within the
// thickness; weights, distances and normals are consistent; normals of nearly
// intersecting primitives are stable.
#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <tuple>

#include "contact/detection/distance.hpp"
#include "contact/detection/proximity.hpp"
#include "framework/mesh_generators.hpp"
#include "tests/support/contact_fixtures.hpp"
#include "framework/triangle_mesh.hpp"

using namespace weft;
using namespace weft::contact::detection;
using weft::support::crumpled_sheet;
using weft::support::Sheet;
using Eigen::Vector3d;

namespace {

Vector3d at(const Eigen::VectorXd& x, int i) { return x.segment<3>(3 * i); }

using Key = std::tuple<int, int, int, int, int>;  // kind, body_a, body_b, a, b
Key key(const ProximityPair& p) { return {static_cast<int>(p.kind), p.body_a, p.body_b, p.a, p.b}; }

// Brute force over all admissible pairs between (xa, Fa, Ea) as side A and (xb, Fb, Eb) as
// side B; `self` skips pairs that share a vertex.
std::vector<Key> brute_force(const Eigen::VectorXd& xa, const std::vector<std::array<int, 2>>& ea, int body_a,
                             const Eigen::VectorXd& xb, const Eigen::MatrixX3i& fb,
                             const std::vector<std::array<int, 2>>& eb, int body_b, double thickness, bool self,
                             bool with_vf = true, bool with_ee = true) {
  std::vector<Key> out;
  if (with_vf)
    for (int v = 0; v < xa.size() / 3; ++v)
      for (int f = 0; f < fb.rows(); ++f) {
        if (self && (fb(f, 0) == v || fb(f, 1) == v || fb(f, 2) == v)) continue;
        if (point_triangle_distance(at(xa, v), at(xb, fb(f, 0)), at(xb, fb(f, 1)), at(xb, fb(f, 2))).distance_squared <=
            thickness * thickness)
          out.emplace_back(0, body_a, body_b, v, f);
      }
  if (with_ee)
    for (size_t i = 0; i < ea.size(); ++i)
      for (size_t j = self ? i + 1 : 0; j < eb.size(); ++j) {
        if (self && (ea[i][0] == eb[j][0] || ea[i][0] == eb[j][1] || ea[i][1] == eb[j][0] || ea[i][1] == eb[j][1]))
          continue;
        if (segment_segment_distance(at(xa, ea[i][0]), at(xa, ea[i][1]), at(xb, eb[j][0]), at(xb, eb[j][1]))
                .distance_squared <= thickness * thickness)
          out.emplace_back(1, body_a, body_b, int(i), int(j));
      }
  return out;
}

// Weights, distance and normal of a pair agree with its positions.
int inconsistent(const ProximityPair& p, const std::vector<const Eigen::VectorXd*>& x, double thickness) {
  const auto& g = p.geometry;
  const int na = p.kind == PairKind::vertex_triangle ? 1 : 2;
  Vector3d gap = Vector3d::Zero();
  double sum = 0;
  for (int j = 0; j < 4; ++j) {
    gap += g.gamma[j] * at(*x[j < na ? p.body_a : p.body_b], p.v[j]);
    sum += g.gamma[j];
  }
  int bad = 0;
  bad += std::abs(sum) > 1e-14;
  bad += g.distance > thickness;
  bad += std::abs(gap.norm() - g.distance) > 1e-12;
  bad += std::abs(g.normal.norm() - 1) > 1e-12;
  bad += g.normal.dot(gap) < -1e-15;
  bad += g.distance > 1e-6 && std::abs(g.normal.dot(gap) - g.distance) > 1e-12;
  return bad;
}

std::vector<Key> keys(const std::vector<ProximityPair>& pairs) {
  std::vector<Key> k;
  for (const auto& p : pairs) k.push_back(key(p));
  return k;
}

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("detection proximity: self query equals brute force on a crumpled sheet") {
    const Sheet s = crumpled_sheet(15, 0.15, 0.6, 1);
    const auto edges = unique_edges(s.F);
    for (double thickness : {0.02, 0.04}) {
      CAPTURE(thickness);
      const auto pairs = self_proximity(s.x, s.F, edges, thickness);
      const auto expected = brute_force(s.x, edges, 0, s.x, s.F, edges, 0, thickness, true);
      CHECK(keys(pairs) == expected);  // same pairs, same order (VF then EE, each sorted)
      int vf = 0, bad = 0;
      for (const auto& p : pairs) {
        vf += p.kind == PairKind::vertex_triangle;
        bad += inconsistent(p, {&s.x}, thickness);
      }
      CHECK(bad == 0);
      CHECK(vf > 30);                                      // not vacuous
      CHECK(static_cast<int>(pairs.size()) - vf > 30);
    }
  }

  TEST_CASE("detection proximity: TriangleMesh edges give the same pairs") {
    const Sheet s = crumpled_sheet(12, 0.15, 0.6, 2);
    const TriangleMesh mesh(s.V, s.F);
    const auto a = self_proximity(s.x, mesh, 0.03);
    const auto b = self_proximity(s.x, s.F, unique_edges(s.F), 0.03);
    REQUIRE(a.size() == b.size());
    // Edge ids differ between the two edge lists, and with them which edge of a pair is
    // side A: compare EE stencils with their two halves in canonical order.
    auto canonical = [](const ProximityPair& p) {
      std::array<int, 4> v = p.v;
      if (p.kind == PairKind::edge_edge && std::make_pair(v[2], v[3]) < std::make_pair(v[0], v[1]))
        v = {v[2], v[3], v[0], v[1]};
      return v;
    };
    std::set<std::array<int, 4>> sa, sb;
    for (const auto& p : a) sa.insert(canonical(p));
    for (const auto& p : b) sb.insert(canonical(p));
    CHECK(sa.size() == a.size());
    CHECK(sa == sb);
  }

  TEST_CASE("detection proximity: two meshes equal brute force") {
    // A sheet (on [-0.5, 0.5]^2) over a tetrahedron whose apex comes within the thickness.
    const Sheet s = crumpled_sheet(14, 0.0, 0.3, 3);
    Eigen::MatrixX3i tf(4, 3);
    tf << 0, 2, 1, 0, 1, 3, 1, 2, 3, 2, 0, 3;
    Eigen::VectorXd tx(12);
    tx << 0.1, 0.1, -0.05, 0.9, 0.2, -0.05, 0.4, 0.9, -0.04, 0, 0, 0;
    // The apex just above the sheet vertex nearest to the base's centre.
    Eigen::Index centre = 0;
    (s.V.rowwise() - Eigen::RowVector3d(0.47, 0.4, 0)).rowwise().squaredNorm().minCoeff(&centre);
    tx.tail<3>() = s.x.segment<3>(3 * centre) + Vector3d(0.003, 0.004, 0.01);
    const auto sheet_edges = unique_edges(s.F), tet_edges = unique_edges(tf);
    const double thickness = 0.02;
    const auto pairs = mesh_proximity(s.x, s.F, sheet_edges, tx, tf, tet_edges, thickness);
    auto expected = brute_force(s.x, sheet_edges, 0, tx, tf, tet_edges, 1, thickness, false, true, false);
    const auto tet_on_sheet = brute_force(tx, tet_edges, 1, s.x, s.F, sheet_edges, 0, thickness, false, true, false);
    const auto ee = brute_force(s.x, sheet_edges, 0, tx, tf, tet_edges, 1, thickness, false, false, true);
    expected.insert(expected.end(), tet_on_sheet.begin(), tet_on_sheet.end());
    expected.insert(expected.end(), ee.begin(), ee.end());
    CHECK(keys(pairs) == expected);
    CHECK(tet_on_sheet.size() >= 1);  // the apex
    CHECK(ee.size() >= 3);
    CHECK(pairs.size() > 20);
    int bad = 0;
    for (const auto& p : pairs) bad += inconsistent(p, {&s.x, &tx}, thickness);
    CHECK(bad == 0);
  }

  TEST_CASE("detection proximity: normals of nearly intersecting primitives are stable") {
    const Vector3d a0(0, 0, 0), a1(1, 0, 0), b0(0.4, -1, 0), b1(0.4, 1, 0);
    // Edge a at heights 1e-6 (gap direction), 1e-13 (below the gap threshold: cross product,
    // sign from the gap), 0 (cross product, largest component positive) and -1e-13, -1e-6.
    for (double h : {1e-6, 1e-13, 0.0}) {
      CAPTURE(h);
      const Vector3d up(0, 0, h);
      const auto p = edge_edge_proximity(a0 + up, a1 + up, b0, b1, 1e-3);
      REQUIRE(p);
      CHECK(p->normal.z() > 1 - 1e-9);
      const auto q = edge_edge_proximity(a0 - up, a1 - up, b0, b1, 1e-3);
      REQUIRE(q);
      CHECK(q->normal.z() == doctest::Approx(h == 0 ? 1.0 : -1.0).epsilon(1e-9));
    }
    // Vertex on the triangle: the face normal; just below it: the reversed face normal.
    const Vector3d A(0, 0, 0), B(1, 0, 0), C(0, 1, 0);
    for (double h : {0.0, 1e-13, -1e-13, 1e-5, -1e-5}) {
      CAPTURE(h);
      const auto p = vertex_triangle_proximity(Vector3d(0.2, 0.3, h), A, B, C, 1e-3);
      REQUIRE(p);
      CHECK(p->normal.z() == doctest::Approx(h < 0 ? -1.0 : 1.0).epsilon(1e-9));
      CHECK(p->gamma[1] == doctest::Approx(-0.5));
    }
    // Collapsed triangle touching the vertex: a unit normal perpendicular to its longest edge.
    const auto d = vertex_triangle_proximity(Vector3d(0.5, 0, 0), A, B, Vector3d(0.3, 0, 0), 1e-3);
    REQUIRE(d);
    CHECK(d->normal.norm() == doctest::Approx(1));
    CHECK(std::abs(d->normal.x()) < 1e-12);
    // Parallel touching edges.
    const auto e = edge_edge_proximity(a0, a1, Vector3d(0.5, 0, 0), Vector3d(1.5, 0, 0), 1e-3);
    REQUIRE(e);
    CHECK(e->normal.norm() == doctest::Approx(1));
    CHECK(std::abs(e->normal.x()) < 1e-12);
    // Beyond the thickness: nothing.
    CHECK_FALSE(vertex_triangle_proximity(Vector3d(0.2, 0.3, 2e-3), A, B, C, 1e-3));
    CHECK_FALSE(edge_edge_proximity(a0 + Vector3d(0, 0, 2e-3), a1 + Vector3d(0, 0, 2e-3), b0, b1, 1e-3));
  }

  TEST_CASE("detection proximity: interior-only edge-edge option drops endpoint pairs") {
    const ProximityOptions interior{.edge_edge_interior_only = true};
    const Vector3d a0(0, 0, 0), a1(1, 0, 0);
    // Crossing in the interiors: kept either way.
    CHECK(edge_edge_proximity(a0, a1, Vector3d(0.5, -1, 1e-4), Vector3d(0.5, 1, 1e-4), 1e-3, interior));
    // T junction: b's endpoint near a's interior: dropped with the option only.
    CHECK(edge_edge_proximity(a0, a1, Vector3d(0.5, 1e-4, 0), Vector3d(0.5, 1, 0), 1e-3));
    CHECK_FALSE(edge_edge_proximity(a0, a1, Vector3d(0.5, 1e-4, 0), Vector3d(0.5, 1, 0), 1e-3, interior));
    // On a sheet: the option gives a subset of the pairs.
    const Sheet s = crumpled_sheet(12, 0.15, 0.6, 4);
    const auto edges = unique_edges(s.F);
    const auto all = self_proximity(s.x, s.F, edges, 0.03);
    const auto some = self_proximity(s.x, s.F, edges, 0.03, interior);
    CHECK(some.size() < all.size());
    std::set<Key> ka;
    for (const auto& p : all) ka.insert(key(p));
    int missing = 0;
    for (const auto& p : some) missing += !ka.count(key(p));
    CHECK(missing == 0);
  }
}
