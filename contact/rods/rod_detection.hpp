#pragma once
/// \file rod_detection.hpp
/// Collision detection for elastic rods (hair): rod-rod contacts (self contact included)
/// and contacts of rods with the scene's scripted obstacles (methods/rod-contact §10.6, thesis
/// Algorithm 5). Geometry only: the rods are their centrelines (vertex positions at the
/// start of the step, x0, and at the end of the unconstrained step, x1) with a circular
/// cross-section of radius r per rod; twist angles and the energy are not seen here.
///
/// **Rod-rod** (`detect_rod_rod`). Candidates: the rod edges' boxes (contact/detection's
/// BVH), swept from x0 to x1 with rod_ccd (else at x0), inflated by max r + proximity / 2 +
/// eta, so that no pair within reach is missed; same-rod pairs fewer than `self_skip` edges
/// apart (adjacent edges included: they share a vertex) are never contacts, nor any same-rod
/// pair without `self_contact`. With delta = r_a + r_b and d the centreline distance:
///  - proximity (default): a pair is a contact when d(x0) < delta + proximity, with the
///    closest points at x0 (toi = 0);
///  - rod_ccd: a pair is a contact when d(x0) < delta + proximity (toi = 0, as above), or
///    when the thick-segment CCD of thick_ccd.hpp finds d reaching delta during x0 -> x1
///    (toi its time of impact, closest points and normal there; the toi is early by at
///    most about eta / approach speed; the gap at a toi > 0 is in (0, eta]).
/// Normal: from b to a along the closest points' difference; for (nearly) intersecting
/// centrelines the normalised cross product of the edges, oriented by the start
/// configuration and the relative motion (thick_ccd.hpp). Every pair within reach is
/// reported, so a rod lying along another gives contacts at several neighbouring edge pairs.
///
/// **Near-duplicates** (`merge_fraction`, `merge_angle`). Where a rod wraps around another
/// (a rod draped across a rod bends around it), the polyline's vertex next to the crossing
/// is a slight valley seen from the other rod, and the closest points of the two edges at
/// that vertex both lie a hair's breadth from it: the same crossing is found twice, with
/// normals a fraction of a degree apart. Two such constraints are redundant: the Delassus
/// operator is singular on them, the multipliers are not unique (any split of the load),
/// and a convergent contact solve stalls. So two rod-rod contacts of the same
/// pair of rods whose edges are the same or adjacent on both rods are merged when their
/// contact points, as material points at the start of the step (the times of impact of
/// the two may differ: one found by proximity, the other by CCD), lie within
/// merge_fraction (r_a + r_b) of each other on both rods and their normals within
/// merge_angle: deepest first, a contact is dropped when it is a near-duplicate of one
/// already kept (so every dropped contact has a kept one at most as deep beside it). What a merge gives up: the dropped contact's gap
/// differs from the kept one's by at most about |p_i - p_j| |n_i - n_j| plus the change of
/// the points' offset over the step. At the defaults (10 % of r_a + r_b, 5 degrees) that is
/// at most 0.009 (r_a + r_b), below the polyline's own geometric error at such a kink (an
/// edge of length l turned by theta deviates from the smooth curve by about l theta^2 / 8,
/// 0.00095 l at 5 degrees: more as soon as l > 10 (r_a + r_b), as for hair). The V-06
/// scenes need the 5 degrees: a rod draped across another bends by about 3 degrees at the
/// vertex above it. merge_fraction = 0 reports every contact.
///
/// **Rod-obstacle** (`detect_rod_obstacles`; sphere, box, plane and mesh obstacles with
/// scripted motion, posed with `ObstaclePose::at`). Obstacles are always treated
/// continuously (methods/rod-contact §10.6: rod-mesh CCD on x0 -> x1).
///  - Vertex contacts, one per (vertex, obstacle): with phi the signed distance, a vertex
///    is a contact when phi(x0, t0) - r < proximity (toi = 0), or when its path x0 + s (x1 -
///    x0) comes within r of the obstacle (posed at t0 + s (t1 - t0)) during the step, at the
///    first such s (up to the tolerance eta, as for the thick CCD of thick_ccd.hpp: no miss
///    of a path within r + eta/2 of the surface, the hit within r + eta of it):
///    - sphere, box, plane: conservative advancement on g(s) = phi - r, hit at the first s
///      with g <= eta. Step: (g - eta/2) / L with L a bound on |dg/ds| (the vertex's
///      displacement, plus for a moving obstacle (t1 - t0)(|v| + |omega| reach), phi being
///      1-Lipschitz in body coordinates); when the obstacle is static or translates
///      linearly over the whole step (a sphere may also spin about its centre), also the
///      exact step to the supporting plane at the closest point (convexity), which makes
///      planes one step and sliding along the surface cheap. A rotating box or plane has
///      only the Lipschitz step; after `ccd_max_iterations` steps the vertex is reported
///      where it is.
///    - mesh: thick point-triangle CCD (thickness r, thick_ccd.hpp) against the triangles
///      whose swept boxes meet the vertex's (a BVH over the mesh posed at t0 and t1; the
///      triangles move linearly in between: exact for translations, a chord of the arc for
///      rotations); the earliest hit over the triangles is the contact time. The start
///      test uses the signed distance (MeshDistance), skipped outside the mesh's bounding
///      sphere.
///    The contact data come from the signed distance at toi: normal = grad phi (outward),
///    the obstacle's point in contact = x - phi grad phi.
///  - Segment contacts (box and mesh obstacles): an obstacle edge sharper than the vertex
///    spacing can pass between two rod vertices (a rod falling across the top of a thin
///    wall). The obstacle's sharp edges, i.e. the 12 edges of a box and the non-flat convex
///    edges and boundary edges of a mesh, are tested against every rod edge as thick
///    segments (thickness r): a contact when their distance at t0 is below r + proximity, or
///    by the thick CCD of thick_ccd.hpp, the obstacle edge moving linearly between its
///    poses at t0 and t1 (exact for translations; a chord of the arc for rotations). Normal:
///    from the obstacle edge's closest point to the rod's, or the edge's outward
///    pseudonormal (the mean of its faces' normals) when that is degenerate or points into
///    the obstacle. A segment contact whose closest point is a rod vertex (s_a = 0 or 1) is
///    dropped when that vertex has a contact with the same obstacle: it is the same point.
///    Spheres and planes have no edges: a rod segment lying over a sphere between its
///    vertices sinks in by up to l^2 / (8 R) (l the edge length), which is not detected.
///  - obstacle_displacement: the scripted motion over the step of the obstacle's material
///    point in contact (the closest surface point at toi, in body coordinates y):
///    (c1 + R1 y) - (c0 + R0 y).
///
/// **Order and determinism.** Contacts are sorted by (kind, rod_a, edge_a, rod_b, edge_b,
/// obstacle, obstacle_edge, s_a), keys that are unique. The narrow phases run in parallel
/// over fixed chunks (contact/detection/parallel.hpp): the output does not depend on the
/// number of OpenMP threads.
///
/// Cost: the BVHs are built on every call (no state is kept between steps); building and
/// traversing the rod-edge BVH dominates. Measured (Release, one thread, a loaded 2-core
/// machine): 250 random rods of 30 vertices ~4-7 ms rod-rod, ~0.4 ms against a sphere;
/// 1000 rods 25-35 ms (proximity) and 50-90 ms (rod_ccd) rod-rod, ~1.3 ms against a sphere.
#include <Eigen/Core>

