#include "framework/mesh_generators.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <random>
#include <vector>

#include "framework/error.hpp"

namespace weft {
namespace {

// Grid vertices and faces; `keep(i, j)` decides whether quad (i, j) is present.
template <class Keep>
MeshData grid(const Eigen::Vector2d& size, std::array<int, 2> res, Tessellation t, int seed, Keep keep) {
  const int nx = res[0], ny = res[1];
  const double hx = size[0] / (nx - 1), hy = size[1] / (ny - 1);
  std::mt19937 rng(static_cast<unsigned>(seed));
  std::uniform_int_distribution<int> coin(0, 1);
  std::vector<Eigen::Vector3i> faces;
  std::vector<char> used(static_cast<size_t>(nx) * ny, 0);
  auto id = [nx](int i, int j) { return j * nx + i; };
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      if (!keep(i, j)) continue;
      const int a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
      const bool flip = t == Tessellation::irregular && coin(rng);
      if (!flip) {
        faces.emplace_back(a, b, c);
        faces.emplace_back(a, c, d);
      } else {
        faces.emplace_back(a, b, d);
        faces.emplace_back(b, c, d);
      }
      used[a] = used[b] = used[c] = used[d] = 1;
    }
  // Boundary vertices (on an edge used by one face) are not jittered, so the outline stays exact.
  std::map<std::pair<int, int>, int> edge_count;
  for (const auto& f : faces)
    for (int k = 0; k < 3; ++k) ++edge_count[std::minmax(f[k], f[(k + 1) % 3])];
  std::vector<char> boundary(used.size(), 0);
  for (const auto& [e, n] : edge_count)
    if (n == 1) boundary[e.first] = boundary[e.second] = 1;

  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  std::vector<int> remap(used.size(), -1);
  std::vector<Eigen::Vector3d> verts, offset;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const int k = id(i, j);
      // Draw jitter for every grid vertex so the sequence does not depend on the shape.
      const double du = jitter(rng), dv = jitter(rng);
      if (!used[k]) continue;
      remap[k] = static_cast<int>(verts.size());
      verts.emplace_back(-0.5 * size[0] + i * hx, -0.5 * size[1] + j * hy, 0.0);
      offset.push_back(t == Tessellation::irregular && !boundary[k] ? Eigen::Vector3d(du * hx, dv * hy, 0.0)
                                                                    : Eigen::Vector3d::Zero());
    }
  // Jitter of both ends of an edge can fold a triangle over (or nearly): halve the offsets of
  // the vertices of every triangle below a tenth of the grid triangle's area until none is left.
  const double min_area = 0.1 * 0.5 * hx * hy;
  for (int pass = 0; pass < 30; ++pass) {
    std::vector<char> shrink(verts.size(), 0);
    bool any = false;
    for (const auto& f : faces) {
      Eigen::Vector3d q[3];
      for (int c = 0; c < 3; ++c) q[c] = verts[remap[f[c]]] + offset[remap[f[c]]];
      const Eigen::Vector3d e1 = q[1] - q[0], e2 = q[2] - q[0];
      const double area = 0.5 * (e1.x() * e2.y() - e1.y() * e2.x());
      if (area < min_area)
        for (int c = 0; c < 3; ++c) shrink[remap[f[c]]] = any = true;
    }
    if (!any) break;
    for (size_t k = 0; k < verts.size(); ++k)
      if (shrink[k]) offset[k] *= 0.5;
  }
  for (size_t k = 0; k < verts.size(); ++k) verts[k] += offset[k];
  MeshData m;
  m.V.resize(static_cast<Eigen::Index>(verts.size()), 3);
  for (size_t k = 0; k < verts.size(); ++k) m.V.row(static_cast<Eigen::Index>(k)) = verts[k];
  m.F.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t k = 0; k < faces.size(); ++k)
    for (int c = 0; c < 3; ++c) m.F(static_cast<Eigen::Index>(k), c) = remap[faces[k][c]];
  return m;
}

// Texture coordinates of a generated sheet: its (u, v) plane coordinates, before placement.
MeshData with_plane_uv(MeshData m) {
  m.UV = m.V.leftCols<2>();
  m.FUV = m.F;
  return m;
}

