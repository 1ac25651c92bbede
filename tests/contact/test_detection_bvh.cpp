// BVH: the self and cross queries return exactly the pairs an O(n^2) loop over the
// primitive boxes finds, after a build, after refits and after a rebuild, for several
// leaf sizes; the boxes enclose the swept primitives; the quality triggers rebuilds; the
// output is the same on 1 and 2 threads.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <random>
#include <set>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "contact/detection/bvh.hpp"
#include "contact/detection/proximity.hpp"
#include "framework/mesh_generators.hpp"
#include "tests/support/contact_fixtures.hpp"

using namespace weft;
using namespace weft::contact::detection;
using weft::support::crumpled_sheet;
using weft::support::displaced;
using weft::support::Sheet;

namespace {



// The box of one primitive, computed independently of the library.
Aabb reference_box(const Primitives& p, int k, const Eigen::VectorXd& x0, const Eigen::VectorXd& x1, double r) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
  for (int j = 0; j < p.arity; ++j)
    for (const Eigen::VectorXd* x : {&x0, &x1}) {
      lo = lo.cwiseMin(Eigen::Vector3d(x->segment<3>(3 * p.v[k][j])));
      hi = hi.cwiseMax(Eigen::Vector3d(x->segment<3>(3 * p.v[k][j])));
    }
  Aabb b;
  b.lo = lo.array() - r;
  b.hi = hi.array() + r;
  return b;
}

bool boxes_overlap(const Aabb& a, const Aabb& b) {
  for (int k = 0; k < 3; ++k)
    if (a.hi[k] < b.lo[k] || b.hi[k] < a.lo[k]) return false;
  return true;
}

bool shares(const std::array<int, 3>& p, int ka, const std::array<int, 3>& q, int kb) {
  for (int i = 0; i < ka; ++i)
    for (int j = 0; j < kb; ++j)
      if (p[i] == q[j]) return true;
  return false;
}

std::vector<PrimitivePair> brute_self(const Primitives& p, const Eigen::VectorXd& x0, const Eigen::VectorXd& x1,
                                      double r) {
  std::vector<Aabb> boxes;
  for (int k = 0; k < p.size(); ++k) boxes.push_back(reference_box(p, k, x0, x1, r));
  std::vector<PrimitivePair> out;
  for (int i = 0; i < p.size(); ++i)
    for (int j = i + 1; j < p.size(); ++j)
      if (boxes_overlap(boxes[i], boxes[j]) && !shares(p.v[i], p.arity, p.v[j], p.arity)) out.push_back({i, j});
  return out;
}

std::vector<PrimitivePair> brute_cross(const Primitives& a, const Primitives& b, const Eigen::VectorXd& x0,
                                       const Eigen::VectorXd& x1, double r, bool skip_shared) {
  std::vector<Aabb> boxes_b;
  for (int k = 0; k < b.size(); ++k) boxes_b.push_back(reference_box(b, k, x0, x1, r));
  std::vector<PrimitivePair> out;
  for (int i = 0; i < a.size(); ++i) {
    const Aabb bi = reference_box(a, i, x0, x1, r);
    for (int j = 0; j < b.size(); ++j)
      if (boxes_overlap(bi, boxes_b[j]) && !(skip_shared && shares(a.v[i], a.arity, b.v[j], b.arity)))
        out.push_back({i, j});
  }
  return out;
}

