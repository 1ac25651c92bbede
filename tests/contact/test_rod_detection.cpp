// Rod collision detection (contact/rods/rod_detection.hpp): rod-rod proximity and CCD
// contacts with their parameters and normals, self contact, vertex and segment contacts
// with scripted obstacles, determinism, and the broad phase against brute force.
#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <set>
#include <tuple>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "contact/detection/distance.hpp"
#include "contact/rods/rod_detection.hpp"
#include "contact/rods/rod_verify.hpp"
#include "contact/rods/thick_ccd.hpp"
#include "contact/obstacle_penalty.hpp"
#include "framework/error.hpp"
#include "framework/obstacle_mesh.hpp"
#include "framework/scene.hpp"

using namespace weft;
using namespace weft::contact::rods;
using Eigen::Vector3d;

namespace {

// Appends a straight rod from a to b with n vertices, moved by `shift` over the step.
void add_rod(RodCurves& c, const Vector3d& a, const Vector3d& b, int n, double radius,
             const Vector3d& shift = Vector3d::Zero()) {
  if (c.first.empty()) c.first.push_back(0);
  for (int i = 0; i < n; ++i) {
    const Vector3d x = a + (b - a) * (double(i) / (n - 1));
    c.x0.push_back(x);
    c.x1.push_back(x + shift);
  }
  c.first.push_back(static_cast<int>(c.x0.size()));
  c.radius.push_back(radius);
}

// Random rods: a random start in a cube of side `box`, a smooth random walk of n vertices
// with segment length `seg`, and a random displacement per vertex of at most `move`.
RodCurves rod_soup(int rods, int n, double box, double seg, double radius, double move, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  auto rand3 = [&] { return Vector3d(u(rng), u(rng), u(rng)); };
  RodCurves c;
  c.first.push_back(0);
  for (int r = 0; r < rods; ++r) {
    Vector3d x = 0.5 * box * rand3();
    Vector3d dir = rand3().normalized();
    const Vector3d drift = move * rand3();
    for (int i = 0; i < n; ++i) {
      c.x0.push_back(x);
      c.x1.push_back(x + drift + 0.3 * move * rand3());
      dir = (dir + 0.4 * rand3()).normalized();
      x += seg * dir;
    }
    c.first.push_back(static_cast<int>(c.x0.size()));
    c.radius.push_back(radius * (1 + 0.5 * (u(rng) + 1)));
  }
  return c;
}

ObstacleSpec sphere(const Vector3d& centre, double radius) {
  ObstacleSpec o;
  o.shape = ObstacleShape::sphere;
  o.center = centre;
  o.radius = radius;
  return o;
}

ObstacleSpec plane(const Vector3d& point, const Vector3d& normal) {
  ObstacleSpec o;
  o.shape = ObstacleShape::plane;
  o.center = point;
  o.normal = normal.normalized();
  return o;
}

ObstacleSpec box(const Vector3d& centre, const Vector3d& half) {
  ObstacleSpec o;
  o.shape = ObstacleShape::box;
  o.center = centre;
  o.half_extents = half;
  return o;
}

// A closed box mesh with the given half extents, centred at `centre` (12 triangles).
ObstacleSpec box_mesh(const Vector3d& centre, const Vector3d& half) {
  Eigen::MatrixX3d V(8, 3);
  for (int k = 0; k < 8; ++k) V.row(k) << ((k & 1) ? 1 : -1) * half.x(), ((k & 2) ? 1 : -1) * half.y(), ((k & 4) ? 1 : -1) * half.z();
  const int quads[6][4] = {{0, 2, 6, 4}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 5, 7, 6}};
  Eigen::MatrixX3i F(12, 3);
  for (int q = 0; q < 6; ++q) {
    int a = quads[q][0], b = quads[q][1], c = quads[q][2], d = quads[q][3];
    const Vector3d n = (V.row(b) - V.row(a)).transpose().cross((V.row(c) - V.row(a)).transpose());
    const Vector3d mid = 0.25 * (V.row(a) + V.row(b) + V.row(c) + V.row(d)).transpose();
    if (n.dot(mid) < 0) std::swap(b, d);  // counter-clockwise seen from outside
    F.row(2 * q) << a, b, c;
    F.row(2 * q + 1) << a, c, d;
  }
  ObstacleSpec o;
  o.shape = ObstacleShape::mesh;
  o.center = centre;
  o.mesh = make_obstacle_mesh(V, F, "test box mesh");
  return o;
}

using Key = std::tuple<int, int, int, int, int>;  // rod_a, edge_a, rod_b, edge_b, kind
std::set<Key> rod_rod_keys(const std::vector<RodContact>& cs) {
  std::set<Key> k;
  for (const RodContact& c : cs) k.emplace(c.rod_a, c.edge_a, c.rod_b, c.edge_b, static_cast<int>(c.kind));
  return k;
}

