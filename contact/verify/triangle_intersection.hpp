#pragma once
/// \file triangle_intersection.hpp
/// Exact intersection tests between closed triangles in 3D, built only on the signs of
/// the exact predicates of predicates.hpp: no epsilon, no tolerance, no constructed
/// points. Triangles may be degenerate: three collinear vertices are treated as the
/// segment they span, three equal vertices as a point.
///
/// Method, for proper (non-collinear) triangles P and Q:
///  - the signs of orient3d(P, q_i) and orient3d(Q, p_j) reject a triangle lying strictly
///    on one side of the other's plane;
///  - not coplanar: the triangles meet iff an edge of one crossing the other's plane
///    (end signs not both zero nor both strictly alike) passes through the other
///    triangle. The crossing point is inside (closed) iff the three orientations of the
///    edge's line against the triangle's edges, orient3d(q_i, q_j, p_k, p_l), are not of
///    strictly mixed signs. This suffices because an extreme point of the convex set
///    P n Q lies on an edge of P or of Q, and on an edge not contained in the other
///    plane (a vertex of P on the planes' common line has an edge off that line);
///  - coplanar: the test runs in 2D on the projection that drops the axis k of the
///    normal's dominant component (chosen in floating point, then confirmed exactly:
///    orient2d_k(P) != 0 makes the projection one-to-one on the plane). A triangle
///    strictly outside an edge line of the other misses it; otherwise the triangles meet
///    iff two edges meet (segment test with collinear overlaps) or a vertex of one lies in
///    the other.
/// Degenerate cases reduce to segment-triangle, segment-segment and point tests. Four
/// coplanar points do not always define a plane (collinear segments), so a segment-segment
/// test requires orient3d == 0 and then a 2D intersection in all three coordinate
/// projections: both sets lie in some plane, and at least one projection is one-to-one on
/// it, so the test is exact whichever it is.
///
/// For two triangles of one mesh that share vertices, the shared part always touches; the
/// adjacent variants report only what lies beyond it (see each function).
#include <Eigen/Core>

namespace weft::contact::verify {

/// Whether the closed triangles (p0, p1, p2) and (q0, q1, q2) have a common point
/// (touching at a single point counts). Exact; symmetric in the two triangles and
/// invariant under any permutation of the vertices of each.
bool triangles_intersect(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                         const Eigen::Vector3d& q0, const Eigen::Vector3d& q1, const Eigen::Vector3d& q2);

/// Whether the closed segment [p, q] (a point if p == q) meets the closed triangle
/// (a, b, c) (possibly degenerate). Exact.
bool segment_triangle_intersect(const Eigen::Vector3d& p, const Eigen::Vector3d& q, const Eigen::Vector3d& a,
                                const Eigen::Vector3d& b, const Eigen::Vector3d& c);

/// Whether the closed segments [p, q] and [r, s] (points when their ends coincide) meet. Exact.
bool segments_intersect(const Eigen::Vector3d& p, const Eigen::Vector3d& q, const Eigen::Vector3d& r,
                        const Eigen::Vector3d& s);

/// Triangles T1 = (v, a, b) and T2 = (v, c, d) of one mesh sharing the vertex v: whether
/// they have a common point other than v, i.e. T1 n T2 != {v}. Touching at v alone is
/// not reported; an edge of one passing through the other, or a common point anywhere
/// else (including a touching point, or the two triangles overlapping in a common plane
/// around v) is. Exact, also for degenerate triangles.
///
/// Method: if c and d lie strictly on one side of T1's plane, T2 meets that plane in v
/// alone (and the same the other way round). Otherwise: near v each triangle coincides
/// with its tangent cone (for coplanar proper triangles the cones are compared in 2D).
/// In general, write T1 as the union of conv(v, F) over its "far parts" F (the opposite
/// edge [a, b] if v is not on it, else the points a and b other than v). For far parts F
/// and G of T1 and T2 (neither contains v), conv(v, F) n conv(v, G) != {v} iff F meets
/// conv(v, G) or G meets conv(v, F): a common ray from v crosses F and G, and whichever
/// crossing is nearer to v lies in both.
bool triangles_intersect_sharing_vertex(const Eigen::Vector3d& v, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                        const Eigen::Vector3d& c, const Eigen::Vector3d& d);

/// Triangles T1 = (u, w, a) and T2 = (u, w, b) of one mesh sharing the edge [u, w]: whether
/// they have a common point outside the segment [u, w], i.e. T1 n T2 is not contained in
/// [u, w]. For proper triangles that happens exactly when they are coplanar with a and b
/// on the same side of the line uw: the sheet folded flat onto itself across the edge.
/// A fold at any dihedral angle other than zero, including a flat unfolded sheet, is not
/// reported. Degenerate cases: if u == w (as points) the pair is tested as sharing the
/// vertex u; if exactly one triangle is collinear it lies on the line uw, where the other
/// holds only [u, w], so nothing is reported; if both are, they are reported iff a and b
/// both extend past the same end of [u, w]. Exact.
bool triangles_intersect_sharing_edge(const Eigen::Vector3d& u, const Eigen::Vector3d& w, const Eigen::Vector3d& a,
                                      const Eigen::Vector3d& b);

namespace detail {
// The same tests with the first orientations already known (callers that cache planes):
//   s[i] = orient3d(p0, p1, p2, q_i), t[j] = orient3d(q0, q1, q2, p_j);
//   sc = orient3d(v, a, b, c), sd = orient3d(v, a, b, d), sa = orient3d(v, c, d, a), sb = orient3d(v, c, d, b);
//   s = orient3d(u, w, a, b).
bool triangles_intersect(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                         const Eigen::Vector3d& q0, const Eigen::Vector3d& q1, const Eigen::Vector3d& q2,
                         const int s[3], const int t[3]);
bool triangles_intersect_sharing_vertex(const Eigen::Vector3d& v, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                        const Eigen::Vector3d& c, const Eigen::Vector3d& d, int sc, int sd, int sa,
                                        int sb);
bool triangles_intersect_sharing_edge(const Eigen::Vector3d& u, const Eigen::Vector3d& w, const Eigen::Vector3d& a,
                                      const Eigen::Vector3d& b, int s);
}  // namespace detail

}  // namespace weft::contact::verify