// Every node box holds its children's boxes (or its primitives' boxes).
bool nested(const Bvh& t) {
  auto inside = [](const Aabb& in, const Aabb& out) {
    return (in.lo.array() >= out.lo.array()).all() && (in.hi.array() <= out.hi.array()).all();
  };
  for (const auto& n : t.nodes()) {
    if (n.leaf()) {
      for (int k = n.first; k < n.first + n.count; ++k)
        if (!inside(t.leaf_boxes()[k], n.box)) return false;
    } else if (!inside(t.nodes()[n.left].box, n.box) || !inside(t.nodes()[n.right].box, n.box)) {
      return false;
    }
  }
  return true;
}

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("detection bvh: self query equals brute force after build and refit and rebuild") {
    const Sheet s = crumpled_sheet(15, 0.15, 0.6, 1);  // 225 vertices, 392 triangles
    REQUIRE(s.F.rows() == 392);
    const auto edges = unique_edges(s.F);
    const double r = 0.01;
    const Eigen::VectorXd x0 = s.x, x1 = displaced(s.x, 0.01, 2);
    const Eigen::VectorXd y0 = displaced(s.x, 0.05, 3), y1 = displaced(y0, 0.01, 4);  // another, rougher step
    for (int leaf : {1, 4, 7}) {
      CAPTURE(leaf);
      for (const Primitives& prims : {Primitives::triangles(s.F), Primitives::edges(edges),
                                      Primitives::vertices(static_cast<int>(s.x.size() / 3))}) {
        CAPTURE(prims.arity);
        Bvh tree(prims, {.leaf_size = leaf, .rebuild_factor = 1e9});
        tree.build(x0, x1, r);
        CHECK(nested(tree));
        for (int k = 0; k < prims.size(); ++k) {
          const Aabb ref = reference_box(prims, k, x0, x1, r);
          REQUIRE(tree.primitive_box(k).lo == ref.lo);
          REQUIRE(tree.primitive_box(k).hi == ref.hi);
        }
        const auto expected = brute_self(prims, x0, x1, r);
        if (prims.arity > 1) CHECK(expected.size() > 100);  // not vacuous: a crumpled sheet
        CHECK(self_pairs(tree) == expected);
        // Refit to a rougher configuration: same tree, new boxes.
        tree.refit(y0, y1, r);
        CHECK(tree.builds() == 1);
        CHECK(nested(tree));
        const auto expected_y = brute_self(prims, y0, y1, r);
        CHECK(expected_y != expected);
        CHECK(self_pairs(tree) == expected_y);
        // Rebuild on the same positions: the same pairs.
        tree.build(y0, y1, r);
        CHECK(tree.quality() == doctest::Approx(1));
        CHECK(self_pairs(tree) == expected_y);
      }
    }
  }

  TEST_CASE("detection bvh: cross queries equal brute force with and without shared-vertex filter") {
    const Sheet s = crumpled_sheet(15, 0.15, 0.6, 5);
    const auto edges = unique_edges(s.F);
    const double r = 0.008;
    const Eigen::VectorXd x0 = s.x, x1 = displaced(s.x, 0.01, 6);
    const Primitives V = Primitives::vertices(static_cast<int>(s.x.size() / 3)), T = Primitives::triangles(s.F),
                     E = Primitives::edges(edges);
    Bvh vt(V, {.leaf_size = 3}), tt(T, {.leaf_size = 2}), et(E);
    for (Bvh* t : {&vt, &tt, &et}) t->update(x0, x1, r);
    const auto vf = brute_cross(V, T, x0, x1, r, true);
    CHECK(vf.size() > 200);
    CHECK(cross_pairs(vt, tt, true) == vf);
    CHECK(cross_pairs(vt, tt, false) == brute_cross(V, T, x0, x1, r, false));
    CHECK(cross_pairs(vt, tt, false).size() > vf.size());
    CHECK(cross_pairs(et, et, false) == brute_cross(E, E, x0, x1, r, false));
    CHECK(cross_pairs(tt, vt, true) == brute_cross(T, V, x0, x1, r, true));
  }

  TEST_CASE("detection bvh: quality grows under deformation and update rebuilds beyond the factor") {
    const Sheet flat = crumpled_sheet(20, 0.0, 0.0, 0);
    const Sheet crumpled = crumpled_sheet(20, 0.3, 0.9, 7);
    Bvh tree(Primitives::triangles(flat.F), {.leaf_size = 4, .rebuild_factor = 1.5});
    CHECK(tree.update(flat.x, flat.x, 1e-3));  // first call builds
    CHECK(tree.quality() == doctest::Approx(1));
    CHECK_FALSE(tree.update(flat.x, flat.x, 1e-3));  // same positions: a refit, Q = 1
    CHECK(tree.refits() == 1);
    CHECK(tree.quality() == doctest::Approx(1));
    // A rigid translation keeps Q = 1 (the measure is translation invariant).
    Eigen::VectorXd moved = flat.x;
    for (Eigen::Index i = 0; i < moved.size(); i += 3) moved.segment<3>(i) += Eigen::Vector3d(3, -2, 5);
    CHECK_FALSE(tree.update(moved, moved, 1e-3));
    CHECK(tree.quality() == doctest::Approx(1).epsilon(1e-9));
    // Crumpling the flat sheet: measured by a refit, then update() rebuilds.
    tree.refit(crumpled.x, crumpled.x, 1e-3);
    const double q = tree.quality();
    CAPTURE(q);
    CHECK(q > 1.5);
    CHECK(tree.update(crumpled.x, crumpled.x, 1e-3));
    CHECK(tree.builds() == 2);
    CHECK(tree.quality() == doctest::Approx(1));
  }

  TEST_CASE("detection bvh: empty and tiny trees") {
    Bvh empty(Primitives::triangles(Eigen::MatrixX3i(0, 3)));
    const Eigen::VectorXd x = Eigen::VectorXd::Zero(9);
    empty.update(x, x, 0.1);
    CHECK(self_pairs(empty).empty());
    Bvh one(Primitives::vertices(1));
    one.update(x.head(3), x.head(3), 0.1);
    CHECK(self_pairs(one).empty());
    CHECK(cross_pairs(one, empty, false).empty());
    Bvh three(Primitives::vertices(3));
    three.update(x, x, 0.0);  // three coincident points: all pairs overlap
    CHECK(self_pairs(three) == std::vector<PrimitivePair>{{0, 1}, {0, 2}, {1, 2}});
    Eigen::VectorXd bad = x;  // a NaN box would overlap nothing: refused
    bad[4] = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_AS(three.update(x, bad, 0.0), InvariantError);
    CHECK_THROWS_AS(Bvh(Primitives::vertices(2), {.leaf_size = 0}), ConfigError);
    CHECK_THROWS_WITH(Bvh(Primitives::vertices(2), {.rebuild_factor = 0.5}), doctest::Contains("rebuild_factor"));
  }

  TEST_CASE("detection bvh: results do not depend on the number of threads") {
    const Sheet s = crumpled_sheet(40, 0.2, 0.8, 9);
    const auto edges = unique_edges(s.F);
    const Eigen::VectorXd x1 = displaced(s.x, 0.005, 10);
    auto run = [&]() {
      Bvh et(Primitives::edges(edges)), vt(Primitives::vertices(static_cast<int>(s.x.size() / 3))),
          tt(Primitives::triangles(s.F));
      for (Bvh* t : {&et, &vt, &tt}) t->update(s.x, x1, 0.005);
      return std::make_pair(self_pairs(et), cross_pairs(vt, tt, true));
    };
#ifdef _OPENMP
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    const auto one = run();
    omp_set_num_threads(2);
    const auto two = run();
    omp_set_num_threads(threads);
#else
    const auto one = run(), two = run();
#endif
    CHECK(one.first.size() > 1000);
    CHECK(one.first == two.first);
    CHECK(one.second == two.second);
  }
}
