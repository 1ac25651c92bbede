// BVH traversals: self pairs of one tree and pairs between two trees.
//
// Determinism: the traversal is cut into a frontier of independent tasks (a node, for
// the pairs inside its subtree, or a pair of nodes), expanded breadth-first from the root
// in a fixed order. Tasks run in parallel, each into its own output; the outputs are
// concatenated and sorted. Every primitive pair is produced by exactly one task (the one
// holding the lowest common ancestor, or the leaf for pairs inside one leaf), so the
// sorted list has no duplicates and does not depend on the schedule.
#include <algorithm>
#include <utility>

#include "contact/detection/bvh.hpp"

namespace weft::contact::detection {

namespace {

struct Task {
  int a, b;  // a == b (self mode): pairs inside the subtree of a
};

// Enough tasks to balance 2-16 threads under a dynamic schedule, few enough to keep the
// frontier cheap to build.
constexpr size_t frontier_size = 256;

class Traversal {
 public:
  Traversal(const Bvh& a, const Bvh& b, bool self, bool skip_shared)
      : a_(a), b_(b), self_(self), skip_shared_(skip_shared) {}

  std::vector<PrimitivePair> run() {
    if (a_.nodes().empty() || b_.nodes().empty()) return {};
    std::vector<Task> frontier{{0, 0}};
    // Breadth-first expansion: replace every expandable task by its children, until the
    // frontier is large enough or only leaf-level tasks remain.
    while (frontier.size() < frontier_size) {
      std::vector<Task> next;
      bool expanded = false;
      for (const Task& t : frontier) {
        if (expandable(t)) {
          expand(t, next);
          expanded = true;
        } else {
          next.push_back(t);
        }
      }
      frontier.swap(next);
      if (!expanded) break;
    }
    const int m = static_cast<int>(frontier.size());
    std::vector<std::vector<PrimitivePair>> out(m);
    // A team costs more than a small traversal (a rod of 50 edges against a wall).
    const bool large = a_.nodes().size() + b_.nodes().size() >= 2048;
#pragma omp parallel for schedule(dynamic, 1) if (m > 1 && large)
    for (int i = 0; i < m; ++i) traverse(frontier[i], out[i]);
    return sorted(out, a_.size());
  }

  // Concatenate and sort lexicographically: a counting sort on the first id (a stable
  // scatter into one bucket per primitive of a), then a sort of each small bucket.
  static std::vector<PrimitivePair> sorted(const std::vector<std::vector<PrimitivePair>>& parts, int n) {
    std::vector<int> start(n + 1, 0);
    for (const auto& part : parts)
      for (const auto& p : part) ++start[p[0] + 1];
    for (int i = 0; i < n; ++i) start[i + 1] += start[i];
    std::vector<PrimitivePair> pairs(start[n]);
    std::vector<int> next(start.begin(), start.end() - 1);
    for (const auto& part : parts)
      for (const auto& p : part) pairs[next[p[0]]++] = p;
#pragma omp parallel for schedule(dynamic, 256) if (n >= 4096)
    for (int i = 0; i < n; ++i) std::sort(pairs.begin() + start[i], pairs.begin() + start[i + 1]);
    return pairs;
  }

 private:
  bool is_self(const Task& t) const { return self_ && t.a == t.b; }

  bool expandable(const Task& t) const {
    const auto& na = a_.nodes()[t.a];
    const auto& nb = b_.nodes()[t.b];
    if (is_self(t)) return !na.leaf();
    return (!na.leaf() || !nb.leaf()) && na.box.overlaps(nb.box);
  }

  // Children of an expandable task, in a fixed order. Non-overlapping pairs are dropped.
  void expand(const Task& t, std::vector<Task>& out) const {
    const auto& na = a_.nodes()[t.a];
    if (is_self(t)) {
      out.push_back({na.left, na.left});
      out.push_back({na.right, na.right});
      if (a_.nodes()[na.left].box.overlaps(a_.nodes()[na.right].box)) out.push_back({na.left, na.right});
      return;
    }
    const auto& nb = b_.nodes()[t.b];
    if (descend_a(na, nb)) {
      for (int c : {na.left, na.right})
        if (a_.nodes()[c].box.overlaps(nb.box)) out.push_back({c, t.b});
    } else {
      for (int c : {nb.left, nb.right})
        if (na.box.overlaps(b_.nodes()[c].box)) out.push_back({t.a, c});
    }
  }

