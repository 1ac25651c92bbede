#include "framework/obstacle_mesh.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <map>

#include "framework/error.hpp"
#include "framework/obj_io.hpp"

namespace weft {

namespace {

// Coplanarity of two unit normals: 1 - cos(angle) below this (an angle below ~1.4e-6 rad).
constexpr double flat_tolerance = 1e-12;
// Reported violations per kind, then a count.
constexpr int max_reported = 10;

struct Reporter {
  std::vector<std::string>& errors;
  const std::string& what;
  std::map<std::string, int> counts;
  template <class... A>
  void add(const std::string& kind, fmt::format_string<A...> f, A&&... a) {
    if (++counts[kind] <= max_reported) errors.push_back(fmt::format("{}: {}", what, fmt::format(f, std::forward<A>(a)...)));
  }
  void finish() {
    for (const auto& [kind, n] : counts)
      if (n > max_reported) errors.push_back(fmt::format("{}: ... and {} more {}", what, n - max_reported, kind));
  }
};

std::shared_ptr<ObstacleMesh> build(Eigen::MatrixX3d V, Eigen::MatrixX3i F, const std::string& what) {
  std::vector<std::string> errors;
  Reporter report{errors, what, {}};
  if (F.rows() == 0) throw ConfigError(fmt::format("{}: the mesh has no triangles", what));
  for (Eigen::Index i = 0; i < V.rows(); ++i)
    if (!V.row(i).allFinite())
      report.add("non-finite vertices", "vertex {} = ({}, {}, {}) is not finite", i + 1, V(i, 0), V(i, 1), V(i, 2));
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (F(f, k) < 0 || F(f, k) >= V.rows())
        report.add("faces out of range", "face {} references vertex {} of {}", f + 1, F(f, k) + 1, V.rows());
  report.finish();
  if (!errors.empty()) throw ConfigError(fmt::format("{}: invalid obstacle mesh", what), errors);

  // Weld exact duplicates (exporters that split vertices at creases would otherwise leave
  // every crease a pair of boundary edges, with the wrong pseudonormals).
  {
    std::map<std::array<double, 3>, int> index;
    std::vector<int> to(V.rows());
    Eigen::MatrixX3d W(V.rows(), 3);
    int n = 0;
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
      const auto [it, added] = index.try_emplace({V(i, 0), V(i, 1), V(i, 2)}, n);
      if (added) W.row(n++) = V.row(i);
      to[i] = it->second;
    }
    if (n < V.rows()) {
      V = W.topRows(n);
      for (Eigen::Index f = 0; f < F.rows(); ++f)
        for (int k = 0; k < 3; ++k) F(f, k) = to[F(f, k)];
    }
  }

  auto m = std::make_shared<ObstacleMesh>();
  const auto nf = F.rows(), nv = V.rows();
  m->face_normals.resize(nf, 3);
  for (Eigen::Index f = 0; f < nf; ++f) {
    const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    const Eigen::Vector3d n = (b - a).cross(c - a);
    // The zero-area test of cloth rest faces (scene.cpp).
    if (n.norm() <= 1e-14 * std::max(1e-300, (b - a).squaredNorm() + (c - a).squaredNorm()))
      report.add("zero-area faces", "face {} (vertices {} {} {}) has zero area", f + 1, F(f, 0) + 1, F(f, 1) + 1, F(f, 2) + 1);
    m->face_normals.row(f) = n.norm() > 0 ? Eigen::RowVector3d((n / n.norm()).transpose()) : Eigen::RowVector3d::Zero();
  }