void check(std::array<int, 2> res) {
  if (res[0] < 2 || res[1] < 2) throw ConfigError(fmt::format("sheet resolution {}x{}: need at least 2x2 vertices", res[0], res[1]));
}

}  // namespace

MeshData make_rectangle(const Eigen::Vector2d& size, std::array<int, 2> res, Tessellation t, int seed) {
  check(res);
  return with_plane_uv(grid(size, res, t, seed, [](int, int) { return true; }));
}

MeshData make_l_shape(const Eigen::Vector2d& size, std::array<int, 2> res, Tessellation t, int seed) {
  check(res);
  if (res[0] % 2 == 0 || res[1] % 2 == 0 || res[0] < 3 || res[1] < 3)
    throw ConfigError(fmt::format("L-shaped sheet resolution {}x{}: both must be odd and >= 3 so the cut lies on grid lines",
                                  res[0], res[1]));
  const int ci = (res[0] - 1) / 2, cj = (res[1] - 1) / 2;
  return with_plane_uv(grid(size, res, t, seed, [=](int i, int j) { return !(i >= ci && j >= cj); }));
}

void place_sheet(MeshData& m, SheetPlane plane, const Eigen::Vector3d& center) {
  for (Eigen::Index k = 0; k < m.V.rows(); ++k) {
    const Eigen::Vector3d p = m.V.row(k);
    Eigen::Vector3d q = p;
    switch (plane) {
      case SheetPlane::xy: q = {p[0], p[1], p[2]}; break;
      case SheetPlane::xz: q = {p[0], p[2], p[1]}; break;
      case SheetPlane::yz: q = {p[2], p[0], p[1]}; break;
    }
    m.V.row(k) = (q + center).transpose();
  }
}

std::vector<Eigen::Vector3d> texture_directions(const MeshData& m, double angle) {
  std::vector<std::string> errors;
  int bad = 0;
  auto report = [&](std::string msg) {
    if (++bad <= 10) errors.push_back(std::move(msg));
  };
  if (!m.has_uv()) throw ConfigError("the mesh has no texture coordinates (OBJ `vt` lines referenced by `f v/vt`)");
  const Eigen::Vector2d dir(std::cos(angle), std::sin(angle));
  std::vector<Eigen::Vector3d> out(static_cast<size_t>(m.F.rows()), Eigen::Vector3d::Zero());
  for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
    if ((m.FUV.row(f).array() < 0).any() || (m.FUV.row(f).array() >= m.UV.rows()).any()) {
      report(fmt::format("face {} has no texture coordinates", f));
      continue;
    }
    Eigen::Matrix<double, 3, 2> X;
    Eigen::Matrix2d U;
    for (int k = 0; k < 2; ++k) {
      X.col(k) = (m.V.row(m.F(f, k + 1)) - m.V.row(m.F(f, 0))).transpose();
      U.col(k) = (m.UV.row(m.FUV(f, k + 1)) - m.UV.row(m.FUV(f, 0))).transpose();
    }
    const double det = U(0, 0) * U(1, 1) - U(0, 1) * U(1, 0);
    // Zero texture area up to rounding (relative to the texture edge lengths).
    if (!(std::abs(det) > 1e-12 * std::max(U.col(0).squaredNorm(), U.col(1).squaredNorm()))) {
      report(fmt::format("face {} has a zero-area texture triangle", f));
      continue;
    }
    // J d with J = X U^-1; U^-1 = adj(U) / det.
    Eigen::Matrix2d adj;
    adj << U(1, 1), -U(0, 1), -U(1, 0), U(0, 0);
    const Eigen::Vector3d t = X * (adj * dir);
    const double n = t.norm();
    if (!(n > 0)) {
      report(fmt::format("face {} has a zero-area rest triangle", f));
      continue;
    }
    out[static_cast<size_t>(f)] = (det > 0 ? 1.0 : -1.0) * t / n;
  }
  if (bad > 10) errors.push_back(fmt::format("... and {} more faces", bad - 10));
  if (!errors.empty()) throw ConfigError("invalid texture coordinates", errors);
  return out;
}

}  // namespace weft