  // Split the node with more primitives (a leaf is never split): on balanced trees this
  // descends both sides in step, and costs no geometry.
  static bool descend_a(const Bvh::Node& na, const Bvh::Node& nb) {
    if (na.leaf()) return false;
    if (nb.leaf()) return true;
    return na.count >= nb.count;
  }

  // Depth-first from one task; only overlapping node pairs are ever pushed.
  void traverse(const Task& root, std::vector<PrimitivePair>& out) const {
    const auto& na_ = a_.nodes();
    const auto& nb_ = b_.nodes();
    std::vector<Task> stack;
    if (is_self(root) || na_[root.a].box.overlaps(nb_[root.b].box)) stack.push_back(root);
    while (!stack.empty()) {
      const Task t = stack.back();
      stack.pop_back();
      const auto& na = na_[t.a];
      if (is_self(t)) {
        if (na.leaf()) {
          leaf_self(na, out);
        } else {
          stack.push_back({na.left, na.left});
          stack.push_back({na.right, na.right});
          if (na_[na.left].box.overlaps(na_[na.right].box)) stack.push_back({na.left, na.right});
        }
        continue;
      }
      const auto& nb = nb_[t.b];
      if (na.leaf() && nb.leaf()) {
        leaf_pair(na, nb, out);
      } else if (descend_a(na, nb)) {
        if (na_[na.left].box.overlaps(nb.box)) stack.push_back({na.left, t.b});
        if (na_[na.right].box.overlaps(nb.box)) stack.push_back({na.right, t.b});
      } else {
        if (na.box.overlaps(nb_[nb.left].box)) stack.push_back({t.a, nb.left});
        if (na.box.overlaps(nb_[nb.right].box)) stack.push_back({t.a, nb.right});
      }
    }
  }

  void leaf_self(const Bvh::Node& n, std::vector<PrimitivePair>& out) const {
    const auto& boxes = a_.leaf_boxes();
    const auto& verts = a_.leaf_vertices();
    const auto& order = a_.order();
    const int k = a_.arity();
    for (int i = n.first; i < n.first + n.count; ++i)
      for (int j = i + 1; j < n.first + n.count; ++j) {
        if (!boxes[i].overlaps(boxes[j]) || share_vertex(verts[i], k, verts[j], k)) continue;
        out.push_back({std::min(order[i], order[j]), std::max(order[i], order[j])});
      }
  }

  void leaf_pair(const Bvh::Node& na, const Bvh::Node& nb, std::vector<PrimitivePair>& out) const {
    const auto& boxes_a = a_.leaf_boxes();
    const auto& boxes_b = b_.leaf_boxes();
    const auto& verts_a = a_.leaf_vertices();
    const auto& verts_b = b_.leaf_vertices();
    const int ka = a_.arity(), kb = b_.arity();
    const bool skip = self_ || skip_shared_;
    for (int i = na.first; i < na.first + na.count; ++i)
      for (int j = nb.first; j < nb.first + nb.count; ++j) {
        if (!boxes_a[i].overlaps(boxes_b[j])) continue;
        if (skip && share_vertex(verts_a[i], ka, verts_b[j], kb)) continue;
        const int p = a_.order()[i], q = b_.order()[j];
        if (self_)
          out.push_back({std::min(p, q), std::max(p, q)});
        else
          out.push_back({p, q});
      }
  }

  const Bvh& a_;
  const Bvh& b_;
  bool self_, skip_shared_;
};

}  // namespace

std::vector<PrimitivePair> self_pairs(const Bvh& tree) { return Traversal(tree, tree, true, true).run(); }

std::vector<PrimitivePair> cross_pairs(const Bvh& a, const Bvh& b, bool skip_shared_vertices) {
  return Traversal(a, b, false, skip_shared_vertices).run();
}

}  // namespace weft::contact::detection