// Every admissible edge pair of every rod, without a broad phase.
std::set<Key> brute_force_rod_rod(const RodCurves& c, const RodDetectionParams& p) {
  std::set<Key> out;
  for (int ra = 0; ra < c.num_rods(); ++ra)
    for (int ea = 0; ea < c.num_edges(ra); ++ea)
      for (int rb = ra; rb < c.num_rods(); ++rb)
        for (int eb = rb == ra ? ea + 1 : 0; eb < c.num_edges(rb); ++eb) {
          if (ra == rb && (!p.self_contact || eb - ea < p.self_skip)) continue;
          const int i = c.first[ra] + ea, j = c.first[rb] + eb;
          const double delta = c.radius[ra] + c.radius[rb];
          const double d0 = std::sqrt(
              contact::detection::segment_segment_distance(c.x0[i], c.x0[i + 1], c.x0[j], c.x0[j + 1]).distance_squared);
          bool hit = d0 < delta + p.proximity;
          if (!hit && p.rod_ccd)
            hit = segment_segment_ccd({c.x0[i], c.x0[i + 1], c.x0[j], c.x0[j + 1]}, {c.x1[i], c.x1[i + 1], c.x1[j], c.x1[j + 1]},
                                      delta, p.ccd_tolerance, p.ccd_max_iterations)
                      .hit;
          if (hit) out.emplace(ra, ea, rb, eb, 0);
        }
  return out;
}

