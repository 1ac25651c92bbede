#pragma once
/// \file bvh.hpp
/// Axis-aligned bounding boxes and a binary bounding volume hierarchy over the vertices,
/// edges or triangles of a mesh, for the broad phase of proximity and continuous
/// collision detection.
///
/// Boxes. The box of a primitive encloses its vertices at the start (x0) and at the end
/// (x1) of the step, inflated by `inflation` on every side. With linear vertex
/// trajectories x(t) = x0 + t (x1 - x0) every point of the primitive at every t in [0, 1]
/// is a convex combination of those 2 k vertex positions, so the box encloses the swept
/// primitive. Two primitives whose swept sets come within a Euclidean distance
/// inflation_a + inflation_b of each other (at possibly different times) have overlapping
/// boxes: the queries below have no false negatives for that distance. For a proximity
/// query at one configuration x, pass x0 = x1 = x.
///
/// Build (top-down): each node splits its primitives at the median of their box centres
/// along the axis of largest centre extent (`std::nth_element`, ties broken by primitive
/// id, so the tree is a deterministic function of the input). Leaves hold at most
/// `leaf_size` primitives. Nodes are stored in pre-order, so every child follows its
/// parent: a refit is one parallel pass over the primitive boxes and one reverse pass over
/// the nodes, O(n) (the build fills its node boxes the same way).
///
/// Quality: Q = (sum of the surface areas of the internal nodes) / (the same sum right
/// after the last build). A refit keeps the topology, so as the mesh deforms its boxes
/// grow and overlap; Q measures that growth. `update` rebuilds when Q exceeds
/// `rebuild_factor`. Q is not scale invariant: a mesh that grows uniformly by s has
/// Q = s^2 without losing tree quality; cloth is nearly inextensible, so this hardly matters.
///
/// Queries (bvh_query.cpp) return sorted pair lists: the result is the exact set of
/// primitive pairs whose boxes overlap (minus those sharing a vertex where asked), the
/// same for any leaf size, tree layout or number of OpenMP threads. The traversal is
/// split into independent sub-traversals (a fixed frontier of node pairs) run in parallel;
/// their outputs are merged by a counting sort on the first id, then each bucket is sorted.
#include <Eigen/Core>

#include <array>
#include <limits>
#include <vector>

#include "framework/params.hpp"

namespace weft::contact::detection {

/// Axis-aligned box [lo, hi]; empty when lo > hi in any coordinate (the default).
struct Aabb {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());

  bool empty() const { return (lo.array() > hi.array()).any(); }
  void extend(const Eigen::Vector3d& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void extend(const Aabb& b) {
    lo = lo.cwiseMin(b.lo);
    hi = hi.cwiseMax(b.hi);
  }
  /// Grow by r on every side.
  void inflate(double r) {
    lo.array() -= r;
    hi.array() += r;
  }
  /// Closed boxes: touching counts as overlapping.
  bool overlaps(const Aabb& b) const {
    return lo.x() <= b.hi.x() && b.lo.x() <= hi.x() && lo.y() <= b.hi.y() && b.lo.y() <= hi.y() &&
           lo.z() <= b.hi.z() && b.lo.z() <= hi.z();
  }
  /// 2 (ex ey + ey ez + ez ex) [m^2]; 0 when empty.
  double surface_area() const {
    if (empty()) return 0;
    const Eigen::Vector3d e = hi - lo;
    return 2 * (e.x() * e.y() + e.y() * e.z() + e.z() * e.x());
  }
  Eigen::Vector3d center() const { return 0.5 * (lo + hi); }
};

/// Primitives of one kind, each a list of `arity` vertex ids into a stacked position
/// vector (vertex i at x.segment<3>(3 i)); unused slots of `v` hold -1.
struct Primitives {
  int arity = 0;                        ///< 1 (vertices), 2 (edges) or 3 (triangles)
  std::vector<std::array<int, 3>> v;    ///< #P primitives

  int size() const { return static_cast<int>(v.size()); }
  /// Vertices 0 .. n-1.
  static Primitives vertices(int n);
  /// Edges as (i, j) pairs, e.g. `TriangleMesh::edges()`.
  static Primitives edges(const std::vector<std::array<int, 2>>& edges);
  /// Triangles, #F by 3.
  static Primitives triangles(const Eigen::MatrixX3i& faces);
};

/// Do primitives p and q (arity ka and kb) share a vertex id?
inline bool share_vertex(const std::array<int, 3>& p, int ka, const std::array<int, 3>& q, int kb) {
  for (int i = 0; i < ka; ++i)
    for (int j = 0; j < kb; ++j)
      if (p[i] == q[j]) return true;
  return false;
}

/// Parameters of a `Bvh`.
struct BvhParams {
  int leaf_size = 4;            ///< primitives per leaf, >= 1
  double rebuild_factor = 2.0;  ///< `update` rebuilds when quality() exceeds it, > 1
  template <class V>
  void visit(V& v) {
    v.field("leaf_size", leaf_size, {Unit::none, Range::closed(1, 64), "BVH primitives per leaf"});
    v.field("rebuild_factor", rebuild_factor,
            {Unit::none, Range::gt(1), "rebuild the BVH when its internal surface area grows by this factor since the last build"});
  }
  static Checker validate(const BvhParams& p) {
    Checker c("bvh");
    c.require(p.leaf_size >= 1 && p.leaf_size <= 64, "leaf_size", p.leaf_size, "in [1, 64]")
        .require(p.rebuild_factor > 1, "rebuild_factor", p.rebuild_factor, "> 1");
    return c;
  }
};

/// Binary BVH over swept, inflated primitive boxes (see the file comment).
class Bvh {
 public:
  using Params = BvhParams;

