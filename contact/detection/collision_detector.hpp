#pragma once
/// \file collision_detector.hpp
/// `CollisionDetector`: the per-step front end of collision detection for one cloth mesh
/// (body 0; several sheets are one mesh with several components) and any number of rigid
/// triangle-mesh obstacles (bodies 1, 2, ...) with scripted positions.
///
/// Each body holds three BVHs (bvh.hpp): over its vertices, edges and triangles. A step
/// calls `update(x0, x1)` once with the cloth's start and end positions; every tree is
/// refitted to the swept primitives, inflated by `margin`, and rebuilt when its quality
/// degrades beyond `bvh.rebuild_factor` (obstacle trees are refitted only when their
/// positions change). The queries then reuse those boxes:
///  - `proximity(x, thickness)`: pairs within `thickness` at a configuration x on the
///    step's trajectory (typically x0, methods/integration-and-contact §11.2), see proximity.hpp;
///  - `ccd(x0, x1, eta)`: pairs that come within eta during the step, with the earliest
///    time of impact, see ccd.hpp for the exact guarantee.
/// Both need thickness, eta <= 2 margin (checked): boxes inflated by margin each overlap
/// for every pair of primitives within 2 margin. The BVH traversal runs once per update:
/// the first query computes the candidate pairs, later ones reuse them.
///
/// Pairs tested: cloth self contact (cloth vertex vs cloth triangle, cloth edge vs cloth
/// edge, no shared vertex), and for every obstacle: cloth vertex vs obstacle triangle,
/// obstacle vertex vs cloth triangle, cloth edge vs obstacle edge. Obstacles are not
/// tested against each other. Output order: cloth self VF, cloth self EE, then per
/// obstacle the three lists above; each sorted by (A, B) primitive ids. The output does not
/// depend on the number of OpenMP threads, nor on when the trees were rebuilt.
#include <Eigen/Core>

#include <array>
#include <vector>

#include "contact/detection/bvh.hpp"
#include "contact/detection/ccd.hpp"
#include "contact/detection/proximity.hpp"
#include "framework/params.hpp"

namespace weft {
class TriangleMesh;
}

namespace weft::contact::detection {

/// Parameters of a `CollisionDetector`.
struct CollisionDetectorParams {
  double margin = 1e-3;       ///< [m] box inflation; proximity thickness and CCD eta must be <= 2 margin
  bool self_contact = true;   ///< test the cloth against itself
  BvhParams bvh;              ///< leaf size and rebuild factor of every tree
  ProximityOptions proximity; ///< options of the proximity narrow phase
  CcdOptions ccd;             ///< options of the CCD narrow phase
  template <class V>
  void visit(V& v) {
    v.field("margin", margin, {Unit::length, Range::gt(0), "BVH box inflation; bounds the proximity thickness and CCD eta (<= 2 margin)"});
    v.field("self_contact", self_contact, {Unit::none, Range::any(), "detect cloth-cloth contact"});
    v.section("bvh", bvh);
    v.field("edge_edge_interior_only", proximity.edge_edge_interior_only,
            {Unit::none, Range::any(), "drop edge-edge proximity pairs closest at an edge endpoint (found as vertex-triangle pairs)"});
    v.field("ccd_max_iterations", ccd.max_iterations,
            {Unit::none, Range::closed(1, 1e9), "distance evaluations per CCD pair before a conservative hit"});
  }
  static Checker validate(const CollisionDetectorParams& p) {
    Checker c("detection");
    c.require(p.margin > 0, "margin", p.margin, "> 0")
        .require(p.ccd.max_iterations >= 1, "ccd_max_iterations", p.ccd.max_iterations, ">= 1");
    c.merge(BvhParams::validate(p.bvh));
    return c;
  }
};

/// Statistics accumulated since construction or the last `reset_stats()`.
struct DetectionStats {
  int updates = 0;                       ///< calls to update()
  int refits = 0;                        ///< tree refits (all bodies, all three trees)
  int rebuilds = 0;                      ///< tree builds, the first one included
  double quality = 1;                    ///< worst tree quality after the last update
  long long proximity_candidates = 0;    ///< broad-phase pairs of proximity()
  long long proximity_pairs = 0;         ///< pairs within the thickness
  long long ccd_candidates = 0;          ///< broad-phase pairs of ccd()
  long long ccd_hits = 0;                ///< pairs with an impact
  long long ccd_conservative = 0;        ///< hits reported at the iteration cap
  long long ccd_iterations = 0;          ///< distance evaluations in CCD
  double seconds_update = 0;             ///< refits and rebuilds [s]
  double seconds_broad = 0;              ///< BVH traversals [s]
  double seconds_narrow = 0;             ///< primitive tests [s]
  double seconds() const { return seconds_update + seconds_broad + seconds_narrow; }
};

/// One pair that comes within eta during the step.
struct CcdPair {
  PairKind kind = PairKind::vertex_triangle;
  int body_a = 0, body_b = 0;  ///< body of side A (vertex or edge) and side B (triangle or edge)
  int a = -1, b = -1;          ///< primitive ids: vertex or edge (A), triangle or edge (B)
  std::array<int, 4> v{};      ///< stencil vertex ids: VF (p, t0, t1, t2), EE (a0, a1, b0, b1)
  Impact impact;               ///< time of impact, weights, normal
};

/// Broad and narrow phase for one cloth mesh and rigid triangle-mesh obstacles.
class CollisionDetector {
 public:
  using Params = CollisionDetectorParams;