bool same(const RodContact& a, const RodContact& b) {
  return a.kind == b.kind && a.rod_a == b.rod_a && a.edge_a == b.edge_a && a.s_a == b.s_a && a.rod_b == b.rod_b &&
         a.edge_b == b.edge_b && a.s_b == b.s_b && a.obstacle == b.obstacle && a.obstacle_edge == b.obstacle_edge &&
         a.normal == b.normal && a.obstacle_displacement == b.obstacle_displacement && a.toi == b.toi && a.gap == b.gap;
}

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("rod detection: crossing rods are contacts iff within the radii plus the proximity") {
    // Rod 0 along x at height h crosses rod 1 along y at z = 0 over the middle of their
    // second edges (3 edges each, so the crossing is at s = t = 0.5).
    const double ra = 0.01, rb = 0.02, prox = 0.005;
    for (double h : {-0.05, -0.03, 0.0001, 0.02, 0.0349, 0.0351, 0.05}) {
      CAPTURE(h);
      RodCurves c;
      add_rod(c, {-1.5, 0, h}, {1.5, 0, h}, 4, ra);
      add_rod(c, {0, -1.5, 0}, {0, 1.5, 0}, 4, rb);
      RodDetectionParams p;
      p.proximity = prox;
      const auto cs = detect_rod_rod(c, p);
      const bool expect = std::abs(h) < ra + rb + prox;
      REQUIRE(cs.size() == (expect ? 1u : 0u));
      if (!expect) continue;
      const RodContact& k = cs[0];
      CHECK(k.kind == RodContact::Kind::rod_rod);
      CHECK(k.rod_a == 0);
      CHECK(k.edge_a == 1);
      CHECK(k.rod_b == 1);
      CHECK(k.edge_b == 1);
      CHECK(k.s_a == doctest::Approx(0.5).epsilon(1e-12));
      CHECK(k.s_b == doctest::Approx(0.5).epsilon(1e-12));
      CHECK(k.toi == 0);
      CHECK(k.gap == doctest::Approx(std::abs(h) - ra - rb).epsilon(1e-12));
      // From b (rod 1) to a (rod 0).
      CHECK((k.normal - Vector3d(0, 0, h > 0 ? 1 : -1)).norm() < 1e-12);
    }
  }

  TEST_CASE("rod detection: the two edges at a slight valley of a rod give one contact") {
    // Rod 1 along y is draped over rod 0 (along x, below): its arms fall away by kink / 2 on
    // either side of the vertex above rod 0. Seen from rod 0 that is a valley: the closest
    // points of both edges lie just beside the vertex (about h kink / 2 from it), one
    // crossing found twice. Merged within 2 degrees, both kept beyond.
    const double r = 1e-4;
    for (const double kink_deg : {0.5, 1.5, 4.0}) {
      CAPTURE(kink_deg);
      const double k = kink_deg * M_PI / 180, h = 2 * r - 1e-7;  // 0.1 um overlap at the vertex
      RodCurves c;
      add_rod(c, {-0.01, 0, 0}, {0.01, 0, 0}, 3, r);
      const Vector3d v(0.0003, 0, h), arm(0, 0.004 * std::cos(k / 2), -0.004 * std::sin(k / 2));  // arms fall by k/2
      const Vector3d left(v.x(), -arm.y(), arm.z()), right = arm;
      for (const Vector3d& x : {Vector3d(v + left), v, Vector3d(v + right)}) c.x0.push_back(x);
      c.first.push_back(static_cast<int>(c.x0.size()));
      c.radius.push_back(r);
      c.x1 = c.x0;
      RodDetectionParams p;
      p.merge_fraction = 0;
      const auto raw = detect_rod_rod(c, p);
      REQUIRE(raw.size() == 2);  // edges 0 and 1 of rod 1, each closest just beside the vertex
      CHECK(raw[0].edge_b != raw[1].edge_b);
      CHECK(std::abs(raw[0].s_b - 0.5) > 0.49);
      const double angle = std::acos(std::clamp(raw[0].normal.dot(raw[1].normal), -1.0, 1.0)) * 180 / M_PI;
      MESSAGE("kink " << kink_deg << " degrees: normals " << angle << " degrees apart, gaps " << raw[0].gap << " and " << raw[1].gap);
      CHECK(angle == doctest::Approx(kink_deg).epsilon(0.05));
      p.merge_fraction = 0.05;
      p.merge_angle = 2;
      const auto merged = detect_rod_rod(c, p);
      CHECK(near_duplicates(c, raw[0], raw[1], p) == (kink_deg < p.merge_angle));
      if (kink_deg < p.merge_angle) {
        REQUIRE(merged.size() == 1);
        CHECK(merged[0].gap == std::min(raw[0].gap, raw[1].gap));  // the deeper one stays
      } else {
        CHECK(merged.size() == 2);
      }
    }
  }

  TEST_CASE("rod detection: merging never leaves a raw contact without a kept one beside it") {
    // Rod soups: every contact dropped by the merge is a near-duplicate of a kept one, no
    // gap of a dropped contact is below the kept one's, and merging is off at fraction 0.
    int dropped = 0;
    for (unsigned seed : {4u, 5u}) {
      const RodCurves c = rod_soup(40, 12, 0.3, 0.03, 0.003, 0.02, seed);
      RodDetectionParams p;
      p.proximity = 0.002;
      p.merge_fraction = 0;
      const auto raw = detect_rod_rod(c, p);
      p.merge_fraction = 0.05;
      const auto kept = detect_rod_rod(c, p);
      CHECK(kept.size() <= raw.size());
      for (const RodContact& k : raw) {
        const bool is_kept = std::any_of(kept.begin(), kept.end(), [&](const RodContact& q) { return same(q, k); });
        if (is_kept) continue;
        ++dropped;
        CHECK(std::any_of(kept.begin(), kept.end(), [&](const RodContact& q) { return near_duplicates(c, q, k, p) && q.gap <= k.gap; }));
      }
    }
    // Parallel rods lying along each other: neighbouring edge pairs meet at shared vertices.
    RodCurves c;
    add_rod(c, {0, 0.025, 0}, {1, 0.025, 0}, 5, 0.015);
    add_rod(c, {0.1, 0, 0}, {1.1, 0, 0}, 5, 0.015);
    RodDetectionParams p;
    const size_t merged = detect_rod_rod(c, p).size();
    p.merge_fraction = 0;
    MESSAGE("rod soups: " << dropped << " near-duplicates merged; parallel rods: " << detect_rod_rod(c, p).size() << " contacts, "
                          << merged << " after merging");
    CHECK(merged < detect_rod_rod(c, p).size());
  }

  TEST_CASE("rod detection: no rods or no obstacles give no contacts") {
    const RodCurves none;
    CHECK(detect_rod_rod(none, {}).empty());
    CHECK(detect_rod_obstacles(none, {sphere(Vector3d::Zero(), 1)}, 0, 0.01, {}).empty());
    RodCurves one;
    add_rod(one, {0, 0, 0}, {1, 0, 0}, 2, 0.01);
    CHECK(detect_rod_rod(one, {}).empty());
    CHECK(detect_rod_obstacles(one, {}, 0, 0.01, {}).empty());
    RodDetectionParams bad;
    bad.self_skip = 1;
    bad.proximity = -1;
    CHECK_THROWS_WITH_AS(detect_rod_rod(one, bad), doctest::Contains("self_skip"), ConfigError);
  }

  TEST_CASE("rod detection: intersecting centrelines get the cross product normal oriented by the motion") {
    for (double dir : {1.0, -1.0}) {
      CAPTURE(dir);
      RodCurves c;
      add_rod(c, {-1, 0, 0}, {1, 0, 0}, 2, 0.01, {0, 0, -0.1 * dir});  // a moves towards -dir z: came from +dir z
      add_rod(c, {0, -1, 0}, {0, 1, 0}, 2, 0.01);
      const auto cs = detect_rod_rod(c, {});
      REQUIRE(cs.size() == 1);
      CHECK(cs[0].gap == doctest::Approx(-0.02));
      CHECK((cs[0].normal - Vector3d(0, 0, dir)).norm() < 1e-12);
    }
  }

  TEST_CASE("rod detection: rods passing through each other in one step are found only with rod_ccd") {
    // Rod 0 falls from z = 1 to z = -1 across rod 1 at z = 0: they meet at 1 - 2 t = r_a + r_b.
    const double ra = 0.01, rb = 0.015;
    RodCurves c;
    add_rod(c, {-1, 0.3, 1}, {1, 0.3, 1}, 3, ra, {0, 0, -2});
    add_rod(c, {0.2, -1, 0}, {0.2, 1, 0}, 5, rb);
    RodDetectionParams p;
    CHECK(detect_rod_rod(c, p).empty());
    p.rod_ccd = true;
    const auto cs = detect_rod_rod(c, p);
    REQUIRE(cs.size() == 1);
    const RodContact& k = cs[0];
    CHECK(k.rod_a == 0);
    CHECK(k.edge_a == 1);
    CHECK(k.rod_b == 1);
    CHECK(k.edge_b == 2);
    CHECK(k.s_a == doctest::Approx(0.2).epsilon(1e-9));
    CHECK(k.s_b == doctest::Approx(0.3 / 0.5 - 0.0).epsilon(1e-9));
    CHECK(std::abs(k.toi - (1 - ra - rb) / 2) < 1e-8);
    CHECK(std::abs(k.gap) <= p.ccd_tolerance);
    CHECK((k.normal - Vector3d(0, 0, 1)).norm() < 1e-9);  // a came from above
  }

  TEST_CASE("rod detection: parallel rods") {
    RodDetectionParams p;
    SUBCASE("side by side: contacts along the overlap with the perpendicular normal") {
      // Rod 0 at y = 0.025 above rod 1 at y = 0 (radii 0.015 + 0.015): every edge pair that overlaps
      // along x, with the normal +y.
      RodCurves c;
      add_rod(c, {0, 0.025, 0}, {1, 0.025, 0}, 5, 0.015);
      add_rod(c, {0.1, 0, 0}, {1.1, 0, 0}, 5, 0.015);
      p.merge_fraction = 0;  // every edge pair (the merge of near-duplicates is tested below)
      const auto cs = detect_rod_rod(c, p);
      REQUIRE(!cs.empty());
      for (const RodContact& k : cs) {
        CAPTURE(k.edge_a);
        CAPTURE(k.edge_b);
        CHECK((k.normal - Vector3d(0, 1, 0)).norm() < 1e-12);
        CHECK(k.gap == doctest::Approx(-0.005).epsilon(1e-9));
      }
      // Edges 0.25 long, shifted by 0.1: edge a overlaps edges a - 1 and a of rod 1 along x.
      std::set<std::pair<int, int>> got, want;
      for (const RodContact& k : cs) got.emplace(k.edge_a, k.edge_b);
      for (int ea = 0; ea < 4; ++ea)
        for (int eb = 0; eb < 4; ++eb)
          if (0.25 * ea < 0.1 + 0.25 * (eb + 1) && 0.1 + 0.25 * eb < 0.25 * (ea + 1)) want.emplace(ea, eb);
      CHECK(got == want);
    }
    SUBCASE("collinear overlapping centrelines: a unit normal perpendicular to the rods") {
      RodCurves c;
      add_rod(c, {0, 0, 0}, {1, 0, 0}, 2, 0.01, {0, 0, 0.01});
      add_rod(c, {0.5, 0, 0}, {1.5, 0, 0}, 2, 0.01);
      const auto cs = detect_rod_rod(c, p);
      REQUIRE(cs.size() == 1);
      CHECK(cs[0].normal.norm() == doctest::Approx(1));
      CHECK(std::abs(cs[0].normal.x()) < 1e-12);
      CHECK((cs[0].normal - Vector3d(0, 0, -1)).norm() < 1e-12);  // a moves up: it came from below
      CHECK(cs[0].gap == doctest::Approx(-0.02));
    }
  }

  TEST_CASE("rod detection: rods touching at their end points") {
    // The last vertex of rod 0 is 0.025 below the first vertex of rod 1 (radii 0.015 each).
    RodCurves c;
    add_rod(c, {-1, 0, 0}, {1, 0, 0}, 5, 0.015);
    add_rod(c, {1, 0, 0.025}, {1, 1, 1}, 4, 0.015);
    const auto cs = detect_rod_rod(c, {});
    REQUIRE(cs.size() == 1);
    CHECK(cs[0].edge_a == 3);
    CHECK(cs[0].s_a == 1);
    CHECK(cs[0].edge_b == 0);
    CHECK(cs[0].s_b == 0);
    CHECK((cs[0].normal - Vector3d(0, 0, -1)).norm() < 1e-12);
    CHECK(cs[0].gap == doctest::Approx(-0.005));
    // Just out of reach.
    RodCurves far = c;
    for (int i = far.first[1]; i < far.first[2]; ++i) far.x0[i].z() += 0.006;
    CHECK(detect_rod_rod(far, {}).empty());
  }

  TEST_CASE("rod detection: self contact of a coiled rod respects self_skip") {
    // A helix of radius 0.1 with 24 edges per turn and a pitch of 0.015 < 2 r = 0.02: each edge
    // touches the edges about one turn away; edges fewer than a turn apart are farther than 2 r.
    const int per_turn = 24, turns = 3;
    RodCurves c;
    c.first = {0};
    for (int i = 0; i <= per_turn * turns; ++i) {
      const double a = 2 * M_PI * i / per_turn;
      c.x0.emplace_back(0.1 * std::cos(a), 0.1 * std::sin(a), 0.015 * a / (2 * M_PI));
    }
    c.x1 = c.x0;
    c.first.push_back(static_cast<int>(c.x0.size()));
    c.radius = {0.01};
    RodDetectionParams p;
    p.merge_fraction = 0;
    const auto cs = detect_rod_rod(c, p);
    REQUIRE(!cs.empty());
    int min_apart = 1 << 30, max_apart = 0;
    for (const RodContact& k : cs) {
      CHECK(k.rod_a == 0);
      CHECK(k.rod_b == 0);
      CHECK(k.edge_a < k.edge_b);
      min_apart = std::min(min_apart, k.edge_b - k.edge_a);
      max_apart = std::max(max_apart, k.edge_b - k.edge_a);
      CHECK(k.normal.z() < -0.9);  // a is the lower turn, b above it
    }
    CHECK(min_apart >= per_turn - 2);
    CHECK(max_apart <= per_turn + 2);
    CHECK(rod_rod_keys(cs) == brute_force_rod_rod(c, p));
    // A skip larger than a turn removes them all; so does switching self contact off.
    p.self_skip = per_turn + 3;
    CHECK(detect_rod_rod(c, p).empty());
    p.self_skip = per_turn;
    for (const RodContact& k : detect_rod_rod(c, p)) CHECK(k.edge_b - k.edge_a >= per_turn);
    p.self_skip = 2;
    p.self_contact = false;
    CHECK(detect_rod_rod(c, p).empty());
    // The brute-force check agrees that the coil overlaps.
    CHECK(count_rod_overlaps(c.x0, c.first, c.radius, 0.0, 2) > 0);
    CHECK(count_rod_overlaps(c.x0, c.first, c.radius, 0.0, per_turn + 3) == 0);
  }

  TEST_CASE("rod detection: vertex contacts with a static or moving sphere") {
    // A rod along x at height z0 above a sphere of radius 1 at the origin; its middle vertex
    // (x = 0) is closest, at distance z0 - 1 from the surface.
    const double r = 0.01, prox = 0.002;
    RodDetectionParams p;
    p.proximity = prox;
    for (double z0 : {1.005, 1.011, 1.0125, 1.02}) {
      CAPTURE(z0);
      RodCurves c;
      add_rod(c, {-0.4, 0, z0}, {0.4, 0, z0}, 5, r);
      const std::vector<ObstacleSpec> obs = {sphere(Vector3d::Zero(), 1.0)};
      const auto cs = detect_rod_obstacles(c, obs, 0.0, 0.01, p);
      std::vector<RodContact> middle;
      for (const RodContact& k : cs)
        if (k.edge_a == 2 && k.s_a == 0) middle.push_back(k);
      const bool expect = z0 - 1 - r < prox;
      REQUIRE(middle.size() == (expect ? 1u : 0u));
      if (!expect) continue;
      const RodContact& k = middle[0];
      CHECK(k.vertex_contact());
      CHECK(k.kind == RodContact::Kind::rod_obstacle);
      CHECK(k.obstacle == 0);
      CHECK(k.toi == 0);
      CHECK(k.gap == doctest::Approx(z0 - 1 - r).epsilon(1e-12));
      CHECK((k.normal - Vector3d(0, 0, 1)).norm() < 1e-12);
      CHECK(k.obstacle_displacement.norm() == 0);
    }
    SUBCASE("a translating sphere carries its contact point") {
      RodCurves c;
      add_rod(c, {-0.4, 0, 1.005}, {0.4, 0, 1.005}, 5, r);
      ObstacleSpec s = sphere(Vector3d::Zero(), 1.0);
      s.motion.velocity = {0.3, 0, -0.2};
      s.motion.start = 0.5;
      const auto cs = detect_rod_obstacles(c, {s}, 0.5, 0.52, p);
      REQUIRE(!cs.empty());
      for (const RodContact& k : cs) CHECK((k.obstacle_displacement - 0.02 * s.motion.velocity).norm() < 1e-12);
    }
    SUBCASE("a spinning sphere moves its contact point along the surface") {
      RodCurves c;
      add_rod(c, {-0.4, 0, 1.005}, {0.4, 0, 1.005}, 5, r);
      ObstacleSpec s = sphere(Vector3d::Zero(), 1.0);
      s.motion.angular_velocity = {0, 2.0, 0};  // about y: the top point (0, 0, 1) moves towards +x
      const double t0 = 0.1, t1 = 0.15;
      const auto cs = detect_rod_obstacles(c, {s}, t0, t1, p);
      std::vector<RodContact> middle;
      for (const RodContact& k : cs)
        if (k.edge_a == 2 && k.s_a == 0) middle.push_back(k);
      REQUIRE(middle.size() == 1);
      // The material point at (0, 0, 1) at t0 is R(2 (t1 - t0)) (0, 0, 1) at t1.
      const Vector3d top(0, 0, 1);
      const Vector3d moved = Eigen::AngleAxisd(2.0 * (t1 - t0), Vector3d::UnitY()) * top;
      CHECK((middle[0].obstacle_displacement - (moved - top)).norm() < 1e-12);
      CHECK(middle[0].obstacle_displacement.x() > 0);
    }
    SUBCASE("a sphere sweeping through a resting rod in one step is caught") {
      RodCurves c;
      add_rod(c, {0, -0.5, 0}, {0, 0.5, 0}, 3, r);  // middle vertex at the origin
      ObstacleSpec s = sphere({-1, 0, 0}, 0.1);
      s.motion.velocity = {200, 0, 0};  // x = -1 + 2 s over a step of 0.01 s
      p.proximity = 0;
      const auto cs = detect_rod_obstacles(c, {s}, 0.0, 0.01, p);
      REQUIRE(cs.size() == 1);
      CHECK(cs[0].edge_a == 1);
      CHECK(cs[0].s_a == 0);
      CHECK(std::abs(cs[0].toi - (1 - 0.1 - r) / 2) < 1e-8);
      CHECK((cs[0].normal - Vector3d(1, 0, 0)).norm() < 1e-6);
      CHECK((cs[0].obstacle_displacement - Vector3d(2, 0, 0)).norm() < 1e-12);
    }
  }

  TEST_CASE("rod detection: vertex contacts with a static or moving plane") {
    const double r = 0.01;
    RodDetectionParams p;
    p.proximity = 0.001;
    p.ccd_tolerance = 1e-10;  // the toi is early by up to eta / 0.06 below
    // A rod tilted over the floor z = 0: vertices at heights 0.005 .. 0.205.
    RodCurves c;
    add_rod(c, {0, 0, 0.005}, {1, 0, 0.205}, 11, r);
    std::vector<ObstacleSpec> obs = {plane(Vector3d::Zero(), Vector3d::UnitZ())};
    auto cs = detect_rod_obstacles(c, obs, 0, 0.01, p);
    REQUIRE(cs.size() == 1);  // heights 0.005 and 0.025: only the first is within r + proximity
    CHECK(cs[0].edge_a == 0);
    CHECK(cs[0].s_a == 0);
    CHECK(cs[0].gap == doctest::Approx(0.005 - r));
    CHECK((cs[0].normal - Vector3d::UnitZ()).norm() < 1e-15);
    // The floor rising by 0.06 over the step reaches the vertices up to 0.06 + r high; the
    // contact point moves with it.
    obs[0].motion.velocity = {0.5, 0, 6};
    cs = detect_rod_obstacles(c, obs, 0, 0.01, p);
    REQUIRE(cs.size() == 4);  // heights 0.005, 0.025, 0.045, 0.065
    for (int k = 0; k < 4; ++k) {
      CAPTURE(k);
      CHECK(cs[k].edge_a == k);
      CHECK((cs[k].obstacle_displacement - Vector3d(0.005, 0, 0.06)).norm() < 1e-12);
      const double h = 0.005 + 0.02 * k;
      CHECK(std::abs(cs[k].toi - (k == 0 ? 0.0 : (h - r) / 0.06)) < 1e-8);
    }
  }

  TEST_CASE("rod detection: a fast rod tunnelling through a plane is caught by CCD") {
    const double r = 0.002;
    RodCurves c;
    add_rod(c, {0, 0, 1}, {1, 0, 1}, 6, r, {0, 0, -2});  // from z = 1 to z = -1
    const std::vector<ObstacleSpec> obs = {plane(Vector3d::Zero(), Vector3d::UnitZ())};
    const auto cs = detect_rod_obstacles(c, obs, 0, 0.01, {});
    REQUIRE(cs.size() == 6);
    for (int k = 0; k < 6; ++k) {
      CAPTURE(k);
      CHECK(cs[k].vertex_contact());
      CHECK(std::abs(cs[k].toi - (1 - r) / 2) < 1e-8);
      CHECK((cs[k].normal - Vector3d::UnitZ()).norm() < 1e-15);
      CHECK(std::abs(cs[k].gap) <= 1e-9);
    }
    // The end positions are deep inside: the brute-force check sees it.
    CHECK(count_obstacle_penetrations(c.x1, c.first, c.radius, obs, 0.01, 1e-6) == 6);
    CHECK(count_obstacle_penetrations(c.x0, c.first, c.radius, obs, 0.0, 1e-6) == 0);
  }

  TEST_CASE("rod detection: a rod falling across a thin wall is caught between its vertices") {
    // A wall 0.01 thick (x in [-0.005, 0.005]) with its top at z = 0.5; a rod along x with
    // vertices 0.2 apart (x = -0.1, 0.1) falls from z = 0.55 to z = 0.45 across its top edges.
    const double r = 0.002;
    RodCurves c;
    add_rod(c, {-0.3, 0, 0.55}, {0.1, 0, 0.55}, 3, r, {0, 0, -0.1});
    RodDetectionParams p;
    for (bool mesh : {false, true}) {
      CAPTURE(mesh);
      const Vector3d half(0.005, 1, 0.25), centre(0, 0, 0.25);
      const std::vector<ObstacleSpec> obs = {mesh ? box_mesh(centre, half) : box(centre, half)};
      // The vertices never come near the wall, but the rod ends up through it.
      CHECK(count_obstacle_penetrations(c.x1, c.first, c.radius, obs, 0.01, 0.0) == 0);
      CHECK(count_obstacle_penetrations(c.x1, c.first, c.radius, obs, 0.01, 0.0, 20) > 0);
      const auto cs = detect_rod_obstacles(c, obs, 0, 0.01, p);
      REQUIRE(cs.size() == 2);  // the wall's two top edges, under the rod's second edge
      for (const RodContact& k : cs) {
        CHECK(!k.vertex_contact());
        CHECK(k.edge_a == 1);
        CHECK(std::abs(k.toi - (0.05 - r) / 0.1) < 1e-8);
        CHECK((k.normal - Vector3d::UnitZ()).norm() < 1e-9);
        CHECK(std::abs(k.gap) <= p.ccd_tolerance);
        const double x = -0.1 + 0.2 * k.s_a;
        CHECK(std::abs(std::abs(x) - 0.005) < 1e-9);  // above one of the two top edges
        CHECK(k.obstacle_displacement.norm() == 0);
      }
      CHECK(cs[0].obstacle_edge != cs[1].obstacle_edge);
      if (!mesh) {  // box edges along y (axis 1) with z = + (bit 0) and x = -/+ (bit 1)
        CHECK(cs[0].obstacle_edge == 5);
        CHECK(cs[1].obstacle_edge == 7);
      }
    }
  }

  TEST_CASE("rod detection: a moving wall edge carries its contact point") {
    // A rod at rest along x at z = 0.503 (radius 0.002, proximity 0.002) over a wall whose top
    // edges move by (0, 0.01, 0) over the step.
    RodCurves c;
    add_rod(c, {-0.1, 0, 0.503}, {0.1, 0, 0.503}, 2, 0.002);
    ObstacleSpec wall = box({0, 0, 0.25}, {0.005, 1, 0.25});
    wall.motion.velocity = {0, 1, 0};
    RodDetectionParams p;
    p.proximity = 0.002;
    const auto cs = detect_rod_obstacles(c, {wall}, 0, 0.01, p);
    REQUIRE(cs.size() == 2);
    for (const RodContact& k : cs) {
      CHECK(k.toi == 0);
      CHECK(k.gap == doctest::Approx(0.001));
      CHECK((k.obstacle_displacement - Vector3d(0, 0.01, 0)).norm() < 1e-12);
    }
  }

  TEST_CASE("rod detection: a fast rod tunnelling through a mesh box is caught by CCD") {
    // A rod along x over a mesh box with its top at z = 0.5, falling from z = 0.7 to z = 0.1
    // in one step: each vertex above the box touches the top face at 0.7 - 0.6 s = 0.5 + r.
    const double r = 0.003;
    RodCurves c;
    add_rod(c, {-0.3, 0.05, 0.7}, {0.3, 0.05, 0.7}, 7, r, {0, 0, -0.6});
    const std::vector<ObstacleSpec> obs = {box_mesh({0, 0, 0.25}, {0.2, 0.2, 0.25})};
    const auto cs = detect_rod_obstacles(c, obs, 0, 0.01, {});
    std::vector<RodContact> vertex;
    for (const RodContact& k : cs)
      if (k.vertex_contact()) vertex.push_back(k);
    REQUIRE(vertex.size() == 5);  // x = -0.2 .. 0.2 (the outer two land on the top edges)
    for (const RodContact& k : vertex) {
      CHECK(std::abs(k.toi - (0.2 - r) / 0.6) < 1e-8);
      CHECK((k.normal - Vector3d::UnitZ()).norm() < 1e-12);
      CHECK(std::abs(k.gap) <= 1e-9);
    }
    CHECK(count_obstacle_penetrations(c.x1, c.first, c.radius, obs, 0.01, 0.0) >= 3);
    // Sliding fast along the top face at a gap of 1e-7: no contact, and cheap.
    RodCurves slide;
    add_rod(slide, {-0.1, 0, 0.5 + r + 1e-7}, {0.1, 0, 0.5 + r + 1e-7}, 5, r, {0.05, 0.05, 0});
    CHECK(detect_rod_obstacles(slide, obs, 0, 0.01, {}).empty());
  }

  TEST_CASE("rod detection: a box rotating through a vertex is caught") {
    // A box of half extents (1, 0.05, 0.5) turning by 90 degrees about z over the step sweeps
    // through a vertex at (0.5, 0.5, 0): in body coordinates the vertex is at height
    // 0.5 (cos a - sin a) above the face y = 0.05, reached at r when a = acos(0.06 sqrt 2) - pi / 4.
    const double r = 0.01, dt = 0.01;
    RodCurves c;
    add_rod(c, {0.5, 0.5, 0}, {0.5, 0.5, 0.8}, 2, r);  // the second vertex is above the box
    ObstacleSpec b = box(Vector3d::Zero(), {1, 0.05, 0.5});
    b.motion.angular_velocity = {0, 0, M_PI / 2 / dt};
    std::vector<RodContact> cs;
    for (const RodContact& k : detect_rod_obstacles(c, {b}, 0, dt, {}))
      if (k.vertex_contact()) cs.push_back(k);
    REQUIRE(cs.size() == 1);
    const double angle = std::acos(0.06 * std::sqrt(2.0)) - M_PI / 4;
    CHECK(cs[0].edge_a == 0);
    CHECK(cs[0].s_a == 0);
    CHECK(std::abs(cs[0].toi - angle / (M_PI / 2)) < 1e-7);
    // The normal is the face normal at toi, R(angle) (0, 1, 0); the contact point turns by the
    // remaining 90 degrees of the step about the axis: |displacement| = sqrt(2) |p| (p in the plane z = 0).
    CHECK((cs[0].normal - Vector3d(-std::sin(angle), std::cos(angle), 0)).norm() < 1e-6);
    const contact::ObstaclePose pose = contact::ObstaclePose::at(b, cs[0].toi * dt);
    const Vector3d p = c.x0[0] - pose.distance(c.x0[0]).phi * cs[0].normal;
    const Vector3d y = pose.rotation.transpose() * p;  // body coordinates
    CHECK((cs[0].obstacle_displacement - (Eigen::AngleAxisd(M_PI / 2, Vector3d::UnitZ()) * y - y)).norm() < 1e-9);
  }

  TEST_CASE("rod detection: output does not depend on the number of threads") {
#ifdef _OPENMP
    const RodCurves c = rod_soup(120, 30, 0.6, 0.03, 0.004, 0.03, 11);
    const std::vector<ObstacleSpec> obs = {sphere({0, 0, 0}, 0.15), box({0.2, 0.1, -0.1}, {0.2, 0.01, 0.1}),
                                           plane({0, 0, -0.2}, {0.1, 0, 1}), box_mesh({-0.2, 0.1, 0}, {0.05, 0.1, 0.2})};
    RodDetectionParams p;
    p.proximity = 0.002;
    for (bool ccd : {false, true}) {
      CAPTURE(ccd);
      p.rod_ccd = ccd;
      const int saved = omp_get_max_threads();
      omp_set_num_threads(1);
      const auto one = detect_rod_contacts(c, obs, 0, 0.01, p);
      omp_set_num_threads(2);
      const auto two = detect_rod_contacts(c, obs, 0, 0.01, p);
      omp_set_num_threads(saved);
      REQUIRE(one.size() == two.size());
      REQUIRE(one.size() > 100);
      bool equal = true;
      for (size_t k = 0; k < one.size(); ++k) equal = equal && same(one[k], two[k]);
      CHECK(equal);
      CHECK(std::is_sorted(one.begin(), one.end(), contact_less));
    }
#else
    MESSAGE("built without OpenMP");
#endif
  }

  TEST_CASE("rod detection: the broad phase finds what brute force finds on random rod soups") {
    for (unsigned seed : {1u, 2u, 3u}) {
      for (bool ccd : {false, true}) {
        CAPTURE(seed);
        CAPTURE(ccd);
        const RodCurves c = rod_soup(40, 12, 0.3, 0.03, 0.003, 0.02, seed);
        RodDetectionParams p;
        p.rod_ccd = ccd;
        p.merge_fraction = 0;
        p.proximity = 0.001 * seed;
        p.self_skip = 1 + static_cast<int>(seed);
        if (p.self_skip < 2) p.self_skip = 2;
        const auto cs = detect_rod_rod(c, p);
        const std::set<Key> brute = brute_force_rod_rod(c, p);
        CHECK(brute.size() > 10);
        CHECK(rod_rod_keys(cs) == brute);
        // Each contact's gap and normal agree with its parameters.
        for (const RodContact& k : cs) {
          const int i = c.first[k.rod_a] + k.edge_a, j = c.first[k.rod_b] + k.edge_b;
          auto at = [&](int v) { return Vector3d((1 - k.toi) * c.x0[v] + k.toi * c.x1[v]); };
          const Vector3d pa = (1 - k.s_a) * at(i) + k.s_a * at(i + 1), pb = (1 - k.s_b) * at(j) + k.s_b * at(j + 1);
          CHECK((pa - pb).norm() - c.radius[k.rod_a] - c.radius[k.rod_b] == doctest::Approx(k.gap).epsilon(1e-9));
          CHECK(k.normal.norm() == doctest::Approx(1).epsilon(1e-12));
          if ((pa - pb).norm() > 1e-6) CHECK((pa - pb).normalized().dot(k.normal) > 1 - 1e-9);
          // Closest points interior to both edges: the normal is orthogonal to both (it is
          // their cross product, methods/rod-contact §4.1 and V-02).
          if (k.s_a > 1e-6 && k.s_a < 1 - 1e-6 && k.s_b > 1e-6 && k.s_b < 1 - 1e-6) {
            CHECK(std::abs(k.normal.dot((at(i + 1) - at(i)).normalized())) < 1e-6);
            CHECK(std::abs(k.normal.dot((at(j + 1) - at(j)).normalized())) < 1e-6);
          }
        }
      }
    }
  }

  TEST_CASE("rod detection: brute-force overlap and penetration counts") {
    RodCurves c;
    add_rod(c, {-1, 0, 0.025}, {1, 0, 0.025}, 3, 0.015);
    add_rod(c, {0, -1, 0}, {0, 1, 0}, 3, 0.015);
    CHECK(count_rod_overlaps(c.x0, c.first, c.radius, 0.0, 2) == 4);  // edges meet at the shared middle vertices
    CHECK(count_rod_overlaps(c.x0, c.first, c.radius, 0.006, 2) == 0);
    const std::vector<ObstacleSpec> obs = {plane({0, 0, 0.02}, Vector3d::UnitZ()), sphere({5, 5, 5}, 1)};
    // Rod 0's vertices are 0.005 above the plane (inside its radius), rod 1's 0.02 below.
    CHECK(count_obstacle_penetrations(c.x0, c.first, c.radius, obs, 0, 0.0) == 6);
    CHECK(count_obstacle_penetrations(c.x0, c.first, c.radius, obs, 0, 0.011) == 3);
    CHECK(count_obstacle_penetrations(c.x0, c.first, c.radius, obs, 0, 0.011, 1) == 5);
  }

  TEST_CASE("rod detection: 250 random rods of 30 vertices") {
    // Hair-like density: rods of 30 vertices 1 cm apart in a 20 cm cube, radius ~0.5 mm.
    const RodCurves c = rod_soup(250, 30, 0.2, 0.01, 0.0005, 0.005, 5);
    const std::vector<ObstacleSpec> obs = {sphere({0, 0, 0}, 0.05)};
    RodDetectionParams p;
    p.proximity = 0.0005;
    for (bool ccd : {false, true}) {
      p.rod_ccd = ccd;
      const auto start = std::chrono::steady_clock::now();
      const auto rr = detect_rod_rod(c, p);
      const auto mid = std::chrono::steady_clock::now();
      const auto ro = detect_rod_obstacles(c, obs, 0, 0.01, p);
      const auto end = std::chrono::steady_clock::now();
      MESSAGE("250 rods x 30 vertices, rod_ccd = " << ccd << ": " << rr.size() << " rod-rod contacts in "
                                                     << std::chrono::duration<double, std::milli>(mid - start).count() << " ms, "
                                                     << ro.size() << " rod-obstacle contacts in "
                                                     << std::chrono::duration<double, std::milli>(end - mid).count() << " ms");
      CHECK(!rr.empty());
    }
  }
}