#include <vector>

#include "framework/params.hpp"
#include "framework/scene.hpp"

namespace weft::contact::rods {

/// Centrelines of all rods, stacked rod after rod.
struct RodCurves {
  std::vector<Eigen::Vector3d> x0;  ///< #V positions at the start of the step [m]
  std::vector<Eigen::Vector3d> x1;  ///< #V positions at the end of the unconstrained step [m]
  /// #rods+1 vertex offsets: rod r has vertices first[r] .. first[r+1]-1 (at least 2) and
  /// the edges between consecutive ones. Empty or {0}: no rods.
  std::vector<int> first;
  std::vector<double> radius;  ///< #rods cross-section radii [m], >= 0

  int num_rods() const { return first.empty() ? 0 : static_cast<int>(first.size()) - 1; }
  int num_vertices() const { return static_cast<int>(x0.size()); }
  int num_edges(int r) const { return first[r + 1] - first[r] - 1; }
};

/// One contact. Contact points: p_a = (1 - s_a) x[first[rod_a] + edge_a] + s_a x[first[rod_a] + edge_a + 1]
/// (same for b), at time toi of the step.
struct RodContact {
  enum class Kind { rod_rod, rod_obstacle };
  Kind kind = Kind::rod_rod;
  int rod_a = -1, edge_a = -1;  ///< the rod edge of side a (rod-rod: (rod_a, edge_a) < (rod_b, edge_b))
  double s_a = 0;               ///< parameter of p_a on edge_a; a vertex contact has 0, or 1 at a rod's last vertex
  int rod_b = -1, edge_b = -1;  ///< rod_rod only (rod_b == rod_a: self contact)
  double s_b = 0;               ///< rod_rod only: parameter of p_b on edge_b
  int obstacle = -1;            ///< rod_obstacle: index into the obstacle list
  /// rod_obstacle: -1 for a vertex contact; else the obstacle edge of a segment contact
  /// (box: 4 k + m for the edge along axis k, m = 0..3 the signs of the other two axes in
  /// binary, (-,-), (+,-), (-,+), (+,+); mesh: index into ObstacleMesh::edges).
  int obstacle_edge = -1;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit, from b (other rod or obstacle) towards a
  /// rod_obstacle: scripted motion of the obstacle's material point in contact over the
  /// step, p_b(t1) - p_b(t0) [m].
  Eigen::Vector3d obstacle_displacement = Eigen::Vector3d::Zero();
  double toi = 0;  ///< contact time in [0, 1] of the step (0 for proximity contacts)
  /// At toi: centreline distance - r_a - r_b (rod-rod), signed distance - r (vertex),
  /// centreline-to-edge distance - r (segment) [m]; < 0: overlap.
  double gap = 0;
  bool vertex_contact() const { return kind == Kind::rod_obstacle && obstacle_edge < 0; }
};

/// The sort key of a contact (file comment); strict weak order on it.
bool contact_less(const RodContact& a, const RodContact& b);

/// Parameters of the rod detection.
struct RodDetectionParams {
  double proximity = 0;  ///< [m] >= 0: extra radius; pairs (and vertices) closer than r_a + r_b + proximity (r + proximity) at the start are contacts
  bool rod_ccd = false;  ///< rod-rod: continuous detection on x0 -> x1 (thickness r_a + r_b) besides the proximity test at x0
  bool self_contact = true;       ///< contacts between edges of one rod
  int self_skip = 2;              ///< >= 2: same-rod edge pairs fewer than this many edges apart are never contacts
  double ccd_tolerance = 1e-9;    ///< eta [m] > 0: CCD accuracy (toi early by ~eta / speed; thick_ccd.hpp)
  int ccd_max_iterations = 10000;  ///< CCD distance evaluations per pair before a conservative hit, >= 1
  double merge_fraction = 0.1;   ///< rod-rod near-duplicates closer than this times r_a + r_b are merged (0: never; file comment)
  double merge_angle = 5;        ///< [degrees] ... and whose normals are within this angle
  template <class V>
  void visit(V& v) {
    v.field("proximity", proximity,
            {Unit::length, Range::ge(0), "extra contact radius: rods and obstacles closer than the radii plus this at the start of the step are in contact"});
    v.field("rod_ccd", rod_ccd, {Unit::none, Range::any(), "rod-rod continuous collision detection over the step (off: proximity at the start)"});
    v.field("self_contact", self_contact, {Unit::none, Range::any(), "contacts between edges of the same rod"});
    v.field("self_skip", self_skip,
            {Unit::none, Range::closed(2, 1e6), "same-rod edge pairs fewer than this many edges apart are never contacts"});
    v.field("ccd_tolerance", ccd_tolerance, {Unit::length, Range::gt(0), "CCD tolerance eta: the time of impact is the first time within eta of contact"});
    v.field("ccd_max_iterations", ccd_max_iterations,
            {Unit::none, Range::closed(1, 1e9), "CCD distance evaluations per pair before a conservative hit"});
    v.field("merge_fraction", merge_fraction,
            {Unit::none, Range::closed(0, 1),
             "rod-rod contacts of adjacent edges whose points are closer than this times the sum of the radii (and normals within merge_angle) are one contact: the one with the smaller gap is kept (0: keep all)"});
    v.field("merge_angle", merge_angle, {Unit::none, Range::closed(0, 90), "largest angle between the normals of merged rod-rod contacts [degrees]"});
  }
  static Checker validate(const RodDetectionParams& p) {
    Checker c("rod_detection");
    c.require(p.proximity >= 0, "proximity", p.proximity, ">= 0")
        .require(p.self_skip >= 2, "self_skip", p.self_skip, ">= 2 (adjacent edges share a vertex and always touch)")
        .require(p.ccd_tolerance > 0, "ccd_tolerance", p.ccd_tolerance, "> 0")
        .require(p.ccd_max_iterations >= 1, "ccd_max_iterations", p.ccd_max_iterations, ">= 1")
        .require(p.merge_fraction >= 0 && p.merge_fraction <= 1, "merge_fraction", p.merge_fraction, "[0, 1]")
        .require(p.merge_angle >= 0 && p.merge_angle <= 90, "merge_angle", p.merge_angle, "[0, 90] degrees");
    return c;
  }
};

/// Whether two rod-rod contacts are near-duplicates on the curves c (file comment: same
/// rods, same or adjacent edges on both, material points within merge_fraction (r_a + r_b)
/// at the start of the step, normals within merge_angle). False when merging is off.
bool near_duplicates(const RodCurves& c, const RodContact& i, const RodContact& j, const RodDetectionParams& p);

/// Rod-rod contacts (file comment), sorted. \throws ConfigError for invalid params;
/// inconsistent curves (sizes, a rod with fewer than 2 vertices) fail WEFT_ASSERT.
std::vector<RodContact> detect_rod_rod(const RodCurves& c, const RodDetectionParams& p);

/// Rod-obstacle contacts over the step [t0, t1] (file comment), sorted.
/// \throws ConfigError for invalid params, or a mesh obstacle without its geometry.
std::vector<RodContact> detect_rod_obstacles(const RodCurves& c, const std::vector<ObstacleSpec>& obstacles, double t0,
                                             double t1, const RodDetectionParams& p);

/// Both, rod-rod contacts first (the sorted order).
std::vector<RodContact> detect_rod_contacts(const RodCurves& c, const std::vector<ObstacleSpec>& obstacles, double t0,
                                            double t1, const RodDetectionParams& p);

}  // namespace weft::contact::rods
