#include "contact/detection/bvh.hpp"

#include <algorithm>
#include <numeric>

#include "framework/error.hpp"

namespace weft::contact::detection {

namespace {
using Eigen::Vector3d;

Aabb swept_box(const std::array<int, 3>& v, int arity, const Eigen::Ref<const Eigen::VectorXd>& x0,
               const Eigen::Ref<const Eigen::VectorXd>& x1, double inflation) {
  Aabb b;
  for (int k = 0; k < arity; ++k) {
    b.extend(Vector3d(x0.segment<3>(3 * v[k])));
    b.extend(Vector3d(x1.segment<3>(3 * v[k])));
  }
  b.inflate(inflation);
  return b;
}

// Sizes, and finiteness: a NaN box overlaps nothing, which would silently drop contacts.
void check_positions(const Eigen::Ref<const Eigen::VectorXd>& x0, const Eigen::Ref<const Eigen::VectorXd>& x1) {
  WEFT_ASSERT(x0.size() == x1.size() && x0.size() % 3 == 0,
              "x0 ({}) and x1 ({}) must be stacked #V*3 vectors of one size", x0.size(), x1.size());
  WEFT_ASSERT(x0.allFinite() && x1.allFinite(), "{}", "BVH positions must be finite (NaN or inf in x0 or x1)");
}
}  // namespace

Primitives Primitives::vertices(int n) {
  Primitives p;
  p.arity = 1;
  p.v.resize(n);
  for (int i = 0; i < n; ++i) p.v[i] = {i, -1, -1};
  return p;
}

Primitives Primitives::edges(const std::vector<std::array<int, 2>>& edges) {
  Primitives p;
  p.arity = 2;
  p.v.resize(edges.size());
  for (size_t e = 0; e < edges.size(); ++e) p.v[e] = {edges[e][0], edges[e][1], -1};
  return p;
}

Primitives Primitives::triangles(const Eigen::MatrixX3i& faces) {
  Primitives p;
  p.arity = 3;
  p.v.resize(faces.rows());
  for (Eigen::Index f = 0; f < faces.rows(); ++f) p.v[f] = {faces(f, 0), faces(f, 1), faces(f, 2)};
  return p;
}

Bvh::Bvh(Primitives prims, const Params& prm) : prm_(prm), prims_(std::move(prims)) {
  Params::validate(prm_).throw_if_failed();
  WEFT_ASSERT(prims_.arity >= 1 && prims_.arity <= 3, "primitive arity {} not in [1, 3]", prims_.arity);
}

double Bvh::internal_area() const {
  double a = 0;
  for (const Node& n : nodes_)
    if (!n.leaf()) a += n.box.surface_area();
  return a;
}

bool Bvh::update(const Eigen::Ref<const Eigen::VectorXd>& x0, const Eigen::Ref<const Eigen::VectorXd>& x1,
                 double inflation) {
  if (!built()) {
    build(x0, x1, inflation);
    return true;
  }
  refit(x0, x1, inflation);
  if (quality() > prm_.rebuild_factor) {
    build(x0, x1, inflation);
    return true;
  }
  return false;
}

void Bvh::build(const Eigen::Ref<const Eigen::VectorXd>& x0, const Eigen::Ref<const Eigen::VectorXd>& x1,
                double inflation) {
  check_positions(x0, x1);
  const int n = size();
  std::vector<Aabb> boxes(n);
  std::vector<Vector3d> centres(n);
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (int p = 0; p < n; ++p) {
    boxes[p] = swept_box(prims_.v[p], prims_.arity, x0, x1, inflation);
    centres[p] = boxes[p].center();
  }
  order_.resize(n);
  std::iota(order_.begin(), order_.end(), 0);
  nodes_.clear();
  nodes_.reserve(n > 0 ? 2 * ((n + prm_.leaf_size - 1) / prm_.leaf_size) * 2 : 0);
  if (n > 0) build_node(0, n, centres);
  position_.resize(n);
  leaf_boxes_.resize(n);
  leaf_vertices_.resize(n);
  for (int k = 0; k < n; ++k) {
    position_[order_[k]] = k;
    leaf_boxes_[k] = boxes[order_[k]];
    leaf_vertices_[k] = prims_.v[order_[k]];
  }
  refit_nodes();
  build_area_ = internal_area();
  ++builds_;
}

int Bvh::build_node(int begin, int end, const std::vector<Vector3d>& centres) {
  // Node boxes are filled afterwards, bottom-up (refit_nodes): only the centres are
  // scanned here, which halves the O(n log n) part of the build.
  const int index = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  Aabb centre_box;
  for (int k = begin; k < end; ++k) centre_box.extend(centres[order_[k]]);
  nodes_[index].first = begin;
  nodes_[index].count = end - begin;
  if (end - begin <= prm_.leaf_size) return index;

  int axis = 0;
  (centre_box.hi - centre_box.lo).maxCoeff(&axis);
  const int mid = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end, [&](int a, int b) {
    const double ca = centres[a][axis], cb = centres[b][axis];
    return ca < cb || (ca == cb && a < b);
  });
  const int left = build_node(begin, mid, centres);
  const int right = build_node(mid, end, centres);
  nodes_[index].left = left;
  nodes_[index].right = right;
  return index;
}

void Bvh::refit(const Eigen::Ref<const Eigen::VectorXd>& x0, const Eigen::Ref<const Eigen::VectorXd>& x1,
                double inflation) {
  WEFT_ASSERT(built(), "{}", "Bvh::refit needs a tree: call build() or update() first");
  check_positions(x0, x1);
  const int n = size();
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (int k = 0; k < n; ++k) leaf_boxes_[k] = swept_box(leaf_vertices_[k], prims_.arity, x0, x1, inflation);
  refit_nodes();
  ++refits_;
}

void Bvh::refit_nodes() {
  // Pre-order layout: children after parents, so one reverse sweep is bottom-up.
  for (int i = static_cast<int>(nodes_.size()) - 1; i >= 0; --i) {
    Node& node = nodes_[i];
    Aabb b;
    if (node.leaf()) {
      for (int k = node.first; k < node.first + node.count; ++k) b.extend(leaf_boxes_[k]);
    } else {
      b = nodes_[node.left].box;
      b.extend(nodes_[node.right].box);
    }
    node.box = b;
  }
}

}  // namespace weft::contact::detection
