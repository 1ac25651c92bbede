// Exact predicates, triangle-triangle tests and the mesh intersection check
// (contact/verify), against references computed independently in exact rational
// arithmetic: the orientation determinants directly, and the triangle tests by solving
// for the intersection of each edge with the other triangle (Cramer's rule, degenerate
// systems split into their faces) rather than from orientation signs.
#include <doctest/doctest.h>

#include <fmt/format.h>
#include <Eigen/Geometry>
#include <boost/multiprecision/cpp_int.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <optional>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "contact/verify/intersection_check.hpp"
#include "contact/verify/predicates.hpp"
#include "contact/verify/triangle_intersection.hpp"
#include "framework/error.hpp"
#include "framework/mesh_generators.hpp"

using namespace weft;
using namespace weft::contact::verify;
using Eigen::Vector3d;

namespace {

// ---- Random numbers with all 53 bits, portable -----------------------------------------

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : g_(seed) {}
  double uniform(double a = 0, double b = 1) { return a + (b - a) * (static_cast<double>(g_() >> 11) * 0x1p-53); }
  int integer(int lo, int hi) { return lo + static_cast<int>(g_() % static_cast<std::uint64_t>(hi - lo + 1)); }
  Vector3d vec3(double a = 0, double b = 1) { return {uniform(a, b), uniform(a, b), uniform(a, b)}; }
  Vector3d ivec3(int lo, int hi) { return Vector3d(integer(lo, hi), integer(lo, hi), integer(lo, hi)); }

 private:
  std::mt19937_64 g_;
};

/// x moved by k ulps.
double ulps(double x, int k) {
  for (; k > 0; --k) x = std::nextafter(x, INFINITY);
  for (; k < 0; ++k) x = std::nextafter(x, -INFINITY);
  return x;
}

// ---- Exact rational reference ------------------------------------------------------------

using boost::multiprecision::cpp_int;
using Q = boost::multiprecision::cpp_rational;
using QV = std::array<Q, 3>;