  /// The cloth's faces and edges from a `TriangleMesh`. \throws ConfigError for bad params.
  explicit CollisionDetector(const TriangleMesh& cloth, const Params& prm = {});
  /// The cloth as #V vertices, #F by 3 faces and its edges (e.g. `unique_edges(faces)`).
  CollisionDetector(int num_vertices, const Eigen::MatrixX3i& faces, std::vector<std::array<int, 2>> edges,
                    const Params& prm = {});

  /// Add a rigid triangle-mesh obstacle (#V vertices, #F by 3 faces, any orientation,
  /// non-manifold allowed). \returns its body id (1, 2, ...). Set its positions with
  /// `set_obstacle_positions` before the next `update`.
  int add_obstacle(const Eigen::MatrixX3i& faces, int num_vertices);
  /// Obstacle positions (stacked #V*3) at the start and the end of the coming step.
  void set_obstacle_positions(int body, const Eigen::Ref<const Eigen::VectorXd>& x0,
                              const Eigen::Ref<const Eigen::VectorXd>& x1);

  /// Refit (or rebuild) the trees to the cloth trajectory x0 -> x1 (stacked #V*3) and to
  /// obstacles whose positions changed.
  void update(const Eigen::Ref<const Eigen::VectorXd>& x0, const Eigen::Ref<const Eigen::VectorXd>& x1);

  /// Pairs within `thickness` (<= 2 margin) at the cloth configuration x, which must lie
  /// on the trajectory of the last update (typically its x0; checked: every vertex must
  /// lie in its swept box). Obstacles are placed at (1 - obstacle_time) x0 +
  /// obstacle_time x1 of their last positions.
  std::vector<ProximityPair> proximity(const Eigen::Ref<const Eigen::VectorXd>& x, double thickness,
                                       double obstacle_time = 0.0);

  /// Pairs that come within eta (<= 2 margin) during the step; x0, x1 must be those of
  /// the last update. Obstacles move linearly between their positions.
  std::vector<CcdPair> ccd(const Eigen::Ref<const Eigen::VectorXd>& x0, const Eigen::Ref<const Eigen::VectorXd>& x1,
                           double eta);

  int num_bodies() const { return static_cast<int>(bodies_.size()); }
  const Params& params() const { return prm_; }
  const DetectionStats& stats() const { return stats_; }
  void reset_stats() { stats_ = DetectionStats{}; }

 private:
  struct Body {
    int num_vertices = 0;
    Eigen::MatrixX3i faces;
    std::vector<std::array<int, 2>> edges;
    Bvh vertex_tree, edge_tree, triangle_tree;
    Eigen::VectorXd x0, x1;  // obstacles only
    bool dirty = true;       // obstacles: positions changed since the last refit
  };
  // The candidate lists of one query, in output order.
  struct Candidates {
    PairKind kind;
    int body_a, body_b;
    std::vector<PrimitivePair> pairs;
  };
  void add_body(int num_vertices, const Eigen::MatrixX3i& faces, std::vector<std::array<int, 2>> edges);
  // Throws InvariantError unless every cloth vertex of x lies in its swept box of the last
  // update (a necessary condition for x to be on that trajectory). O(#V).
  void check_on_trajectory(const Eigen::Ref<const Eigen::VectorXd>& x, const char* what) const;
  // The candidate pairs for the current boxes: computed by the first query after an
  // update and reused by the next ones (proximity and CCD share the boxes).
  const std::vector<Candidates>& broad_phase();

  Params prm_;
  std::vector<Body> bodies_;
  std::vector<Candidates> candidates_;
  bool candidates_valid_ = false;
  DetectionStats stats_;
};

}  // namespace weft::contact::detection
