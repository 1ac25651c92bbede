#include "contact/verify/triangle_intersection.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>

#include "contact/verify/predicates.hpp"

namespace weft::contact::verify {

namespace {

using Eigen::Vector3d;

// ---- 2D tests on the projection that drops coordinate k ------------------------------

/// Whether x lies in the axis-aligned box of the projected segment [r, s]. For a point
/// already known collinear with r and s (in the projection) this is "x on [r, s]".
bool in_box_2d(int k, const Vector3d& r, const Vector3d& s, const Vector3d& x) {
  const int i = (k + 1) % 3, j = (k + 2) % 3;
  return std::min(r[i], s[i]) <= x[i] && x[i] <= std::max(r[i], s[i]) && std::min(r[j], s[j]) <= x[j] &&
         x[j] <= std::max(r[j], s[j]);
}

/// Closed projected segments [p, q] and [r, s] meet (any of them may be a point).
bool segments_2d(int k, const Vector3d& p, const Vector3d& q, const Vector3d& r, const Vector3d& s) {
  const int d1 = orient2d(k, r, s, p), d2 = orient2d(k, r, s, q);
  if (d1 * d2 > 0) return false;
  const int d3 = orient2d(k, p, q, r), d4 = orient2d(k, p, q, s);
  if (d3 * d4 > 0) return false;
  if (d1 * d2 < 0 && d3 * d4 < 0) return true;  // proper crossing
  // A zero means an endpoint on the other segment's line: it decides (two overlapping
  // collinear segments always have an endpoint of one inside the other).
  return (d1 == 0 && in_box_2d(k, r, s, p)) || (d2 == 0 && in_box_2d(k, r, s, q)) ||
         (d3 == 0 && in_box_2d(k, p, q, r)) || (d4 == 0 && in_box_2d(k, p, q, s));
}

/// x in the closed projected triangle (a, b, c) of orientation o = orient2d(k, a, b, c) != 0.
bool point_in_triangle_2d(int k, const Vector3d& x, const Vector3d& a, const Vector3d& b, const Vector3d& c, int o) {
  return orient2d(k, a, b, x) != -o && orient2d(k, b, c, x) != -o && orient2d(k, c, a, x) != -o;
}

/// Closed projected segment [p, q] meets the proper projected triangle (a, b, c).
bool segment_triangle_2d(int k, const Vector3d& p, const Vector3d& q, const Vector3d& a, const Vector3d& b,
                         const Vector3d& c, int o) {
  return point_in_triangle_2d(k, p, a, b, c, o) || point_in_triangle_2d(k, q, a, b, c, o) ||
         segments_2d(k, p, q, a, b) || segments_2d(k, p, q, b, c) || segments_2d(k, p, q, c, a);
}

// ---- Classification -------------------------------------------------------------------

/// A triangle seen as the simplex it spans: a proper triangle (with an axis k whose
/// projection is one-to-one on its plane, and its orientation there), a segment [s0, s1]
/// or a point s0 = s1.
struct Simplex {
  enum Kind { point, segment, triangle } kind;
  int axis = -1;  // triangle: orient2d(axis, v) == orientation != 0
  int orientation = 0;
  const Vector3d* s0 = nullptr;  // segment / point
  const Vector3d* s1 = nullptr;
};

bool lex_less(const Vector3d& a, const Vector3d& b) {
  return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
}

Simplex classify(const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  // Try the axes in the order of the floating-point normal's components, largest first:
  // the first nonzero exact orient2d is normally the first one tried.
  const Vector3d n = (b - a).cross(c - a).cwiseAbs();
  const int k0 = n[0] >= n[1] ? (n[0] >= n[2] ? 0 : 2) : (n[1] >= n[2] ? 1 : 2);
  for (int k : {k0, (k0 + 1) % 3, (k0 + 2) % 3})
    if (const int o = orient2d(k, a, b, c); o != 0) return {Simplex::triangle, k, o};
  // Collinear: on a line, the lexicographic order is monotone along the line, so the
  // lexicographic extremes are the ends of the segment.
  const Vector3d* lo = &a;
  const Vector3d* hi = &a;
  for (const Vector3d* x : {&b, &c}) {
    if (lex_less(*x, *lo)) lo = x;
    if (lex_less(*hi, *x)) hi = x;
  }
  return {*lo == *hi ? Simplex::point : Simplex::segment, -1, 0, lo, hi};
}

/// Whether the line through p and q, which crosses the plane of the proper triangle
/// (a, b, c) in a single point, crosses it inside the closed triangle.
bool line_through_triangle(const Vector3d& p, const Vector3d& q, const Vector3d& a, const Vector3d& b,
                           const Vector3d& c) {
  const int o1 = orient3d(p, q, a, b), o2 = orient3d(p, q, b, c);
  if (o1 * o2 < 0) return false;
  const int o3 = orient3d(p, q, c, a);
  return o3 * o1 >= 0 && o3 * o2 >= 0;
}

/// [p, q] against a proper triangle (a, b, c) classified as t.
bool segment_proper_triangle(const Vector3d& p, const Vector3d& q, const Vector3d& a, const Vector3d& b,
                             const Vector3d& c, const Simplex& t) {
  const int sp = orient3d(a, b, c, p), sq = orient3d(a, b, c, q);
  if (sp * sq > 0) return false;
  if (sp == 0 && sq == 0) return segment_triangle_2d(t.axis, p, q, a, b, c, t.orientation);
  return line_through_triangle(p, q, a, b, c);
}

/// Two proper triangles in one plane, projected by k (one-to-one on the plane), with
/// orientations o and oq there.
bool coplanar_triangles(int k, int o, int oq, const Vector3d& p0, const Vector3d& p1, const Vector3d& p2,
                        const Vector3d& q0, const Vector3d& q1, const Vector3d& q2) {
  const std::array<const Vector3d*, 3> p{&p0, &p1, &p2}, q{&q0, &q1, &q2};
  // Fast rejection: all of one triangle strictly outside an edge line of the other.
  for (int i = 0; i < 3; ++i) {
    const Vector3d &a = *p[i], &b = *p[(i + 1) % 3];
    if (orient2d(k, a, b, q0) == -o && orient2d(k, a, b, q1) == -o && orient2d(k, a, b, q2) == -o) return false;
    const Vector3d &c = *q[i], &d = *q[(i + 1) % 3];
    if (orient2d(k, c, d, p0) == -oq && orient2d(k, c, d, p1) == -oq && orient2d(k, c, d, p2) == -oq) return false;
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (segments_2d(k, *p[i], *p[(i + 1) % 3], *q[j], *q[(j + 1) % 3])) return true;
  return point_in_triangle_2d(k, p0, q0, q1, q2, oq) || point_in_triangle_2d(k, q0, p0, p1, p2, o);
}

/// Two triangles that are coplanar or of which one is degenerate; q_in_p_plane: every
/// orient3d(p0, p1, p2, q_i) is zero.
bool coplanar_or_degenerate(const Vector3d& p0, const Vector3d& p1, const Vector3d& p2, const Vector3d& q0,
                            const Vector3d& q1, const Vector3d& q2, bool q_in_p_plane) {
  const Simplex P = classify(p0, p1, p2);
  if (P.kind == Simplex::triangle && q_in_p_plane) {
    // Q lies in P's plane, where projection P.axis is one-to-one: Q is proper iff its
    // projection is.
    const int oq = orient2d(P.axis, q0, q1, q2);
    if (oq != 0) return coplanar_triangles(P.axis, P.orientation, oq, p0, p1, p2, q0, q1, q2);
  }
  const Simplex Q = classify(q0, q1, q2);
  if (P.kind == Simplex::triangle && Q.kind == Simplex::triangle)  // (then coplanar)
    return coplanar_triangles(P.axis, P.orientation, orient2d(P.axis, q0, q1, q2), p0, p1, p2, q0, q1, q2);
  if (P.kind == Simplex::triangle) return segment_proper_triangle(*Q.s0, *Q.s1, p0, p1, p2, P);
  if (Q.kind == Simplex::triangle) return segment_proper_triangle(*P.s0, *P.s1, q0, q1, q2, Q);
  return segments_intersect(*P.s0, *P.s1, *Q.s0, *Q.s1);
}

bool strictly_one_side(int a, int b, int c) { return (a > 0 && b > 0 && c > 0) || (a < 0 && b < 0 && c < 0); }

/// Whether the edge with end signs (si, sj) against the other triangle's plane crosses
/// that plane at a single point.
bool crosses_plane(int si, int sj) { return si * sj <= 0 && (si != 0 || sj != 0); }

/// x on the closed segment [a, b] (a point if a == b). Exact.
bool point_on_segment(const Vector3d& x, const Vector3d& a, const Vector3d& b) {
  for (int k = 0; k < 3; ++k)
    if (x[k] < std::min(a[k], b[k]) || x[k] > std::max(a[k], b[k])) return false;
  for (int k = 0; k < 3; ++k)
    if (orient2d(k, a, b, x) != 0) return false;
  return true;
}

bool collinear(const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  for (int k = 0; k < 3; ++k)
    if (orient2d(k, a, b, c) != 0) return false;
  return true;
}

/// A far part of a triangle around a shared vertex v: the segment [f0, f1] (f0 == f1 for
/// a point), not containing v.
struct FarPart {
  const Vector3d* f0;
  const Vector3d* f1;
};

/// The far parts of (v, a, b): [a, b] if v is not on it, else a and b where they differ
/// from v. \returns their number (0 if a == b == v).
int far_parts(const Vector3d& v, const Vector3d& a, const Vector3d& b, std::array<FarPart, 2>& out) {
  if (!point_on_segment(v, a, b)) {
    out[0] = {&a, &b};
    return 1;
  }
  int n = 0;
  if (a != v) out[n++] = {&a, &a};
  if (b != v) out[n++] = {&b, &b};
  return n;
}

/// Proper coplanar triangles (v, a, b) and (v, c, d), projected by k (one-to-one on their
/// plane, orientations o1 and o2 there): whether their tangent cones at v share a ray.
/// Two closed convex wedges meet in a wedge whose boundary rays are boundary rays of one
/// of them, so it suffices to find a boundary ray of one inside the other.
bool coplanar_cones_overlap(int k, int o1, int o2, const Vector3d& v, const Vector3d& a, const Vector3d& b,
                            const Vector3d& c, const Vector3d& d) {
  // Counter-clockwise in the projection (o1, o2: the orientations of (v, a, b) and
  // (v, c, d) there): the wedge sweeps from its first ray to its second.
  const Vector3d* a1 = &a;
  const Vector3d* b1 = &b;
  const Vector3d* c1 = &c;
  const Vector3d* d1 = &d;
  if (o1 < 0) std::swap(a1, b1);
  if (o2 < 0) std::swap(c1, d1);
  // Ray v -> r inside the wedge from ray v -> p to ray v -> q (angle below pi).
  auto in_wedge = [&](const Vector3d& r, const Vector3d& p, const Vector3d& q) {
    return orient2d(k, v, p, r) >= 0 && orient2d(k, v, r, q) >= 0;
  };
  return in_wedge(*a1, *c1, *d1) || in_wedge(*b1, *c1, *d1) || in_wedge(*c1, *a1, *b1) || in_wedge(*d1, *a1, *b1);
}

}  // namespace

bool segments_intersect(const Vector3d& p, const Vector3d& q, const Vector3d& r, const Vector3d& s) {
  if (orient3d(p, q, r, s) != 0) return false;
  // Coplanar: the segments lie in a common plane and some coordinate projection is
  // one-to-one on it; every projection of an intersection is an intersection, so the
  // segments meet iff all three projections do.
  for (int k = 0; k < 3; ++k)
    if (!segments_2d(k, p, q, r, s)) return false;
  return true;
}

bool segment_triangle_intersect(const Vector3d& p, const Vector3d& q, const Vector3d& a, const Vector3d& b,
                                const Vector3d& c) {
  const Simplex t = classify(a, b, c);
  if (t.kind == Simplex::triangle) return segment_proper_triangle(p, q, a, b, c, t);
  return segments_intersect(p, q, *t.s0, *t.s1);
}

bool triangles_intersect(const Vector3d& p0, const Vector3d& p1, const Vector3d& p2, const Vector3d& q0,
                         const Vector3d& q1, const Vector3d& q2) {
  // Q's vertices against P's plane (all zero if P is degenerate), and vice versa.
  const int s[3] = {orient3d(p0, p1, p2, q0), orient3d(p0, p1, p2, q1), orient3d(p0, p1, p2, q2)};
  if (strictly_one_side(s[0], s[1], s[2])) return false;
  const int t[3] = {orient3d(q0, q1, q2, p0), orient3d(q0, q1, q2, p1), orient3d(q0, q1, q2, p2)};
  return detail::triangles_intersect(p0, p1, p2, q0, q1, q2, s, t);
}

bool triangles_intersect_sharing_vertex(const Vector3d& v, const Vector3d& a, const Vector3d& b, const Vector3d& c,
                                        const Vector3d& d) {
  // If c and d lie strictly on one side of T1's plane, T2 meets that plane in v alone
  // (and the same the other way round).
  const int sc = orient3d(v, a, b, c), sd = orient3d(v, a, b, d);
  if (sc * sd > 0) return false;
  return detail::triangles_intersect_sharing_vertex(v, a, b, c, d, sc, sd, orient3d(v, c, d, a), orient3d(v, c, d, b));
}

bool triangles_intersect_sharing_edge(const Vector3d& u, const Vector3d& w, const Vector3d& a, const Vector3d& b) {
  return detail::triangles_intersect_sharing_edge(u, w, a, b, orient3d(u, w, a, b));
}

namespace detail {

bool triangles_intersect(const Vector3d& p0, const Vector3d& p1, const Vector3d& p2, const Vector3d& q0,
                         const Vector3d& q1, const Vector3d& q2, const int s[3], const int t[3]) {
  if (strictly_one_side(s[0], s[1], s[2]) || strictly_one_side(t[0], t[1], t[2])) return false;
  const bool q_in_p_plane = s[0] == 0 && s[1] == 0 && s[2] == 0;
  if (q_in_p_plane || (t[0] == 0 && t[1] == 0 && t[2] == 0))
    return coplanar_or_degenerate(p0, p1, p2, q0, q1, q2, q_in_p_plane);
  // Both proper, planes distinct: an edge crossing the other plane through the other triangle.
  if (crosses_plane(s[0], s[1]) && line_through_triangle(q0, q1, p0, p1, p2)) return true;
  if (crosses_plane(s[1], s[2]) && line_through_triangle(q1, q2, p0, p1, p2)) return true;
  if (crosses_plane(s[2], s[0]) && line_through_triangle(q2, q0, p0, p1, p2)) return true;
  if (crosses_plane(t[0], t[1]) && line_through_triangle(p0, p1, q0, q1, q2)) return true;
  if (crosses_plane(t[1], t[2]) && line_through_triangle(p1, p2, q0, q1, q2)) return true;
  if (crosses_plane(t[2], t[0]) && line_through_triangle(p2, p0, q0, q1, q2)) return true;
  return false;
}

bool triangles_intersect_sharing_vertex(const Vector3d& v, const Vector3d& a, const Vector3d& b, const Vector3d& c,
                                        const Vector3d& d, int sc, int sd, int sa, int sb) {
  if (sc * sd > 0 || sa * sb > 0) return false;
  // A nonzero sign makes the other triangle proper, so v is not on its far edge and the
  // far edges are the far parts: [a, b] against T2 and [c, d] against T1. Neither far
  // edge lies in the other plane (that would put the whole triangle there, making its
  // signs zero), so each crosses it in one point.
  const bool t1_proper = sc != 0 || sd != 0, t2_proper = sa != 0 || sb != 0;
  if (t1_proper && t2_proper) return line_through_triangle(a, b, v, c, d) || line_through_triangle(c, d, v, a, b);
  if (!t1_proper && !t2_proper) {
    // Every sign zero: coplanar, or a degenerate triangle. T1 proper: c and d lie in its
    // plane, where the projection P.axis is one-to-one, so T2 is proper iff its projection
    // is. Both proper: compare the tangent cones at v in 2D.
    const Simplex P = classify(v, a, b);
    if (P.kind == Simplex::triangle)
      if (const int o2 = orient2d(P.axis, v, c, d); o2 != 0)
        return coplanar_cones_overlap(P.axis, P.orientation, o2, v, a, b, c, d);
  }
  std::array<FarPart, 2> F, G;
  const int nf = far_parts(v, a, b, F), ng = far_parts(v, c, d, G);
  for (int i = 0; i < nf; ++i)
    for (int j = 0; j < ng; ++j) {
      if (segment_triangle_intersect(*F[i].f0, *F[i].f1, v, *G[j].f0, *G[j].f1)) return true;
      if (segment_triangle_intersect(*G[j].f0, *G[j].f1, v, *F[i].f0, *F[i].f1)) return true;
    }
  return false;
}

bool triangles_intersect_sharing_edge(const Vector3d& u, const Vector3d& w, const Vector3d& a, const Vector3d& b,
                                      int s) {
  // Not coplanar: a hinge at a nonzero angle, which meets only along [u, w] (then neither
  // triangle is degenerate, and u != w).
  if (s != 0) return false;
  if (u == w) return verify::triangles_intersect_sharing_vertex(u, u, a, u, b);
  const bool a_on = collinear(u, w, a), b_on = collinear(u, w, b);
  if (!a_on && !b_on) {
    // Coplanar: same side of the line uw in a projection one-to-one on the plane.
    for (int k = 0; k < 3; ++k)
      if (const int oa = orient2d(k, u, w, a); oa != 0) return orient2d(k, u, w, b) == oa;
  }
  if (a_on != b_on) return false;  // the proper one meets the line uw in [u, w] only
  // Both on the line uw: beyond the same end. The lexicographic order runs along the line.
  const bool up = lex_less(u, w);
  auto beyond_w = [&](const Vector3d& x) { return up ? lex_less(w, x) : lex_less(x, w); };
  auto beyond_u = [&](const Vector3d& x) { return up ? lex_less(x, u) : lex_less(u, x); };
  return (beyond_w(a) && beyond_w(b)) || (beyond_u(a) && beyond_u(b));
}

}  // namespace detail

}  // namespace weft::contact::verify