Q exact(double x) {
  int e = 0;
  const double f = std::frexp(x, &e);
  const cpp_int m(static_cast<std::int64_t>(std::ldexp(f, 53)));
  e -= 53;
  return e >= 0 ? Q(cpp_int(m << e)) : Q(m, cpp_int(1) << -e);
}
QV exact(const Vector3d& v) { return {exact(v[0]), exact(v[1]), exact(v[2])}; }
QV sub(const QV& a, const QV& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
QV add(const QV& a, const QV& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
QV scale(const Q& s, const QV& a) { return {s * a[0], s * a[1], s * a[2]}; }
QV cross(const QV& a, const QV& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Q dot(const QV& a, const QV& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Q det(const QV& a, const QV& b, const QV& c) { return dot(a, cross(b, c)); }
bool is_zero(const QV& a) { return a[0] == 0 && a[1] == 0 && a[2] == 0; }
int sgn(const Q& q) { return q > 0 ? 1 : q < 0 ? -1 : 0; }

int orient3d_rational(const Vector3d& a, const Vector3d& b, const Vector3d& c, const Vector3d& d) {
  const QV A = exact(a);
  return sgn(det(sub(exact(b), A), sub(exact(c), A), sub(exact(d), A)));
}
int orient2d_rational(double ax, double ay, double bx, double by, double cx, double cy) {
  return sgn((exact(bx) - exact(ax)) * (exact(cy) - exact(ay)) - (exact(by) - exact(ay)) * (exact(cx) - exact(ax)));
}
double orient3d_naive(const Vector3d& a, const Vector3d& b, const Vector3d& c, const Vector3d& d) {
  return (b - a).cross(c - a).dot(d - a);
}

/// Parameters t in [0, 1] of the points p + t (q - p) of a segment, as an interval.
struct Interval {
  Q lo, hi;
  void hull(const Interval& o) {
    lo = std::min(lo, o.lo);
    hi = std::max(hi, o.hi);
  }
};
using MaybeInterval = std::optional<Interval>;
void merge(MaybeInterval& into, const MaybeInterval& o) {
  if (!o) return;
  if (!into)
    into = o;
  else
    into->hull(*o);
}

/// {t in [0, 1] : p + t d == x}.
MaybeInterval point_on_segment_params(const QV& x, const QV& p, const QV& q) {
  const QV d = sub(q, p);
  if (is_zero(d)) return x == p ? MaybeInterval(Interval{0, 1}) : std::nullopt;
  const Q t = dot(sub(x, p), d) / dot(d, d);
  if (t < 0 || t > 1 || add(p, scale(t, d)) != x) return std::nullopt;
  return Interval{t, t};
}

/// {t : p + t (q - p) in [r, s]}: a unique solution when the directions are independent,
/// else the hull of the faces' solutions (a vertex of the feasible set has t or s at a bound).
MaybeInterval segment_segment_params(const QV& p, const QV& q, const QV& r, const QV& s) {
  const QV d = sub(q, p), e = sub(s, r), n = cross(d, e);
  if (!is_zero(n)) {
    const QV rp = sub(r, p);
    const Q nn = dot(n, n);
    const Q t = dot(cross(rp, e), n) / nn, u = dot(cross(rp, d), n) / nn;
    if (t < 0 || t > 1 || u < 0 || u > 1 || add(p, scale(t, d)) != add(r, scale(u, e))) return std::nullopt;
    return Interval{t, t};
  }
  MaybeInterval out;
  if (point_on_segment_params(p, r, s)) merge(out, Interval{0, 0});
  if (point_on_segment_params(q, r, s)) merge(out, Interval{1, 1});
  merge(out, point_on_segment_params(r, p, q));
  merge(out, point_on_segment_params(s, p, q));
  return out;
}

bool point_in_triangle(const QV& x, const QV& a, const QV& b, const QV& c) {
  const QV e1 = sub(b, a), e2 = sub(c, a), n = cross(e1, e2);
  if (!is_zero(n)) {
    const QV r = sub(x, a);
    const Q nn = dot(n, n);
    const Q l1 = dot(cross(r, e2), n) / nn, l2 = dot(cross(e1, r), n) / nn;
    return l1 >= 0 && l2 >= 0 && l1 + l2 <= 1 && add(a, add(scale(l1, e1), scale(l2, e2))) == x;
  }
  return point_on_segment_params(x, a, b) || point_on_segment_params(x, b, c) || point_on_segment_params(x, c, a);
}

/// {t : p + t (q - p) in triangle (a, b, c)}: Cramer's rule when the system in
/// (t, l1, l2) is regular, else the hull over the faces t = 0, t = 1 and l_i = 0.
MaybeInterval segment_triangle_params(const QV& p, const QV& q, const QV& a, const QV& b, const QV& c) {
  const QV d = sub(q, p), e1 = sub(b, a), e2 = sub(c, a), r = sub(p, a);
  const QV md = scale(Q(-1), d);
  const Q D = det(e1, e2, md);
  if (D != 0) {  // r = l1 e1 + l2 e2 - t d
    const Q l1 = det(r, e2, md) / D, l2 = det(e1, r, md) / D, t = det(e1, e2, r) / D;
    if (t < 0 || t > 1 || l1 < 0 || l2 < 0 || l1 + l2 > 1) return std::nullopt;
    return Interval{t, t};
  }
  MaybeInterval out;
  if (point_in_triangle(p, a, b, c)) merge(out, Interval{0, 0});
  if (point_in_triangle(q, a, b, c)) merge(out, Interval{1, 1});
  merge(out, segment_segment_params(p, q, a, b));
  merge(out, segment_segment_params(p, q, b, c));
  merge(out, segment_segment_params(p, q, c, a));
  return out;
}

using Tri = std::array<Vector3d, 3>;

/// The ends of every edge-triangle intersection: they include every extreme point of
/// P n Q (an extreme point lies on an edge of one triangle within the other), and P n Q
/// is empty iff the list is.
std::vector<QV> extreme_candidates(const Tri& P, const Tri& Q_) {
  std::array<QV, 3> p{exact(P[0]), exact(P[1]), exact(P[2])}, q{exact(Q_[0]), exact(Q_[1]), exact(Q_[2])};
  std::vector<QV> out;
  for (int side = 0; side < 2; ++side) {
    const auto& e = side == 0 ? p : q;
    const auto& t = side == 0 ? q : p;
    for (int i = 0; i < 3; ++i) {
      const QV& a = e[i];
      const QV& b = e[(i + 1) % 3];
      if (const auto I = segment_triangle_params(a, b, t[0], t[1], t[2])) {
        const QV d = sub(b, a);
        out.push_back(add(a, scale(I->lo, d)));
        out.push_back(add(a, scale(I->hi, d)));
      }
    }
  }
  return out;
}

bool oracle_intersect(const Tri& P, const Tri& Q_) { return !extreme_candidates(P, Q_).empty(); }

/// P n Q not contained in conv(shared) (a point or a segment).
bool oracle_beyond(const Tri& P, const Tri& Q_, const std::vector<Vector3d>& shared) {
  for (const QV& x : extreme_candidates(P, Q_)) {
    const bool inside = shared.size() == 1 ? x == exact(shared[0])
                                           : point_on_segment_params(x, exact(shared[0]), exact(shared[1])).has_value();
    if (!inside) return true;
  }
  return false;
}

// ---- Checks on every argument order ---------------------------------------------------------

constexpr std::array<std::array<int, 3>, 6> perms{{{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}}};

/// triangles_intersect on all 72 orderings (6 x 6 vertex permutations, both argument
/// orders); all must agree. \returns the common answer.
bool intersect_all_orders(const Tri& P, const Tri& Q_) {
  const bool r = triangles_intersect(P[0], P[1], P[2], Q_[0], Q_[1], Q_[2]);
  for (const auto& a : perms)
    for (const auto& b : perms) {
      const Tri p{P[a[0]], P[a[1]], P[a[2]]}, q{Q_[b[0]], Q_[b[1]], Q_[b[2]]};
      const bool r1 = triangles_intersect(p[0], p[1], p[2], q[0], q[1], q[2]);
      const bool r2 = triangles_intersect(q[0], q[1], q[2], p[0], p[1], p[2]);
      REQUIRE(r1 == r);
      REQUIRE(r2 == r);
    }
  return r;
}

/// triangles_intersect_sharing_vertex on (v, a, b), (v, c, d) in every order.
bool sharing_vertex_all_orders(const Vector3d& v, const Vector3d& a, const Vector3d& b, const Vector3d& c,
                               const Vector3d& d) {
  const bool r = triangles_intersect_sharing_vertex(v, a, b, c, d);
  CHECK(triangles_intersect_sharing_vertex(v, b, a, c, d) == r);
  CHECK(triangles_intersect_sharing_vertex(v, a, b, d, c) == r);
  CHECK(triangles_intersect_sharing_vertex(v, c, d, a, b) == r);
  CHECK(triangles_intersect_sharing_vertex(v, d, c, b, a) == r);
  return r;
}

bool sharing_edge_all_orders(const Vector3d& u, const Vector3d& w, const Vector3d& a, const Vector3d& b) {
  const bool r = triangles_intersect_sharing_edge(u, w, a, b);
  CHECK(triangles_intersect_sharing_edge(w, u, a, b) == r);
  CHECK(triangles_intersect_sharing_edge(u, w, b, a) == r);
  CHECK(triangles_intersect_sharing_edge(w, u, b, a) == r);
  return r;
}

/// Random and near-touching pairs (generic, vertex or edge of one nearly on the other,
/// exactly coplanar, degenerate, nearly coincident) against the rational reference.
void random_pairs_against_reference(std::uint64_t seed, int count) {
  Rng rng(seed);
  int counts[2] = {0, 0};
  auto compare = [&](const Tri& P, const Tri& Q_) {
    const bool expected = oracle_intersect(P, Q_);
    CAPTURE(P[0].transpose());
    CAPTURE(P[1].transpose());
    CAPTURE(P[2].transpose());
    CAPTURE(Q_[0].transpose());
    CAPTURE(Q_[1].transpose());
    CAPTURE(Q_[2].transpose());
    REQUIRE(triangles_intersect(P[0], P[1], P[2], Q_[0], Q_[1], Q_[2]) == expected);
    REQUIRE(triangles_intersect(Q_[2], Q_[0], Q_[1], P[1], P[0], P[2]) == expected);
    ++counts[expected];
  };
  for (int trial = 0; trial < count; ++trial) {
    const Tri P{rng.vec3(), rng.vec3(), rng.vec3()};
    const int kind = trial % 8;
    Tri Q_;
    if (kind == 0) {  // generic
      Q_ = {rng.vec3(), rng.vec3(), rng.vec3()};
    } else if (kind <= 2) {  // a vertex of Q next to a point of P (interior, edge or vertex)
      double l1 = rng.uniform(), l2 = rng.uniform();
      if (kind == 2) l1 = std::round(l1), l2 = std::round(l2) * (1 - l1);
      if (l1 + l2 > 1) l1 = 1 - l1, l2 = 1 - l2;
      Vector3d x = P[0] + l1 * (P[1] - P[0]) + l2 * (P[2] - P[0]);
      x[trial % 3] = ulps(x[trial % 3], rng.integer(-2, 2));
      Q_ = {x, rng.vec3(), rng.vec3()};
    } else if (kind <= 4) {  // an edge of Q through (nearly) a point of an edge of P
      const int e = rng.integer(0, 2);
      Vector3d x = P[e] + rng.uniform() * (P[(e + 1) % 3] - P[e]);
      x[trial % 3] = ulps(x[trial % 3], rng.integer(-1, 1));
      const Vector3d dir = rng.vec3(-1, 1);
      Q_ = {x + 0.5 * dir, x - 0.5 * dir, rng.vec3()};
    } else if (kind == 5) {  // coplanar, small integers in the plane z = x + 2y - 3
      auto pt = [&] {
        const double x = rng.integer(-4, 4), y = rng.integer(-4, 4);
        return Vector3d(x, y, x + 2 * y - 3);
      };
      Tri Pc{pt(), pt(), pt()};
      compare(Pc, {pt(), pt(), pt()});
      continue;
    } else if (kind == 6) {  // degenerate: collinear or point triangles from integers
      auto deg = [&] {
        const Vector3d p = rng.ivec3(-3, 3), d = rng.ivec3(-2, 2);
        const int m = rng.integer(0, 2);
        return m == 0 ? Tri{p, p, p} : Tri{p, p + d, p + rng.integer(-2, 2) * d};
      };
      const Tri D = deg();
      compare(D, rng.integer(0, 1) ? deg() : Tri{rng.ivec3(-3, 3), rng.ivec3(-3, 3), rng.ivec3(-3, 3)});
      continue;
    } else {  // Q a copy of P shifted by a few ulps, or P's plane slightly tilted
      Q_ = P;
      for (auto& q : Q_) q[trial % 3] = ulps(q[trial % 3], rng.integer(-1, 1));
    }
    compare(P, Q_);
  }
  MESSAGE(fmt::format("random pairs: {} intersecting, {} apart", counts[1], counts[0]));
  CHECK(counts[0] > count / 8);
  CHECK(counts[1] > count / 8);
}

/// Random pairs sharing a vertex or an edge (reals, nearly coplanar reals, small
/// integers with coincident and collinear points, coplanar integers) against the
/// rational reference.
void random_adjacent_pairs_against_reference(std::uint64_t seed, int count) {
  Rng rng(seed);
  int counts[2][2] = {{0, 0}, {0, 0}};
  for (int trial = 0; trial < count; ++trial) {
    CAPTURE(trial);
    // 0: random reals; 1: nearly coplanar reals; 2: small integers (coincident and
    // collinear points included); 3: small integers on one plane.
    const int mode = trial % 4;
    auto pt = [&] { return mode >= 2 ? Vector3d(rng.ivec3(-2, 2)) : rng.vec3(-1, 1); };
    const Vector3d v = pt();
    Vector3d a = pt(), b = pt(), c = pt(), d = pt();
    if (mode == 1) {  // c nearly on the plane of (v, a, b), in or near its wedge
      c = v + rng.uniform(-0.2, 1) * (a - v) + rng.uniform(-0.2, 1) * (b - v);
      c[2] = ulps(c[2], rng.integer(-2, 2));
    }
    if (mode == 3)  // the plane z = x - y + const through v
      for (Vector3d* p : {&a, &b, &c, &d}) (*p)[2] = (*p)[0] - (*p)[1] + v[2] - v[0] + v[1];
    {
      const bool r = triangles_intersect_sharing_vertex(v, a, b, c, d);
      CAPTURE(v.transpose());
      CAPTURE(a.transpose());
      CAPTURE(b.transpose());
      CAPTURE(c.transpose());
      CAPTURE(d.transpose());
      REQUIRE(r == oracle_beyond({v, a, b}, {v, c, d}, {v}));
      REQUIRE(triangles_intersect_sharing_vertex(v, d, c, b, a) == r);
      ++counts[0][r];
    }
    {
      Vector3d bb = d;
      if (mode == 1) {  // nearly folded flat
        bb = v + rng.uniform(-1, 2) * (a - v) + rng.uniform(0, 1) * (b - v);
        bb[trial % 3] = ulps(bb[trial % 3], rng.integer(-1, 1));
      }
      // Edge (v, a) shared; the third vertices b and bb.
      const bool r = triangles_intersect_sharing_edge(v, a, b, bb);
      CAPTURE(v.transpose());
      CAPTURE(a.transpose());
      CAPTURE(b.transpose());
      CAPTURE(bb.transpose());
      REQUIRE(r == oracle_beyond({v, a, b}, {v, a, bb}, {v, a}));
      REQUIRE(triangles_intersect_sharing_edge(a, v, bb, b) == r);
      ++counts[1][r];
    }
  }
  MESSAGE(fmt::format("sharing a vertex: {} reported, {} not; sharing an edge: {} reported, {} not", counts[0][1],
                      counts[0][0], counts[1][1], counts[1][0]));
  CHECK(counts[0][0] > count / 12);
  CHECK(counts[0][1] > count / 12);
  CHECK(counts[1][1] > count / 60);
}

// ---- Meshes ------------------------------------------------------------------------------

std::vector<Vector3d> points_of(const MeshData& m) { return points_from_rows(m.V); }

/// The set of all pairs of a report made with max_pairs large enough.
std::vector<std::array<int, 2>> all_pairs(std::span<const Vector3d> x, const Eigen::MatrixX3i& F, BroadPhase method,
                                          int threads = 0) {
  IntersectionCheckParams prm;
  prm.max_pairs = 1 << 30;
  prm.broad_phase.method = method;
  prm.broad_phase.threads = threads;
  const IntersectionReport r = check_self_intersections(x, F, prm);
  REQUIRE(r.num_pairs == static_cast<std::int64_t>(r.pairs.size()));
  return r.pairs;
}

/// A strip of nu x nv vertices over u in [0, 2L], v in [-W/2, W/2], folded at u = L back
/// over itself: the bottom layer u <= L lies in z = 0; the top layer climbs over the
/// first column after the crease to height `rise`, then follows z = top(x) where x = 2L - u.
template <class Top>
MeshData folded_strip(int nu, int nv, double L, double W, double rise, Top&& top, double top_shift_y = 0) {
  MeshData m = make_rectangle(Eigen::Vector2d(2 * L, W), {nu, nv}, Tessellation::regular, 0);
  const double du = 2 * L / (nu - 1);
  for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
    const double u = m.V(i, 0) + L;  // make_rectangle is centred: u in [0, 2L]
    if (u <= L) {
      m.V(i, 0) = u;
      m.V(i, 2) = 0;
    } else {
      const double x = 2 * L - u;
      m.V(i, 0) = x;
      m.V(i, 2) = u <= L + du * 1.0000001 ? rise : top(x);
      if (u > L + du * 1.0000001) m.V(i, 1) += top_shift_y;
    }
  }
  return m;
}

}  // namespace

TEST_SUITE("contact") {
  // ---- Predicates ------------------------------------------------------------------------

  TEST_CASE("orient3d: exact on nearly coplanar points where naive double arithmetic fails") {
    Rng rng(11);
    int naive_wrong = 0, zero = 0, total = 0;
    for (int trial = 0; trial < 1500; ++trial) {
      // d is coplanar with a, b, c up to rounding, then moved by a few ulps: the exact
      // determinant is then of the size of the naive evaluation's rounding errors.
      const Vector3d a = rng.vec3(-1, 1), b = rng.vec3(-1, 1), c = rng.vec3(-1, 1);
      const double s = rng.uniform(-1, 2), t = rng.uniform(-1, 2);
      Vector3d d = a + s * (b - a) + t * (c - a);
      const int k = trial % 3;
      d[k] = ulps(d[k], rng.integer(-3, 3));
      const int expected = orient3d_rational(a, b, c, d);
      CAPTURE(trial);
      REQUIRE(orient3d(a, b, c, d) == expected);
      REQUIRE(orient3d_exact(a, b, c, d) == expected);
      REQUIRE(orient3d(b, a, c, d) == -expected);  // alternating
      REQUIRE(orient3d(a, b, d, c) == -expected);
      REQUIRE(orient3d(d, a, b, c) == -expected);
      const double naive = orient3d_naive(a, b, c, d);
      naive_wrong += (naive > 0) - (naive < 0) != expected;
      zero += expected == 0;
      ++total;
    }
    MESSAGE(
        fmt::format("{} nearly coplanar cases: naive sign wrong in {}, exactly coplanar {}", total, naive_wrong, zero));
    CHECK(naive_wrong > total / 10);  // the cases are hard: a guard against a vacuous test
  }

  TEST_CASE("orient3d: exact when the differences are exact too") {
    // Coordinates in [1, 2): every difference is exact (Sterbenz), the case the
    // floating-point expansion stage decides without integers.
    Rng rng(12);
    int decided_exactly = 0;
    for (int trial = 0; trial < 1500; ++trial) {
      const Vector3d a = rng.vec3(1, 2), b = rng.vec3(1, 2), c = rng.vec3(1, 2);
      const double s = rng.uniform(0, 1), t = rng.uniform(0, 1 - s);
      Vector3d d = a + s * (b - a) + t * (c - a);
      d[trial % 3] = ulps(d[trial % 3], rng.integer(-2, 2));
      if ((d.array() < 1).any() || (d.array() >= 2).any()) continue;
      const int expected = orient3d_rational(a, b, c, d);
      const std::uint64_t before = exact_evaluations();
      CAPTURE(trial);
      REQUIRE(orient3d(a, b, c, d) == expected);
      REQUIRE(orient3d(c, a, b, d) == expected);
      REQUIRE(Orient3dPlane(a, b, c).side(a, b, c, d) == expected);
      decided_exactly += exact_evaluations() > before;
    }
    CHECK(decided_exactly > 300);
  }

  TEST_CASE("orient3d: a plane prepared once gives the same signs as orient3d") {
    Rng rng(21);
    for (int trial = 0; trial < 3000; ++trial) {
      Vector3d a = rng.vec3(-1, 1), b = rng.vec3(-1, 1), c = rng.vec3(-1, 1);
      if (trial % 5 == 0) b = a;                                            // degenerate plane
      if (trial % 7 == 0) a[2] = b[2] = c[2] = 0.25;                        // a coordinate plane
      if (trial % 11 == 0) a *= 0x1p-1000, b *= 0x1p-1000, c *= 0x1p-1000;  // tiny
      Vector3d d = a + rng.uniform(-1, 2) * (b - a) + rng.uniform(-1, 2) * (c - a);
      if (trial % 2) d[trial % 3] = ulps(d[trial % 3], rng.integer(-2, 2));
      const Orient3dPlane plane(a, b, c);
      CAPTURE(trial);
      REQUIRE(plane.side(a, b, c, d) == orient3d(a, b, c, d));
      REQUIRE(plane.side(a, b, c, d) == orient3d_exact(a, b, c, d));
    }
  }

  TEST_CASE("orient3d: exactly coplanar integer points give zero even when naive products round") {
    Rng rng(5);
    int naive_nonzero = 0;
    for (int trial = 0; trial < 300; ++trial) {
      // Integers below 2^53 (exact), differences near 2^20: the naive products need about
      // 62 bits and round, so the naive sum need not cancel.
      const Vector3d a = rng.ivec3(-1000, 1000) * 0x1p40 + rng.ivec3(-1000, 1000);
      const Vector3d e1 = rng.ivec3(-(1 << 20), 1 << 20), e2 = rng.ivec3(-(1 << 20), 1 << 20);
      const Vector3d b = a + e1, c = a + e2, d = a + 3 * e1 - 2 * e2;  // all exact
      CAPTURE(trial);
      REQUIRE(orient3d_rational(a, b, c, d) == 0);
      REQUIRE(orient3d(a, b, c, d) == 0);
      REQUIRE(orient3d(c, d, a, b) == 0);
      naive_nonzero += orient3d_naive(c, a, d, b) != 0;
    }
    MESSAGE(fmt::format("naive orient3d nonzero on {} of 300 coplanar quadruples", naive_nonzero));
    CHECK(naive_nonzero > 0);
  }

  TEST_CASE("orient3d: signs are invariant under scaling by powers of two outside the filter range") {
    Rng rng(17);
    for (int trial = 0; trial < 300; ++trial) {
      const Vector3d a = rng.vec3(), b = rng.vec3(), c = rng.vec3();
      Vector3d d = a + 0.3 * (b - a) + 0.4 * (c - a);
      d[2] = ulps(d[2], rng.integer(-2, 2));
      const int expected = orient3d_rational(a, b, c, d);
      CAPTURE(trial);
      for (double s : {0x1p-900, 0x1p-340, 0x1p340, 0x1p900}) {  // exact scalings, beyond the filter's range
        CAPTURE(s);
        REQUIRE(orient3d(s * a, s * b, s * c, s * d) == expected);
      }
    }
    // Mixed magnitudes: differences below the filter's range next to ordinary ones.
    const Vector3d tiny(0x1p-1000, 0, 0);
    CHECK(orient3d(tiny, tiny + Vector3d(0x1p-1020, 0, 0), tiny + Vector3d(0, 1, 0), tiny + Vector3d(0, 0, 1)) == 1);
    CHECK(orient3d(Vector3d(0, 0, 0), Vector3d(0x1p-1074, 0, 0), Vector3d(0, 1, 0), Vector3d(0, 0, 1)) == 1);
    CHECK(orient2d(0, 0, 0x1p-1074, 0x1p-1074, 1, ulps(1, 1)) == 1);
  }

  TEST_CASE("orient2d: exact on the classic near-collinear grid") {
    // a = (0.5 + i u, 0.5 + j u) against the line through (12, 12) and (24, 24).
    int naive_wrong = 0, total = 0;
    for (int i = 0; i < 64; ++i)
      for (int j = 0; j < 64; ++j) {
        const double ax = 0.5 + i * 0x1p-53, ay = 0.5 + j * 0x1p-53;
        const int expected = orient2d_rational(ax, ay, 12, 12, 24, 24);
        CAPTURE(i);
        CAPTURE(j);
        REQUIRE(orient2d(ax, ay, 12, 12, 24, 24) == expected);
        REQUIRE(orient2d(12, 12, 24, 24, ax, ay) == expected);
        REQUIRE(orient2d_exact(ax, ay, 12, 12, 24, 24) == expected);
        const double naive = (12 - ax) * (24 - ay) - (12 - ay) * (24 - ax);
        naive_wrong += (naive > 0) - (naive < 0) != expected;
        ++total;
      }
    MESSAGE(fmt::format("naive orient2d wrong on {} of {} points", naive_wrong, total));
    CHECK(naive_wrong > total / 10);
    // The same near (1.5, 1.5) against (1.25, 1.25) and (1.75, 1.75): exact differences.
    for (int i = 0; i < 32; ++i)
      for (int j = 0; j < 32; ++j) {
        const double ax = 1.5 + i * 0x1p-52, ay = 1.5 + j * 0x1p-52;
        CAPTURE(i);
        CAPTURE(j);
        REQUIRE(orient2d(ax, ay, 1.25, 1.25, 1.75, 1.75) == orient2d_rational(ax, ay, 1.25, 1.25, 1.75, 1.75));
        REQUIRE(orient2d(ax, ay, 1.25, 1.25, 1.75, 1.75) == (j > i) - (j < i));  // above the diagonal: +1
      }
  }

  TEST_CASE("orient3d: the filter decides ordinary inputs without exact arithmetic") {
    Rng rng(3);
    const std::uint64_t before = exact_evaluations();
    int nonzero = 0;
    for (int i = 0; i < 10000; ++i) nonzero += orient3d(rng.vec3(), rng.vec3(), rng.vec3(), rng.vec3()) != 0;
    CHECK(nonzero == 10000);
    CHECK(exact_evaluations() - before < 10);
  }

  // ---- Triangle pairs --------------------------------------------------------------------

  TEST_CASE("triangles: crossing and separated pairs") {
    const Tri P{Vector3d(0, 0, 0), Vector3d(2, 0, 0), Vector3d(0, 2, 0)};
    // Q pierces P's interior.
    CHECK(intersect_all_orders(P, {Vector3d(0.5, 0.5, -1), Vector3d(0.5, 0.5, 1), Vector3d(3, 3, 0.5)}));
    // Q crosses P's plane outside P.
    CHECK_FALSE(intersect_all_orders(P, {Vector3d(1.5, 1.5, -1), Vector3d(1.5, 1.5, 1), Vector3d(3, 3, 0.5)}));
    // Parallel planes, overlapping footprints.
    CHECK_FALSE(intersect_all_orders(P, {Vector3d(0, 0, 1e-300), Vector3d(2, 0, 1e-300), Vector3d(0, 2, 1e-300)}));
    // Q upright in the plane x = 1, reaching P's hypotenuse from outside; then stopping short.
    CHECK(intersect_all_orders(P, {Vector3d(1, -1, 0.5), Vector3d(1, -1, -0.5), Vector3d(1, 1, 0)}));
    CHECK_FALSE(intersect_all_orders(P, {Vector3d(1, -1, 0.5), Vector3d(1, -1, -0.5), Vector3d(1, -0.5, 0)}));
  }

  TEST_CASE("triangles: touching at a vertex or along an edge counts and one ulp away does not") {
    const Tri P{Vector3d(0, 0, 0), Vector3d(2, 0, 0), Vector3d(0, 2, 0)};
    // Vertex on vertex.
    CHECK(intersect_all_orders(P, {Vector3d(2, 0, 0), Vector3d(3, 1, 1), Vector3d(3, -1, 1)}));
    // Vertex of Q on P's interior, rest above; then one ulp above.
    CHECK(intersect_all_orders(P, {Vector3d(0.5, 0.5, 0), Vector3d(1, 1, 1), Vector3d(0, 1, 2)}));
    CHECK_FALSE(intersect_all_orders(P, {Vector3d(0.5, 0.5, 0x1p-1074), Vector3d(1, 1, 1), Vector3d(0, 1, 2)}));
    // Vertex of Q on P's edge, Q otherwise outside.
    CHECK(intersect_all_orders(P, {Vector3d(1, 0, 0), Vector3d(1, -1, 1), Vector3d(1, -1, -1)}));
    CHECK_FALSE(intersect_all_orders(P, {Vector3d(1, ulps(0, -1), 0), Vector3d(1, -1, 1), Vector3d(1, -1, -1)}));
    // Edge of Q lying on P's face (Q perpendicular to P).
    CHECK(intersect_all_orders(P, {Vector3d(0.2, 0.2, 0), Vector3d(0.6, 0.3, 0), Vector3d(0.4, 0.2, 1)}));
    // An edge of Q along P's hypotenuse (collinear overlap), Q rising out of P's plane.
    CHECK(intersect_all_orders(P, {Vector3d(0.5, 1.5, 0), Vector3d(1.5, 0.5, 0), Vector3d(1, 1, 3)}));
    // Edge against edge, not coplanar: Q's edge crosses P's hypotenuse at (1, 1, 0); then one ulp beside.
    CHECK(intersect_all_orders(P, {Vector3d(1, 1, -1), Vector3d(1, 1, 1), Vector3d(3, 3, 0)}));
    CHECK_FALSE(intersect_all_orders(P, {Vector3d(1, ulps(1, 1), -1), Vector3d(1, ulps(1, 1), 1), Vector3d(3, 3, 0)}));
  }

  TEST_CASE("triangles: coplanar pairs") {
    const Tri P{Vector3d(0, 0, 0), Vector3d(2, 0, 0), Vector3d(0, 2, 0)};
    CHECK(intersect_all_orders(P, {Vector3d(1, 1, 0), Vector3d(-1, 1, 0), Vector3d(1, -1, 0)}));  // overlapping
    CHECK(intersect_all_orders(P, {Vector3d(0.2, 0.2, 0), Vector3d(0.5, 0.2, 0), Vector3d(0.2, 0.5, 0)}));  // inside
    CHECK_FALSE(intersect_all_orders(P, {Vector3d(3, 3, 0), Vector3d(4, 3, 0), Vector3d(3, 4, 0)}));        // disjoint
    CHECK(intersect_all_orders(P, {Vector3d(2, 0, 0), Vector3d(0, 2, 0), Vector3d(2, 2, 0)}));   // common edge
    CHECK(intersect_all_orders(P, {Vector3d(2, 0, 0), Vector3d(3, 0, 0), Vector3d(3, -1, 0)}));  // common vertex
    CHECK(intersect_all_orders(P, {Vector3d(1, 0, 0), Vector3d(3, 0, 0), Vector3d(2, -1, 0)}));  // overlapping edges
    // Just apart across the hypotenuse, in a tilted plane (z = x + 2y, exact on these points).
    auto tilt = [](double x, double y) { return Vector3d(x, y, x + 2 * y); };
    const Tri Pt{tilt(0, 0), tilt(2, 0), tilt(0, 2)};
    CHECK(intersect_all_orders(Pt, {tilt(1, 1), tilt(2, 2), tilt(3, 1)}));
    const Tri apart{tilt(1, ulps(1, 1)), tilt(2, 2), tilt(3, ulps(1, 2))};
    for (const Vector3d& q : apart) REQUIRE(orient3d(Pt[0], Pt[1], Pt[2], q) == 0);  // exactly coplanar
    CHECK_FALSE(intersect_all_orders(Pt, apart));
  }

  TEST_CASE("triangles: degenerate triangles act as segments and points") {
    const Tri P{Vector3d(0, 0, 0), Vector3d(2, 0, 0), Vector3d(0, 2, 0)};
    const Tri seg_through{Vector3d(0.5, 0.5, -1), Vector3d(0.5, 0.5, 1), Vector3d(0.5, 0.5, 0.25)};
    const Tri seg_beside{Vector3d(1.5, 1.5, -1), Vector3d(1.5, 1.5, 1), Vector3d(1.5, 1.5, 0)};
    const Tri point_in{Vector3d(0.5, 0.5, 0), Vector3d(0.5, 0.5, 0), Vector3d(0.5, 0.5, 0)};
    const Tri point_off{Vector3d(0.5, 0.5, 1e-300), Vector3d(0.5, 0.5, 1e-300), Vector3d(0.5, 0.5, 1e-300)};
    const Tri seg_in_plane{Vector3d(-1, 1, 0), Vector3d(3, 1, 0), Vector3d(1, 1, 0)};
    const Tri seg_in_plane_out{Vector3d(-1, 3, 0), Vector3d(3, 3, 0), Vector3d(1, 3, 0)};
    CHECK(intersect_all_orders(P, seg_through));
    CHECK_FALSE(intersect_all_orders(P, seg_beside));
    CHECK(intersect_all_orders(P, point_in));
    CHECK_FALSE(intersect_all_orders(P, point_off));
    CHECK(intersect_all_orders(P, seg_in_plane));
    CHECK_FALSE(intersect_all_orders(P, seg_in_plane_out));
    // Degenerate against degenerate: collinear overlapping, collinear apart, crossing, skew.
    const Tri s1{Vector3d(0, 0, 0), Vector3d(1, 1, 1), Vector3d(2, 2, 2)};
    CHECK(intersect_all_orders(s1, {Vector3d(2, 2, 2), Vector3d(3, 3, 3), Vector3d(4, 4, 4)}));
    CHECK_FALSE(intersect_all_orders(s1, {Vector3d(3, 3, 3), Vector3d(4, 4, 4), Vector3d(5, 5, 5)}));
    CHECK(intersect_all_orders(s1, {Vector3d(0, 2, 0), Vector3d(2, 0, 2), Vector3d(1, 1, 1)}));
    CHECK_FALSE(intersect_all_orders(s1, {Vector3d(0, 2, 0), Vector3d(2, 0, ulps(2, 1)), Vector3d(0, 2, 0)}));
    CHECK(intersect_all_orders(s1, point_in) == false);
    CHECK(intersect_all_orders(s1, {Vector3d(1, 1, 1), Vector3d(1, 1, 1), Vector3d(1, 1, 1)}));
    CHECK(intersect_all_orders(point_in, point_in));
    CHECK_FALSE(intersect_all_orders(point_in, point_off));
  }

  TEST_CASE("adjacent triangles: a shared vertex alone is not an intersection") {
    const Vector3d v(0, 0, 0), a(1, 0, 0), b(0, 1, 0);
    // Flat fan, the other triangle in the opposite quadrant: touches only at v.
    CHECK_FALSE(sharing_vertex_all_orders(v, a, b, Vector3d(-1, 0, 0), Vector3d(0, -1, 0)));
    // Same, at an angle.
    CHECK_FALSE(sharing_vertex_all_orders(v, a, b, Vector3d(-1, 0, 1), Vector3d(0, -1, 1)));
    // An edge of the other passes through the interior of (v, a, b).
    CHECK(sharing_vertex_all_orders(v, a, b, Vector3d(0.3, 0.3, -1), Vector3d(0.3, 0.3, 1)));
    // ... through the edge [v, a], then one ulp beside it: the other triangle meets the
    // plane z = 0 in a segment from v, along the edge or just outside (v, a, b).
    CHECK(sharing_vertex_all_orders(v, a, b, Vector3d(0.5, 0, -1), Vector3d(0.5, 0, 1)));
    CHECK_FALSE(sharing_vertex_all_orders(v, a, b, Vector3d(0.5, ulps(0, -1), -1), Vector3d(0.5, ulps(0, -1), 1)));
    // An edge of (v, a, b) passes through the other's interior: the far edge [a, b] crosses it.
    CHECK(sharing_vertex_all_orders(v, a, b, Vector3d(1, 1, -1), Vector3d(1, 1, 1)));
    // Coplanar and overlapping around v; coplanar along a common ray (touching along a segment).
    CHECK(sharing_vertex_all_orders(v, a, b, Vector3d(1, 1, 0), Vector3d(-1, 2, 0)));
    CHECK(sharing_vertex_all_orders(v, a, b, Vector3d(2, 0, 0), Vector3d(1, -1, 0)));
    // Touching along a common ray out of plane: (v, c, d) contains the ray towards a.
    CHECK(sharing_vertex_all_orders(v, a, b, Vector3d(3, 0, 0), Vector3d(1, -1, 1)));
    // The other triangle's far vertex touches (v, a, b)'s far edge.
    CHECK(sharing_vertex_all_orders(v, a, b, Vector3d(0.5, 0.5, 0), Vector3d(0, -1, 1)));
    // Degenerate: (v, a, b) collinear through v, the other containing a part of it.
    CHECK(sharing_vertex_all_orders(v, Vector3d(-1, 0, 0), Vector3d(1, 0, 0), Vector3d(1, 1, 0), Vector3d(1, -1, 0)));
    CHECK_FALSE(
        sharing_vertex_all_orders(v, Vector3d(-1, 0, 0), Vector3d(1, 0, 0), Vector3d(1, 1, 1), Vector3d(1, -1, 1)));
    CHECK_FALSE(sharing_vertex_all_orders(v, v, v, Vector3d(1, 1, 0), Vector3d(1, -1, 0)));
  }

  TEST_CASE("adjacent triangles: a shared edge is reported only when folded flat onto itself") {
    const Vector3d u(0, 0, 0), w(1, 0, 0), a(0.3, 1, 0);
    CHECK_FALSE(sharing_edge_all_orders(u, w, a, Vector3d(0.6, -1, 0)));      // flat sheet
    CHECK_FALSE(sharing_edge_all_orders(u, w, a, Vector3d(0.6, -1, 0.5)));    // hinge
    CHECK_FALSE(sharing_edge_all_orders(u, w, a, Vector3d(0.6, 1, 1e-300)));  // folded, a tiny gap
    CHECK(sharing_edge_all_orders(u, w, a, Vector3d(0.6, 1, 0)));             // folded flat
    CHECK(sharing_edge_all_orders(u, w, a, Vector3d(5, 0.001, 0)));           // folded flat, thin
    // Degenerate: collinear triangles along the edge's line.
    CHECK_FALSE(sharing_edge_all_orders(u, w, Vector3d(2, 0, 0), Vector3d(0.6, 1, 0)));
    CHECK(sharing_edge_all_orders(u, w, Vector3d(2, 0, 0), Vector3d(3, 0, 0)));
    CHECK_FALSE(sharing_edge_all_orders(u, w, Vector3d(2, 0, 0), Vector3d(-3, 0, 0)));
    CHECK_FALSE(sharing_edge_all_orders(u, w, Vector3d(0.5, 0, 0), Vector3d(2, 0, 0)));
    // The shared edge itself degenerate (u == w as points): tested as sharing a vertex.
    CHECK(triangles_intersect_sharing_edge(u, u, a, Vector3d(0.6, 2, 0)));
    CHECK_FALSE(triangles_intersect_sharing_edge(u, u, a, Vector3d(-0.6, -2, 0)));
  }

  TEST_CASE("triangles: agree with the rational edge-intersection reference on random and near-touching pairs") {
    random_pairs_against_reference(2024, 800);
  }

  TEST_CASE("adjacent triangles: agree with the rational reference on random and near-touching pairs") {
    random_adjacent_pairs_against_reference(77, 400);
  }

  // ---- Mesh checks -------------------------------------------------------------------------

  TEST_CASE("mesh check: flat sheets have no intersections") {
    for (auto tess : {Tessellation::regular, Tessellation::irregular}) {
      MeshData m = make_rectangle(Eigen::Vector2d(1.0, 0.7), {31, 23}, tess, 3);
      // Also tilted: no coordinate plane, so the coplanar decisions need the exact stage.
      for (bool tilted : {false, true}) {
        CAPTURE(tilted);
        std::vector<Vector3d> x = points_of(m);
        if (tilted)
          for (auto& p : x) p = Eigen::AngleAxisd(0.7, Vector3d(1, 2, 3).normalized()) * p;
        // A valid planar embedding (the irregular generator can invert a triangle at some
        // sizes and seeds; this one has none), so nothing overlaps.
        for (int f = 0; f < m.F.rows(); ++f)
          REQUIRE(orient2d(2, m.V.row(m.F(f, 0)), m.V.row(m.F(f, 1)), m.V.row(m.F(f, 2))) > 0);
        const IntersectionReport r = check_self_intersections(x, m.F);
        CHECK(r.num_pairs == 0);
        CHECK(r.intersection_free());
        CHECK(r.candidates >= m.F.rows());  // every face has neighbours whose boxes overlap
        CHECK(all_pairs(x, m.F, BroadPhase::brute_force).empty());
      }
    }
  }

  TEST_CASE("mesh check: matches the rational reference on every pair of small crumpled meshes") {
    Rng rng(31);
    int total_hits = 0;
    for (int trial = 0; trial < 3; ++trial) {
      MeshData m = make_rectangle(Eigen::Vector2d(1, 1), {5, 4}, Tessellation::regular, 0);
      std::vector<Vector3d> x = points_of(m);
      for (auto& p : x) p += Vector3d(rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), rng.uniform(-0.3, 0.3));
      if (trial == 2)  // one vertex pushed across its neighbour, the rest flat
        for (std::size_t i = 0; i < x.size(); ++i)
          x[i] = points_of(m)[i] + (i == 7 ? Vector3d(0.31, 0.07, 0.0) : Vector3d::Zero());
      const auto pairs = all_pairs(x, m.F, BroadPhase::hash_grid);
      const std::set<std::array<int, 2>> hit(pairs.begin(), pairs.end());
      for (int f = 0; f < m.F.rows(); ++f)
        for (int g = f + 1; g < m.F.rows(); ++g) {
          const Tri P{x[m.F(f, 0)], x[m.F(f, 1)], x[m.F(f, 2)]}, Q_{x[m.F(g, 0)], x[m.F(g, 1)], x[m.F(g, 2)]};
          std::vector<Vector3d> shared;
          for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b)
              if (m.F(f, a) == m.F(g, b)) shared.push_back(x[m.F(f, a)]);
          const bool expected = shared.empty() ? oracle_intersect(P, Q_) : oracle_beyond(P, Q_, shared);
          CAPTURE(trial);
          CAPTURE(f);
          CAPTURE(g);
          REQUIRE(hit.contains({f, g}) == expected);
        }
      total_hits += static_cast<int>(pairs.size());
    }
    MESSAGE(fmt::format("small crumpled meshes: {} intersecting pairs in all", total_hits));
    CHECK(total_hits > 5);
  }

  TEST_CASE("mesh check: an inverted triangle in a flat sheet overlaps its neighbours") {
    MeshData m = make_rectangle(Eigen::Vector2d(1, 1), {11, 11}, Tessellation::regular, 0);
    std::vector<Vector3d> x = points_of(m);
    CHECK(check_self_intersections(x, m.F).num_pairs == 0);
    x[60] += Vector3d(0.13, 0.0, 0.0);  // the centre vertex, moved past its right neighbour
    const IntersectionReport r = check_self_intersections(x, m.F, {.max_pairs = 1000, .broad_phase = {}});
    CHECK(r.num_pairs > 0);
    for (const auto& p : r.pairs) {  // only faces around the moved vertex changed
      bool touches = false;
      for (int k = 0; k < 3; ++k) touches = touches || m.F(p[0], k) == 60 || m.F(p[1], k) == 60;
      CHECK(touches);
    }
  }

  TEST_CASE("broad phase: the hash grid lists the same box pairs as brute force") {
    Rng rng(8);
    for (int trial = 0; trial < 6; ++trial) {
      std::vector<Box> boxes;
      for (int i = 0; i < 400; ++i) {
        // Integer corners: many boxes touching face to face, edge to edge or corner to corner.
        const Vector3d lo = rng.ivec3(0, 12), hi = lo + rng.ivec3(0, 2);
        boxes.push_back({lo, hi});
      }
      if (trial % 2) boxes.push_back({Vector3d(-50, -50, 5), Vector3d(50, 50, 5.5)});  // huge: outside the grid
      if (trial % 3 == 2) boxes.push_back({Vector3d(1e6, 1e6, 1e6), Vector3d(1e6, 1e6, 1e6)});  // far outlier
      BroadPhaseParams grid, brute;
      brute.method = BroadPhase::brute_force;
      grid.cell_size = trial < 3 ? 0.0 : 0.7;
      grid.threads = 1 + trial % 2;
      const auto a = overlapping_pairs(boxes, grid), b = overlapping_pairs(boxes, brute);
      CAPTURE(trial);
      REQUIRE(b.size() > boxes.size());
      CHECK(a == b);
    }
  }

  TEST_CASE("mesh check: a strip folded through itself reports exactly the crossing pairs") {
    // Bottom layer z = 0; the top layer rises over the crease column to 0.3, then descends
    // along z = beta (x - x0) and passes through the bottom layer on the line x = x0.
    const int nu = 41, nv = 9;
    const double L = 1.0, W = 0.4, x0 = 0.4137;
    const double beta = 0.3 / (L - 0.05 - x0);
    auto top = [&](double x) { return beta * (x - x0); };
    const MeshData m = folded_strip(nu, nv, L, W, 0.3, top, 0.0123);
    const std::vector<Vector3d> x = points_of(m);
    const IntersectionReport r = check_self_intersections(x, m.F, {.max_pairs = 1 << 20, .broad_phase = {}});

    // Expected, independently: faces are planar pieces z = 0 (bottom) or z = beta (x - x0)
    // (top, past the crease column), which meet only on the line x = x0, z = 0; a bottom
    // and a top face intersect iff their y-intervals on that line overlap.
    auto y_interval = [&](int f) -> std::optional<std::array<double, 2>> {
      std::vector<double> ys;
      for (int e = 0; e < 3; ++e) {
        const Vector3d& p = x[m.F(f, e)];
        const Vector3d& q = x[m.F(f, (e + 1) % 3)];
        if ((p[0] - x0) * (q[0] - x0) > 0 || p[0] == q[0]) continue;
        const double s = (x0 - p[0]) / (q[0] - p[0]);
        ys.push_back(p[1] + s * (q[1] - p[1]));
      }
      if (ys.empty()) return std::nullopt;
      return std::array<double, 2>{*std::min_element(ys.begin(), ys.end()), *std::max_element(ys.begin(), ys.end())};
    };
    std::vector<int> bottom, upper;
    for (int f = 0; f < m.F.rows(); ++f) {
      bool all_flat = true, all_top = true;
      for (int e = 0; e < 3; ++e) {
        const Vector3d& p = x[m.F(f, e)];
        all_flat = all_flat && p[2] == 0;
        all_top = all_top && p[0] < L - 0.06;  // past the crease column, on the plane z = beta (x - x0)
      }
      if (all_flat)
        bottom.push_back(f);
      else if (all_top && x[m.F(f, 0)][2] != 0.3)
        upper.push_back(f);
    }
    std::vector<std::array<int, 2>> expected;
    double margin = INFINITY;
    for (int f : bottom)
      for (int g : upper) {
        const auto I = y_interval(f), J = y_interval(g);
        if (!I || !J) continue;
        const double gap = std::max((*I)[0] - (*J)[1], (*J)[0] - (*I)[1]);
        margin = std::min(margin, std::abs(gap));
        if (gap <= 0) expected.push_back({std::min(f, g), std::max(f, g)});
      }
    std::sort(expected.begin(), expected.end());
    MESSAGE(fmt::format("folded strip: {} faces, {} crossing pairs, {} candidates, margin {:.2e}", m.F.rows(),
                        expected.size(), r.candidates, margin));
    REQUIRE(margin > 1e-6);  // no near-ties: the floating-point expectation is reliable
    REQUIRE(expected.size() >= nv);
    CHECK(r.num_pairs == static_cast<std::int64_t>(expected.size()));
    CHECK(r.pairs == expected);
    CHECK(all_pairs(x, m.F, BroadPhase::brute_force) == expected);
    // The default report lists the first pairs only.
    const IntersectionReport short_report = check_self_intersections(x, m.F);
    CHECK(short_report.num_pairs == r.num_pairs);
    REQUIRE(short_report.pairs.size() == 16);
    CHECK(std::equal(short_report.pairs.begin(), short_report.pairs.end(), expected.begin()));
  }

  TEST_CASE("mesh check: a strip folded onto itself at a small gap has no intersections") {
    // Rotated to a generic orientation, so that the layers' boxes overlap and every close
    // pair reaches the exact test; rounding moves points by ~1e-16, far below the gaps.
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.9, Vector3d(1, -2, 3).normalized()).toRotationMatrix();
    for (double gap : {1e-3, 1e-9}) {
      CAPTURE(gap);
      const MeshData m = folded_strip(41, 9, 1.0, 0.4, gap, [&](double) { return gap; });
      std::vector<Vector3d> x = points_of(m);
      for (auto& p : x) p = R * p;
      const IntersectionReport r = check_self_intersections(x, m.F);
      CHECK(r.num_pairs == 0);
      CHECK(r.candidates > 3 * m.F.rows());  // the layers' boxes overlap: the test is not vacuous
    }
    // A gap of 1e-300, unrotated (exact coordinates): only exact arithmetic separates the layers.
    const MeshData m = folded_strip(41, 9, 1.0, 0.4, 1e-300, [&](double) { return 1e-300; });
    CHECK(check_self_intersections(points_of(m), m.F).num_pairs == 0);
    // Closed onto itself (gap 0): the layers overlap everywhere.
    const MeshData flat = folded_strip(41, 9, 1.0, 0.4, 0.0, [](double) { return 0.0; });
    CHECK(check_self_intersections(points_of(flat), flat.F).num_pairs > flat.F.rows() / 2);
  }

  TEST_CASE("mesh check: hash grid and brute force agree on a crumpled mesh on 1 and 2 threads") {
    Rng rng(9);
    MeshData m = make_rectangle(Eigen::Vector2d(1, 1), {13, 13}, Tessellation::irregular, 4);
    for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
      m.V(i, 2) = 0.15 * std::sin(9 * m.V(i, 0)) * std::cos(7 * m.V(i, 1)) + rng.uniform(-0.05, 0.05);
      m.V(i, 0) += rng.uniform(-0.06, 0.06);
    }
    const std::vector<Vector3d> x = points_of(m);
    const auto grid1 = all_pairs(x, m.F, BroadPhase::hash_grid, 1);
    const auto grid2 = all_pairs(x, m.F, BroadPhase::hash_grid, 2);
    const auto brute = all_pairs(x, m.F, BroadPhase::brute_force, 2);
    MESSAGE(fmt::format("crumpled mesh: {} faces, {} intersecting pairs", m.F.rows(), brute.size()));
    REQUIRE(brute.size() >= 10);
    CHECK(grid1 == brute);
    CHECK(grid2 == brute);
    // Every pair once, ordered, and the report is the same on any thread count.
    CHECK(std::adjacent_find(brute.begin(), brute.end()) == brute.end());
    IntersectionCheckParams p1, p2, pc;
    p1.broad_phase.threads = 1;
    p2.broad_phase.threads = 2;
    pc.broad_phase.cell_size = 0.01;  // a fine grid: boxes over many cells
    const auto r1 = check_self_intersections(x, m.F, p1), r2 = check_self_intersections(x, m.F, p2);
    CHECK(r1.num_pairs == r2.num_pairs);
    CHECK(r1.pairs == r2.pairs);
    CHECK(r1.candidates == r2.candidates);
    CHECK(all_pairs(x, m.F, BroadPhase::hash_grid) == brute);
    const auto rc = check_self_intersections(x, m.F, pc);
    CHECK(rc.num_pairs == r1.num_pairs);
    CHECK(rc.candidates == r1.candidates);
    // Each reported pair agrees with the pair test; a pair not reported does not intersect.
    const std::set<std::array<int, 2>> hit(brute.begin(), brute.end());
    for (int f = 0; f < m.F.rows(); ++f)
      for (int g = f + 1; g < m.F.rows(); g += 7) {
        const std::array<int, 3> a{m.F(f, 0), m.F(f, 1), m.F(f, 2)}, b{m.F(g, 0), m.F(g, 1), m.F(g, 2)};
        REQUIRE(faces_intersect(x, a, b) == hit.contains({f, g}));
      }
  }

  TEST_CASE("mesh check: huge triangles outside the grid are still tested") {
    MeshData m = make_rectangle(Eigen::Vector2d(1, 1), {21, 21}, Tessellation::regular, 0);
    const std::vector<Vector3d> cloth = points_of(m);
    // A vertical wall of two triangles at x = 0.0123 through the sheet, far larger than a cell.
    const std::vector<Vector3d> wall{Vector3d(0.0123, -5, -5), Vector3d(0.0123, 5, -5), Vector3d(0.0123, 5, 5),
                                     Vector3d(0.0123, -5, 5)};
    Eigen::MatrixX3i wf(2, 3);
    wf << 0, 1, 2, 0, 2, 3;
    IntersectionCheckParams prm;
    prm.max_pairs = 1 << 20;
    const IntersectionReport r = check_intersections(cloth, m.F, wall, wf, prm);
    prm.broad_phase.method = BroadPhase::brute_force;
    const IntersectionReport b = check_intersections(cloth, m.F, wall, wf, prm);
    // The sheet's faces straddling x = 0.0123 meet the wall (in one or both of its halves).
    int straddling = 0;
    for (int f = 0; f < m.F.rows(); ++f) {
      double lo = INFINITY, hi = -INFINITY;
      for (int e = 0; e < 3; ++e) lo = std::min(lo, cloth[m.F(f, e)][0]), hi = std::max(hi, cloth[m.F(f, e)][0]);
      straddling += lo < 0.0123 && hi > 0.0123;
    }
    REQUIRE(straddling > 0);
    std::set<int> faces_hit;
    for (const auto& p : r.pairs) faces_hit.insert(p[0]);
    CHECK(static_cast<int>(faces_hit.size()) == straddling);
    CHECK(r.pairs == b.pairs);
    CHECK(r.num_pairs >= straddling);
    // Moved off the sheet's extent: nothing.
    std::vector<Vector3d> far = wall;
    for (auto& p : far) p[0] = 0.6;
    CHECK(check_intersections(cloth, m.F, far, wf).num_pairs == 0);
  }

  TEST_CASE("mesh check: a duplicated face is reported and invalid faces are refused") {
    const std::vector<Vector3d> x{Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(0, 1, 0), Vector3d(1, 1, 0)};
    Eigen::MatrixX3i F(3, 3);
    F << 0, 1, 2, 1, 3, 2, 2, 0, 1;  // the third face repeats the first, rotated
    const IntersectionReport r = check_self_intersections(x, F);
    REQUIRE(r.num_pairs == 1);
    CHECK(r.pairs[0] == std::array<int, 2>{0, 2});
    Eigen::MatrixX3i bad(1, 3);
    bad << 0, 1, 7;
    CHECK_THROWS_AS(check_self_intersections(x, bad), InvariantError);
    bad << 0, 1, 1;
    CHECK_THROWS_AS(check_self_intersections(x, bad), InvariantError);
  }

  TEST_CASE("mesh check: the stacked position vector gives the same report") {
    const MeshData m = folded_strip(21, 5, 1.0, 0.4, 0.3, [](double x) { return 0.5 * (x - 0.4137); });
    const std::vector<Vector3d> x = points_of(m);
    Eigen::VectorXd stacked(3 * x.size());
    for (std::size_t i = 0; i < x.size(); ++i) stacked.segment<3>(3 * i) = x[i];
    const auto a = check_self_intersections(x, m.F), b = check_self_intersections(stacked, m.F);
    CHECK(a.num_pairs > 0);
    CHECK(a.num_pairs == b.num_pairs);
    CHECK(a.pairs == b.pairs);
  }
}