  // Edges: the one opposite local vertex k of face f runs F(f, k+1) -> F(f, k+2).
  std::map<std::array<int, 2>, int> edge_id;
  m->face_edges.resize(nf, 3);
  std::vector<std::array<int, 2>> first_direction;  // of the first face's traversal
  for (Eigen::Index f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int i = F(f, (k + 1) % 3), j = F(f, (k + 2) % 3);
      const std::array<int, 2> key{std::min(i, j), std::max(i, j)};
      const auto [it, added] = edge_id.try_emplace(key, static_cast<int>(m->edges.size()));
      const int e = it->second;
      m->face_edges(f, k) = e;
      if (added) {
        m->edges.push_back(key);
        m->edge_faces.push_back({static_cast<int>(f), -1});
        first_direction.push_back({i, j});
      } else if (m->edge_faces[e][1] < 0) {
        m->edge_faces[e][1] = static_cast<int>(f);
        if (first_direction[e][0] == i)
          report.add("inconsistently oriented faces",
                     "faces {} and {} run through their common edge ({} {}) in the same direction: orient every face "
                     "counter-clockwise seen from outside",
                     m->edge_faces[e][0] + 1, f + 1, i + 1, j + 1);
      } else {
        report.add("non-manifold edges", "edge ({} {}) has more than two faces (faces {}, {}, {}, ...)", key[0] + 1, key[1] + 1,
                   m->edge_faces[e][0] + 1, m->edge_faces[e][1] + 1, f + 1);
      }
    }
  const auto ne = static_cast<Eigen::Index>(m->edges.size());
  m->edge_normals.resize(ne, 3);
  m->flat_edge.assign(ne, 0);
  std::vector<unsigned char> boundary_vertex(nv, 0);
  for (Eigen::Index e = 0; e < ne; ++e) {
    const auto [f0, f1] = m->edge_faces[e];
    Eigen::RowVector3d n = m->face_normals.row(f0);
    if (f1 >= 0) {
      n += m->face_normals.row(f1);
      m->flat_edge[e] = m->face_normals.row(f0).dot(m->face_normals.row(f1)) >= 1 - flat_tolerance;
    } else {
      ++m->boundary_edges;
      boundary_vertex[m->edges[e][0]] = boundary_vertex[m->edges[e][1]] = 1;
    }
    m->edge_normals.row(e) = n.norm() > 0 ? Eigen::RowVector3d(n / n.norm()) : n;
  }

  // Angle-weighted vertex pseudonormals (Baerentzen & Aanaes, Eq. 2).
  m->vertex_normals = Eigen::MatrixX3d::Zero(nv, 3);
  for (Eigen::Index f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d x = V.row(F(f, k));
      const Eigen::Vector3d a = Eigen::Vector3d(V.row(F(f, (k + 1) % 3))) - x, b = Eigen::Vector3d(V.row(F(f, (k + 2) % 3))) - x;
      m->vertex_normals.row(F(f, k)) += std::atan2(a.cross(b).norm(), a.dot(b)) * m->face_normals.row(f);
    }
  for (Eigen::Index i = 0; i < nv; ++i) {
    const double len = m->vertex_normals.row(i).norm();
    if (len > 0) m->vertex_normals.row(i) /= len;
  }
  // A vertex is flat when it is interior and every face at it is parallel to its normal.
  m->flat_vertex.assign(nv, 1);
  for (Eigen::Index i = 0; i < nv; ++i)
    if (boundary_vertex[i]) m->flat_vertex[i] = 0;
  for (Eigen::Index f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k)
      if (m->face_normals.row(f).dot(m->vertex_normals.row(F(f, k))) < 1 - flat_tolerance) m->flat_vertex[F(f, k)] = 0;

  if (m->boundary_edges == 0 && errors.empty()) {
    // Enclosed volume (divergence theorem): negative when the faces point inwards.
    double volume = 0;
    for (Eigen::Index f = 0; f < nf; ++f)
      volume += Eigen::Vector3d(V.row(F(f, 0))).dot(Eigen::Vector3d(V.row(F(f, 1))).cross(Eigen::Vector3d(V.row(F(f, 2))))) / 6;
    if (volume < 0)
      report.add("inward faces", "the closed mesh has negative volume {} m^3: its faces point inwards; reverse the vertex order "
                 "of every face (counter-clockwise seen from outside)", volume);
  }
  report.finish();
  if (!errors.empty()) throw ConfigError(fmt::format("{}: invalid obstacle mesh", what), errors);

  m->extent = (V.colwise().maxCoeff() - V.colwise().minCoeff()).norm();
  m->V = std::move(V);
  m->F = std::move(F);
  return m;
}

}  // namespace

std::shared_ptr<const ObstacleMesh> make_obstacle_mesh(Eigen::MatrixX3d V, Eigen::MatrixX3i F, const std::string& what) {
  return build(std::move(V), std::move(F), what);
}

std::shared_ptr<const ObstacleMesh> load_obstacle_mesh(const std::string& path, double scale, const std::string& what) {
  MeshData d;
  try {
    d = read_obj(path);
  } catch (const ConfigError& e) {
    throw ConfigError(fmt::format("{}: {}", what, e.what()));
  }
  const Eigen::MatrixX3d V = d.V * scale;
  if (const std::string bad = check_extent(V); !bad.empty()) throw ConfigError(fmt::format("{}: {}", what, bad));
  auto m = build(V, d.F, what);
  m->source = path;
  return m;
}

}  // namespace weft