  /// A node covers order()[first, first + count); internal nodes have two children.
  struct Node {
    Aabb box;
    int left = -1, right = -1;  ///< children (-1 for a leaf)
    int first = 0, count = 0;   ///< range in leaf order
    bool leaf() const { return left < 0; }
  };

  Bvh() = default;
  /// No boxes until the first `update` or `build`. \throws ConfigError for invalid params.
  explicit Bvh(Primitives prims, const Params& prm = {});

  /// Refit to the new positions, and rebuild if the quality exceeds `rebuild_factor` (or on
  /// the first call). \param x0, x1 stacked #V*3 positions at the start and end of the step.
  /// \returns true if the tree was rebuilt.
  bool update(const Eigen::Ref<const Eigen::VectorXd>& x0, const Eigen::Ref<const Eigen::VectorXd>& x1,
              double inflation);
  /// Top-down build from scratch; resets quality() to 1.
  void build(const Eigen::Ref<const Eigen::VectorXd>& x0, const Eigen::Ref<const Eigen::VectorXd>& x1,
             double inflation);
  /// Bottom-up refit with the topology of the last build. Requires a previous build.
  void refit(const Eigen::Ref<const Eigen::VectorXd>& x0, const Eigen::Ref<const Eigen::VectorXd>& x1,
             double inflation);

  /// Internal surface area relative to the last build (1 right after a build).
  double quality() const { return build_area_ > 0 ? internal_area() / build_area_ : 1.0; }
  /// Sum of the surface areas of the internal nodes [m^2].
  double internal_area() const;
  int builds() const { return builds_; }  ///< number of builds so far
  int refits() const { return refits_; }  ///< number of refits so far
  bool built() const { return builds_ > 0; }

  const Params& params() const { return prm_; }
  const Primitives& primitives() const { return prims_; }
  int arity() const { return prims_.arity; }
  int size() const { return prims_.size(); }
  /// Box of primitive p (by its id in `primitives()`).
  const Aabb& primitive_box(int p) const { return leaf_boxes_[position_[p]]; }

  // Read-only tree layout, for the traversals.
  const std::vector<Node>& nodes() const { return nodes_; }
  /// Primitive ids in leaf order.
  const std::vector<int>& order() const { return order_; }
  /// Boxes and vertex ids in leaf order (leaf_boxes()[k] belongs to order()[k]).
  const std::vector<Aabb>& leaf_boxes() const { return leaf_boxes_; }
  const std::vector<std::array<int, 3>>& leaf_vertices() const { return leaf_vertices_; }

 private:
  void compute_boxes(const Eigen::Ref<const Eigen::VectorXd>& x0, const Eigen::Ref<const Eigen::VectorXd>& x1,
                     double inflation, bool in_leaf_order);
  int build_node(int begin, int end, const std::vector<Eigen::Vector3d>& centres);
  void refit_nodes();

  Params prm_;
  Primitives prims_;
  std::vector<Node> nodes_;
  std::vector<int> order_, position_;
  std::vector<Aabb> leaf_boxes_;
  std::vector<std::array<int, 3>> leaf_vertices_;
  double build_area_ = 0;
  int builds_ = 0, refits_ = 0;
};

/// A pair of primitive ids.
using PrimitivePair = std::array<int, 2>;

/// Every pair (i, j), i < j, of primitives of `tree` whose boxes overlap and which share
/// no vertex, sorted lexicographically. Empty for a tree that was never built.
std::vector<PrimitivePair> self_pairs(const Bvh& tree);

/// Every pair (i, j), i a primitive of `a` and j of `b`, whose boxes overlap, sorted
/// lexicographically. With `skip_shared_vertices` (trees over the same vertex array, e.g.
/// the vertices and the triangles of one mesh) pairs that share a vertex id are left out.
std::vector<PrimitivePair> cross_pairs(const Bvh& a, const Bvh& b, bool skip_shared_vertices);

}  // namespace weft::contact::detection