TEST_SUITE("contact") {
  TEST_CASE("mesh check: no false intersection on flat wavy rotated and folded sheets - one and two threads agree") {
    // Regular sheets (no inverted triangles): flat in z = 0, wavy, flat but rotated (every
    // orientation of neighbouring points nearly zero: the exact stages decide), and folded
    // onto itself at a 1e-4 gap and gently bent (two layers of close, overlapping boxes;
    // the bend moves the layers' interpolations apart by < 1e-6, far below the gap).
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.9, Vector3d(1, -2, 3).normalized()).toRotationMatrix();
    for (int n : {61, 101}) {
      for (int shape = 0; shape < 4; ++shape) {
        MeshData m = make_rectangle(Eigen::Vector2d(1, 1), {n, n}, Tessellation::regular, 0);
        const char* name = shape == 0 ? "flat" : shape == 1 ? "wavy" : shape == 2 ? "flat rotated" : "folded and bent";
        if (shape == 1)
          for (Eigen::Index i = 0; i < m.V.rows(); ++i)
            m.V(i, 2) = 0.05 * std::sin(10 * m.V(i, 0)) * std::cos(13 * m.V(i, 1));
        if (shape == 3) m = folded_strip(2 * n - 1, n / 2 + 1, 1.0, 1.0, 1e-4, [](double) { return 1e-4; });
        std::vector<Vector3d> x = points_of(m);
        if (shape == 2)
          for (auto& p : x) p = R * p;
        if (shape == 3)
          for (auto& p : x) p[2] += 0.02 * std::sin(3 * p[0]) * std::cos(2 * p[1]);
        IntersectionReport r[2];
        for (int threads : {1, 2}) {
          IntersectionCheckParams prm;
          prm.broad_phase.threads = threads;
          r[threads - 1] = check_self_intersections(x, m.F, prm);
        }
        CAPTURE(name);
        CAPTURE(n);
        CHECK(r[0].num_pairs == 0);
        CHECK(r[1].num_pairs == 0);
        CHECK(r[0].candidates == r[1].candidates);
        CHECK(r[0].candidates > 0);  // the close layers and neighbours do reach the exact stages
      }
    }
  }
}

TEST_SUITE("slow") {
  TEST_CASE("triangles: agree with the rational reference on 20000 random and near-touching pairs") {
    random_pairs_against_reference(4048, 20000);
  }

  TEST_CASE("adjacent triangles: agree with the rational reference on 10000 random pairs") {
    random_adjacent_pairs_against_reference(154, 10000);
  }

}
