#include "framework/triangle_mesh.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <map>
#include <numeric>

#include "framework/error.hpp"

namespace weft {

TriangleMesh::TriangleMesh(Eigen::MatrixX3d rest, Eigen::MatrixX3i faces)
    : rest_(std::move(rest)), faces_(std::move(faces)) {
  const int nv = num_vertices(), nf = num_faces();
  std::vector<std::string> errors;
  for (int f = 0; f < nf && errors.size() < 10; ++f) {
    for (int k = 0; k < 3; ++k)
      if (faces_(f, k) < 0 || faces_(f, k) >= nv)
        errors.push_back(fmt::format("face {} references vertex {} (valid: 0..{})", f, faces_(f, k), nv - 1));
    if (faces_(f, 0) == faces_(f, 1) || faces_(f, 1) == faces_(f, 2) || faces_(f, 0) == faces_(f, 2))
      errors.push_back(fmt::format("face {} repeats a vertex ({} {} {})", f, faces_(f, 0), faces_(f, 1), faces_(f, 2)));
  }
  if (!rest_.allFinite()) errors.emplace_back("rest positions contain NaN or Inf");
  if (!errors.empty()) throw ConfigError("Invalid triangle mesh:", errors);

  // Edges keyed by (low, high); remember each face's traversal direction.
  std::map<std::pair<int, int>, int> edge_id;
  face_edges_.assign(nf, {-1, -1, -1});
  struct Use { int face; int from; };
  std::vector<std::vector<Use>> uses;
  for (int f = 0; f < nf; ++f) {
    for (int i = 0; i < 3; ++i) {
      const int a = faces_(f, (i + 1) % 3), b = faces_(f, (i + 2) % 3);  // edge opposite vertex i
      const auto key = std::minmax(a, b);
      auto [it, inserted] = edge_id.try_emplace({key.first, key.second}, static_cast<int>(edges_.size()));
      if (inserted) {
        edges_.push_back({key.first, key.second});
        uses.emplace_back();
      }
      face_edges_[f][i] = it->second;
      uses[it->second].push_back({f, a});
    }
  }
  edge_faces_.assign(edges_.size(), {-1, -1});
  for (size_t e = 0; e < edges_.size(); ++e) {
    const auto& u = uses[e];
    if (u.size() > 2)
      errors.push_back(fmt::format("edge ({}, {}) is shared by {} faces (non-manifold)", edges_[e][0], edges_[e][1], u.size()));
    else if (u.size() == 2 && u[0].from == u[1].from)
      errors.push_back(fmt::format("faces {} and {} traverse edge ({}, {}) in the same direction (inconsistent orientation)",
                                   u[0].face, u[1].face, edges_[e][0], edges_[e][1]));
    if (errors.size() >= 10) break;
    edge_faces_[e][0] = u[0].face;
    if (u.size() == 2) edge_faces_[e][1] = u[1].face;
  }
  if (!errors.empty()) throw ConfigError("Invalid triangle mesh:", errors);

  // Hinges: T is the first face; x0 is its vertex opposite the edge.
  for (size_t e = 0; e < edges_.size(); ++e) {
    if (edge_faces_[e][1] < 0) continue;
    const int fa = edge_faces_[e][0], fb = edge_faces_[e][1];
    int ia = 0, ib = 0;
    while (face_edges_[fa][ia] != static_cast<int>(e)) ++ia;
    while (face_edges_[fb][ib] != static_cast<int>(e)) ++ib;
    Hinge h;
    h.v = {faces_(fa, ia), faces_(fa, (ia + 1) % 3), faces_(fa, (ia + 2) % 3), faces_(fb, ib)};
    h.face = {fa, fb};
    h.edge = static_cast<int>(e);
    hinges_.push_back(h);
  }

  // Vertex adjacency (CSR, sorted).
  std::vector<std::vector<int>> nbr(nv);
  for (const auto& ed : edges_) {
    nbr[ed[0]].push_back(ed[1]);
    nbr[ed[1]].push_back(ed[0]);
  }
  vertex_offsets_.assign(nv + 1, 0);
  for (int i = 0; i < nv; ++i) {
    std::sort(nbr[i].begin(), nbr[i].end());
    vertex_offsets_[i + 1] = vertex_offsets_[i] + static_cast<int>(nbr[i].size());
  }
  vertex_neighbours_.reserve(vertex_offsets_.back());
  for (auto& n : nbr) vertex_neighbours_.insert(vertex_neighbours_.end(), n.begin(), n.end());
}

int TriangleMesh::num_boundary_edges() const {
  return static_cast<int>(std::count_if(edge_faces_.begin(), edge_faces_.end(), [](auto& f) { return f[1] < 0; }));
}

int TriangleMesh::num_components() const {
  std::vector<int> parent(num_faces());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  for (const auto& ef : edge_faces_)
    if (ef[1] >= 0) parent[find(ef[0])] = find(ef[1]);
  int n = 0;
  for (int f = 0; f < num_faces(); ++f) n += find(f) == f;
  return n;
}

double TriangleMesh::rest_area() const {
  double a = 0;
  for (int f = 0; f < num_faces(); ++f) {
    const Eigen::Vector3d p0 = rest_.row(faces_(f, 0)), p1 = rest_.row(faces_(f, 1)), p2 = rest_.row(faces_(f, 2));
    a += 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  return a;
}

}  // namespace weft
